"""State files (the cards' EEPROM images): where they live, written atomically and durably
(:func:`mlink_sim._files.write_atomically`: temporary file, fsync, rename, fsync of the directory). A process
killed in between leaves its temporary file behind; :func:`remove_stale_temps` clears those of a state file at
start.

Touches: the state files and their temporary files; nothing else.
"""

from __future__ import annotations

from pathlib import Path

from ..._files import stale_temps, write_atomically

__all__ = ["atomic_write", "read_state", "eeprom_path", "remove_stale_temps"]


def eeprom_path(state_dir: str | Path, card: str, address: int) -> Path:
    """Where a station keeps its EEPROM image: ``STATE_DIR/<card>-<address>H.eeprom.json``."""
    return Path(state_dir) / f"{card}-{address:02X}H.eeprom.json"


def atomic_write(path: str | Path, data: bytes) -> None:
    """Replace the state file *path* with *data* so that a crash leaves either the old or the new file, never a
    partial one; its directory is created when missing. Mode 0600: the station's own state."""
    write_atomically(path, data, mode=0o600, parents=True)


def remove_stale_temps(path: str | Path) -> int:
    """Remove the temporary files an interrupted :func:`atomic_write` of *path* left (a kill -9 between the write and
    the rename); only *path*'s own, so processes sharing a state directory keep theirs. Returns how many."""
    n = 0
    for stale in stale_temps(path):
        try:
            stale.unlink()
            n += 1
        except FileNotFoundError:
            pass
    return n


def read_state(path: str | Path) -> bytes | None:
    """The file's bytes, or None when it does not exist yet."""
    try:
        return Path(path).read_bytes()
    except FileNotFoundError:
        return None
