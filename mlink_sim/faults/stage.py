"""The master-side fault stage, which makes a station or the master misbehave on purpose: sans-I/O, between one
master core and its transport.

The master's transport hands it each command on its way out (:meth:`FaultStage.to_station`) and each response on
its way in (:meth:`FaultStage.to_master`); the stage drops, rewrites or replaces them as the faults in force say and
passes everything else through untouched. It runs as the first stage ("gate" and "rewrite") of the impairment
layer's pipeline (:mod:`mlink_sim.impair`), so the real-time master, the virtual clock and the proxy share it.
The master core is not changed and does not know: it sees what a master on a faulty line, or a faulty master's
own transport, would see. The card on the other side runs its own state
machine and answers as its manual says (docs/faults.md lists each fault with its tables):

==================  =====================================================================================
``silence``         every response of the station is dropped before it reaches the master (the card keeps
                    receiving and running; to the master it is silent: missing answers, OFFLINE after
                    ``offline_after``, then reconnection when it answers again)
``skip-cycles``     the station's commands of the next *count* transmission cycles are not sent (SI-T3 Table
                    22 reception failures: 96 then E6; bUS after F6-26; SI-ET3 COMM_ALM 2/3 then 9/A)
``freeze-wdt``      the master's WDT count (bits 4–7) of every command to the station repeats the last one,
                    FCS recomputed (SI-T3 Tables 23/24 E5, F6-25; SI-ET3 COMM_ALM CH); afterwards the commands
                    carry the master's own count again, which ran on underneath (one more jump for the card)
``bad-command``     the station's next cyclic INV_CTL slot carries a command the card must refuse
                    (:func:`~mlink_sim.faults.frames.bad_command`); the card's answer is recorded
==================  =====================================================================================

Every fault is an :class:`~mlink_sim.faults.recovery.Episode` of a :class:`~mlink_sim.faults.recovery.RecoveryLog`:
:meth:`after_cycle` measures the station's recovery after the fault's end. Plant faults (the drive's own, applied on
the slave side) are entered with :meth:`begin` / :meth:`end` so that their recovery is measured the same way.

Cost: nothing while no fault is in force (the layer is not called at all; :meth:`after_cycle` only while
:attr:`watching`).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Any

from . import frames
from .recovery import Episode, RecoveryLog
from .spec import BadCommand, FaultSpec, FreezeWdt, MasterFault, Silence, SkipCycles
from ..wire.frame import ENVELOPE, HEADER_SIZE, cycle_of
from ..wire.layout import field_offset

_STATION_AT = field_offset(ENVELOPE, "station")  # the envelope's station address

__all__ = ["FaultStage", "StationTraits", "is_healthy", "INJECTED"]

#: What :meth:`FaultStage.injected` counts, per station (the report's ``injected`` keys, docs/report.md).
INJECTED: tuple[str, ...] = ("silences", "skips", "wdt_freezes", "bad_commands", "drive_faults")


@dataclass(frozen=True)
class StationTraits:
    """What the stage needs to know of a station: its drive family and whether it has sub-commands."""

    address: int
    family: str = "a1000"  #: "a1000" (SI-T3, SI-ET3) or "v7" (SI-T/V7)
    subcmd: bool = False  #: CONNECT with SUBCMD = 1 (32-byte MECHATROLINK-II, 64-byte III)


#: Each master-side fault's slots in a station's state: its episode, and what keeps it in force.
_SLOTS = {"silence": ("silence_ep", "silence_until"), "skip-cycles": ("skip_ep", "skip"),
          "freeze-wdt": ("freeze_ep", "freeze_until"), "bad-command": ("bad_ep", "bad")}


class _State:
    __slots__ = ("traits", "silence_until", "silence_ep", "skip", "skip_ep", "freeze_until", "freeze_ep",
                 "frozen", "bad", "bad_ep", "watch", "answers")

    def __init__(self, traits: StationTraits) -> None:
        self.traits = traits
        self.silence_until: int | None = None
        self.silence_ep: Episode | None = None
        self.skip: tuple[int, int | None] | None = None  # (count, first cycle skipped: None until the first)
        self.skip_ep: Episode | None = None
        self.freeze_until: int | None = None
        self.freeze_ep: Episode | None = None
        self.frozen: int | None = None  # the count the WDT stays at (None: not known yet)
        self.bad: BadCommand | None = None
        self.bad_ep: Episode | None = None
        self.watch: tuple[int, str, Episode] | None = None  # (cycle, "this" | "after", episode)
        self.answers: list[tuple[Episode, frames.Answer]] = []

    @property
    def busy(self) -> bool:
        return (self.silence_until is not None or self.skip is not None or self.freeze_until is not None
                or self.bad is not None or self.watch is not None)


def is_healthy(view: Any, since_ns: int = 0) -> bool:
    """The master's view of a station says it has recovered: at its target phase (3, or 2 without ``sync``), no
    alarm (ML-II STATUS.ALM, ML-III D_ALM) and no communication alarm (COMM_ALM 8 and up), as of an answer received
    after *since_ns* (the fault's end: a view no answer has updated since says nothing of the recovery). Warnings do
    not count, as in the timeline's ``expect = "no-alarm"``."""
    last = view.last_response_ns
    return bool(view.at_target and not view.fault and view.comm_alm < 8 and last is not None and last > since_ns)


class FaultStage:
    """The master-side faults of a set of stations (see the module docstring)."""

    def __init__(self, stations: Iterable[StationTraits] = (), *, healthy: Callable[[int, int], bool] | None = None,
                 on_recovery: Callable[[int, int], None] | None = None,
                 on_unrecovered: Callable[[int], None] | None = None) -> None:
        self._st = {t.address: _State(t) for t in stations}
        #: ``healthy(station, since_ns)``: back at its target phase with no alarm, as of an answer received after
        #: *since_ns* (:func:`is_healthy` of the master's view), for the recoveries
        self.healthy = healthy or (lambda station, since_ns: True)
        self.log = RecoveryLog(on_recovery, on_unrecovered)
        self._counts: dict[int, dict[str, int]] = {}
        #: some fault acts on datagrams: only then must they pass through :meth:`to_station` / :meth:`to_master`
        #: (kept up to date on every change: the master reads it many times per cycle)
        self.active = False

    def add_station(self, traits: StationTraits) -> None:
        if traits.address not in self._st:
            self._st[traits.address] = _State(traits)

    # ------------------------------------------------------------------ control
    def inject(self, station: int, fault: MasterFault, now: int) -> Episode:
        """Start the master-side *fault* on *station* at *now* (a second fault of the same kind replaces the first)."""
        st = self._state(station)
        what = fault.describe
        if isinstance(fault, Silence):
            assert fault.for_ns is not None
            self._close(st.silence_ep, now)
            st.silence_until = now + fault.for_ns
            ep = st.silence_ep = self.log.begin(station, what, now, st.silence_until)
        elif isinstance(fault, SkipCycles):
            assert fault.count is not None
            self._close(st.skip_ep, now)
            st.skip = (fault.count, None)
            ep = st.skip_ep = self.log.begin(station, what, now)
        elif isinstance(fault, FreezeWdt):
            assert fault.for_ns is not None
            self._close(st.freeze_ep, now)
            if st.freeze_until is None:
                st.frozen = None
            st.freeze_until = now + fault.for_ns
            ep = st.freeze_ep = self.log.begin(station, what, now, st.freeze_until)
        elif isinstance(fault, BadCommand):
            self._close(st.bad_ep, now)
            st.bad = fault
            ep = st.bad_ep = self.log.begin(station, what, now)
        else:  # pragma: no cover - the spec types are closed
            raise TypeError(f"not a master-side fault: {fault!r}")
        self.active = True
        return ep

    def begin(self, station: int, fault: FaultSpec, now: int, end_ns: int | None = None) -> Episode:
        """A fault applied elsewhere (a drive fault on the slave side) begins at *now*: measure its recovery."""
        self._state(station)
        ep = self.log.begin(station, fault.describe, now, end_ns)
        self._count(station, "drive_faults", ep)
        return ep

    def end(self, episode: Episode, now: int) -> None:
        """The fault of *episode* ended at *now* (a drive fault whose end the caller applied)."""
        self.log.end(episode, now)

    def clear(self, station: int | None, now: int, actions: Iterable[str] | None = None) -> None:
        """End every master-side fault of *station* (None: of every station) at *now*; of the *actions* only
        (``"silence"``, ``"skip-cycles"``, ``"freeze-wdt"``, ``"bad-command"``) if given."""
        wanted = None if actions is None else set(actions)
        for address, st in self._st.items():
            if station is not None and address != station:
                continue
            for action, (episode, holds) in _SLOTS.items():
                if wanted is None or action in wanted:
                    self._close(getattr(st, episode), now)
                    setattr(st, episode, None)
                    setattr(st, holds, None)
        self._refresh()

    def busy(self, station: int) -> bool:
        """Some fault of *station* still acts on its datagrams."""
        st = self._st.get(station)
        return st is not None and st.busy

    @property
    def watching(self) -> bool:
        """Some fault's recovery is still to be measured (call :meth:`after_cycle` every cycle)."""
        return self.log.watching

    def last_answer(self, station: int) -> tuple[Episode, frames.Answer] | None:
        """The card's answer to the latest bad command injected into *station* (None: none answered yet)."""
        st = self._st.get(station)
        return st.answers[-1] if st is not None and st.answers else None

    def latest(self, station: int) -> Episode | None:
        """The latest fault episode of *station*."""
        return self.log.latest(station)

    def injected(self) -> dict[int, dict[str, int]]:
        """What was done so far, per station (cumulative): ``{0x21: {"silences": 40, "skips": 2}}``."""
        return {station: dict(c) for station, c in sorted(self._counts.items())}

    # ------------------------------------------------------------------ datagrams
    def to_station(self, station: int, datagram: bytes, now: int) -> bytes | None:
        """A command on its way to *station*: None when a fault keeps it from being sent, else what is sent."""
        st = self._st.get(station)
        if st is None or not st.busy or len(datagram) <= HEADER_SIZE:
            return datagram
        if st.skip is not None:
            count, first = st.skip
            cycle = cycle_of(datagram)
            if first is None:
                first = cycle
                st.skip = (count, first)
            if (cycle - first) & 0xFFFFFFFF < count:
                self._count(station, "skips", st.skip_ep)
                return None
            st.skip = None  # the first command after the skipped cycles: the fault's end
            if st.skip_ep is not None:
                self.log.end(st.skip_ep, now)
                st.skip_ep = None
            self._refresh()
        until = st.freeze_until
        if until is not None:
            if now >= until:
                st.freeze_until = st.freeze_ep = None
                self._refresh()
            else:
                wdt = frames.wdt_count(datagram)
                if wdt is not None:
                    if st.frozen is None:
                        st.frozen = (wdt - 1) & 0xF  # it stops: the first frozen command repeats the last count
                    self._count(station, "wdt_freezes", st.freeze_ep)
                    datagram = frames.set_wdt_count(datagram, st.frozen)
        if st.bad is not None and frames.is_cyclic(datagram):
            datagram = self._bad(st, datagram, now)
        return datagram

    def from_station(self, datagram: bytes, now: int) -> bytes | None:
        """:meth:`to_master` of a response, its station read from the envelope; a datagram shorter than the
        envelope passes as it is."""
        if len(datagram) <= HEADER_SIZE:
            return datagram
        return self.to_master(datagram[_STATION_AT], datagram, now)

    def to_master(self, station: int, datagram: bytes, now: int) -> bytes | None:
        """A response from *station* on its way to the master: None when a fault swallows it."""
        st = self._st.get(station)
        if st is None or not st.busy or len(datagram) <= HEADER_SIZE:
            return datagram
        if st.watch is not None:
            self._watch(st, datagram)
        until = st.silence_until
        if until is not None:
            if now < until:
                self._count(station, "silences", st.silence_ep)
                return None
            st.silence_until = st.silence_ep = None
            self._refresh()
        return datagram

    def after_cycle(self, now: int) -> None:
        """Once per cycle while :attr:`watching`: the recoveries (see :class:`RecoveryLog`)."""
        self.log.poll(now, self.healthy)

    # ------------------------------------------------------------------ internals
    def _bad(self, st: _State, datagram: bytes, now: int) -> bytes:
        fault, ep = st.bad, st.bad_ep
        assert fault is not None and fault.kind is not None and ep is not None
        st.bad = st.bad_ep = None
        replaced = frames.bad_command(datagram, fault.kind, subcmd=st.traits.subcmd, family=st.traits.family)
        st.watch = (cycle_of(datagram), "after" if fault.kind == "phase" else "this", ep)
        self._count(st.traits.address, "bad_commands", ep)
        self.log.end(ep, now)
        return replaced

    def _watch(self, st: _State, datagram: bytes) -> None:
        assert st.watch is not None
        cycle, mode, ep = st.watch
        d = (cycle_of(datagram) - cycle) & 0xFFFFFFFF
        if d != 0 if mode == "this" else not 0 < d < 1 << 31:  # phase: the answer to the master's next command
            return
        answer = frames.read_answer(datagram)
        if answer is None:
            return
        st.watch = None
        st.answers.append((ep, answer))
        ep.notes.append(f"answered {answer.describe()}")
        self._refresh()

    def _state(self, station: int) -> _State:
        st = self._st.get(station)
        if st is None:
            st = self._st[station] = _State(StationTraits(station))
        return st

    def _close(self, ep: Episode | None, now: int) -> None:
        if ep is not None:
            self.log.end(ep, now)

    def _refresh(self) -> None:
        self.active = any(st.busy for st in self._st.values())

    def _count(self, station: int, what: str, episode: Episode | None) -> None:
        counts = self._counts.setdefault(station, {})
        counts[what] = counts.get(what, 0) + 1
        if episode is not None:
            episode.injected[what] = episode.injected.get(what, 0) + 1
