"""A capture as text, one line (or one JSON object) per datagram: ``mlink-sim decode --pcap``."""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from typing import Any

from ..wire import Kind, WireError, decode, describe, format_line
from .reader import Datagram

__all__ = ["datagram_lines", "datagram_records", "station_of"]


def _endpoint(addr: tuple[str, int]) -> str:
    host, port = addr
    return f"[{host}]:{port}" if ":" in host else f"{host}:{port}"


def station_of(data: bytes) -> int | None:
    """The station byte of a datagram (envelope byte 3), None when it is too short to have one."""
    return data[3] if len(data) > 3 else None


def _direction(data: bytes) -> str:
    kind = data[2] if len(data) > 2 else None
    return {Kind.COMMAND: "master->slave", Kind.RESPONSE: "slave->master"}.get(kind, "?")  # type: ignore[call-overload]


def datagram_records(datagrams: Iterable[Datagram], station: int | None = None) -> Iterator[dict[str, Any]]:
    """One dict per datagram (of *station* only, when given): relative time, addresses, direction, the decoded
    frame (``describe``) or the reason it was rejected, and the capture's comments."""
    t0 = None
    for index, d in enumerate(datagrams, 1):
        t0 = d.ts_ns if t0 is None else t0
        if station is not None and station_of(d.data) != station:
            continue
        rec: dict[str, Any] = {"index": index, "t": round((d.ts_ns - t0) / 1e9, 6), "src": _endpoint(d.src),
                               "dst": _endpoint(d.dst), "direction": _direction(d.data), "length": len(d.data)}
        try:
            rec["frame"] = describe(decode(d.data))
        except WireError as exc:
            rec["error"] = str(exc)
            rec["reason"] = exc.reason.name
        if d.comments:
            rec["comments"] = list(d.comments)
        yield rec


def datagram_lines(datagrams: Iterable[Datagram], station: int | None = None) -> Iterator[tuple[str, bool]]:
    """``(line, ok)`` per datagram: ``t  src -> dst  frame`` (``format_line``), or the rejection reason; comments
    follow on their own ``#`` lines. Times count from the first datagram of the capture."""
    t0 = None
    for d in datagrams:
        t0 = d.ts_ns if t0 is None else t0
        if station is not None and station_of(d.data) != station:
            continue
        head = f"{(d.ts_ns - t0) / 1e9:11.6f}  {_endpoint(d.src)} -> {_endpoint(d.dst)}  "
        try:
            line, ok = head + format_line(decode(d.data)), True
        except WireError as exc:
            line, ok = head + f"REJECTED {exc} ({len(d.data)} bytes)", False
        yield line, ok
        for comment in d.comments:
            yield f"{'':11}  # {comment}", True
