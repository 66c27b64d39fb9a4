"""What ``mlink-sim watch`` shows, as python-can's ``can.viewer`` shows a CAN bus: one row per station, direction and
command, with how many came, their rate, and the last one decoded into named fields, the fields that changed since
the one before marked.

The table is fed datagrams (:meth:`WatchTable.add`) and keeps time by the capture's own timestamps, so that a
capture read from a file or a pipe shows the rates it was recorded at. A field is *changed* when its value differs
from the row's at the screen before, and stays marked for :data:`MARK_NS` after it last changed, so that a single
change is seen on a screen redrawn a few times a second. The envelope's counters (cycle, WDT, RWDT) change with
every datagram and are not fields: the rate says they come.

Fields, as a reader of the manuals names them: INV_CTL's speed reference and output frequency in Hz by the
station's units (``ref``/``out``, o1-03 / n035: *scale*, :mod:`mlink_sim.cli.speed_units`), the operation signals
and status bits by name (SI-T3 Table 16 and "STATUS Field", SI-ET3 Table 20 and "INVCMD_STAT"), a PRM_RD / PRM_WR
by its parameter and value in units where *names* knows the card (``mlink-sim decode``'s names), the alarm codes by
name; every other body field as ``name=value``.
"""

from __future__ import annotations

import enum
from collections import deque
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import Any

from ..wire import MAGIC, HEADER_SIZE, Kind, Link, M2Cmd, M3Cmd, WireError, datagram_size, decode, describe, ml2, ml3
from ..wire.codes import InvCmdCtrl, InvCmdStat, M2Status, M2SubStatus, OperationSignal
from ..wire.frame import datagram_offset, fcs_ok
from .reader import Datagram
from .text import Names

__all__ = ["WatchTable", "Row", "RATE_WINDOW_NS", "MARK_NS", "frame_fields"]

RATE_WINDOW_NS = 1_000_000_000  #: the rate counts the datagrams of the last second of the capture
MARK_NS = 2_000_000_000  #: a changed field stays marked this long after its last change
_ENVELOPE = frozenset({"link", "kind", "station", "cycle", "tcycle_ns", "data_size", "wdt", "rwdt", "main", "sub",
                       "alarm_name", "status_bits", "substatus_bits"})
_BODY_SKIP = frozenset({"command", "code", "param", "no", "size", "parameter", "data"})
#: bit fields named by their flags (the manuals' tables in the module docstring)
_FLAGS: dict[str, type[enum.IntFlag]] = {"signals": OperationSignal, "invcmd_ctrl": InvCmdCtrl,
                                         "invcmd_stat": InvCmdStat, "status": M2Status, "substatus": M2SubStatus}
#: Hz fields of INV_CTL: body field -> its label
_HZ = {"speed_ref": "ref", "output_freq": "out"}

#: Hz of raw counts for a station: ``scale(link, station) -> (raw -> Hz)``
Scale = Callable[[str, int], Callable[[int], float]]


def _flag_text(flags: type[enum.IntFlag], value: int) -> str:
    names = [m.name for m in flags if m.name and m.value.bit_count() == 1 and value & m.value]
    return "|".join(names) or "-"


def _body_fields(body: dict[str, Any], hz: Callable[[int], float] | None, prefix: str) -> Iterator[tuple[str, str]]:
    param = body.get("param")
    if param is not None:
        yield f"{prefix}param", str(param["text"])
    elif body.get("command") in ("PRM_RD", "PRM_WR"):
        for key in ("no", "size", "parameter", "data"):
            if key in body:
                value = body[key]
                yield f"{prefix}{key}", f"{value:04X}H" if key == "no" else str(value)
    for key, value in body.items():
        if key in _BODY_SKIP or key.endswith("_bits"):
            continue
        if key in _HZ and hz is not None and body.get("command") == "INV_CTL":
            yield f"{prefix}{_HZ[key]}", f"{hz(value):.2f} Hz"
        elif key in _FLAGS and isinstance(value, int):
            yield f"{prefix}{key}", _flag_text(_FLAGS[key], value)
        else:
            yield f"{prefix}{key}", str(value)


#: the order fields are shown in, so that a narrow screen keeps the telling ones: the speed in Hz, the signals and
#: status bits, the alarms, the parameter, the other body fields, then the ready bits
_ORDER = {"ref": 0, "out": 0, "signals": 1, "invcmd_ctrl": 1, "status": 1, "invcmd_stat": 1, "alarm": 2,
          "cmd_alm": 2, "comm_alm": 2, "subcmd_alm": 2, "param": 3, "cmd_stat": 5, "sub_stat": 5, "substatus": 5,
          "cmd_ctrl": 5}


def frame_fields(d: dict[str, Any], hz: Callable[[int], float] | None = None) -> list[tuple[str, str]]:
    """The fields of a described frame (``describe``, with a reader's names) as ``(name, text)``, the telling ones
    first (:data:`_ORDER`). With a sub-command other than NOP, the fields are the sub-command's (``sub.NAME``) and
    the station's state: the main command has a row of its own. A zero ALARM, CMD_ALM, COMM_ALM or SUBCMD_ALM is
    left out (an alarm that comes is a field that appears)."""
    out: list[tuple[str, str]] = []
    for key, value in d.items():
        if key in _ENVELOPE:
            continue
        if key == "alarm":
            if value:
                out.append(("alarm", f"{value:02X}H {d.get('alarm_name') or ''}".strip()))
        elif key in _FLAGS and isinstance(value, int):
            out.append((key, _flag_text(_FLAGS[key], value)))
        elif key in ("cmd_stat", "sub_stat"):
            out.append((key, "|".join(k.upper() for k, v in value.items() if v is True) or "-"))
            for alm in ("cmd_alm", "comm_alm", "subcmd_alm"):
                if value.get(alm):
                    out.append((alm, f"{value[alm]:X}H {value.get(alm + '_name') or ''}".strip()))
        elif key == "cmd_ctrl":
            if value.get("alm_clr"):
                out.append(("cmd_ctrl", "ALM_CLR"))
        elif not isinstance(value, dict):
            out.append((key, str(value)))
    sub = d.get("sub")
    if sub is not None and sub["command"] != "NOP":
        out.extend(_body_fields(sub, hz, "sub."))
    else:
        out.extend(_body_fields(d["main"], hz, ""))
    return sorted(out, key=lambda f: _ORDER.get(f[0].removeprefix("sub."), 4))


#: where the sub-command's code sits in the frames that carry one (link, datagram length) -> offset
_SUBCODE_AT: dict[tuple[int, int], int] = {
    (int(Link.ML2), datagram_size(32)): datagram_offset("subcode", ml2.COMMAND_FRAME_32, ml2.RESPONSE_FRAME_32),
    (int(Link.ML3), datagram_size(64)): datagram_offset("subcode", ml3.COMMAND_FRAME_64, ml3.RESPONSE_FRAME_64)}
_CODE_AT = datagram_offset("code", ml2.COMMAND_FRAME_17, ml2.RESPONSE_FRAME_17, ml3.COMMAND_FRAME_32,
                           ml3.RESPONSE_FRAME_32)
#: the datagram lengths each link allows (SI-T3 Table 29 note <3>, SI-ET3 Table 28)
_LENGTHS = {(int(link), datagram_size(n)) for link in Link for n in link.data_sizes}
_KINDS = {int(Kind.COMMAND): "cmd", int(Kind.RESPONSE): "rsp"}


def _code_name(link: int, code: int) -> str:
    table: Any = M3Cmd if link == Link.ML3 else M2Cmd
    try:
        return str(table(code).name)
    except ValueError:
        return f"{code:02X}H"


@dataclass
class Row:
    """One station, direction and command: how many came, when, the latest datagram and the fields shown."""

    station: int
    kind: str  #: ``cmd`` or ``rsp``
    command: str  #: the main command, ``/SUB`` when a sub-command other than NOP rides along
    count: int = 0
    first_ns: int = 0
    last_ns: int = 0
    latest: bytes = b""  #: the latest datagram
    fields: list[tuple[str, str]] = field(default_factory=list)  #: of the datagram :meth:`WatchTable.refresh` took
    shown: bytes = b""  #: that datagram
    #: field name -> the capture time it last changed
    changed_at: dict[str, int] = field(default_factory=dict)
    arrivals: deque[int] = field(default_factory=deque)

    def changed(self, now_ns: int) -> set[str]:
        """The fields that changed less than :data:`MARK_NS` before *now_ns*."""
        return {name for name, at in self.changed_at.items() if now_ns - at < MARK_NS}

    def rate(self, now_ns: int, start_ns: int | None) -> float:
        """Datagrams per second: those of the last :data:`RATE_WINDOW_NS` before *now_ns*, over that window (over
        the time since *start_ns*, the stream's first datagram, while it is shorter)."""
        arrivals = self.arrivals
        while arrivals and now_ns - arrivals[0] >= RATE_WINDOW_NS:
            arrivals.popleft()
        span = min(RATE_WINDOW_NS, now_ns - (start_ns if start_ns is not None else now_ns))
        return len(arrivals) * 1e9 / span if span > 0 else 0.0


class WatchTable:
    """The rows of a stream of datagrams (see the module docstring). *names* adds the parameter names (and
    learns the capture's card notes); *scale* gives a station's Hz per count; *on_note* sees every note.

    :meth:`add` costs a few byte reads and the FCS per datagram (a screen follows a network of thousands of
    datagrams a second): the row is found by the envelope and the command codes; the latest datagram of each row
    is decoded when the screen is drawn (:meth:`refresh`), and a field is marked *changed* when it differs from
    the row's value at the screen before."""

    def __init__(self, names: Names | None = None, scale: Scale | None = None,
                 on_note: Callable[[str], None] | None = None) -> None:
        self.names = names
        self.scale = scale
        self.on_note = on_note
        self.rows: dict[tuple[int, int, int, int], Row] = {}
        self.datagrams = 0
        self.rejected = 0
        self.last_rejection = ""
        self.notes: deque[str] = deque(maxlen=3)  #: the latest notes of the capture
        self.start_ns: int | None = None
        self.now_ns = 0  #: the capture time of the latest datagram

    def add(self, d: Datagram) -> None:
        """Take one datagram: its row's count and rate, its latest datagram; a rejected one is counted."""
        if self.start_ns is None:
            self.start_ns = d.ts_ns
        self.now_ns = max(self.now_ns, d.ts_ns)
        self.datagrams += 1
        for comment in d.comments:
            self.notes.append(comment)
            if self.names is not None:
                self.names.learn(comment)
            if self.on_note is not None:
                self.on_note(comment)
        data = d.data
        n = len(data)
        if n < HEADER_SIZE or data[0] != MAGIC or (data[1], n) not in _LENGTHS or data[2] not in _KINDS \
                or not fcs_ok(data):
            self._reject(data)
            return
        link, kind, station = data[1], data[2], data[3]
        at = _SUBCODE_AT.get((link, n))
        sub = data[at] if at is not None else 0
        key = (station, kind, data[_CODE_AT], sub)
        row = self.rows.get(key)
        if row is None:
            command = _code_name(link, data[_CODE_AT]) + (f"/{_code_name(link, sub)}" if sub else "")
            row = self.rows[key] = Row(station, _KINDS[kind], command, first_ns=d.ts_ns)
        row.count += 1
        row.last_ns = d.ts_ns
        row.latest = data
        arrivals = row.arrivals
        arrivals.append(d.ts_ns)
        while d.ts_ns - arrivals[0] >= RATE_WINDOW_NS:
            arrivals.popleft()

    def _reject(self, data: bytes) -> None:
        try:
            decode(data)
        except WireError as exc:
            self.rejected += 1
            self.last_rejection = f"{exc} ({len(data)} bytes)"

    def refresh(self) -> None:
        """Decode each row's latest datagram, if it is not the one shown, and mark the fields that changed."""
        for row in self.rows.values():
            data = row.latest
            if data is row.shown:
                continue
            frame = decode(data)
            desc = self.names.describe(frame) if self.names is not None else describe(frame)
            hz = self.scale(desc["link"], frame.station) if self.scale is not None else None
            fields = frame_fields(desc, hz)
            if row.shown:
                before = dict(row.fields)
                for name, text in fields:
                    if before.get(name) != text:
                        row.changed_at[name] = row.last_ns
            row.fields, row.shown = fields, data

    def sorted_rows(self) -> list[Row]:
        """By station, then command, the command before its answer."""
        return sorted(self.rows.values(), key=lambda r: (r.station, r.command, r.kind))
