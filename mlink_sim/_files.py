"""Durable, atomic file writes: the one helper behind the EEPROM images (``aio/slave/state.py``), the run report
(``metrics/report.py``), the compose file (``cli/compose.py``) and the installed Wireshark dissector.

The data go to a temporary file in the target's directory (``.<name>.<random>.tmp``), which is flushed,
fsync'ed, given its mode and renamed over the target with :func:`os.replace`; then the directory is fsync'ed so
that the rename itself survives a power loss. A crash leaves either the old file or the new one, never a partial
one; only a process killed between the write and the rename leaves its temporary file behind
(:func:`stale_temps` finds those). On any error the temporary file is removed and the target is untouched.

A leaf module of the I/O layers (no import of ours): the sans-I/O cores never write files.
"""

from __future__ import annotations

import errno
import glob
import os
import tempfile
from pathlib import Path

__all__ = ["stale_temps", "write_atomically"]

_TEMP_SUFFIX = ".tmp"

# fsync on a directory: file systems that cannot (some FUSE and network ones) answer EINVAL or ENOTSUP; the
# rename is then as durable as that file system makes it. Any other error is the caller's.
_DIR_SYNC_UNSUPPORTED = frozenset({errno.EINVAL, errno.ENOTSUP, errno.EOPNOTSUPP})


def _temp_prefix(path: Path) -> str:
    return f".{path.name}."


def write_atomically(path: str | os.PathLike[str], data: bytes | str, *, mode: int | None = None,
                     parents: bool = False) -> None:
    """Replace *path* with *data* (``str`` is written as UTF-8), durably: temp file, fsync, rename, fsync dir.

    *mode*: the new file's permission bits; None keeps those of the file replaced, else 0644. *parents*: create
    missing parent directories (else a missing directory raises :class:`FileNotFoundError`)."""
    target = Path(path)
    directory = target.parent
    if parents:
        directory.mkdir(parents=True, exist_ok=True)
    if mode is None:
        try:
            mode = target.stat().st_mode & 0o7777
        except FileNotFoundError:
            mode = 0o644
    payload = data.encode("utf-8") if isinstance(data, str) else data
    fd, tmp = tempfile.mkstemp(prefix=_temp_prefix(target), suffix=_TEMP_SUFFIX, dir=directory)
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(payload)
            f.flush()
            os.fsync(f.fileno())
        os.chmod(tmp, mode)
        os.replace(tmp, target)
    except BaseException:
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass
        raise
    _fsync_dir(directory)


def _fsync_dir(directory: Path) -> None:
    """Persist a rename in *directory*."""
    dfd = os.open(directory, os.O_RDONLY)
    try:
        os.fsync(dfd)
    except OSError as exc:
        if exc.errno not in _DIR_SYNC_UNSUPPORTED:
            raise
    finally:
        os.close(dfd)


def stale_temps(path: str | os.PathLike[str]) -> list[Path]:
    """The temporary files an interrupted :func:`write_atomically` of *path* left behind (a kill -9 between the
    write and the rename); only *path*'s own, so processes sharing a directory keep theirs."""
    p = Path(path)
    return sorted(p.parent.glob(f"{glob.escape(_temp_prefix(p))}*{_TEMP_SUFFIX}"))
