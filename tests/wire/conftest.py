"""tests/wire: make the shared helper modules importable by name: the hypothesis strategies (``wire_strategies``)
and the golden datagrams (``wire_golden``).

pytest runs with ``--import-mode=importlib``, which does not put test directories on ``sys.path``; each helper
module is loaded here once, by path, and registered under its own (unique) name.
"""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

for _name in ("wire_strategies", "wire_golden"):
    if _name not in sys.modules:
        _spec = importlib.util.spec_from_file_location(_name, Path(__file__).with_name(f"{_name}.py"))
        assert _spec is not None and _spec.loader is not None
        _module = importlib.util.module_from_spec(_spec)
        sys.modules[_name] = _module
        _spec.loader.exec_module(_module)
