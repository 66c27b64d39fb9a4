"""What several benchmarks need of the operating system and of their own processes: the repository's root, the
command that starts a benchmark module as a child process, a child that dies with its parent, and a result file
written whole or not at all."""

from __future__ import annotations

import contextlib
import importlib.machinery
import os
import sys
import tempfile
from pathlib import Path

__all__ = ["ROOT", "child_env", "cores", "module_command", "write_atomically"]

ROOT = Path(__file__).resolve().parents[1]  #: the repository's root: the package ``benchmarks`` lives in it


def child_env(env: dict[str, str] | None = None) -> dict[str, str]:
    """*env* (default: this process's environment) with the repository's root first on ``PYTHONPATH``, so that a
    child started from any directory imports ``benchmarks`` (and the ``mlink_sim`` of this checkout)."""
    env = dict(os.environ if env is None else env)
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT), *filter(None, env.get("PYTHONPATH", "").split(os.pathsep))])
    return env


def module_command(module: str, *args: str) -> list[str]:
    """The command line that runs the benchmark module *module* (``"benchmarks.floor"``) with *args*, by this
    interpreter; start it with ``env=child_env()``."""
    return [sys.executable, "-m", module, *args]


def cores(cls: type) -> str:
    """``"compiled"`` when the module that defines *cls* was loaded from a compiled extension (the install's mypyc
    build), ``"pure"`` when from its Python source: which of the two a micro-benchmark measured."""
    path = getattr(sys.modules.get(cls.__module__), "__file__", None) or ""
    return "compiled" if path.endswith(tuple(importlib.machinery.EXTENSION_SUFFIXES)) else "pure"


def write_atomically(path: str | os.PathLike[str], text: str) -> None:
    """Replace *path* with *text* (UTF-8): a temporary file in the same directory, renamed over it, so that an
    interrupted run leaves the previous result or the new one, never half of it."""
    target = Path(path)
    fd, tmp = tempfile.mkstemp(dir=target.parent or ".", prefix=f".{target.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            f.write(text)
        os.replace(tmp, target)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise
