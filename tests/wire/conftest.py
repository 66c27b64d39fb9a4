"""tests/wire: make the shared hypothesis strategies importable as ``wire_strategies``.

pytest runs with ``--import-mode=importlib``, which does not put test directories on ``sys.path``; the helper
module is loaded here once, by path, and registered under its own (unique) name.
"""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

if "wire_strategies" not in sys.modules:
    _spec = importlib.util.spec_from_file_location("wire_strategies", Path(__file__).with_name("wire_strategies.py"))
    assert _spec is not None and _spec.loader is not None
    _module = importlib.util.module_from_spec(_spec)
    sys.modules["wire_strategies"] = _module
    _spec.loader.exec_module(_module)
