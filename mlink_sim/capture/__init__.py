"""Captures of the wire: pcapng files written off the hot path (:class:`CaptureWriter`, tapped sockets), read
back (:func:`read_capture`), decoded (``mlink-sim decode --pcap``) and replayed against live slaves
(``mlink-sim replay``). docs/capture.md describes the files."""

from .reader import Capture, CaptureError, CaptureFile, Datagram, read_capture
from .tap import Record, TappedSocket
from .writer import CaptureStats, CaptureWriter, event_text, ip_packet

__all__ = ["CaptureWriter", "CaptureStats", "TappedSocket", "Record", "read_capture", "Capture", "CaptureError", "CaptureFile",
           "Datagram", "ip_packet", "event_text"]
