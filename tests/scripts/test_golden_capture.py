"""scripts/golden_capture.py: the committed golden capture (tests/wireshark/golden.pcapng) is its output."""

from __future__ import annotations

import importlib.util
import sys
from collections.abc import Iterator
from pathlib import Path
from types import ModuleType

import pytest

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def golden() -> Iterator[ModuleType]:
    """scripts/golden_capture.py (a script, not a module of a package), loaded from its file."""
    spec = importlib.util.spec_from_file_location("golden_capture", ROOT / "scripts" / "golden_capture.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # its dataclasses look their module up
    spec.loader.exec_module(module)
    yield module
    del sys.modules[spec.name]


def test_golden_capture_is_the_scripts_output(golden: ModuleType, tmp_path: Path) -> None:
    out = tmp_path / "golden.pcapng"
    assert golden.write(out) == 126
    assert out.read_bytes() == (ROOT / "tests" / "wireshark" / "golden.pcapng").read_bytes(), \
        "run: python scripts/golden_capture.py"
