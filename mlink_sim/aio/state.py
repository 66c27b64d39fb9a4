"""Atomic state files (the cards' EEPROM images): written to a temporary file, fsynced, renamed, and the directory
fsynced. A process killed in between leaves its temporary file behind; :func:`remove_stale_temps` clears those of a
state file at start."""

from __future__ import annotations

import glob
import os
import tempfile
from pathlib import Path

__all__ = ["atomic_write", "read_state", "eeprom_path", "remove_stale_temps"]

_TEMP_SUFFIX = ".tmp"


def eeprom_path(state_dir: str | Path, card: str, address: int) -> Path:
    """Where a station keeps its EEPROM image: ``STATE_DIR/<card>-<address>H.eeprom.json``."""
    return Path(state_dir) / f"{card}-{address:02X}H.eeprom.json"


def atomic_write(path: str | Path, data: bytes) -> None:
    """Replace *path* with *data* so that a crash leaves either the old or the new file, never a partial one."""
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=_temp_prefix(p), suffix=_TEMP_SUFFIX, dir=p.parent)
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, p)
    except BaseException:
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass
        raise
    dir_fd = os.open(p.parent, os.O_RDONLY)
    try:
        os.fsync(dir_fd)
    finally:
        os.close(dir_fd)


def remove_stale_temps(path: str | Path) -> int:
    """Remove the temporary files an interrupted :func:`atomic_write` of *path* left (a kill -9 between the write and
    the rename); only *path*'s own, so processes sharing a state directory keep theirs. Returns how many."""
    p = Path(path)
    n = 0
    for stale in p.parent.glob(f"{glob.escape(_temp_prefix(p))}*{_TEMP_SUFFIX}"):
        try:
            stale.unlink()
            n += 1
        except FileNotFoundError:
            pass
    return n


def _temp_prefix(p: Path) -> str:
    return f".{p.name}."


def read_state(path: str | Path) -> bytes | None:
    """The file's bytes, or None when it does not exist yet."""
    try:
        return Path(path).read_bytes()
    except FileNotFoundError:
        return None
