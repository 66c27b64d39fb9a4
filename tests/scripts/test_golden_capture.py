"""scripts/golden_capture.py: the committed golden capture (tests/wireshark/golden.pcapng) is its output."""

from __future__ import annotations

from pathlib import Path
from types import ModuleType

from .scripts_loader import ROOT, script_fixture


golden = script_fixture("golden", "golden_capture.py")


def test_golden_capture_is_the_scripts_output(golden: ModuleType, tmp_path: Path) -> None:
    out = tmp_path / "golden.pcapng"
    assert golden.write(out) == 126
    assert out.read_bytes() == (ROOT / "tests" / "wireshark" / "golden.pcapng").read_bytes(), \
        "run: python scripts/golden_capture.py"
