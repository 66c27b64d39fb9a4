"""A capture's figures per station and command, as Wireshark's statistics give them (``mlink-sim decode --pcap FILE
--stats``): how many commands and responses, the response time of each command (min, p50, p99, max), the gaps
between a station's cycles, the answers lost and late, the FCS and sequence errors, and the range of INV_CTL's
speed reference and output frequency (raw counts: :mod:`mlink_sim.cli.speed_units` gives them in Hz).

The rules, on the capture's own times (the master's socket for ``up``/``master --capture``: a response time is
then the round trip the master saw; a slave's socket for ``slave --capture``: its turnaround):

* A response is matched to its command by station and cycle number (a response echoes its command's cycle,
  docs/wire-format.md §1); its **response time** is its time minus the command's. The figures are those of the
  command's main command (a sub-command travels in the same datagrams).
* An answer is **late** when a newer command to its station was sent before it came: a MECHATROLINK master judges
  an answer missing at the station's next slot (docs/master.md, "Scheduling").
* A command is **lost** when no answer to it is in the capture, unless it is within one transmission cycle of the
  end of that station's part of the capture (the recording ended before the answer could come: replay's rule).
* A **gap** is the time between two consecutive commands to a station: its communication cycle as the wire saw it.
* A **sequence error** is a command whose cycle number is not above the one before to its station (repeated or
  going back), or an answer to a cycle no command of the capture had or one already answered (a duplicate).
  Answers to cycles before the station's first recorded command are the capture's start, not errors.
* An **FCS error** is a datagram whose FCS is wrong (CRC-16/X-25, docs/wire-format.md §2); another rejected
  datagram (size, magic, link, kind) is counted as rejected. Both by the station byte of the envelope.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from typing import Any

from ..wire import DropReason, Frame, describe
from .reader import Datagram
from .text import Selection, card_of_note, select_items, station_of

__all__ = ["capture_stats", "summary", "percentile"]


def percentile(ordered: Sequence[int], p: float) -> int:
    """The *p*-th percentile of the sorted *ordered* by nearest rank (the smallest value with at least *p* % of
    the values at or below it)."""
    rank = max(1, math.ceil(p / 100 * len(ordered)))
    return ordered[rank - 1]


def summary(values: list[int]) -> dict[str, int] | None:
    """``{"count", "min", "p50", "p99", "max"}`` of *values* (ns), None when there are none."""
    if not values:
        return None
    ordered = sorted(values)
    return {"count": len(ordered), "min": ordered[0], "p50": percentile(ordered, 50), "p99": percentile(ordered, 99),
            "max": ordered[-1]}


@dataclass
class _Command:
    cmd: int = 0
    rsp: int = 0
    lost: int = 0
    late: int = 0
    times: list[int] = field(default_factory=list)  #: response times, ns


@dataclass
class _Range:
    """The smallest, largest and last value seen of a field."""

    low: int | None = None
    high: int | None = None
    last: int | None = None

    def add(self, value: int) -> None:
        self.low = value if self.low is None else min(self.low, value)
        self.high = value if self.high is None else max(self.high, value)
        self.last = value

    def as_dict(self) -> dict[str, int] | None:
        return None if self.last is None else {"min": self.low or 0, "max": self.high or 0, "last": self.last}


@dataclass
class _Station:
    link: str = ""
    commands: dict[str, _Command] = field(default_factory=dict)
    gaps: list[int] = field(default_factory=list)
    fcs_errors: int = 0
    rejected: int = 0
    sequence_errors: int = 0
    first_cycle: int | None = None  #: of the station's first command in the capture
    last_cycle: int | None = None  #: of its latest command
    last_command_ns: int | None = None
    last_ns: int = 0  #: its latest datagram
    #: cycle -> (time, main command, transmission cycle ns) of the commands not answered yet
    pending: dict[int, tuple[int, str, int]] = field(default_factory=dict)
    answered: set[int] = field(default_factory=set)
    speed_ref: _Range = field(default_factory=_Range)
    output_freq: _Range = field(default_factory=_Range)

    def command(self, name: str) -> _Command:
        found = self.commands.get(name)
        if found is None:
            found = self.commands[name] = _Command()
        return found


def _on_command(st: _Station, ts: int, d: dict[str, Any], keys: list[str]) -> None:
    cycle, name = d["cycle"], keys[0]
    for key in keys:
        st.command(key).cmd += 1
    if st.last_command_ns is not None:
        st.gaps.append(ts - st.last_command_ns)
    if st.last_cycle is not None and cycle <= st.last_cycle:
        st.sequence_errors += 1
    if st.first_cycle is None:
        st.first_cycle = cycle
    st.last_cycle, st.last_command_ns = cycle, ts
    st.pending[cycle] = (ts, name, d["tcycle_ns"])
    if name == "INV_CTL" and "speed_ref" in d["main"]:
        st.speed_ref.add(d["main"]["speed_ref"])


def _on_response(st: _Station, ts: int, d: dict[str, Any], keys: list[str]) -> None:
    cycle = d["cycle"]
    for key in keys:
        st.command(key).rsp += 1
    if keys[0] == "INV_CTL" and "output_freq" in d["main"]:
        st.output_freq.add(d["main"]["output_freq"])
    sent = st.pending.pop(cycle, None)
    if sent is None:
        if cycle in st.answered or (st.first_cycle is not None and cycle >= st.first_cycle):
            st.sequence_errors += 1  # a duplicate, or an answer to a cycle never commanded
        return
    st.answered.add(cycle)
    at, name, _ = sent
    command = st.command(name)
    command.times.append(ts - at)
    if st.last_cycle != cycle:  # the station's next command went out before this answer came
        command.late += 1


def _on_rejected(stations: dict[int, _Station], data: bytes, reason: DropReason) -> None:
    station = station_of(data)
    if station is None:
        return
    st = stations.setdefault(station, _Station())
    if reason is DropReason.BAD_FCS:
        st.fcs_errors += 1
    else:
        st.rejected += 1


def _finish(st: _Station) -> None:
    """The commands still unanswered: lost, but for those within a cycle of the end of the station's capture."""
    for at, name, tcycle in st.pending.values():
        if st.last_ns - at >= tcycle:
            st.command(name).lost += 1
    st.pending.clear()


class _CardNotes:
    """What :func:`select_items` hands the notes to: keeps each station's card note (``station 21H: card SI-T3 …``),
    whose text names the station's speed units where the recorder knew them."""

    def __init__(self) -> None:
        self.notes: dict[int, str] = {}

    def learn(self, comment: str) -> None:
        found = card_of_note(comment)
        if found is not None:
            self.notes[found[0]] = comment

    def describe(self, frame: Frame) -> dict[str, Any]:
        return describe(frame)


def capture_stats(datagrams: Iterable[Datagram], selection: Selection | None = None) -> dict[str, Any]:
    """The figures of the *selection*'s datagrams (see the module docstring)::

        {"datagrams": n, "rejected": n,
         "stations": {"21H": {"INV_CTL": {"cmd", "rsp", "lost", "late", "response_ns": {count, min, p50, p99, max}},
                              "sub PRM_RD": {"cmd", "rsp"}, …}},
         "timing": {"21H": {"link", "gap_ns": {…}, "fcs_errors", "rejected", "sequence_errors",
                            "speed_ref": {min, max, last}, "output_freq": {min, max, last}, "card_note"}}}

    ``response_ns`` and ``gap_ns`` are None where nothing was measured; ``speed_ref`` and ``output_freq`` (raw
    counts of the station's o1-03 / n035 units) are None without INV_CTL; ``card_note`` is the capture's note naming
    the station's card (None without one)."""
    stations: dict[int, _Station] = {}
    notes = _CardNotes()
    total = rejected = 0
    for item in select_items(datagrams, selection or Selection(), notes):
        if not item.shown:
            continue
        total += 1
        data = item.datagram.data
        d = item.described
        if d is None:
            rejected += 1
            if item.error is not None:
                _on_rejected(stations, data, item.error.reason)
            continue
        st = stations.setdefault(d["station"], _Station())
        st.link = d["link"]
        st.last_ns = max(st.last_ns, item.datagram.ts_ns)
        keys = [d["main"]["command"]]
        sub = d.get("sub")
        if sub is not None and sub["command"] != "NOP":
            keys.append("sub " + sub["command"])
        if d["kind"] == "command":
            _on_command(st, item.datagram.ts_ns, d, keys)
        else:
            _on_response(st, item.datagram.ts_ns, d, keys)
    out_stations: dict[str, Any] = {}
    timing: dict[str, Any] = {}
    for address in sorted(stations):
        st = stations[address]
        _finish(st)
        name = f"{address:02X}H"
        per: dict[str, Any] = {}
        for key in sorted(st.commands):
            c = st.commands[key]
            per[key] = {"cmd": c.cmd, "rsp": c.rsp} if key.startswith("sub ") else {
                "cmd": c.cmd, "rsp": c.rsp, "lost": c.lost, "late": c.late, "response_ns": summary(c.times)}
        if per:
            out_stations[name] = per
        timing[name] = {"link": st.link, "gap_ns": summary(st.gaps), "fcs_errors": st.fcs_errors,
                        "rejected": st.rejected, "sequence_errors": st.sequence_errors,
                        "speed_ref": st.speed_ref.as_dict(), "output_freq": st.output_freq.as_dict(),
                        "card_note": notes.notes.get(address)}
    return {"datagrams": total, "rejected": rejected, "stations": out_stations, "timing": timing}
