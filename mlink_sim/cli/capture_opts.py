"""``--capture FILE.pcapng`` and ``--capture-max SIZE``, shared by ``up``, ``master`` and ``slave``; ``--capture -``
writes the pcapng stream to standard output (:func:`claim_stdout`)."""

from __future__ import annotations

import os
import re
import sys
from pathlib import Path
from typing import Any

import click

from .params import Parsed

__all__ = ["capture_options", "parse_size", "open_capture_or_exit", "claim_stdout"]

_UNITS = {"": 1, "b": 1, "k": 10**3, "kb": 10**3, "m": 10**6, "mb": 10**6, "g": 10**9, "gb": 10**9,
          "kib": 2**10, "mib": 2**20, "gib": 2**30}


def parse_size(text: str) -> int:
    """``100MB`` -> 100 000 000 (k/M/G are powers of 10, KiB/MiB/GiB of 2); ValueError says what is expected."""
    m = re.fullmatch(r"\s*(\d+(?:\.\d+)?)\s*([a-zA-Z]*)\s*", text)
    unit = m.group(2).lower() if m else ""
    if not m or unit not in _UNITS:
        raise ValueError(f"expected a size such as 100MB, 512KiB or 2000000, got {text!r}")
    value = int(float(m.group(1)) * _UNITS[unit])
    if value < 4096:
        raise ValueError(f"a capture needs at least 4096 bytes, got {text!r}")
    return value


def capture_options(fn: Any) -> Any:
    fn = click.option("--capture-max", "capture_max", type=Parsed("SIZE", parse_size, int), default="100MB",
                      show_default=True,
                      help="The capture stops growing at this size (the rest is counted, not written).")(fn)
    return click.option("--capture", "capture_path", type=click.Path(dir_okay=False, path_type=Path),
                        help="Record every datagram sent and received to this pcapng file (Wireshark: "
                             "'mlink-sim wireshark --install'); '-': a live pcapng stream on stdout (| wireshark -k "
                             "-i -, | mlink-sim watch -), everything else the command prints goes to stderr.")(fn)


def open_capture_or_exit(command: str, path: Path | None, max_bytes: int, *, background: bool = True) -> Any:
    """A started CaptureWriter (None without --capture); exit 2 with one line when the file cannot be created, or
    for ``-`` when stdout is a terminal. *background*: False on the virtual clock, whose session writes the capture
    in place (``CaptureWriter.flush``)."""
    if path is None:
        return None
    from ..capture import CaptureWriter

    if str(path) == "-":
        if sys.stdout.isatty():
            click.echo(f"mlink-sim {command}: --capture - writes a binary pcapng stream: pipe it (| wireshark -k -i -, "
                       "| tshark -r -, | mlink-sim watch -) or give a file name", err=True)
            raise SystemExit(2)
        return CaptureWriter("-", max_bytes=max_bytes, stream=claim_stdout()).start(background=background)
    try:
        return CaptureWriter(path, max_bytes=max_bytes).start(background=background)
    except OSError as exc:
        click.echo(f"mlink-sim {command}: cannot write the capture {path}: {exc.strerror or exc}", err=True)
        raise SystemExit(2) from None


def claim_stdout() -> Any:
    """Standard output for a binary stream of this process's own: the stream gets a duplicate of file descriptor 1
    (unbuffered, not inherited by child processes), and descriptor 1 becomes a duplicate of 2, so that whatever else
    the process and its children print to stdout (the live status, the summary, notices) goes to stderr and never
    into the stream."""
    sys.stdout.flush()
    fd = os.dup(1)
    os.dup2(2, 1)
    return open(fd, "wb", buffering=0)
