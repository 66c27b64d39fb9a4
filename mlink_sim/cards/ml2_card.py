"""MECHATROLINK-I/II station machinery shared by the SI-T3 and the SI-T/V7 (SI-T3 §7–§9, SI-T/V7 §5–§8).

Each command is answered by a handler from a table keyed by command code (:data:`MAIN_HANDLERS`,
:data:`SUB_HANDLERS`): the handlers both generations share come from :mod:`mlink_sim.cards.commands`, the
MECHATROLINK-I/II ones (CONNECT, DISCONNECT, ID_RD, ALM_RD, INV_CTL) are ``_handle_*`` methods below; a card
profile copies and adjusts the tables. A handler returns the response body and an
:class:`~mlink_sim.cards.results.Err`; a refused command is ignored and reported with A.94/A.95 in the ALARM
byte ("Received commands are ignored", SI-T3 Table 25), a refused sub-command additionally with SUBWARNG.
Main before sub: "If a conflict occurs between a request for a main command and a request for a sub-command,
the request for the main command is processed"; INV_I/O references are applied after INV_CTL's, so "If an
INV_CTL main command and an INV_I/O sub-command conflict, the sub-command is given priority".
"""

from __future__ import annotations

from collections.abc import Callable, Hashable, Mapping
from types import MappingProxyType
from typing import Any, ClassVar, Final

from mlink_sim.profiles import CardProfile
from mlink_sim.wire import (
    MAGIC, Frame, Kind, Link, M2Alarm, M2Cmd, M2Status, M2SubStatus, Unknown, encode, ml2,
)
from mlink_sim.wire.frame import (
    FCS_SIZE, HEADER_SIZE, datagram_offset, datagram_struct, fcs_ok, Template,
)

from . import commands
from .alarms import Ml2Alarms, ml2_failure_code
from .base import SLOW, Station
from .commands import Handler, SubHandler
from .drive_link import DriveCommand, Fault, ml2_status_bits
from .eeprom import BUSY
from .idinfo import ML2_ID_AREAS, ml2_id_window
from .phases import ML2_COMBINATIONS, ML2_MAIN_PHASES, ML2_SUB_PHASES, Admit, combination_ok
from .reception import FailureKind
from .results import Err
from .settings import CardSettings

__all__ = ["Ml2Station", "MAIN_HANDLERS", "SUB_HANDLERS", "echo_main", "echo_sub"]

_ZERO_MAIN: Final = bytes(ml2.RESPONSE_MAIN.size)
_ZERO_SUB: Final = bytes(ml2.RESPONSE_SUB.size)
_MAIN_CODE = {cls: layout.code for cls, layout in ml2.COMMAND_MAIN.by_class.items()}
_SUB_CODE = {cls: layout.code for cls, layout in ml2.COMMAND_SUB.by_class.items()}
_ALLOWED, _IGNORED = Admit.ALLOWED, Admit.IGNORED


# The fast path's formats, offsets and codes, derived from the wire declarations (so they cannot drift from them),
# as master/fastpath.py does: whole datagrams (envelope, frame and INV_CTL body) in one struct each, the command's
# first 17 data bytes (alike in both frame sizes) and the response of each frame size.
_CMD_DG, _CMD_NAMES = datagram_struct(ml2.COMMAND_FRAME_17, 17, main=(
    ml2.COMMAND_MAIN.by_code[M2Cmd.INV_CTL].struct.subcon, ml2.COMMAND_MAIN.size))
#: Final (a C static under mypyc) and bound once: no lookup per datagram
_CMD_UNPACK: Final = _CMD_DG.unpack_from
_RSP_DG = {size: datagram_struct(frame, size, main=(ml2.RESPONSE_MAIN.by_code[M2Cmd.INV_CTL].struct.subcon,
                                                    ml2.RESPONSE_MAIN.size))
           for size, frame in ((17, ml2.RESPONSE_FRAME_17), (32, ml2.RESPONSE_FRAME_32))}
if _CMD_NAMES != ("magic", "link", "kind", "station", "cycle", "tcycle_ns", "code", "signals", "speed_ref",
                  "torque_ref", "sel_ref", "sel_mon", "ref1", "ref2", "wdt"):
    raise ImportError(f"MECHATROLINK-II fast path: the INV_CTL command fields are {_CMD_NAMES}")
if _RSP_DG[32][1][-3:] != ("subcode", "substatus", "sub") or _RSP_DG[17][1] != _RSP_DG[32][1][:-3] or \
        _RSP_DG[17][1][6:] != ("code", "alarm", "status", "output_freq", "output_current", "sel_ref", "sel_mon",
                               "mon1", "mon2", "rwdt"):
    raise ImportError(f"MECHATROLINK-II fast path: the INV_CTL response fields are {_RSP_DG[32][1]}")
_SUBCODE_AT: Final = datagram_offset("subcode", ml2.COMMAND_FRAME_32)
_WDT_AT: Final = datagram_offset("wdt", ml2.COMMAND_FRAME_17)  # alike in both frame sizes
_RWDT_AT: Final = datagram_offset("rwdt", ml2.RESPONSE_FRAME_17)
if (_WDT_AT != datagram_offset("wdt", ml2.COMMAND_FRAME_32)
        or _RWDT_AT != datagram_offset("rwdt", ml2.RESPONSE_FRAME_32) or _RSP_DG[17][1][4] != "cycle"):
    raise ImportError("MECHATROLINK-II fast path: WDT, RWDT or the cycle moved between the frame sizes")
_CMD_INV_CTL: Final = int(M2Cmd.INV_CTL)
_KIND_COMMAND: Final = int(Kind.COMMAND)
_KIND_RESPONSE: Final = int(Kind.RESPONSE)
_CMDRDY: Final = int(M2Status.CMDRDY)
_SUBRDY: Final = int(M2SubStatus.SUBCMDRDY)
_WARNG: Final = int(M2Status.WARNG)
_SUBWARN: Final = int(M2SubStatus.SUBCMDRDY | M2SubStatus.SUBWARNG)
_MS: Final = 1_000_000
_HALF_MS: Final = 500_000


def echo_main(body: Any) -> Any:
    """The response body of a command that was not executed: its fields echoed, data zero."""
    t = type(body)
    if t is ml2.PrmRd:
        return ml2.PrmRdResponse(body.no, body.size)
    if t is ml2.IdRd:
        return ml2.IdRdResponse(body.device_code, body.offset, body.size)
    if t is ml2.AlmRd:
        return ml2.AlmRdResponse(body.alm_rd_mod)
    if t is ml2.InvCtl:
        return ml2.InvCtlResponse(sel_ref=body.sel_ref, sel_mon=body.sel_mon)
    if t is Unknown:
        return Unknown(body.code, _ZERO_MAIN)
    return body  # NOP, PRM_WR, CONFIG, ALM_CLR, SYNC_SET, CONNECT, DISCONNECT echo themselves


def echo_sub(sub: Any) -> Any:
    t = type(sub)
    if t is ml2.PrmRd:
        return ml2.PrmRdResponse(sub.no, sub.size)
    if t is ml2.AlmRd:
        return ml2.AlmRdResponse(sub.alm_rd_mod)
    if t is ml2.InvIo:
        return ml2.InvIoResponse(sub.sel_ref34, sub.sel_ref56, sub.sel_mon34, sub.sel_mon56)
    if t is Unknown:
        return Unknown(sub.code, _ZERO_SUB)
    return sub


class Ml2Station(Station):
    """A MECHATROLINK-I/II slave; the card classes set the tables and the power-up settings."""

    main_phases: ClassVar[Mapping[int, Any]] = ML2_MAIN_PHASES
    sub_phases: ClassVar[Mapping[int, Any]] = ML2_SUB_PHASES
    combinations: ClassVar[Mapping[int, frozenset[int]]] = ML2_COMBINATIONS
    id_areas: ClassVar[Mapping[int, bytes]] = ML2_ID_AREAS
    alm_rd_modes: ClassVar[frozenset[int]] = frozenset((0, 1, 2))
    handlers: ClassVar[Mapping[int, Handler]]  #: the card class's main-command table (MAIN_HANDLERS, adjusted)
    sub_handlers: ClassVar[Mapping[int, SubHandler]]  #: its sub-command table (SUB_HANDLERS, adjusted)
    alm_rd_history: ClassVar[int] = 10  #: ALM_RD mode 1: fault history entries (SI-T3 Table 14; SI-T/V7: 2)
    mfi_mask: ClassVar[int] = 0x3F  #: operation signals bits 2–7 -> S3–S8 (SI-T3 Table 16); V7: S3–S7
    _cmd_wdt_at: ClassVar[int] = _WDT_AT

    def __init__(self, profile: CardProfile, *, settings: CardSettings, now: int, eeprom: bytes | None = None
                 ) -> None:
        # the parameters spelled out: mypyc (docs/architecture.md, "Compiled cores (mypyc)") passes a **kwargs dict on
        # as one positional argument
        super().__init__(profile, settings=settings, now=now, eeprom=eeprom)
        # mapping-like: Ml2Alarms only calls get()
        self.alarms = Ml2Alarms(_CodeTable(self.drive.fault_code), _CodeTable(self.drive.minor_code))  # type: ignore[arg-type]
        self._subcmd = self.data_size == 32
        self._bits_e_f = profile.status_bits_e_f  # STATUS bits E and F (V7 §7.3: not used)
        self._status_seen: object = None  # the DriveStatus self._status_word was computed from
        self._status_word = 0
        self._deferred_cyc = False
        self._fast_len = HEADER_SIZE + self.data_size + FCS_SIZE
        self._frame32 = self.data_size == 32
        self._rsp_pack = _RSP_DG[self.data_size][0].pack  # bound once: no lookup per datagram
        # the fast path's steady state (_fast_receive): the last command it took and its fields, and its answers'
        # template
        self._c_link = self._c_tcycle = self._c_sig = self._c_speed = self._c_torque = 0
        self._c_sel_ref = self._c_sel_mon = self._c_ref1 = self._c_ref2 = 0
        self._answer = Template(_RWDT_AT)

    # -- the command ---------------------------------------------------------------------------
    def _process(self, frame: Frame, source: Hashable, now: int) -> bytes:
        msg = frame.message
        body = msg.body
        btype = type(body)
        code = body.code if btype is Unknown else _MAIN_CODE[btype]
        phase, subcmd = self._arrival_phase(), self._subcmd  # the state the command arrived in rules the sub-command
        row = self.main_phases.get(code)
        hold: Any = self.eeprom.hold(False, code)  # None, BUSY (a sentinel) or an Err
        if hold is not None:  # a CONFIG waits for the EEPROM (eeprom.EepromWriteBack)
            rbody, err = echo_main(body), (Err.OK if hold is BUSY else hold)
        elif row is None:
            rbody, err = echo_main(body), Err.UNSUPPORTED
        else:
            adm = row[phase - 1]
            if adm is _ALLOWED:
                rbody, err = self.handlers[code](self, body, frame, source, now)
            elif adm is _IGNORED:
                rbody, err = echo_main(body), Err.OK
            else:
                rbody, err = echo_main(body), Err.PHASE
        if err is not Err.OK:
            self.alarms.warning(err.ml2)
            self.counters.commands_refused += 1
        sub = msg.sub
        if sub is None:
            rsub, substatus = None, 0
        else:
            rsub, substatus = self._process_sub(code, sub, phase, subcmd, now)
        alarm, word = self._alarm_status(code == M2Cmd.PRM_RD)
        if self.eeprom.busy(False):
            word &= ~_CMDRDY  # "Command ready: 0 Busy" (SI-T3 / SI-T/V7 "STATUS Field")
        resp = ml2.M2Response(rbody, alarm, word, self.watchdog.rwdt(), rsub, substatus)
        self.alarms.reported()
        if self._deferred_cyc:  # the drive learns of the cycle error after the card answered the CONNECT
            self._deferred_cyc = False
            self.drive.minor(Fault.CYC, True, now)
        return encode(Frame(self.link, Kind.RESPONSE, self.address, frame.cycle, frame.tcycle_ns, resp))

    def _status_reply(self, frame: Frame) -> bytes:
        """NOP response with ALARM/STATUS as they stand, for a source other than the connected master (health
        checks): nothing is executed, no warning is consumed, RWDT does not advance (docs/cards.md)."""
        status = self.drive.status
        alarm, alm, warng = self.alarms.report(status.fault, status.minor, status.fault_reset_input)
        word = ml2_status_bits(status, cmdrdy=not self.eeprom.busy(False), bits_e_f=self._bits_e_f) & ~3 | alm | warng << 1
        sub = frame.message.sub
        resp = ml2.M2Response(ml2.Nop(), alarm, word, self.watchdog.peek(), None if sub is None else ml2.Nop(),
                              0 if sub is None or self.eeprom.busy(True) else _SUBRDY)
        return encode(Frame(self.link, Kind.RESPONSE, self.address, frame.cycle, frame.tcycle_ns, resp))

    def _alarm_status(self, prm_rd: bool) -> tuple[int, int]:
        """ALARM byte and STATUS word of the next response (SI-T3 "STATUS Field", Tables 19–21)."""
        status = self.drive.status
        alarms = self.alarms
        alarms.observe(status.fault)
        alarm, alm, warng = alarms.report(status.fault, status.minor, status.fault_reset_input)
        if prm_rd:  # PRM_RD: "only the settings for the STATUS (CMDRDY) is valid"
            return alarm, _CMDRDY | alm | warng << 1
        if status is not self._status_seen:
            self._status_seen = status
            self._status_word = ml2_status_bits(status, cmdrdy=True, bits_e_f=self._bits_e_f) & ~3
        return alarm, self._status_word | alm | warng << 1

    def _fast_receive(self, dg: bytes, source: Hashable, now: int) -> object:
        """INV_CTL with a NOP (or no) sub-command in phase 2/3 – the per-cycle command – straight from and to
        bytes with ``struct`` formats derived from the wire declarations; identical responses to the general
        path (tests/cards/test_fast_path.py). The steady state as on the SI-ET3 (``SiEt3._fast_receive``): a
        command that differs from the last one taken only in its cycle, WDT and FCS is not unpacked again, and
        the answer is the last one's template with the cycle and RWDT patched in while its other fields hold."""
        d = self._steady_delta(dg)
        if d >= 0:  # the fields kept from the last command (native ints, no unpack)
            cycle, wdt, stn = d & 0xFFFFFFFF, d >> 32, self.address
            link, tcycle, sig = self._c_link, self._c_tcycle, self._c_sig
            speed, torque, sel_ref, sel_mon, ref1, ref2 = (self._c_speed, self._c_torque, self._c_sel_ref,
                                                           self._c_sel_mon, self._c_ref1, self._c_ref2)
        else:
            if len(dg) != self._fast_len:
                return SLOW
            (magic, link, kind, stn, cycle, tcycle, code, sig, speed, torque, sel_ref, sel_mon, ref1, ref2,
             wdt) = _CMD_UNPACK(dg)
            if (magic != MAGIC or link != self.link or kind != _KIND_COMMAND or stn != self.address
                    or code != _CMD_INV_CTL or (self._frame32 and dg[_SUBCODE_AT] != 0) or not fcs_ok(dg)):
                return SLOW
            self._fast_cmd, self._c_link, self._c_tcycle, self._c_sig = dg, link, tcycle, sig
            self._c_speed, self._c_torque, self._c_sel_ref, self._c_sel_mon = speed, torque, sel_ref, sel_mon
            self._c_ref1, self._c_ref2 = ref1, ref2
        if not self._accept(cycle, tcycle, wdt, _CMD_INV_CTL, source, now):
            return None
        if self._source is None:  # this command's gap lost the connection
            return self._answer_after_loss(dg, source, now)
        ofreq, cur, mon1, mon2 = self._inv_ctl(sig, speed, torque, sel_ref, sel_mon, ref1, ref2, now)
        alarm, word = self._alarm_status(False)
        rwdt = self.watchdog.rwdt()
        self.alarms.reported()
        self.counters.tx += 1  # self._sent(now), spelt out
        self._tx_at = now
        if self.drive.status.fault is not self._seen_fault:
            self._watch_history()
        answer = self._answer
        if answer.stale(alarm, word, ofreq, cur, sel_ref, sel_mon, mon1, mon2, tcycle):
            if self._frame32:
                answer.body = self._rsp_pack(MAGIC, link, _KIND_RESPONSE, stn, 0, tcycle, _CMD_INV_CTL, alarm,
                                               word, ofreq, cur, sel_ref, sel_mon, mon1, mon2, 0, 0, _SUBRDY,
                                               _ZERO_SUB)
            else:
                answer.body = self._rsp_pack(MAGIC, link, _KIND_RESPONSE, stn, 0, tcycle, _CMD_INV_CTL, alarm,
                                               word, ofreq, cur, sel_ref, sel_mon, mon1, mon2, 0)
        elif tcycle == self.tcycle_ns and not word & _WARNG and self._out_key >= 0:
            # a fixed point (self.prediction), as on the SI-ET3; and no communications warning in it: the answer
            # that carries one drops it (Ml2Alarms.reported), so the next one differs
            self._steady_cycle = cycle
        return answer.seal(cycle, rwdt)

    def _inv_ctl(self, sig: int, speed: int, torque: int, sel_ref: int, sel_mon: int, ref1: int, ref2: int,
                 now: int) -> tuple[int, int, int, int]:
        """INV_CTL (SI-T3 Table 16 / V7 Table 3 operation signals): the drive command; returns output
        frequency, output current, MON1, MON2."""
        ck = self._cmd_key  # compared field by field: a tuple built each cycle would be allocated and compared
        if ck is None or ck[0] != sig or ck[1] != speed or ck[2] != torque:
            self._cmd_key = (sig, speed, torque)
            cmd = DriveCommand(
                forward=bool(sig & 0x0001), reverse=bool(sig & 0x0002), fault_reset=bool(sig & 0x0200),
                external_fault=bool(sig & 0x0100), external_baseblock=bool(sig & 0x8000),
                multi_inputs=(sig >> 2) & self.mfi_mask, freq_ref_raw=speed, torque_ref_raw=torque,
                torque_limit_raw=torque, fault_history_clear=bool(sig & 0x4000),
            )
            self.drive.command(cmd, now)
            if cmd.fault_history_clear:
                self._watch_history()
        if sel_ref:
            self.select_refs(sel_ref, ref1, ref2)
        return self._outputs(sel_mon)

    def _process_sub(self, main_code: int, sub: Any, phase: int, subcmd: bool, now: int) -> tuple[Any, int]:
        stype = type(sub)
        scode = sub.code if stype is Unknown else _SUB_CODE[stype]
        if not subcmd:  # CONNECT with SUBCMD = 0: the sub-command area is not used
            return echo_sub(sub), _SUBRDY
        row = self.sub_phases.get(scode)
        hold: Any = self.eeprom.hold(True, scode)  # None, BUSY (a sentinel) or an Err
        if hold is BUSY:  # the SI-T/V7 CONFIG sub-command waits for the EEPROM: "SUBCMDRDY 0 Busy"
            return echo_sub(sub), 0
        if hold is Err.OK:
            return echo_sub(sub), _SUBRDY
        if hold is not None:
            err = hold
        elif row is None:
            err = Err.UNSUPPORTED
        elif not combination_ok(self.combinations, main_code, scode):
            err = Err.COMBINATION  # SI-T3 Table 7 "NG (A.95)"
        else:
            adm = row[phase - 1]
            if adm is _ALLOWED:
                rsub, err = self.sub_handlers[scode](self, sub, now)
                if err is Err.OK:
                    return rsub, 0 if self.eeprom.busy(True) else _SUBRDY
            else:
                err = Err.OK if adm is _IGNORED else Err.PHASE
                if err is Err.OK:
                    return echo_sub(sub), _SUBRDY
        self.alarms.warning(err.ml2)
        self.counters.commands_refused += 1
        return echo_sub(sub), _SUBWARN

    # -- the MECHATROLINK-I/II handlers (the tables MAIN_HANDLERS / SUB_HANDLERS below) ------------------
    def _handle_id_rd(self, body: ml2.IdRd, frame: Frame, source: Hashable, now: int) -> tuple[Any, Err]:
        """ID_RD (SI-T3 Tables 10/11, SI-T/V7 ID_RD): up to 8 bytes of the DEVICE_CODE's area."""
        data = ml2_id_window(self.id_areas, body.device_code, body.offset, body.size)
        if data is None:
            return echo_main(body), Err.DATA
        return ml2.IdRdResponse(body.device_code, body.offset, body.size, data), Err.OK

    def _handle_alm_rd(self, body: ml2.AlmRd, frame: Frame, source: Hashable, now: int) -> tuple[Any, Err]:
        data, err = self._alm_data(body.alm_rd_mod, body.alm_index)
        return ml2.AlmRdResponse(body.alm_rd_mod, data), err

    def _handle_sub_alm_rd(self, sub: ml2.AlmRd, now: int) -> tuple[Any, Err]:
        data, err = self._alm_data(sub.alm_rd_mod, sub.alm_index)
        return ml2.AlmRdResponse(sub.alm_rd_mod, data), err

    def _handle_connect(self, body: ml2.Connect, frame: Frame, source: Hashable, now: int) -> tuple[Any, Err]:
        """CONNECT (SI-T3 CONNECT with its errata, SI-T/V7 CONNECT): phase 2 or 3 per SYNCMOD."""
        err, sync, cyc = self._check_connect(body, frame.tcycle_ns)
        if self.has_cyc:  # SI-T3 Table 27 33H CyC "Transmission Cycle Error": raised once this A.94 is answered
            if cyc:
                self._deferred_cyc = True
            else:
                self.drive.minor(Fault.CYC, False, now)
        if err is not Err.OK:
            self.log_refused(ver=body.ver, com_mod=body.com_mod, com_tim=body.com_tim,
                             tcycle_ns=frame.tcycle_ns, cycle_fault=cyc)
            return body, err
        self._subcmd = self.data_size == 32 and bool(body.com_mod & 0x80)
        comm = frame.tcycle_ns if self.link is not Link.ML1 else body.com_tim * _MS
        self.connect(source, frame.cycle, now, sync=sync, tcycle_ns=frame.tcycle_ns, com_tim=body.com_tim,
                     comm_cycle_ns=comm, wdt=frame.message.wdt)
        return body, Err.OK

    def _handle_disconnect(self, body: Any, frame: Frame, source: Hashable, now: int) -> tuple[Any, Err]:
        self.disconnect(now)
        self._subcmd = self.data_size == 32
        return body, Err.OK

    def _handle_inv_ctl(self, body: ml2.InvCtl, frame: Frame, source: Hashable, now: int) -> tuple[Any, Err]:
        ofreq, cur, mon1, mon2 = self._inv_ctl(body.signals, body.speed_ref, body.torque_ref, body.sel_ref,
                                               body.sel_mon, body.ref1, body.ref2, now)
        return ml2.InvCtlResponse(ofreq, cur, body.sel_ref, body.sel_mon, mon1, mon2), Err.OK

    def _alm_data(self, mod: int, index: int) -> tuple[bytes, Err]:
        """ALM_DATA (10 bytes): modes per SI-T3 Table 13 (ALM_RD_MOD), data per SI-T3 Table 14 (ALM_DATA); SI-T/V7:
        modes 0 and 1, two history entries."""
        if mod not in self.alm_rd_modes:
            return bytes(10), Err.DATA
        drive = self.drive
        hist = [drive.fault_code(f) & 0xFF for f in drive.history()]
        if mod == 0:
            return bytes((drive.monitor("U2-01") & 0xFF, drive.monitor("U2-02") & 0xFF)).ljust(10, b"\0"), Err.OK
        if mod == 1:
            return bytes(hist[:self.alm_rd_history]).ljust(10, b"\0"), Err.OK
        if not 0 <= index <= 9:  # mode 2: "Alarm Index + 1" selects U3-01 … U3-10
            return bytes(10), Err.DATA
        value = hist[index] if index < len(hist) else 0
        return (bytes((index,)) + value.to_bytes(2, "little")).ljust(10, b"\0"), Err.OK

    # -- CONNECT -------------------------------------------------------------------------------
    def _check_connect(self, body: ml2.Connect, tcycle: int) -> tuple[Err, bool, bool]:
        """``(verdict, synchronous, transmission-cycle fault)`` of a CONNECT (SI-T3 CONNECT with its errata,
        SI-T/V7 CONNECT)."""
        ver, mod, tim = body.ver, body.com_mod, body.com_tim
        ml1 = self.link is Link.ML1
        if ver != (0x10 if ml1 else 0x21):  # "This setting must match the switch setting" (SI-T/V7)
            return Err.DATA, False, False
        if ml1:
            exmod = bool(mod & 0x01)
            # "If Bit6, Bit5, Bit4, Bit3, or Bit0 is set to 1" / SUBCMD "for Ver. 1.0"; DTMOD = 00 only
            if mod & 0xFC or (exmod and not self.options.ml1_exmod_accepted):
                return Err.DATA, False, False
            sync = bool(mod & 0x02) and not exmod  # EXMOD: "SYNCMOD will be set to 0"
            if tcycle != 2 * _MS:  # "For MECHATROLINK-I, a cycle is 2 ms" (Table 29 <1>)
                return Err.DATA, False, True
            if tim != 2:  # errata (2): "If COM_TIM ≠ 2: Data setting warning (A.94)"
                return Err.DATA, False, False
            return Err.OK, sync, False
        if mod & 0x71 or mod & 0x0C:  # reserved bits 6, 5, 4, 0; DTMOD other than 00
            return Err.DATA, False, False
        if mod & 0x80 and self.data_size == 17:  # "If SUBCMD is set to 1 in 17-byte data transmission"
            return Err.DATA, False, False
        if self.data_size == 32:
            ok = _MS <= tcycle <= 8 * _MS and tcycle % _MS == 0
        else:
            ok = _HALF_MS <= tcycle <= 8 * _MS and tcycle % _HALF_MS == 0
        if not ok:
            return Err.DATA, False, True
        if tim != 1:  # errata (1): "(COM_TIM ≠ 1): A warning (Data setting warning: A.94) is generated"
            return Err.DATA, False, False
        return Err.OK, bool(mod & 0x02), False

    # -- failures and alarms ---------------------------------------------------------------------
    def _report_failure(self, kind: FailureKind, first: bool) -> None:
        code = ml2_failure_code(kind, first, self.phase)
        if first and kind is not FailureKind.CYCLE:
            self.alarms.warning(code)
        else:
            self.alarms.alarm(code)

    def _report_wdt(self) -> None:
        self.alarms.alarm(M2Alarm.WDT_ERROR)

    def _clear_comm_alarms(self) -> None:
        self.alarms.clear()

    def _observe_drive(self) -> None:
        self.alarms.observe(self.drive.status.fault)

    def _subcommands_active(self) -> bool:
        return self.data_size == 32 and self._subcmd

    def _alarm_view(self) -> tuple[int, str | None, tuple[str, ...], int]:
        status = self.drive.status
        self.alarms.observe(status.fault)
        code, alm, _ = self.alarms.report(status.fault, status.minor, status.fault_reset_input)
        name: str | None = None
        if code:
            try:
                name = M2Alarm(code).name
            except ValueError:
                if alm and status.fault is not None:
                    name = status.fault.display
                elif status.minor is not None:
                    name = status.minor.display
        warnings = tuple(f"A.{c:02X}" for c in sorted(self.alarms.comm_warnings))
        warnings += tuple(sorted(f.display for f in status.minors))
        return code, name, warnings, 0


class _CodeTable:
    """Mapping-like view of a fault -> code function (what :class:`Ml2Alarms` expects)."""

    __slots__ = ("_fn",)

    def __init__(self, fn: Callable[[Any], int]) -> None:
        self._fn = fn

    def get(self, key: Any, default: int = 0) -> int:
        return self._fn(key) or default


#: MECHATROLINK-I/II main commands (SI-T3 Table 5, SI-T/V7 Table 1) -> handler; admission by phase in
#: :data:`~mlink_sim.cards.phases.ML2_MAIN_PHASES`.
MAIN_HANDLERS: Mapping[int, Handler] = MappingProxyType({
    M2Cmd.NOP: commands.nop,
    M2Cmd.PRM_RD: commands.prm_rd,
    M2Cmd.PRM_WR: commands.prm_wr,
    M2Cmd.ID_RD: Ml2Station._handle_id_rd,
    M2Cmd.CONFIG: commands.config,
    M2Cmd.ALM_RD: Ml2Station._handle_alm_rd,
    M2Cmd.ALM_CLR: commands.alm_clr,
    M2Cmd.SYNC_SET: commands.sync_set,
    M2Cmd.CONNECT: Ml2Station._handle_connect,
    M2Cmd.DISCONNECT: Ml2Station._handle_disconnect,
    M2Cmd.INV_CTL: Ml2Station._handle_inv_ctl,
})

#: MECHATROLINK-I/II sub-commands (SI-T3 Table 6, SI-T/V7 Table 2 and the CONFIG sub-command of §7.2) -> handler;
#: the SI-T3 drops CONFIG (si_t3.py).
SUB_HANDLERS: Mapping[int, SubHandler] = MappingProxyType({
    M2Cmd.NOP: commands.sub_nop,
    M2Cmd.PRM_RD: commands.sub_prm_rd,
    M2Cmd.PRM_WR: commands.sub_prm_wr,
    M2Cmd.ALM_RD: Ml2Station._handle_sub_alm_rd,
    M2Cmd.CONFIG: commands.sub_config,
    M2Cmd.INV_IO: commands.sub_inv_io,
})
