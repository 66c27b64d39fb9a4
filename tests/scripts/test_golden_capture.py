"""scripts/golden_capture.py: the committed golden capture (tests/wireshark/golden.pcapng) is its output."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from types import ModuleType

import pytest

from .scripts_loader import ROOT, load_script


@pytest.fixture(scope="module")
def golden() -> Iterator[ModuleType]:
    yield from load_script("golden_capture.py", "mlink_golden_capture")


def test_golden_capture_is_the_scripts_output(golden: ModuleType, tmp_path: Path) -> None:
    out = tmp_path / "golden.pcapng"
    assert golden.write(out) == 126
    assert out.read_bytes() == (ROOT / "tests" / "wireshark" / "golden.pcapng").read_bytes(), \
        "run: python scripts/golden_capture.py"
