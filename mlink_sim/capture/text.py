"""A capture as text, one line (or one JSON object) per datagram: ``mlink-sim decode --pcap`` (its filters:
:class:`Selection`, which :func:`select_items` applies; the figures per station and command: :mod:`.stats`)."""

from __future__ import annotations

import re
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from typing import Any, Protocol

from ..wire import Frame, Kind, WireError, decode, describe, format_line
from .reader import Datagram

__all__ = ["datagram_lines", "datagram_records", "select_items", "Item", "Names", "Selection", "station_of", "card_note",
           "card_of_note", "speed_of_note", "stations_of_note"]

_CARD_NOTE = re.compile(r"^station ([0-9A-F]{2})H: card (\S+)")
_SPEED_NOTE = re.compile(r"speed in ([0-9.]+(?:[eE][-+]?\d+)?) Hz counts")
_NOTE_STATION = re.compile(r"station (?:([0-9A-Fa-f]{2})H|0x([0-9A-Fa-f]{1,2}))\b")


def card_note(station: int, card: str, detail: str = "", hz_per_count: float = 0.0) -> str:
    """The note that tells a reader of the capture which card *station* is: ``station 21H: card SI-T3 …``
    (``mlink-sim decode`` names its parameters by it), and, with *hz_per_count*, the units of its INV_CTL speed
    reference and output frequency (``…, speed in 0.01 Hz counts``: the drive's o1-03 / n035 as it was set)."""
    speed = f", speed in {hz_per_count:.9g} Hz counts" if hz_per_count > 0 else ""
    return f"station {station:02X}H: card {card}{(' ' + detail) if detail else ''}{speed}"


def speed_of_note(text: str) -> float | None:
    """The Hz of one speed count a :func:`card_note` names, None when it names none."""
    m = _SPEED_NOTE.search(text)
    return float(m.group(1)) if m and card_of_note(text) else None


def card_of_note(text: str) -> tuple[int, str] | None:
    """``(station, card)`` of a :func:`card_note`, None for any other note."""
    m = _CARD_NOTE.match(text)
    return (int(m.group(1), 16), m.group(2)) if m else None


def stations_of_note(text: str) -> set[int]:
    """The stations a note names (``station 21H``, ``station 0x21``); empty for a note about none."""
    return {int(a or b, 16) for a, b in _NOTE_STATION.findall(text)}


def _endpoint(addr: tuple[str, int]) -> str:
    host, port = addr
    return f"[{host}]:{port}" if ":" in host else f"{host}:{port}"


def station_of(data: bytes) -> int | None:
    """The station byte of a datagram (envelope byte 3), None when it is too short to have one."""
    return data[3] if len(data) > 3 else None


def _direction(data: bytes) -> str:
    kind = data[2] if len(data) > 2 else None
    return {Kind.COMMAND: "master->slave", Kind.RESPONSE: "slave->master"}.get(kind, "?")  # type: ignore[call-overload]


class Names(Protocol):
    """What adds names to a decoded frame (``mlink_sim.cli.frame_names.FrameNames``: parameters and units where
    the card is known); the capture layer only hands it the frames and the notes."""

    def learn(self, comment: str) -> None: ...

    def describe(self, frame: Frame) -> dict[str, Any]: ...


@dataclass(frozen=True)
class Selection:
    """Which datagrams of a capture to show: one *station* (with the notes about it, wherever they were
    recorded, and without the notes about other stations), main or sub-commands named in *commands* (then only
    the notes on the datagrams shown), and a time range *from_ns* … *to_ns* since the first datagram of the
    capture (both ends included). A note about no station goes with the datagram it was recorded on."""

    station: int | None = None
    commands: frozenset[str] = frozenset()
    from_ns: int | None = None
    to_ns: int | None = None


@dataclass
class Item:
    """One datagram of a capture as a :class:`Selection` sees it, decoded, with the notes to show with it."""

    index: int
    t_ns: int
    datagram: Datagram
    shown: bool  #: the datagram itself passes the selection
    notes: list[str]  #: the notes to show with it (a note about the selected station, also on a hidden datagram)
    frame: Frame | None = None
    error: WireError | None = None
    described: dict[str, Any] | None = None


def _command_names(d: dict[str, Any]) -> set[str]:
    return {d["main"]["command"], *([d["sub"]["command"]] if "sub" in d else [])}


def select_items(datagrams: Iterable[Datagram], sel: Selection, names: Names | None) -> Iterator[Item]:
    """The datagrams of *sel* (``shown``) and those carrying notes about its station, decoded (``describe``, with
    *names*' additions); times since the first datagram of the capture."""
    t0 = None
    for index, d in enumerate(datagrams, 1):
        t0 = d.ts_ns if t0 is None else t0
        t_ns = d.ts_ns - t0
        if names is not None:
            for comment in d.comments:
                names.learn(comment)
        if (sel.from_ns is not None and t_ns < sel.from_ns) or (sel.to_ns is not None and t_ns > sel.to_ns):
            continue
        item = Item(index, t_ns, d, sel.station is None or station_of(d.data) == sel.station, [])
        if item.shown:
            try:
                item.frame = decode(d.data)
            except WireError as exc:
                item.error = exc
            if item.frame is not None:
                item.described = names.describe(item.frame) if names is not None else describe(item.frame)
            if sel.commands and (item.described is None or not _command_names(item.described) & sel.commands):
                item.shown = False
        for comment in d.comments:
            about = stations_of_note(comment)
            if sel.station is not None and about and not sel.commands:
                keep = sel.station in about  # about the station, wherever it was recorded
            else:
                keep = item.shown and (sel.station is None or not about or sel.station in about)
            if keep:
                item.notes.append(comment)
        if item.shown or item.notes:
            yield item


def datagram_records(datagrams: Iterable[Datagram], station: int | None = None, *,
                     selection: Selection | None = None, names: Names | None = None) -> Iterator[dict[str, Any]]:
    """One dict per datagram of the *selection* (or of *station* only, when given): relative time, addresses,
    direction, the decoded frame (``describe``, with *names*' additions) or the reason it was rejected, and the
    capture's comments. A note about the selected station recorded on another station's datagram comes as a
    dict of its own: ``index``, ``t``, ``comments``, ``note_only`` true."""
    sel = selection or Selection(station=station)
    for item in select_items(datagrams, sel, names):
        d = item.datagram
        t = round(item.t_ns / 1e9, 6)
        if not item.shown:
            yield {"index": item.index, "t": t, "comments": item.notes, "note_only": True}
            continue
        rec: dict[str, Any] = {"index": item.index, "t": t, "src": _endpoint(d.src), "dst": _endpoint(d.dst),
                               "direction": _direction(d.data), "length": len(d.data)}
        if item.described is not None:
            rec["frame"] = item.described
        elif item.error is not None:
            rec["error"] = str(item.error)
            rec["reason"] = item.error.reason.name
        if item.notes:
            rec["comments"] = item.notes
        yield rec


def datagram_lines(datagrams: Iterable[Datagram], station: int | None = None, *,
                   selection: Selection | None = None, names: Names | None = None) -> Iterator[tuple[str, bool]]:
    """``(line, ok)`` per datagram of the *selection*: ``t  src -> dst  frame`` (``format_line``, with *names*'
    additions), or the rejection reason; comments follow on their own ``#`` lines (a note about the selected
    station recorded on another station's datagram: ``t  # note``). Times count from the first datagram of the
    capture."""
    sel = selection or Selection(station=station)
    for item in select_items(datagrams, sel, names):
        d = item.datagram
        stamp = f"{item.t_ns / 1e9:11.6f}"
        if item.shown:
            head = f"{stamp}  {_endpoint(d.src)} -> {_endpoint(d.dst)}  "
            if item.frame is not None:
                yield head + format_line(item.frame, item.described), True
            else:
                yield head + f"REJECTED {item.error} ({len(d.data)} bytes)", False
            stamp = ""
        for comment in item.notes:
            yield f"{stamp:11}  # {comment}", True
