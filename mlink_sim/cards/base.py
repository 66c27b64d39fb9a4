"""The station the cards share: the Station API (receive, poll, the prediction, the deadline, EEPROM bookkeeping,
the snapshot), the receive path's envelope checks, and the operations the command handlers use on the drive; the
connection and its supervision (reception failures, alarms, the watchdog, the phases) are
:class:`~mlink_sim.cards.connection.Connection`, its base.

A station is sans-I/O: :meth:`Station.receive` takes a datagram, its source and the time and returns the
response datagram (or None); :meth:`Station.poll` lets time pass (silence detection, the drive);
:meth:`Station.next_deadline` says when ``poll`` is next due. Nothing raises out of ``receive``/``poll``:
malformed input is a counted drop with a reason (:class:`StationCounters`). A station is made from its card's
profile (:mod:`mlink_sim.profiles`: its key and label, parameter table, drive family, SEL_MON/SEL_REF tables) by
:func:`~mlink_sim.cards.registry.create_card`.

EEPROM timing (:class:`~mlink_sim.cards.eeprom.EepromWriteBack`): when the I/O layer persists the images
(:meth:`Station.persist_eeprom`), a CONFIG that stores to EEPROM is completed only once :meth:`Station.eeprom_durable`
confirms its image; until then the card answers with CMDRDY = 0 and executes nothing else.

The answer first (docs/timing.md, "When each command is answered"): ``receive`` returns the answer and leaves the
work that does not change it for :meth:`Station.finish`, which the I/O layer calls once the answer is sent: the log
lines of the command (phase changes, connections, refusals), the values CONFIG_MOD = 1 stores, the drive settings a
written parameter will take at CONFIG (built ahead, so that CONFIG only applies them) and, on a card whose PRM_WR takes
effect at once (SI-T/V7), the drive taking the written value. Every other entry point (``receive``, ``poll``,
``snapshot``, ``take_eeprom``) finishes what is left first, so nothing depends on the I/O layer calling it.
"""

from __future__ import annotations

import abc
from collections.abc import Hashable, Mapping
from types import MappingProxyType
from typing import Any, ClassVar, Final

from mlink_sim.drive.activity import DriveActivity
from mlink_sim.params import for_card
from mlink_sim.profiles import CardProfile
from mlink_sim.wire import DropReason, Frame, Kind, Link, WireError, decode, ml2, ml3
from mlink_sim.wire.frame import CYCLE_AT, Template, steady_delta
from mlink_sim.wire.selections import SEL_REF_TABLES

from .._log import get_logger
from .connection import DEFAULT_TCYCLE_NS, Connection
from .drive_link import DriveLink, Fault
from .eeprom import EepromImage, EepromWriteBack, power_up
from .monitors import sel_mon_value
from .parameters import prepare_settings, reconfigure
from .paramstore import ParamStore
from .prediction import Prediction, offer
from .reception import FailureKind, ReceptionMonitor
from .settings import CardSettings
from .snapshot import DriveSnapshot, StationCounters, StationSnapshot
from .watchdog import Watchdog

__all__ = ["Station", "StationCounters", "StationSnapshot", "DriveSnapshot", "DEFAULT_TCYCLE_NS", "SLOW"]

_LOG = get_logger("mlink_sim.cards")

#: While the drive is still moving, poll at least this often (status displays, coasting after a fault).
DRIVE_TICK_NS: Final = 10_000_000
#: TX/RX/LK LEDs count as lit for this long after the last datagram ("LED may appear to be flashing").
LED_WINDOW_NS: Final = 100_000_000
#: :meth:`Station._fast_receive` declines: take the general path.
SLOW: Final = object()


_NOPS: Final = (ml2.Nop, ml3.Nop)


def _is_status_query(msg: Any) -> bool:
    """A main NOP with no sub-command or a NOP one: the only command another source may send (a status query,
    answered by ``_status_reply`` of the generation's class without changing anything)."""
    return type(msg.body) in _NOPS and (msg.sub is None or type(msg.sub) in _NOPS)


class Station(Connection):
    """Base of the card classes; see the module docstring. A card class sets the class attributes below and
    implements the generation-specific hooks (``_power_up``, ``_process``, ``_status_reply``, ``_leds``,
    ``_alarm_view``; those of :class:`~mlink_sim.cards.connection.Connection`); what it is (key, label, tables) comes
    from the profile it is made with."""

    prm_immediate: ClassVar[bool] = False  #: PRM_WR takes effect without CONFIG (SI-T/V7)
    has_cyc: ClassVar[bool] = True  #: the drive has the CyC/CYC minor fault (not the VS-606V7)
    _cmd_wdt_at: ClassVar[int] = 0  #: the WDT byte's offset in an INV_CTL command datagram (the fast path's cards)

    address: int
    link: Link
    data_size: int

    def __init__(self, profile: CardProfile, *, settings: CardSettings, now: int, eeprom: bytes | None = None) -> None:
        self.profile = profile
        self.card = profile.key  #: the registry key ("si-t-v7"): the snapshot's card, the EEPROM image's
        self.label = profile.label  #: as the manual names the card ("SI-T/V7")
        self.options = settings.options
        self.counters = StationCounters()
        self._later = []
        self.unfinished = False  #: the commands answered since the last finish() left work for it
        self._prepare_due = False  # a PRM_WR changed the pending values: finish() builds the settings CONFIG takes
        self._prepared: tuple[int, Any] | None = None  # (ParamStore.version, DriveSettings or why none) for CONFIG
        self._reconfigure_due = False  # a value in effect at once (SI-T/V7 PRM_WR): finish() gives it to the drive
        self._save_due = ""  # why the values in effect are to be stored (CONFIG_MOD = 1): finish() lists them
        self._log0 = _LOG.bind(card=self.card)
        table = for_card(profile)
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
        self.drive = DriveLink(profile.family, profile.selections, values, settings.load, now,
                               history=boot.history)
        self._sel_ref = SEL_REF_TABLES.get(profile.selections, ("",) * 16)
        self.watchdog = Watchdog()
        self.reception = ReceptionMonitor()
        self.phase = 1
        self.tcycle_ns = DEFAULT_TCYCLE_NS
        self.com_tim = 1
        self.comm_cycle_ns = DEFAULT_TCYCLE_NS
        self._source = None
        self._bus_count = 0
        self._now = now
        self._rx_at = None
        self._tx_at = None
        self._any_rx: int | None = None
        self._cmd_key = None
        # the fast path's steady state (a card's _fast_receive): the last command it took, its answers' template,
        # and the cycle of an answer that repeated the one before (-1: none; self.prediction)
        self._fast_cmd = b""
        self._answer = Template(0)
        self._steady_cycle = -1
        self._prediction: Prediction | None = None  # the one this card hands out, updated in place (prediction())
        self.refs = {}
        self.eeprom = EepromWriteBack()
        self._seen_fault = None
        self._history = self.drive.history_names()
        self._foreign_logged = set()
        self._incidents = {}
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
    def _status_reply(self, frame: Frame) -> bytes:
        """The answer to a status query from another source (each generation's own; SI-T3 / SI-ET3 NOP).
        A method, not a declared attribute: compiled (mypyc), a declared attribute is a slot of its own."""
        ...

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
        ignored or malformed). What the command leaves for after its answer waits for :meth:`finish`. Never
        raises."""
        try:
            if self.unfinished:
                self._finish()
            return self._receive(datagram, source, now)
        except Exception:  # noqa: BLE001 - the station must keep answering its master
            self._internal_error("receive")
            return None

    def finish(self) -> None:
        """The work the commands answered since the last call left for after their answers (the module docstring):
        the I/O layer calls it once their answers are sent. Never raises."""
        if not self.unfinished:
            return
        try:
            self._finish()
        except Exception:  # noqa: BLE001 - the station must keep answering its master
            self._internal_error("finish")

    def _finish(self) -> None:
        self.unfinished = False
        if self._reconfigure_due:  # the drive takes the values PRM_WR put in effect (SI-T/V7): before anything else
            self._reconfigure_due = False
            reconfigure(self, self._now)
        if self._prepare_due:
            self._prepare_due = False
            self._prepared = prepare_settings(self)
        if self._save_due:  # the values in effect when the command was taken: no command came in between
            reason, self._save_due = self._save_due, ""
            self.saved_params = self.store.overrides()
            self._note("info", "eeprom_dirty", {"reason": reason, "params": len(self.saved_params)})
        if self._later:
            self._write_notes()
        self.unfinished = False

    def poll(self, now: int) -> None:
        """Let time pass: silence detection and the drive. Cheap; never raises."""
        self._steady_cycle = -1
        try:
            if self.unfinished:
                self._finish()
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
            if cycle < 0 or source is None or self.eeprom.wait is not None or self._reconfigure_due:
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

    def persist_eeprom(self, enabled: bool) -> None:
        """The I/O layer persists this station's EEPROM images (*enabled*: it writes each :meth:`take_eeprom` and
        reports it with :meth:`eeprom_durable`, so a CONFIG to EEPROM completes once its image is durable) or not
        (the default: a CONFIG completes at once)."""
        self.eeprom.enabled = enabled

    def take_eeprom(self) -> bytes | None:
        """The EEPROM image to persist, when CONFIG_MOD = 1 or a fault-history change asks for it; its generation
        is :attr:`eeprom_generation` (for :meth:`eeprom_durable`)."""
        self.finish()
        if not self.eeprom.take():
            return None
        return EepromImage(self.card, self.saved_params, self._history).to_bytes()

    @property
    def eeprom_generation(self) -> int:
        """The generation of the image :meth:`take_eeprom` last returned."""
        return self.eeprom.taken

    def eeprom_durable(self, generation: int, ok: bool = True) -> None:
        """The I/O layer's input: the image of *generation* is written, fsync'd and renamed (*ok*), or could not be
        written (:meth:`EepromWriteBack.durable`)."""
        if not self.eeprom.durable(generation, ok):
            self._log.error("eeprom_write_failed", generation=generation)

    def drive_activity(self) -> DriveActivity:
        """What the drive is doing and what holds it (:meth:`Drive.activity <mlink_sim.drive.Drive.activity>`),
        read without advancing it."""
        return self.drive.drive.activity()

    def snapshot(self) -> StationSnapshot:
        self.finish()
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
            if self.unfinished:
                self._finish()
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

    def _subcommands_active(self) -> bool:
        return False

    def _led_recent(self, at: int | None) -> bool:
        return at is not None and self._now - at <= LED_WINDOW_NS

    # -- the operations the command handlers use (mlink_sim.cards.commands, the cards' handler tables) --------------
    def select_refs(self, sel: int, *values: int) -> None:
        """Record REF values by the item their SEL_REF nibble selects (SI-T3 Table 17, SI-ET3 Table 21, SI-T/V7
        Table 4; unused codes are ignored)."""
        table = self._sel_ref
        for i, value in enumerate(values):
            item = table[(sel >> (4 * i)) & 0xF]
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
            self._note("info", "connect_refused", fields)

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
