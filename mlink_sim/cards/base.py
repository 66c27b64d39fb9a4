"""The station machinery the three cards share: envelope checks, the connection, phases, reception
failures, the watchdog, EEPROM bookkeeping, counters and the snapshot.

A station is sans-I/O: :meth:`Station.receive` takes a datagram, its source and the time and returns the
response datagram (or None); :meth:`Station.poll` lets time pass (silence detection, the drive);
:meth:`Station.next_deadline` says when ``poll`` is next due. Nothing raises out of ``receive``/``poll``:
malformed input is a counted drop with a reason (:class:`StationCounters`).

Ownership (docs/cards.md, "Who may change a station"): no source other than the connected master ever changes a
parameter, the EEPROM, the run state or the phase. Once a master has CONNECTed, commands from any other source are
ignored (counted, and logged once per source) until DISCONNECT or connection loss – F6-26 consecutive communication
alarms, the point where the drive declares bUS "After establishing initial communication, the connection was lost"
(SI-T3 Table 28). A station released by a connection loss is admitted "as from phase 1": only CONNECT binds it
to a new master, nothing else that writes is executed. A NOP with no (or a NOP) sub-command is a read-only
status query from anyone but the connected master, in phase 2/3 and after a loss alike.

EEPROM timing (:class:`~mlink_sim.cards.eeprom.EepromWriteBack`): when the I/O layer persists the images, a CONFIG
that stores to EEPROM is completed only once :meth:`Station.eeprom_durable` confirms its image; until then the card
answers with CMDRDY = 0 and executes nothing else.
"""

from __future__ import annotations

import abc
from collections.abc import Hashable, Mapping
from types import MappingProxyType
from typing import Any, ClassVar, Final

from mlink_sim.wire import DropReason, Frame, Kind, Link, WireError, decode, ml2, ml3
from mlink_sim.wire.frame import CYCLE_AT, Template, steady_delta

from .._log import get_logger
from .drive_link import DriveCommand, DriveLink, Fault
from .eeprom import EepromImage, EepromWriteBack, power_up
from .monitors import sel_mon_value, sel_ref_item
from .paramstore import ParamStore
from .phases import PhaseEvent, next_phase
from .prediction import Prediction, offer
from .reception import FailureKind, ReceptionMonitor
from .settings import CARD_NAMES, CardOptions, CardSettings, param_table
from .snapshot import DriveSnapshot, StationCounters, StationSnapshot
from .watchdog import Watchdog

__all__ = ["Station", "StationCounters", "StationSnapshot", "DriveSnapshot", "DEFAULT_TCYCLE_NS", "SLOW"]

_LOG = get_logger("mlink_sim.cards")

#: "Operation proceeds with a default transmission cycle of 2 ms" until CONNECT (phase 1, all three manuals).
DEFAULT_TCYCLE_NS: Final = 2_000_000
#: While the drive is still moving, poll at least this often (status displays, coasting after a fault).
DRIVE_TICK_NS: Final = 10_000_000
#: TX/RX/LK LEDs count as lit for this long after the last datagram ("LED may appear to be flashing").
LED_WINDOW_NS: Final = 100_000_000
_IDLE: Final = DriveCommand()
#: :meth:`Station._fast_receive` declines: take the general path.
SLOW: Final = object()


_MAX_LOGGED_SOURCES: Final = 32
#: Incidents that can repeat every cycle on an overloaded machine (reception failures, WDT errors, phase changes,
#: bUS errors and the reconnections after them) are logged the first _LOG_FIRST times, then at the 2**k-th
#: occurrence only; the counters keep every one. An unbounded log line per lost cycle would make an overloaded
#: worker slower still.
_LOG_FIRST: Final = 8


_NOPS: Final = (ml2.Nop, ml3.Nop)


def _is_status_query(msg: Any) -> bool:
    """A main NOP with no sub-command or a NOP one: the only command another source may send (a status query,
    answered by ``_status_reply`` of the generation's class without changing anything)."""
    return type(msg.body) in _NOPS and (msg.sub is None or type(msg.sub) in _NOPS)


class Station(abc.ABC):
    """Base of the card profiles; see the module docstring. Subclasses set the class attributes below and
    implement the generation-specific hooks (``_power_up``, ``_process``, ``_report_failure``,
    ``_report_wdt``, ``_clear_comm_alarms``, ``_leds``, ``_alarm_view``)."""

    card: ClassVar[str] = ""
    family: ClassVar[str] = ""
    prm_immediate: ClassVar[bool] = False  #: PRM_WR takes effect without CONFIG (SI-T/V7)
    has_cyc: ClassVar[bool] = True  #: the drive has the CyC/CYC minor fault (not the VS-606V7)
    _cmd_wdt_at: ClassVar[int] = 0  #: the WDT byte's offset in an INV_CTL command datagram (the fast path's cards)

    address: int
    link: Link
    data_size: int

    def __init__(self, *, settings: CardSettings, now: int, eeprom: bytes | None = None) -> None:
        self.label = CARD_NAMES[self.card]
        self.options: CardOptions = settings.options
        self.counters = StationCounters()
        self._log0 = _LOG.bind(card=self.card)
        table = param_table(self.card)
        boot = power_up(self.card, table, eeprom, settings.params, self._log0)
        values = boot.values
        self.eeprom_error: str | None = boot.error  #: why the EEPROM image was not used (None: used, or none)
        self.saved_params = boot.saved  #: the values CONFIG_MOD = 1 last stored to EEPROM
        self.station_error: str | None = None
        self._mon_regs: dict[str, int] = {}  #: {"F6-23": register, "F6-24": register} read at power-up
        self._power_up(values, settings)
        self._log0 = self._log0.bind(station=f"{self.address:02X}H")
        self._log = self._log0.bind(phase=1)
        self.store = ParamStore(table, values, immediate=self.prm_immediate)
        self.drive = DriveLink(self.family, self.label, values, settings.load, now,
                               history=boot.history)
        self.watchdog = Watchdog()
        self.reception = ReceptionMonitor()
        self.phase = 1
        self.tcycle_ns = DEFAULT_TCYCLE_NS
        self.com_tim = 1
        self.comm_cycle_ns = DEFAULT_TCYCLE_NS
        self._source: Hashable | None = None
        self._bus_count = 0
        self._now = now
        self._rx_at: int | None = None
        self._tx_at: int | None = None
        self._any_rx: int | None = None
        self._cmd_key: tuple[int, int, int] | None = None
        # the fast path's steady state (a card's _fast_receive): the last command it took, its answers' template,
        # and the cycle of an answer that repeated the one before (-1: none; self.prediction)
        self._fast_cmd = b""
        self._answer = Template(0)
        self._steady_cycle = -1
        self._prediction: Prediction | None = None  # the one this card hands out, updated in place (prediction())
        self.refs: dict[str, int] = {}  #: SEL_REF item -> last value (snapshot only)
        self.eeprom = EepromWriteBack()
        self._seen_fault: Fault | None = None
        self._history = self.drive.history_names()
        self._foreign_logged: set[str] = set()
        self._incidents: dict[str, int] = {}
        self.keep_outputs = True  #: False: compute the INV_CTL outputs every cycle (tests)
        self._out_key = -1  # DriveLink.outputs_key of self._out (-1: none)
        self._out: tuple[int, int, int, int] = (0, 0, 0, 0)
        self._last_refused: tuple[Any, ...] = ()
        self._show_station_error(now)
        self._log.info("power_up", link=self.link.name, data_size=self.data_size)

    def _show_station_error(self, now: int) -> None:
        """AEr (an invalid station address) as the drive's minor fault. A method of its own: in ``__init__``,
        mypy takes ``station_error`` for the None it was set to before ``_power_up`` set it, and the compiled
        code (mypyc) would check it for None."""
        if self.station_error is not None:
            self.drive.minor(Fault.AER, True, now)
            self._log.warning("station_address_error", address=self.address)

    # -- hooks -----------------------------------------------------------------------------------
    @abc.abstractmethod
    def _power_up(self, values: Mapping[str, int], settings: CardSettings) -> None:
        """Set address, link, data_size (and station_error) from the power-up settings."""
        ...

    @abc.abstractmethod
    def _process(self, frame: Any, source: Hashable, now: int) -> bytes:
        """Execute one accepted command; return the response datagram."""
        ...

    @abc.abstractmethod
    def _report_failure(self, kind: FailureKind, first: bool) -> None:
        """Show a reception failure: warning (*first*) or communications alarm."""
        ...

    @abc.abstractmethod
    def _report_wdt(self) -> None:
        ...

    @abc.abstractmethod
    def _status_reply(self, frame: Frame) -> bytes:
        """The answer to a status query from another source (each generation's own; SI-T3 / SI-ET3 NOP).
        A method, not a declared attribute: compiled (mypyc), a declared attribute is a slot of its own."""
        ...

    @abc.abstractmethod
    def _clear_comm_alarms(self) -> None:
        ...

    def _observe_drive(self) -> None:
        """Take note of the drive's fault now (MECHATROLINK-II "most recent alarm" ordering); nothing by default."""
        return None

    @abc.abstractmethod
    def _leds(self) -> tuple[dict[str, str], dict[str, str]]:
        ...

    @abc.abstractmethod
    def _alarm_view(self) -> tuple[int, str | None, tuple[str, ...], int]:
        """(alarm code, its name, warning names, CMD_ALM) for the snapshot."""
        ...

    # -- the Station API --------------------------------------------------------------------------
    def receive(self, datagram: bytes, source: Hashable, now: int) -> bytes | None:
        """One datagram from *source* at *now*: the response datagram, or None (not for this station,
        ignored or malformed). Never raises."""
        try:
            return self._receive(datagram, source, now)
        except Exception:  # noqa: BLE001 - the station must keep answering its master
            self._internal_error("receive")
            return None

    def poll(self, now: int) -> None:
        """Let time pass: silence detection and the drive. Cheap; never raises."""
        self._steady_cycle = -1
        try:
            if now > self._now:
                self._now = now
            self.drive.advance(now)
            if self.phase > 1:
                n, before = self.reception.poll(now)
                if n:
                    self._failures(FailureKind.SILENCE, n, before, now)
            if self.drive.status.fault is not self._seen_fault:
                self._watch_history()
        except Exception:  # noqa: BLE001
            self._internal_error("poll")

    def silence_due(self, now: int) -> bool:
        """:meth:`poll` at *now* would count reception failures for silence (phase 2/3, no command for a whole
        communication cycle plus the tolerance). The I/O layer first reads the commands waiting on the socket:
        a worker that was held up must not take its own delay for the master's silence."""
        due = self._silence_deadline()
        return due is not None and now >= due

    def prediction(self, now: int) -> Prediction | None:
        """Right after :meth:`receive`: the answer to the command expected next, if the last answer was a fixed
        point of the steady state (:mod:`mlink_sim.cards.prediction`), holding until the drive's next change (a
        :meth:`poll` in between must drop it); None if there is none or it would not hold at *now*. The card's
        state is not touched. The card has one :class:`Prediction` object, updated in place by each call that
        returns it: what the last call returned holds until the next call. Never raises."""
        try:
            cycle, source = self._steady_cycle, self._source
            if cycle < 0 or source is None or self.eeprom.wait is not None:
                return None
            pred = offer(self._prediction, source, self._fast_cmd, self._cmd_wdt_at, cycle, self.drive.quiet_until(),
                         self.reception, self.watchdog, self._answer, now)
        except Exception:  # noqa: BLE001 - a card that cannot predict answers in the chain
            self._internal_error("prediction")
            return None
        if pred is not None:
            self._prediction = pred
        return pred

    def next_deadline(self) -> int | None:
        """Absolute time (ns) when :meth:`poll` is next due, or None when nothing is pending."""
        due = self.reception.deadline() if self.phase > 1 else None  # self._silence_deadline(), spelt out
        if not self.drive.drive.is_steady:
            tick = self._now + DRIVE_TICK_NS
            due = tick if due is None or tick < due else due
        return due

    def _silence_deadline(self) -> int | None:
        """When silence becomes a reception failure (SI-T3 Table 22); None outside phase 2/3 or while inactive."""
        return self.reception.deadline() if self.phase > 1 else None

    @property
    def eeprom_pending(self) -> bool:
        """An EEPROM image waits for :meth:`take_eeprom`."""
        return self.eeprom.dirty

    def take_eeprom(self) -> bytes | None:
        """The EEPROM image to persist, when CONFIG_MOD = 1 or a fault-history change asks for it; its generation
        is ``eeprom.taken`` (for :meth:`eeprom_durable`)."""
        if not self.eeprom.take():
            return None
        return EepromImage(self.card, self.saved_params, self._history).to_bytes()

    def eeprom_durable(self, generation: int, ok: bool = True) -> None:
        """The I/O layer's input: the image of *generation* is written, fsync'd and renamed (*ok*), or could not be
        written (:meth:`EepromWriteBack.durable`)."""
        if not self.eeprom.durable(generation, ok):
            self._log.error("eeprom_write_failed", generation=generation)

    def snapshot(self) -> StationSnapshot:
        leds, colors = self._leds()
        code, name, warnings, cmd_alm = self._alarm_view()  # code: an int (an M2Alarm loses its enum compiled)
        return StationSnapshot(
            card=self.card, address=self.address, link=self.link.name, data_size=self.data_size,
            phase=self.phase, connected_source=self._source, tcycle_ns=self.tcycle_ns, com_tim=self.com_tim,
            comm_cycle_ns=self.comm_cycle_ns, subcommands=self._subcommands_active(),
            leds=MappingProxyType(leds), led_colors=MappingProxyType(colors), alarm_code=int(code),
            alarm_name=name, warnings=warnings, cmd_alm=cmd_alm, station_error=self.station_error,
            drive=self.drive.snapshot(), counters=MappingProxyType(self.counters.as_dict()),
            eeprom_error=self.eeprom_error,
        )

    # -- receive path ------------------------------------------------------------------------------
    def _receive(self, datagram: bytes, source: Hashable, now: int) -> bytes | None:
        c = self.counters
        self._steady_cycle = -1
        if now > self._now:
            self._now = now
        self._any_rx = now
        if self._source is not None and self.eeprom.wait is None:  # connected (phase 2/3), no CONFIG in progress
            out = self._fast_receive(datagram, source, now)
            if out is not SLOW:
                return out  # type: ignore[return-value]
        try:
            frame = decode(datagram, kind=Kind.COMMAND)
        except WireError as exc:
            c.drop(exc.reason.name)
            if (exc.reason is DropReason.BAD_FCS and self._source is not None and source == self._source
                    and datagram[3] == self.address):
                self._fcs_error(now)
            return None
        if not self._addressed(frame):
            return None
        msg = frame.message
        if self.phase > 1 and source != self._source and _is_status_query(msg):
            # another source than the connected master, or anyone after a connection loss: read-only
            self.counters.status_queries += 1
            return self._status_reply(frame)
        if not self._accept(frame.cycle, frame.tcycle_ns, msg.wdt, msg.code, source, now):
            return None
        out = self._process(frame, source, now)
        self._sent(now)
        return out

    def _addressed(self, frame: Frame) -> bool:
        """*frame* is a command this station takes up: its address, its link and its size (else a counted drop)."""
        c = self.counters
        if frame.station != self.address:
            c.other_station += 1
            return False
        if self.station_error is not None:
            c.drop("AER")
            return False
        if frame.link is not self.link:
            c.drop("WRONG_LINK")
            return False
        if frame.message.size != self.data_size:
            c.drop(DropReason.BAD_SIZE.name)
            return False
        return True

    def receive_untrusted(self, datagram: bytes, source: Hashable, now: int) -> bytes | None:
        """One datagram from a source the I/O layer does not let change this station (``mlink-sim slave
        --allow-master``, docs/cards.md "Who may change a station"): a status query is answered read-only, as a
        non-owner's is (:meth:`_status_reply`); any other command, CONNECT included, is counted in
        ``foreign_source`` and dropped. Never raises."""
        try:
            frame = decode(datagram, kind=Kind.COMMAND)
            if not self._addressed(frame):
                return None
            if _is_status_query(frame.message):
                self.counters.status_queries += 1
                return self._status_reply(frame)
            self._foreign(source)
            return None
        except WireError as exc:
            self.counters.drop(exc.reason.name)
            return None
        except Exception:  # noqa: BLE001 - the station must keep answering its master
            self._internal_error("receive_untrusted")
            return None

    def _steady_delta(self, dg: bytes) -> int:
        """:func:`~mlink_sim.wire.frame.steady_delta` of the command *dg* against the last one the fast path took
        (-1: none yet, or *dg* differs from it in more than its cycle, WDT and FCS). When *dg* is the very datagram
        the card's prediction was just checked against (the worker answered it ahead, :mod:`.prediction`), that
        check's result: the same bytes against the same command, not compared a second time."""
        fast = self._fast_cmd
        if not fast:
            return -1
        pred = self._prediction
        if pred is not None and pred.checked is dg and pred.command is fast:
            return pred.delta
        return steady_delta(dg, fast, CYCLE_AT, self._cmd_wdt_at)

    def _fast_receive(self, datagram: bytes, source: Hashable, now: int) -> object:
        """The cyclic INV_CTL without building frame objects (a card may implement it); :data:`SLOW` to take
        the general path. It must decide before :meth:`_accept` has run."""
        return SLOW

    def _answer_after_loss(self, datagram: bytes, source: Hashable, now: int) -> bytes:
        """The fast path's command whose gap just lost the connection (:meth:`_accept` released the station): answered
        by the general path, as from phase 1."""
        out = self._process(decode(datagram, kind=Kind.COMMAND), source, now)
        self._sent(now)
        return out

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

    def _incident(self, event: str, level: str = "info", **fields: Any) -> None:
        """Log a repeatable incident, bounded (see ``_LOG_FIRST``); ``occurrence`` numbers it."""
        n = self._incidents[event] = self._incidents.get(event, 0) + 1
        if n <= _LOG_FIRST or n & (n - 1) == 0:
            getattr(self._log, level)(event, occurrence=n, **fields)

    def _foreign(self, source: Hashable) -> None:
        self.counters.foreign_source += 1
        key = repr(source)
        if key not in self._foreign_logged and len(self._foreign_logged) < _MAX_LOGGED_SOURCES:
            self._foreign_logged.add(key)
            self._log.warning("foreign_source_ignored", source=key, connected=repr(self._source))

    def _internal_error(self, where: str) -> None:
        n = self.counters.internal_errors = self.counters.internal_errors + 1
        if n <= 10 or n & (n - 1) == 0:
            self._log.exception("station_internal_error", where=where, count=n)

    def _watch_history(self) -> None:
        self._seen_fault = self.drive.status.fault
        names = self.drive.history_names()
        if names != self._history:
            self._history = names
            self.eeprom.changed()
            self._log.info("eeprom_dirty", reason="fault history", history=list(names))

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

    def _subcommands_active(self) -> bool:
        return False

    def _arrival_phase(self) -> int:
        """The phase a command is admitted in: the phase, or 1 for a station released by a connection loss – "as
        from phase 1", so only CONNECT binds it and nothing that writes is executed (docs/cards.md)."""
        return self.phase if self._source is not None else 1

    def _led_recent(self, at: int | None) -> bool:
        return at is not None and self._now - at <= LED_WINDOW_NS

    # -- the operations the command handlers use (mlink_sim.cards.commands, the cards' handler tables) --------------
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

    def select_refs(self, sel: int, *values: int) -> None:
        """Record REF values by the item their SEL_REF nibble selects (SI-T3 Table 17, SI-ET3 Table 21, SI-T/V7
        Table 4; unused codes are ignored)."""
        for i, value in enumerate(values):
            item = sel_ref_item(self.card, (sel >> (4 * i)) & 0xF)
            if item:
                self.refs[item] = value

    def monitor(self, code: int) -> int:
        """The 16-bit value SEL_MON *code* selects (SI-T3 Table 18, SI-ET3 Table 22, SI-T/V7 Table 5)."""
        drive = self.drive
        read = drive.mon_readers[code & 0xF]
        if read is not None:  # a plain monitor: sel_mon_value -> DriveLink.monitor -> read_monitor, spelt out
            try:
                return int(read(drive.drive)) & 0xFFFF
            except Exception:  # noqa: BLE001 - a monitor the model cannot compute reads 0 (DriveLink.monitor)
                return 0
        return sel_mon_value(drive, self.store, self._mon_regs, code)

    def log_refused(self, **fields: Any) -> None:
        """"connect_refused", once per distinct refused CONNECT (a master may retry it every cycle)."""
        key = tuple(sorted(fields.items()))
        if key != self._last_refused:
            self._last_refused = key
            self._log.info("connect_refused", **fields)

    # -- helpers of the generations --------------------------------------------------------------------
    def _outputs(self, sel_mon: int) -> tuple[int, int, int, int]:
        """Output frequency, output current, MON1 and MON2 of the INV_CTL response. While the drive is steady they
        cannot change, so they are kept under :meth:`DriveLink.outputs_key` (the per-cycle cost of a steady
        station); tests/cards/test_fast_path.py checks the kept values against fresh ones."""
        drive = self.drive
        key = drive.outputs_key(sel_mon) if self.keep_outputs else -1
        if key >= 0 and key == self._out_key:
            return self._out
        out = (drive.output_freq_raw(), drive.output_current_raw(), self.monitor(sel_mon & 0xF),
               self.monitor(sel_mon >> 4))
        self._out_key, self._out = key, out
        return out
