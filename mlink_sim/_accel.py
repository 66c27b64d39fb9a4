"""Which cores run: the mypyc-compiled modules or the pure-Python ones (docs/architecture.md, "Compiled cores
(mypyc)").

The install compiles the hot modules of the sans-I/O cores (:data:`COMPILED_MODULES`) with mypyc, each into an
extension module next to its ``.py`` file (setup.py). The ``.py`` files are the one source and the fallback.
:func:`select` runs once, when ``mlink_sim`` is imported, before any core module is, and decides for the whole
process (and the processes it starts, through the environment):

* ``MLINK_PURE=1`` in the environment: pure Python, whatever was built;
* every compiled module built from the ``.py`` next to it (by content: setup.py records each one's sha256 in
  :data:`BUILD_STAMP`) and the native library loadable: compiled;
* else pure Python, with the reason (not built: no compiler at install time or ``MLINK_BUILD_PURE=1``; a
  ``.py`` edited after the build: rebuild with ``pip install -e .``; the native library failed to load).

When the choice is pure, a finder placed first on ``sys.meta_path`` loads those modules from their ``.py``
files, so a stale or partial build is never mixed with the source. :data:`MODE` and :data:`REASON` say what was
chosen; ``mlink-sim --version``, the report's ``meta.host.cores`` and the ``cores`` log line show it.
"""

from __future__ import annotations

import hashlib
import importlib
import importlib.machinery
import os
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path
from types import ModuleType

from . import profiles  # the card profiles: the standard library only, so no compiled module is imported yet

__all__ = ["BUILD_STAMP", "BUILT_MODULES", "CORE_MODULES", "COMPILED_MODULES", "C_EXTENSIONS", "MODE", "NATIVE_LIBRARY",
           "REASON", "describe", "pure_requested", "select", "source_of"]

#: The modules mypyc compiles but the cards' own (setup.py reads this tuple): the steady-state paths of the master
#: core, the cards and the drive model, and the wire helpers they call per datagram; the virtual clock's per-event
#: path (its event queue and in-memory network), a slave worker's per-read path (aio.slave.bus), the metrics'
#: per-exchange recorder (counters, RTT histograms) and the capture writer's per-datagram loop (capture.pack, without
#: dpkt: the block layout is handed in). Not here: modules whose classes derive from RuntimeError (mypyc cannot
#: compile them: cards.phases, master.machine, master.types), the declaration tables (construct layouts, codes,
#: parameter tables, the card profiles) and everything else above the cores.
CORE_MODULES: tuple[str, ...] = (
    "mlink_sim.wire.fcs",
    "mlink_sim.wire.frame",
    "mlink_sim.wire.layout",
    "mlink_sim.drive.faults",
    "mlink_sim.drive.search",
    "mlink_sim.drive.motor",
    "mlink_sim.drive.status",
    "mlink_sim.drive.monitors",
    "mlink_sim.drive.integrate",
    "mlink_sim.drive.drive",
    "mlink_sim.cards.results",
    "mlink_sim.cards.reception",
    "mlink_sim.cards.watchdog",
    "mlink_sim.cards.prediction",
    "mlink_sim.cards.alarms",
    "mlink_sim.cards.drive_link",
    "mlink_sim.cards.monitors",
    "mlink_sim.cards.paramstore",
    "mlink_sim.cards.writeback",
    "mlink_sim.cards.snapshot",
    "mlink_sim.cards.parameters",
    "mlink_sim.cards.commands",
    "mlink_sim.cards.connection",
    "mlink_sim.cards.base",
    "mlink_sim.cards.ml2_card",
    "mlink_sim.master.plan",
    "mlink_sim.master.codec",
    "mlink_sim.master.commands",
    "mlink_sim.master.requests",
    "mlink_sim.master.restart",
    "mlink_sim.master.slave",
    "mlink_sim.master.answers",
    "mlink_sim.master.fastpath",
    "mlink_sim.master.operations",
    "mlink_sim.master.core",
    "mlink_sim.aio.virtual.vqueue",
    "mlink_sim.aio.virtual.fabric",
    "mlink_sim.aio.slave.bus",
    "mlink_sim.metrics.histogram",
    "mlink_sim.metrics.network",
    "mlink_sim.capture.pack",
)
#: Every module mypyc compiles: :data:`CORE_MODULES` and the station module of each card of the package (its profile's
#: ``station``, :data:`mlink_sim.profiles.BUILTIN`): a card added there is compiled with the rest.
COMPILED_MODULES: tuple[str, ...] = CORE_MODULES + tuple(p.module for p in profiles.BUILTIN)
#: Hand-written C extension modules of the compiled cores, each built by setup.py from the ``.c`` file of its name
#: (mlink_sim/wire/_fcsc.c: the FCS and the datagram steps around it; mlink_sim/wire/fcs.py says why by hand). The
#: module that uses one imports it when it can and keeps its pure-Python functions as the fallback; in pure mode
#: the import fails on purpose (:class:`_SourceFinder`), so the choice stays one for the whole process.
C_EXTENSIONS: tuple[str, ...] = ("mlink_sim.wire._fcsc",)
#: Everything the compiled cores are made of: the mypyc modules and the C ones.
BUILT_MODULES: tuple[str, ...] = COMPILED_MODULES + C_EXTENSIONS
#: setup.py's record of the sources it compiled (one "module sha256" line each), next to this file
BUILD_STAMP = "_accel_build.txt"
#: mypyc's shared library of the group (setup.py: ``group_name="mlink_sim_native"``), a top-level module.
NATIVE_LIBRARY = "mlink_sim_native__mypyc"

_PACKAGE_DIR = Path(__file__).resolve().parent
_SOURCE_LOADER = (importlib.machinery.SourceFileLoader, importlib.machinery.SOURCE_SUFFIXES)

#: "compiled" or "pure", set by :func:`select`.
MODE = "pure"
#: Why :data:`MODE` is what it is (one line).
REASON = "not selected yet"


def pure_requested(environ: Mapping[str, str] | None = None) -> bool:
    """``MLINK_PURE`` set to anything but empty or ``0``."""
    return (os.environ if environ is None else environ).get("MLINK_PURE", "") not in ("", "0")


class _SourceFinder:
    """Loads the compiled modules' ``.py`` files instead of their extension modules, and refuses the C extension
    modules (their users fall back to Python), in pure mode."""

    names = frozenset(COMPILED_MODULES)
    refused = frozenset(C_EXTENSIONS)

    @classmethod
    def find_spec(cls, fullname: str, path: Sequence[str] | None = None,
                  target: ModuleType | None = None) -> importlib.machinery.ModuleSpec | None:
        if fullname in cls.refused:
            raise ModuleNotFoundError(f"{fullname}: the cores run pure Python ({REASON})", name=fullname)
        if fullname not in cls.names or not path:
            return None
        for entry in path:
            spec = importlib.machinery.FileFinder(entry, _SOURCE_LOADER).find_spec(fullname)
            if spec is not None:
                return spec
        return None

    @classmethod
    def invalidate_caches(cls) -> None:
        return None


def source_of(name: str) -> Path:
    """The source file a built module is made from: its ``.py`` file, or the ``.c`` file of a C extension."""
    return _PACKAGE_DIR.joinpath(*name.split(".")[1:]).with_suffix(".c" if name in C_EXTENSIONS else ".py")


def _extension(name: str) -> Path | None:
    """The built extension module of ``name`` next to its ``.py`` file, if there is one."""
    stem = _PACKAGE_DIR.joinpath(*name.split(".")[1:])
    for suffix in importlib.machinery.EXTENSION_SUFFIXES:
        candidate = stem.with_name(stem.name + suffix)
        if candidate.exists():
            return candidate
    return None


def _built_from() -> dict[str, str]:
    """setup.py's record of the sources the extensions were built from: module -> sha256 (empty: none)."""
    try:
        text = (_PACKAGE_DIR / BUILD_STAMP).read_text(encoding="utf-8")
    except OSError:
        return {}
    return dict(line.split(" ", 1) for line in text.splitlines() if " " in line)


def _why_not_compiled() -> str | None:
    """None when every compiled module is built from the .py next to it and the native library loads; else the
    reason. "Built from" is by content (sha256, about a millisecond for all: docs/performance.md, "Builds and
    checks"), not by file times, which an install resets."""
    missing = [name for name in BUILT_MODULES if _extension(name) is None]
    if len(missing) == len(BUILT_MODULES):
        return "not built (no C compiler or mypyc at install time, or MLINK_BUILD_PURE=1)"
    if missing:
        return f"partly built ({len(missing)} of {len(BUILT_MODULES)} modules missing, e.g. {missing[0]})"
    built = _built_from()
    if not built:
        return f"no record of what was built ({BUILD_STAMP} missing; rebuild: pip install -e .)"
    stale = []
    for name in BUILT_MODULES:
        try:
            digest = hashlib.sha256(source_of(name).read_bytes()).hexdigest()
        except OSError:
            continue  # an install without the .py files: nothing to be stale against
        if built.get(name) != digest:
            stale.append(name)
    if stale:
        return f"{stale[0]} and {len(stale) - 1} more changed after the build (rebuild: pip install -e .)" \
            if len(stale) > 1 else f"{stale[0]} changed after the build (rebuild: pip install -e .)"
    try:
        importlib.import_module(NATIVE_LIBRARY)
    except ImportError as exc:
        return f"the native library {NATIVE_LIBRARY} does not load ({exc})"
    return None


def select() -> str:
    """Decide compiled or pure for this process (once; later calls return :data:`MODE`)."""
    global MODE, REASON
    if REASON != "not selected yet":
        return MODE
    if pure_requested():
        why: str | None = "MLINK_PURE is set"
    else:
        why = _why_not_compiled()
    if why is None:
        MODE, REASON = "compiled", f"mypyc, {len(COMPILED_MODULES)} modules; C, {len(C_EXTENSIONS)}"
    else:
        MODE, REASON = "pure", why
        if _SourceFinder not in sys.meta_path:
            sys.meta_path.insert(0, _SourceFinder)  # a finder class, as importlib allows
    return MODE


def describe() -> str:
    """One line: ``compiled (mypyc, 32 modules)`` or ``pure Python (<reason>)``."""
    return f"compiled ({REASON})" if MODE == "compiled" else f"pure Python ({REASON})"
