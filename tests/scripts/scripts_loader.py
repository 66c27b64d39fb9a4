"""Load a script of scripts/ as a module for its tests."""

from __future__ import annotations

import importlib.util
import sys
from collections.abc import Iterator
from pathlib import Path
from types import ModuleType
from typing import Any

import pytest

ROOT = Path(__file__).resolve().parents[2]


def load_script(filename: str, module_name: str) -> Iterator[ModuleType]:
    """Yield scripts/*filename* as module *module_name* (registered in ``sys.modules`` meanwhile: dataclasses look
    their module up); for a module-scoped fixture."""
    spec = importlib.util.spec_from_file_location(module_name, ROOT / "scripts" / filename)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[module_name] = module
    spec.loader.exec_module(module)
    yield module
    del sys.modules[module_name]


def script_fixture(name: str, filename: str) -> Any:
    """A module-scoped fixture *name* that yields scripts/*filename* loaded as ``mlink_<its stem>``
    (:func:`load_script`): ``bench = script_fixture("bench", "bench.py")``."""
    @pytest.fixture(scope="module", name=name)
    def fixture() -> Iterator[ModuleType]:
        yield from load_script(filename, "mlink_" + Path(filename).stem)

    return fixture
