"""What the command-line tests share: tshark with the shipped dissector (installed on demand, as the dissector
tests have it)."""

from tests.wireshark.conftest import tshark

__all__ = ["tshark"]
