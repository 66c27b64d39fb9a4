"""Build of mlink-sim: the metadata is in pyproject.toml; this file adds the optional compiled cores.

The sans-I/O cores' hot modules (:data:`mlink_sim._accel.COMPILED_MODULES`: its ``CORE_MODULES``, read from
mlink_sim/_accel.py by its syntax tree, and the cards' station modules, read from mlink_sim/profiles.py) are
compiled with mypyc, as written, from their type annotations (docs/performance.md, "Compiled cores"). Each
compiled module is an extension module next to its ``.py`` file; the ``.py`` stays the one source and the
pure-Python fallback. The hand-written C modules (:data:`mlink_sim._accel.C_EXTENSIONS`, e.g. the FCS in
mlink_sim/wire/_fcsc.c) are built with them; the module that uses one keeps Python functions for the same work.

Without a C compiler (or mypy), or with ``MLINK_BUILD_PURE=1``, the install goes on without the extensions and
says so; the package then runs the pure-Python modules and reports it (``mlink-sim --version``).
"""

from __future__ import annotations

import ast
import hashlib
import importlib.util
import os
import shutil
import sys
from pathlib import Path
from typing import Any

from setuptools import Extension, setup
from setuptools.command.build_ext import build_ext

ROOT = Path(__file__).resolve().parent


#: mypy's options for the build, not pyproject's [tool.mypy]: the build environment has mypy but not the runtime
#: dependencies (pydantic's plugin, structlog, construct), whose types then count as Any; pyproject's per-package
#: override for the cards and the master (union-attr) is repeated here. Errors are reported in the compiled modules
#: only (``--follow-imports=silent``): the modules they import are read for their types, and pyproject's mypy run
#: checks them with the pydantic plugin (without it, a pydantic ``Field(default_factory=…)`` is an error, and
#: the virtual clock's fabric imports the config units through the impairment layer).
MYPY_OPTIONS = ["--config-file", os.devnull, "--ignore-missing-imports", "--follow-imports=silent",
                "--disable-error-code", "union-attr"]


def _say(message: str) -> None:
    print(f"mlink-sim build: {message}", file=sys.stderr, flush=True)


def _names(tuple_name: str) -> list[str]:
    """A tuple of module names in mlink_sim/_accel.py (parsed, not imported)."""
    tree = ast.parse((ROOT / "mlink_sim" / "_accel.py").read_text(encoding="utf-8"))
    for node in tree.body:
        if isinstance(node, ast.AnnAssign | ast.Assign):
            targets = [node.target] if isinstance(node, ast.AnnAssign) else node.targets
            if any(isinstance(t, ast.Name) and t.id == tuple_name for t in targets):
                assert node.value is not None
                return list(ast.literal_eval(node.value))
    raise SystemExit(f"setup.py: {tuple_name} not found in mlink_sim/_accel.py")


def _card_modules() -> list[str]:
    """The station modules of the package's cards (``mlink_sim.profiles.BUILTIN``, as ``_accel.COMPILED_MODULES``
    adds them): profiles.py is a leaf of the standard library, loaded from its file without the package."""
    spec = importlib.util.spec_from_file_location("_mlink_sim_profiles", ROOT / "mlink_sim" / "profiles.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look their module up while the class is made
    try:
        spec.loader.exec_module(module)
    finally:
        del sys.modules[spec.name]
    return [profile.module for profile in module.BUILTIN]


def _modules() -> list[str]:
    """The mypyc modules' file paths (``_accel.COMPILED_MODULES``: ``CORE_MODULES`` and the cards' modules)."""
    return [name.replace(".", "/") + ".py" for name in _names("CORE_MODULES") + _card_modules()]


def _c_sources() -> dict[str, str]:
    """The hand-written C extension modules (``C_EXTENSIONS``): module name -> its ``.c`` file."""
    return {name: name.replace(".", "/") + ".c" for name in _names("C_EXTENSIONS")}


class OptionalBuildExt(build_ext):
    """build_ext that reuses an up-to-date extension from the source tree and says so when one does not compile.

    Reuse: pip builds in a fresh temporary directory each time, so without it every ``pip install -e .`` (which
    scripts/test and scripts/up run) would compile the cores again, minutes each time (docs/performance.md,
    "Builds and checks"). mypyc rewrites its C
    files only when they change, so an extension in the tree newer than its C sources (those under build/; the
    runtime's own files come with the pinned mypy, checked by the stamp) is the same build.
    Failure: each extension is ``optional``, so the install goes on; mlink_sim._accel then runs the whole
    package pure and says why."""

    def run(self) -> None:
        stamp = ROOT / "build" / "mypyc-version"
        self._reuse = stamp.exists() and stamp.read_text(encoding="utf-8") == _mypy_version()
        self._failed = False
        super().run()
        if self.extensions and not self._failed:
            stamp.parent.mkdir(parents=True, exist_ok=True)
            stamp.write_text(_mypy_version(), encoding="utf-8")
            # what the extensions were built from, for mlink_sim._accel (next to it, in the wheel and the tree)
            targets = [Path(self.build_lib) / "mlink_sim"]
            if self.inplace or self.editable_mode:
                targets.append(ROOT / "mlink_sim")
            text = _source_stamp()
            for folder in targets:
                folder.mkdir(parents=True, exist_ok=True)
                (folder / BUILD_STAMP).write_text(text, encoding="utf-8")

    def build_extension(self, ext: Any) -> None:
        built = ROOT / self.get_ext_filename(ext.name)
        target = Path(self.get_ext_fullpath(ext.name))
        if self._reuse and built != target.resolve() and _current(built, ext.sources + list(ext.depends)):
            target.parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(built, target)  # a new mtime: the copy is as current as the .py files it was checked
            shutil.copymode(built, target)  # against (mlink_sim._accel compares the two)
            _say(f"{ext.name}: its C sources are unchanged, the extension in the tree is reused")
            return
        try:
            super().build_extension(ext)
        except Exception as exc:  # any compiler failure: the module stays pure (reported)
            self._failed = True
            _say(f"the compiled cores could not be built ({type(exc).__name__}: {exc}); "
                 "the pure-Python modules will be used")
            raise


def _current(built: Path, sources: list[str]) -> bool:
    """``built`` exists and is newer than its own C sources: mypyc's under build/, or a hand-written module's."""
    if not built.exists():
        return False
    mtime = built.stat().st_mtime
    own = [Path(src) for src in sources
           if any((ROOT / src).resolve().is_relative_to(ROOT / folder) for folder in ("build", "mlink_sim"))]
    return bool(own) and all((ROOT / src).stat().st_mtime < mtime for src in own)


#: The sources the compiled modules were built from: one line "module sha256" each (mlink_sim._accel reads it).
BUILD_STAMP = "_accel_build.txt"


def _source_stamp() -> str:
    lines = []
    for path in _modules():
        name = path[: -len(".py")].replace("/", ".")
        lines.append(f"{name} {hashlib.sha256((ROOT / path).read_bytes()).hexdigest()}\n")
    for name, path in _c_sources().items():
        lines.append(f"{name} {hashlib.sha256((ROOT / path).read_bytes()).hexdigest()}\n")
    return "".join(lines)


def _mypy_version() -> str:
    from mypy.version import __version__

    return __version__


def _ext_modules() -> list[object]:
    if os.environ.get("MLINK_BUILD_PURE", "") not in ("", "0"):
        _say("MLINK_BUILD_PURE is set: the compiled cores are not built; the pure-Python modules will be used")
        return []
    try:
        from mypyc.build import mypycify
    except ImportError as exc:
        _say(f"mypyc is not available ({exc}); the pure-Python modules will be used")
        return []
    cwd = os.getcwd()
    os.chdir(ROOT)  # mypyc writes its C files to build/ from here
    try:
        exts = mypycify([*MYPY_OPTIONS, *_modules()], opt_level="3", group_name="mlink_sim_native")
    except (Exception, SystemExit) as exc:  # noqa: BLE001  # a type error mypyc refuses: build pure
        _say(f"mypyc failed ({exc!r}); the pure-Python modules will be used")
        return []
    finally:
        os.chdir(cwd)
    # the C modules are built with the mypyc ones or not at all: the cores are compiled as a whole (mlink_sim._accel)
    exts = [*exts, *(Extension(name, [path], extra_compile_args=["-O2"]) for name, path in _c_sources().items())]
    for ext in exts:
        ext.optional = True  # a failed compile or link leaves that module pure instead of failing the install
    return list(exts)


#: Only the commands that build extensions run mypyc (its type check alone takes seconds): pip also runs this file
#: for the build requirements and the metadata.
_BUILDS = {"build", "build_ext", "bdist_wheel", "editable_wheel", "develop", "install"}


setup(ext_modules=_ext_modules() if _BUILDS & set(sys.argv[1:]) else [], cmdclass={"build_ext": OptionalBuildExt})
