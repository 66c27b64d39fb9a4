"""A station's connection to its master and what supervises it: the commands admitted (one master at a time), the
reception failures and communication alarms, bUS, the watchdog error, the phases, the incidents logged
(:class:`Connection`, the base of :class:`~mlink_sim.cards.base.Station`).

Ownership (docs/cards.md, "Who may change a station"): no source other than the connected master ever changes a
parameter, the EEPROM, the run state or the phase. Once a master has CONNECTed, commands from any other source are
ignored (counted, and logged once per source) until DISCONNECT or connection loss – F6-26 consecutive communication
alarms, the point where the drive declares bUS "After establishing initial communication, the connection was lost"
(SI-T3 Table 28). A station released by a connection loss is admitted "as from phase 1": only CONNECT binds it
to a new master, nothing else that writes is executed. A NOP with no (or a NOP) sub-command is a read-only
status query from anyone but the connected master, in phase 2/3 and after a loss alike.

The answer first (docs/timing.md, "When each command is answered"): what a command logs (a phase change, a connection,
a reception failure, a refused CONNECT …) is kept as a record (:meth:`Connection._note`) and written once the answer
is out (:meth:`~mlink_sim.cards.base.Station.finish`): formatting a log line takes longer than answering.
"""

from __future__ import annotations

import abc
from collections.abc import Hashable
from typing import Any, Final

from .drive_link import DriveCommand, DriveLink, Fault
from .eeprom import EepromWriteBack
from .phases import PhaseEvent, next_phase
from .reception import FailureKind, ReceptionMonitor
from .settings import CardOptions
from .snapshot import StationCounters
from .watchdog import Watchdog

__all__ = ["Connection", "DEFAULT_TCYCLE_NS"]

#: "Operation proceeds with a default transmission cycle of 2 ms" until CONNECT (phase 1, all three manuals).
DEFAULT_TCYCLE_NS: Final = 2_000_000
_IDLE: Final = DriveCommand()
_MAX_LOGGED_SOURCES: Final = 32
#: Incidents that can repeat every cycle on an overloaded machine (reception failures, WDT errors, phase changes,
#: bUS errors and the reconnections after them) are logged the first _LOG_FIRST times, then at the 2**k-th
#: occurrence only; the counters keep every one. An unbounded log line per lost cycle would make an overloaded
#: worker slower still.
_LOG_FIRST: Final = 8


class Connection(abc.ABC):
    """The connection side of a station (see the module docstring). Its state is made by ``Station.__init__``;
    a generation implements the hooks below (``_report_failure``, ``_report_wdt``, ``_clear_comm_alarms``)."""

    phase: int
    tcycle_ns: int
    com_tim: int
    comm_cycle_ns: int
    options: CardOptions
    counters: StationCounters
    drive: DriveLink
    watchdog: Watchdog
    reception: ReceptionMonitor
    eeprom: EepromWriteBack
    refs: dict[str, int]  #: SEL_REF item -> last value (snapshot only)
    _source: Hashable | None
    _bus_count: int
    _rx_at: int | None
    _tx_at: int | None
    _cmd_key: tuple[int, int, int] | None
    _seen_fault: Fault | None
    _history: tuple[str, ...]
    _incidents: dict[str, int]
    _foreign_logged: set[str]
    _log0: Any
    _log: Any
    #: the log records of the commands answered since the last ``finish()``: (logger, level, event, fields)
    _later: list[tuple[Any, str, str, dict[str, Any]]]
    unfinished: bool

    # -- hooks -----------------------------------------------------------------------------------
    @abc.abstractmethod
    def _report_failure(self, kind: FailureKind, first: bool) -> None:
        """Show a reception failure: warning (*first*) or communications alarm."""
        ...

    @abc.abstractmethod
    def _report_wdt(self) -> None:
        ...

    @abc.abstractmethod
    def _clear_comm_alarms(self) -> None:
        ...

    def _observe_drive(self) -> None:
        """Take note of the drive's fault now (MECHATROLINK-II "most recent alarm" ordering); nothing by default."""
        return None

    # -- admission, reception failures, alarms ----------------------------------------------------
    def _accept(self, cycle: int, tcycle_ns: int, wdt: int, code: int, source: Hashable, now: int) -> bool:
        """A well-formed command for this station: the connection, reception failures, the watchdog."""
        known = self._source  # the worker hands every datagram of one source the same address object: `is` first
        if known is not None and source is not known and source != known:
            self._foreign(source)
            return False
        self.drive.drive.advance(now)  # the model itself: DriveLink.advance is only this
        if self._source is not None:  # connected (phase 2/3): failures found by poll() are counted; the gap the rest
            seen = self.reception.on_command(cycle, now)
            if seen is None:
                self.counters.drop("DUPLICATE")
                return False
            new, before, elapsed, jump = seen
            if jump:  # a number the elapsed time does not allow: one failure (reception.py, SI-T3 Table 22)
                self._incident("cycle_discontinuity", level="warning", source=repr(source), cycle=cycle)
            if new:
                self._failures(FailureKind.GAP, new, before, now)
            if tcycle_ns != self.tcycle_ns:
                self._failures(FailureKind.CYCLE, 1, 1, now)
            if not self.watchdog.check(wdt, elapsed) and code != 0x0F:  # DISCONNECT carries no WDT (SI-ET3)
                self._wdt_error(now)
            self._bus_count = 0
        else:  # phase 1, or released by a connection loss: admitted as from phase 1 (_arrival_phase)
            self.watchdog.check(wdt, 1)
        self.counters.rx_ok += 1
        self._rx_at = now
        return True

    def _sent(self, now: int) -> None:
        self.counters.tx += 1
        self._tx_at = now
        if self.drive.status.fault is not self._seen_fault:
            self._watch_history()

    def _fcs_error(self, now: int) -> None:
        self.counters.fcs_errors += 1
        before = self.reception.on_lost()
        self._failures(FailureKind.FCS, 1, before, now)

    def _failures(self, kind: FailureKind, n: int, before: int, now: int) -> None:
        """*n* failures of *kind*, after *before* consecutive ones: the first is a warning, the rest alarms."""
        self.counters.reception_failures += n if kind is not FailureKind.CYCLE else 0
        alarms = n
        if kind is not FailureKind.CYCLE and before == 0:
            self._report_failure(kind, True)
            alarms -= 1
        if alarms:
            self._report_failure(kind, False)
            self._comm_alarm(alarms, now)
        self._incident("reception_failure", kind=kind.value, count=n, consecutive=before + n)

    def _comm_alarm(self, n: int, now: int) -> None:
        """*n* communications alarms (E6 / COMM_ALM 8–B): phase 3 -> 2, bUS after F6-26 of them."""
        if self._source is not None:  # not in the command whose gap has just released the station (phase 1 on)
            self._phase_event(PhaseEvent.COMM_ALARM)
        self.counters.bus_alarms += n
        before = self._bus_count
        self._bus_count += n
        limit = self._bus_limit()
        if before < limit <= self._bus_count:
            detected = self.drive.trip_bus(now)
            self._incident("bus_error", level="warning", alarms=self._bus_count, limit=limit, drive_fault=detected)
            if self._source is not None:  # released: admitted as from phase 1 until a CONNECT (docs/cards.md)
                self._incident("connection_lost", level="warning", source=repr(self._source))
                self._source = None
                self.reception.stop()  # nobody to count failures for ("Phase 1 never notifies")

    def _bus_limit(self) -> int:
        return 1

    def _wdt_error(self, now: int) -> None:
        self.counters.wdt_errors += 1
        self.drive.trip_e5(now)  # the drive's E5 is this same event: the card's code is the most recent
        self._observe_drive()
        self._report_wdt()
        self._phase_event(PhaseEvent.WDT_ERROR)
        self._incident("wdt_error", level="warning", master_count=self.watchdog.master)

    def _note(self, level: str, event: str, fields: dict[str, Any]) -> None:
        """Log *event* at *level* with *fields* once the answer is out (``Station.finish``), bound as the station is
        now (its phase)."""
        self._later.append((self._log, level, event, fields))
        self.unfinished = True

    def _write_notes(self) -> None:
        """Write the log records kept by :meth:`_note`, oldest first."""
        later = self._later
        self._later = []
        for logger, level, event, fields in later:
            getattr(logger, level)(event, **fields)

    def _incident(self, event: str, level: str = "info", **fields: Any) -> None:
        """Log a repeatable incident, bounded (see ``_LOG_FIRST``); ``occurrence`` numbers it."""
        n = self._incidents[event] = self._incidents.get(event, 0) + 1
        if n <= _LOG_FIRST or n & (n - 1) == 0:
            self._note(level, event, {"occurrence": n, **fields})

    def _foreign(self, source: Hashable) -> None:
        self.counters.foreign_source += 1
        key = repr(source)
        if key not in self._foreign_logged and len(self._foreign_logged) < _MAX_LOGGED_SOURCES:
            self._foreign_logged.add(key)
            self._note("warning", "foreign_source_ignored", {"source": key, "connected": repr(self._source)})

    def record_internal_error(self) -> int:
        """Count an internal error of this station (``counters.internal_errors``): a bug, in the card or in the I/O
        layer's answers made for it (an answer sent ahead that the card then contradicts); the count so far."""
        n = self.counters.internal_errors = self.counters.internal_errors + 1
        return n

    def _internal_error(self, where: str) -> None:
        n = self.record_internal_error()
        if n <= 10 or n & (n - 1) == 0:
            self._log.exception("station_internal_error", where=where, count=n)

    def _watch_history(self) -> None:
        self._seen_fault = self.drive.status.fault
        names = self.drive.history_names()
        if names != self._history:
            self._history = names
            self.eeprom.changed()
            self._note("info", "eeprom_dirty", {"reason": "fault history", "history": list(names)})

    # -- phases ----------------------------------------------------------------------------------------
    def _phase_event(self, event: PhaseEvent) -> None:
        """Take the transition of *event* in the phase the station acts in (phases.PHASE_TRANSITIONS; an illegal one
        raises PhaseError there)."""
        self._set_phase(next_phase(self._arrival_phase(), event))

    def _set_phase(self, phase: int) -> None:
        if phase != self.phase:
            old, self.phase = self.phase, phase
            self._log = self._log0.bind(phase=phase)
            self._incident("phase_changed", old=old, new=phase)
            if phase == 3:
                self.watchdog.armed = True
            else:
                self.watchdog.disarm()

    def _arrival_phase(self) -> int:
        """The phase a command is admitted in: the phase, or 1 for a station released by a connection loss – "as
        from phase 1", so only CONNECT binds it and nothing that writes is executed (docs/cards.md)."""
        return self.phase if self._source is not None else 1


    # -- the connection operations of the command handlers (mlink_sim.cards.commands) --------------------------
    def connect(self, source: Hashable, cycle: int, now: int, *, sync: bool, tcycle_ns: int, com_tim: int,
                comm_cycle_ns: int, wdt: int) -> None:
        """An accepted CONNECT from *source*: the connection, the transmission/communication cycle of the header from
        now on, phase 2 or 3 (*sync*), reception-failure monitoring and the watchdog start."""
        phase = next_phase(self._arrival_phase(), PhaseEvent.CONNECT_SYNC if sync else PhaseEvent.CONNECT_ASYNC)
        self._source = source
        self.tcycle_ns, self.com_tim, self.comm_cycle_ns = tcycle_ns, com_tim, comm_cycle_ns
        self.reception.start(cycle, now, comm_cycle_ns, max(1, round(comm_cycle_ns / tcycle_ns)),
                             self.options.silence_tolerance_ns)
        self._bus_count = 0
        self.watchdog.arm(wdt)
        self._set_phase(phase)
        if not sync:
            self.watchdog.disarm()
        self._incident("connected", source=repr(source), tcycle_ns=tcycle_ns, com_tim=com_tim, sync=sync)

    def disconnect(self, now: int) -> None:
        """DISCONNECT: "the data for the control command to the Drive is cleared to 0, and a fault reset
        command is carried out" (SI-T3 / SI-T/V7); back to phase 1 and the 2 ms default cycle. Without a connection
        (phase 1, or released by a connection loss) there is none to release and nothing changes: only the
        connected master changes the run state or the phase."""
        if self._source is None:
            return
        phase = next_phase(self._arrival_phase(), PhaseEvent.DISCONNECT)
        self._incident("disconnected", source=repr(self._source))
        self._source = None
        self.reception.stop()
        self.tcycle_ns = self.comm_cycle_ns = DEFAULT_TCYCLE_NS
        self.com_tim = 1
        self.drive.command(_IDLE, now)
        self.drive.reset_fault(now)
        self._cmd_key = None
        self.refs.clear()
        self._clear_comm_alarms()
        self._set_phase(phase)

    def sync_set(self, wdt: int) -> None:
        """SYNC_SET: phase 3, the watchdog checked from the master count in *wdt* on."""
        self.watchdog.arm(wdt)
        self._phase_event(PhaseEvent.SYNC_SET)

    def alarm_clear(self, now: int) -> bool:
        """ALM_CLR / CMD_CTRL.ALM_CLR: communication alarms, card minor faults, drive faults (refused by the
        drive while RUN is on). True if the drive accepted the reset."""
        self._clear_comm_alarms()
        self._bus_count = 0
        return self.drive.reset_fault(now)
