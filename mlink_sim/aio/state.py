"""Atomic state files (the cards' EEPROM images): written to a temporary file, fsynced, then renamed."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

__all__ = ["atomic_write", "read_state", "eeprom_path"]


def eeprom_path(state_dir: str | Path, card: str, address: int) -> Path:
    """Where a station keeps its EEPROM image: ``STATE_DIR/<card>-<address>H.eeprom.json``."""
    return Path(state_dir) / f"{card}-{address:02X}H.eeprom.json"


def atomic_write(path: str | Path, data: bytes) -> None:
    """Replace *path* with *data* so that a crash leaves either the old or the new file, never a partial one."""
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{p.name}.", suffix=".tmp", dir=p.parent)
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


def read_state(path: str | Path) -> bytes | None:
    """The file's bytes, or None when it does not exist yet."""
    try:
        return Path(path).read_bytes()
    except FileNotFoundError:
        return None
