"""SI-ET3: the MECHATROLINK-III option card, standard inverter profile (YASKAWA SIEP C730600 88).

* Power-up settings (Table 7, note <9>): F6-20 station address 03H–EFH (outside: AEr; 20H/3FH only with
  ``CardOptions.et3_aer_on_20_3f``, note <10> being a copy of the SI-T3 note); F6-21 frame size (0 = 64-byte
  with sub-commands, 1 = 32-byte); F6-23/F6-24 the registers of SEL_MON E/F.
* Commands: Tables 11/12; phases Tables 9/10 ("–" = CMD_ALM / SUBCMD_ALM CH, "△" ignored); combinations
  Table 13 (CMD_ALM BH). CMD_CTRL / CMD_STAT (§8): RCMD_ID echoes CMD_ID, CMDRDY, D_ALM/D_WAR from the drive,
  CMD_ALM for the command answered, COMM_ALM latched until ALM_CLR or the rising edge of CMD_CTRL.ALM_CLR
  (answered with ALM_CLR_CMP). ID_RD Table 14, CONFIG Table 15, ALM_RD Tables 16/17, INVCMD_CTRL Table 20,
  SEL_REF Table 21, SEL_MON Table 22, SUB_STAT Tables 24/25.
* CONNECT: VER 30H, COM_MOD Tables 18/19 (reserved bits 0; SUBCMD only with 64-byte frames), COM_TIM 1–255,
  PROFILE_TYPE 20H, transmission cycle 250 µs–8 ms on the granularity of ID_CODE 18H (31.25/62.5/125/250/500/
  750 µs, 1–64 ms in 0.5 ms steps, within ID_CODE 16H/17H), communication cycle within ID_CODE 19H/1AH
  (250 µs–32 ms); otherwise CMD_ALM 9H and, for a cycle, the CYC minor fault (Table 26).
* LEDs (Table 4): R/E (green/red), CON, LK1, LK2.
"""

from __future__ import annotations

from collections.abc import Hashable, Mapping
from types import MappingProxyType
from typing import Any, ClassVar, Final

from mlink_sim.profiles import CardProfile
from mlink_sim.wire import (
    MAGIC, PROFILE_TYPE_INVERTER, CommAlm, Frame, Kind, Link, M3Cmd, Unknown, encode, ml3,
)
from mlink_sim.wire.frame import (
    FCS_SIZE, HEADER_SIZE, datagram_offset, datagram_struct, fcs_ok, Template,
)

from . import commands
from .alarms import Ml3Alarms, ml3_failure_code
from .base import SLOW, Station
from .commands import Handler, SubHandler
from .drive_link import DriveCommand, DriveStatus, Fault, ml3_invcmd_stat_bits
from .eeprom import BUSY
from .idinfo import ml3_id_data, ml3_id_window
from .monitors import sel_mon_enabled
from .phases import ML3_COMBINATIONS, ML3_MAIN_PHASES, ML3_SUB_PHASES, Admit, combination_ok
from .reception import FailureKind
from .results import Err
from .settings import CardSettings

__all__ = ["SiEt3", "MAIN_HANDLERS", "SUB_HANDLERS", "VALID_TCYCLES_NS", "MANUAL_TABLES", "cmd_stat"]

_ZERO_MAIN: Final = bytes(ml3.RESPONSE_MAIN.size)
_ZERO_SUB: Final = bytes(ml3.RESPONSE_SUB.size)
_MAIN_CODE = {cls: layout.code for cls, layout in ml3.COMMAND_MAIN.by_class.items()}
_SUB_CODE = {cls: layout.code for cls, layout in ml3.COMMAND_SUB.by_class.items()}
_ALLOWED, _IGNORED, _PHASE = Admit.ALLOWED, Admit.IGNORED, Admit.PHASE_ERROR


# The fast path's formats, offsets and codes, derived from the wire declarations (so they cannot drift from them),
# as master/fastpath.py does: whole datagrams (envelope, frame and INV_CTL body) in one struct each, the command's
# first 32 data bytes (alike in both frame sizes) and the response of each frame size.
_CMD_DG, _CMD_NAMES = datagram_struct(ml3.COMMAND_FRAME_32, 32, main=(
    ml3.COMMAND_MAIN.by_code[M3Cmd.INV_CTL].struct.subcon, ml3.COMMAND_MAIN.size))
#: Final (a C static under mypyc) and bound once: no lookup per datagram
_CMD_UNPACK: Final = _CMD_DG.unpack_from
_RSP_DG = {size: datagram_struct(frame, size, main=(ml3.RESPONSE_MAIN.by_code[M3Cmd.INV_CTL].struct.subcon,
                                                    ml3.RESPONSE_MAIN.size))
           for size, frame in ((32, ml3.RESPONSE_FRAME_32), (64, ml3.RESPONSE_FRAME_64))}
if _CMD_NAMES != ("magic", "link", "kind", "station", "cycle", "tcycle_ns", "code", "wdt", "cmd_ctrl", "invcmd_ctrl",
                  "invcmd_io", "speed_ref", "torque_ref", "sel_ref", "sel_mon", "ref1", "ref2"):
    raise ImportError(f"SI-ET3 fast path: the INV_CTL command fields are {_CMD_NAMES}")
if _RSP_DG[64][1][-3:] != ("subcode", "sub_stat", "sub") or _RSP_DG[32][1] != _RSP_DG[64][1][:-3] or \
        _RSP_DG[32][1][6:] != ("code", "rwdt", "cmd_stat", "invcmd_stat", "invcmd_io", "output_freq",
                               "output_current", "sel_ref", "sel_mon", "mon1", "mon2"):
    raise ImportError(f"SI-ET3 fast path: the INV_CTL response fields are {_RSP_DG[64][1]}")
_SUBCODE_AT: Final = datagram_offset("subcode", ml3.COMMAND_FRAME_64)
_WDT_AT: Final = datagram_offset("wdt", ml3.COMMAND_FRAME_32)  # alike in both frame sizes
_RWDT_AT: Final = datagram_offset("rwdt", ml3.RESPONSE_FRAME_32)
if (_WDT_AT != datagram_offset("wdt", ml3.COMMAND_FRAME_64)
        or _RWDT_AT != datagram_offset("rwdt", ml3.RESPONSE_FRAME_64) or _RSP_DG[32][1][4] != "cycle"):
    raise ImportError("SI-ET3 fast path: WDT, RWDT or the cycle moved between the frame sizes")
_CMD_INV_CTL: Final = int(M3Cmd.INV_CTL)
_LINK: Final = int(Link.ML3)
_KIND_COMMAND: Final = int(Kind.COMMAND)
_KIND_RESPONSE: Final = int(Kind.RESPONSE)
_SUBCMDRDY: Final = ml3.SubStat(subcmdrdy=True).to_int()  # SUB_STAT with SUBCMDRDY only (Table 24)
_US = 1_000

#: ID_CODE 18H = 03H granularity within 16H (250 µs) … 17H (8 ms): 250, 500, 750 µs and 1–8 ms in 0.5 ms steps
#: (Table 14; Table 28 "Minimum transmission cycle 250 μs", "Maximum transmission cycle 8 ms").
VALID_TCYCLES_NS = frozenset({250 * _US, 500 * _US, 750 * _US} | {1000 * _US + 500 * _US * k for k in range(15)})
_COMM_MIN_NS, _COMM_MAX_NS = 250 * _US, 32_000 * _US  # ID_CODE 19H / 1AH


def cmd_stat(status: DriveStatus, alarms: Ml3Alarms, ready: bool, ctrl: int, cmd_alm: int,
             handshake: bool = True) -> int:
    """CMD_STAT ("Command Status (CMD_STAT)", bit for bit :class:`mlink_sim.wire.ml3.CmdStat`): D_ALM/D_WAR from the
    drive, CMDRDY (*ready*), ALM_CLR_CMP (with *handshake*), RCMD_ID = CMD_ID of *ctrl*, *cmd_alm*, COMM_ALM."""
    return (status.faulted | status.minor_fault << 1 | ready << 2 | (handshake and alarms.alm_clr_cmp) << 3
            | (ctrl & 0xC0) | cmd_alm << 8 | alarms.comm_alm << 12)


def _echo_main(body: Any) -> Any:
    t = type(body)
    if t is ml3.PrmRd:
        return ml3.PrmRdResponse(body.no, body.size)
    if t is ml3.IdRd:
        return ml3.IdRdResponse(body.id_code, body.offset, body.size)
    if t is ml3.AlmRd:
        return ml3.AlmRdResponse(body.alm_rd_mod, body.alm_index)
    if t is ml3.InvCtl:
        return ml3.InvCtlResponse(invcmd_io=0, sel_ref=body.sel_ref, sel_mon=body.sel_mon)
    if t is Unknown:
        return Unknown(body.code, _ZERO_MAIN)
    return body


def _echo_sub(sub: Any) -> Any:
    t = type(sub)
    if t is ml3.PrmRd:
        return ml3.PrmRdResponse(sub.no, sub.size)
    if t is ml3.AlmRd:
        return ml3.AlmRdResponse(sub.alm_rd_mod, sub.alm_index)
    if t is ml3.InvIo:
        return ml3.InvIoResponse(sub.sel_ref34, sub.sel_ref56, sub.sel_mon34, sub.sel_mon56)
    if t is Unknown:
        return Unknown(sub.code, _ZERO_SUB)
    return sub


class SiEt3(Station):
    """SI-ET3 MECHATROLINK-III option card on an A1000-family drive."""

    _cmd_wdt_at: ClassVar[int] = _WDT_AT
    handlers: ClassVar[Mapping[int, Handler]]
    sub_handlers: ClassVar[Mapping[int, SubHandler]]

    def __init__(self, profile: CardProfile, *, settings: CardSettings, now: int, eeprom: bytes | None = None
                 ) -> None:
        # the parameters spelled out: mypyc (docs/architecture.md, "Compiled cores (mypyc)") passes a **kwargs dict on
        # as one positional argument
        super().__init__(profile, settings=settings, now=now, eeprom=eeprom)
        self.alarms = Ml3Alarms()
        self._subcmd = False
        self._profile = 0
        self._status_seen: object = None  # the DriveStatus self._status_word was computed from
        self._status_word = 0
        self._last_cmd_alm = 0
        self._last_sub_alm = 0
        self._fast_len = HEADER_SIZE + self.data_size + FCS_SIZE
        self._frame64 = self.data_size == 64
        self._rsp_pack = _RSP_DG[self.data_size][0].pack  # bound once: no lookup per datagram
        # the fast path's steady state (_fast_receive): the last command it took and its fields, and its answers'
        # template
        self._c_tcycle = self._c_ctrl = self._c_ictrl = self._c_speed = self._c_torque = 0
        self._c_sel_ref = self._c_sel_mon = self._c_ref1 = self._c_ref2 = 0
        self._answer = Template(_RWDT_AT)
        self._sel_mon_bits: dict[int, int] = {}  # SEL_MON -> INVCMD_STAT bits 24/25, filled as codes are seen

    def _power_up(self, values: Mapping[str, int], settings: CardSettings) -> None:
        self.address = values["F6-20"]
        self.link = Link.ML3
        self.data_size = 32 if values["F6-21"] == 1 else 64
        bad = not 0x03 <= self.address <= 0xEF
        if settings.options.et3_aer_on_20_3f and self.address in (0x20, 0x3F):
            bad = True
        if bad:
            self.station_error = "AEr"
        self._mon_regs = {"F6-23": values["F6-23"], "F6-24": values["F6-24"]}

    def _bus_limit(self) -> int:
        return self.store.active.get("F6-26", 2)

    # -- the command ---------------------------------------------------------------------------
    def _process(self, frame: Frame, source: Hashable, now: int) -> bytes:
        msg = frame.message
        alarms = self.alarms
        ctrl = msg.cmd_ctrl
        # CMD_CTRL.ALM_CLR: "same processing as ALM_CLR_MODE = 0" – so, like ALM_CLR, only from the connected master
        if self._source is not None and alarms.alm_clr_edge(bool(ctrl & 0x08)):
            self.alarm_clear(now)
            alarms.alm_clr_cmp = True
        body = msg.body
        btype = type(body)
        code = body.code if btype is Unknown else _MAIN_CODE[btype]
        phase, subcmd = self._arrival_phase(), self._subcmd  # the state the command arrived in rules the sub-command
        row = ML3_MAIN_PHASES.get(code)
        hold: Any = self.eeprom.hold(False, code)  # None, BUSY (a sentinel) or an Err
        if hold is not None:  # a CONFIG waits for the EEPROM (eeprom.EepromWriteBack)
            rbody, err = _echo_main(body), (Err.OK if hold is BUSY else hold)
        elif row is None:
            rbody, err = _echo_main(body), Err.UNSUPPORTED
        else:
            adm = row[phase - 1]
            if adm is _PHASE and code == M3Cmd.NOP and self.options.et3_nop_in_phase1:
                adm = _ALLOWED
            if adm is _ALLOWED:
                rbody, err = self.handlers[code](self, body, frame, source, now)
            elif adm is _IGNORED:
                rbody, err = _echo_main(body), Err.OK
            else:
                rbody, err = _echo_main(body), Err.PHASE
        cmd_alm = err.ml3
        sub = msg.sub
        if sub is None:
            rsub, sub_stat = None, 0
        else:
            rsub, sub_err = self._process_sub(code, sub, phase, subcmd, now)
            sub_alm = sub_err.ml3
            if sub_err is Err.COMBINATION and not cmd_alm:
                cmd_alm = 0xB  # Table 13 note: "CMD_ALM = BH (sub-command combination error)"
            if sub_alm:
                self.counters.commands_refused += 1
            self._last_sub_alm = sub_alm
            sub_stat = _SUBCMDRDY | sub_alm << 8  # SUBCMDRDY, SUBCMD_ALM (Table 24)
        if err is not Err.OK:
            self.counters.commands_refused += 1
        self._last_cmd_alm = cmd_alm
        # CMD_STAT.CMDRDY "1: Command reception enabled 0: Other"
        stat = cmd_stat(self.drive.status, alarms, not self.eeprom.busy(False), ctrl, cmd_alm)
        resp = ml3.M3Response(rbody, self.watchdog.rwdt(), stat, rsub, sub_stat)
        return encode(Frame(Link.ML3, Kind.RESPONSE, self.address, frame.cycle, frame.tcycle_ns, resp))

    def _status_reply(self, frame: Frame) -> bytes:
        """NOP response with CMD_STAT as it stands, for a source other than the connected master (health checks):
        nothing is executed, CMD_ALM is not touched, RWDT does not advance (docs/cards.md)."""
        stat = cmd_stat(self.drive.status, self.alarms, not self.eeprom.busy(False), 0, 0, False)
        sub = frame.message.sub
        resp = ml3.M3Response(ml3.Nop(), self.watchdog.peek(), stat, None if sub is None else ml3.Nop(),
                              0 if sub is None else _SUBCMDRDY)
        return encode(Frame(Link.ML3, Kind.RESPONSE, self.address, frame.cycle, frame.tcycle_ns, resp))

    def _fast_receive(self, dg: bytes, source: Hashable, now: int) -> object:
        """INV_CTL with a NOP (or no) sub-command in phase 2/3 straight from and to bytes (``struct`` formats
        derived from the wire declarations; identical responses to the general path, tests/cards/test_fast_path.py).

        The steady state costs less: a command that differs from the last one taken here only in its cycle, WDT
        and FCS (:func:`~mlink_sim.wire.frame.steady_delta`, one C call) is not unpacked and checked field by field
        again, and the answer is its template (:class:`~mlink_sim.wire.frame.Template`) with the cycle and RWDT
        patched in, packed again only when one of its other fields changes."""
        d = self._steady_delta(dg)
        if d >= 0:  # the fields kept from the last command (native ints, no unpack)
            cycle, wdt, stn = d & 0xFFFFFFFF, d >> 32, self.address
            tcycle, ctrl, ictrl = self._c_tcycle, self._c_ctrl, self._c_ictrl
            speed, torque, sel_ref, sel_mon, ref1, ref2 = (self._c_speed, self._c_torque, self._c_sel_ref,
                                                           self._c_sel_mon, self._c_ref1, self._c_ref2)
        else:
            if len(dg) != self._fast_len:
                return SLOW
            (magic, link, kind, stn, cycle, tcycle, code, wdt, ctrl, ictrl, _io, speed, torque, sel_ref, sel_mon,
             ref1, ref2) = _CMD_UNPACK(dg)
            if (magic != MAGIC or link != _LINK or kind != _KIND_COMMAND or stn != self.address
                    or code != _CMD_INV_CTL or (self._frame64 and dg[_SUBCODE_AT] != 0) or not fcs_ok(dg)):
                return SLOW
            self._fast_cmd, self._c_tcycle, self._c_ctrl, self._c_ictrl = dg, tcycle, ctrl, ictrl
            self._c_speed, self._c_torque, self._c_sel_ref, self._c_sel_mon = speed, torque, sel_ref, sel_mon
            self._c_ref1, self._c_ref2 = ref1, ref2
        if not self._accept(cycle, tcycle, wdt, _CMD_INV_CTL, source, now):
            return None
        if self._source is None:  # this command's gap lost the connection
            return self._answer_after_loss(dg, source, now)
        alarms = self.alarms
        if alarms.alm_clr_edge(bool(ctrl & 0x08)):  # CMD_CTRL.ALM_CLR (bit 3 of its low byte)
            self.alarm_clear(now)
            alarms.alm_clr_cmp = True
        invcmd_stat, ofreq, cur, mon1, mon2 = self._inv_ctl(ictrl, speed, torque, sel_ref, sel_mon, ref1, ref2, now)
        self._last_cmd_alm = 0
        status = self.drive.status
        # cmd_stat(status, alarms, True, ctrl, 0), spelt out
        stat = (status.faulted | status.minor_fault << 1 | 4 | alarms.alm_clr_cmp << 3 | (ctrl & 0xC0)
                | alarms.comm_alm << 12)
        rwdt = self.watchdog.rwdt()
        self.counters.tx += 1  # self._sent(now), spelt out
        self._tx_at = now
        if status.fault is not self._seen_fault:
            self._watch_history()
        if self._frame64:
            self._last_sub_alm = 0
        answer = self._answer
        if answer.stale(stat, invcmd_stat, ofreq, cur, sel_ref, sel_mon, mon1, mon2, tcycle):
            if self._frame64:
                answer.body = self._rsp_pack(MAGIC, _LINK, _KIND_RESPONSE, stn, 0, tcycle, _CMD_INV_CTL, 0, stat,
                                               invcmd_stat, 0, ofreq, cur, sel_ref, sel_mon, mon1, mon2, 0,
                                               _SUBCMDRDY, _ZERO_SUB)
            else:
                answer.body = self._rsp_pack(MAGIC, _LINK, _KIND_RESPONSE, stn, 0, tcycle, _CMD_INV_CTL, 0, stat,
                                               invcmd_stat, 0, ofreq, cur, sel_ref, sel_mon, mon1, mon2)
        elif tcycle == self.tcycle_ns and self._out_key >= 0:
            # a fixed point (self.prediction): the answer repeated the last one, in the cycle CONNECT set (no
            # transmission cycle fault counted), with outputs kept while the drive is steady
            self._steady_cycle = cycle
        return answer.seal(cycle, rwdt)

    def _inv_ctl(self, ctrl: int, speed: int, torque: int, sel_ref: int, sel_mon: int, ref1: int, ref2: int,
                 now: int) -> tuple[int, int, int, int, int]:
        """INV_CTL (Table 20 INVCMD_CTRL): the drive command; returns INVCMD_STAT, output frequency, output
        current, MON1, MON2."""
        ck = self._cmd_key  # compared field by field: a tuple built each cycle would be allocated and compared
        if ck is None or ck[0] != ctrl or ck[1] != speed or ck[2] != torque:
            self._cmd_key = (ctrl, speed, torque)
            cmd = DriveCommand(
                forward=bool(ctrl & 0x0001), reverse=bool(ctrl & 0x0002), fault_reset=bool(ctrl & 0x0200),
                external_fault=bool(ctrl & 0x0400), external_baseblock=bool(ctrl & 0x1000),
                multi_inputs=(ctrl >> 16) & 0x3F, freq_ref_raw=speed, torque_ref_raw=torque,
                torque_limit_raw=torque, fault_history_clear=bool(ctrl & 0x0800),
            )
            self.drive.command(cmd, now)
            if cmd.fault_history_clear:
                self._watch_history()
        if sel_ref:
            self.select_refs(sel_ref, ref1, ref2)
        status = self.drive.status
        if status is not self._status_seen:
            self._status_seen = status
            self._status_word = ml3_invcmd_stat_bits(status)
        enabled = self._sel_mon_bits.get(sel_mon)
        if enabled is None:  # INVCMD_STAT bits 24/25 "SEL_MONx enabled" of this SEL_MON (constant per card)
            drive = self.drive
            enabled = self._sel_mon_bits[sel_mon] = (sel_mon_enabled(drive, sel_mon & 0xF) << 24
                                                     | sel_mon_enabled(drive, sel_mon >> 4) << 25)
        ofreq, cur, mon1, mon2 = self._outputs(sel_mon)
        return self._status_word | enabled, ofreq, cur, mon1, mon2

    def _process_sub(self, main_code: int, sub: Any, phase: int, subcmd: bool, now: int) -> tuple[Any, Err]:
        """The sub-command: admission (Table 10), combination (Table 13), handler; SUB_CTRL (Table 23) is reserved
        bits only and not read."""
        stype = type(sub)
        scode = sub.code if stype is Unknown else _SUB_CODE[stype]
        row = ML3_SUB_PHASES.get(scode)
        if row is None:
            return _echo_sub(sub), Err.UNSUPPORTED
        adm = row[phase - 1]
        if adm is _PHASE and scode == M3Cmd.NOP and (
            self.options.et3_nop_in_phase1 or main_code in (M3Cmd.CONNECT, M3Cmd.DISCONNECT)
        ):  # an empty sub-command area beside CONNECT/DISCONNECT is no phase error (docs/cards.md)
            adm = _ALLOWED
        if adm is _PHASE:
            return _echo_sub(sub), Err.PHASE
        if not subcmd:  # CONNECT with SUBCMD = 0 ("Sub-command disabled"): not executed, no alarm
            return _echo_sub(sub), Err.OK
        if not combination_ok(ML3_COMBINATIONS, main_code, scode):
            return _echo_sub(sub), Err.COMBINATION
        rsub, err = self.sub_handlers[scode](self, sub, now)
        return (rsub if err is Err.OK else _echo_sub(sub)), err

    # -- the MECHATROLINK-III handlers (the tables MAIN_HANDLERS / SUB_HANDLERS below) --------------------
    def _handle_id_rd(self, body: ml3.IdRd, frame: Frame, source: Hashable, now: int) -> tuple[Any, Err]:
        """ID_RD (Table 14): up to 24 bytes of the ID_CODE's value."""
        data = ml3_id_data(body.id_code, data_size=self.data_size, profile=self._profile,
                           speed_unit=self.store.active.get("o1-03", 0))
        window = None if data is None else ml3_id_window(data, body.offset, body.size)
        if window is None:
            return _echo_main(body), Err.DATA
        return ml3.IdRdResponse(body.id_code, body.offset, body.size, window), Err.OK

    def _handle_alm_rd(self, body: ml3.AlmRd, frame: Frame, source: Hashable, now: int) -> tuple[Any, Err]:
        data, err = self._alm_data(body.alm_rd_mod, body.alm_index)
        return ml3.AlmRdResponse(body.alm_rd_mod, body.alm_index, data), err

    def _handle_sub_alm_rd(self, sub: ml3.AlmRd, now: int) -> tuple[Any, Err]:
        data, err = self._alm_data(sub.alm_rd_mod, sub.alm_index)
        return ml3.AlmRdResponse(sub.alm_rd_mod, sub.alm_index, data), err

    def _handle_connect(self, body: ml3.Connect, frame: Frame, source: Hashable, now: int) -> tuple[Any, Err]:
        """CONNECT (Table 18 COM_MOD): phase 2 or 3 per SYNCMODE (Table 19)."""
        err, sync, cyc = self._check_connect(body, frame.tcycle_ns)
        self.drive.minor(Fault.CYC, cyc, now)  # Table 26 CYC "Communications Cycle Setting Error"
        if err is not Err.OK:
            self.log_refused(ver=body.ver, com_mod=body.com_mod, com_tim=body.com_tim,
                             profile=body.profile_type, tcycle_ns=frame.tcycle_ns, cycle_fault=cyc)
            return self._connect_echo(body), err
        self._subcmd = self.data_size == 64 and bool(body.com_mod & 0x80)
        self._profile = body.profile_type
        self.connect(source, frame.cycle, now, sync=sync, tcycle_ns=frame.tcycle_ns, com_tim=body.com_tim,
                     comm_cycle_ns=frame.tcycle_ns * body.com_tim, wdt=frame.message.wdt)
        return self._connect_echo(body), Err.OK

    def _handle_disconnect(self, body: Any, frame: Frame, source: Hashable, now: int) -> tuple[Any, Err]:
        self.disconnect(now)
        self._subcmd = False
        self._profile = 0
        return body, Err.OK

    def _handle_inv_ctl(self, body: ml3.InvCtl, frame: Frame, source: Hashable, now: int) -> tuple[Any, Err]:
        invcmd_stat, ofreq, cur, mon1, mon2 = self._inv_ctl(body.invcmd_ctrl, body.speed_ref, body.torque_ref,
                                                            body.sel_ref, body.sel_mon, body.ref1, body.ref2, now)
        return ml3.InvCtlResponse(invcmd_stat, 0, ofreq, cur, body.sel_ref, body.sel_mon, mon1, mon2), Err.OK

    def _alm_data(self, mod: int, index: int) -> tuple[bytes, Err]:
        """ALM_DATA from byte 8, two bytes per code: modes per Table 16 (ALM_RD_MOD), data per Table 17 (ALM_DATA)."""
        drive = self.drive
        names: tuple[str, ...]
        if mod == 0:
            names = ("U2-01", "U2-02")
        elif mod == 1:
            names = tuple(f"U3-{i:02d}" for i in range(1, 11))
        elif mod == 2 and 0 <= index <= 10:
            names = ("U2-01",) if index == 0 else (f"U3-{index:02d}",)
        else:
            return bytes(20), Err.DATA
        data = b"".join((drive.monitor(n) & 0xFFFF).to_bytes(2, "little") for n in names)
        return data.ljust(20, b"\0"), Err.OK

    def _check_connect(self, body: ml3.Connect, tcycle: int) -> tuple[Err, bool, bool]:
        """``(verdict, synchronous, cycle fault)`` of a CONNECT (SI-ET3 CONNECT): COM_MOD per Table 18 and its bits per
        Table 19, the cycles per Table 14 (ID_CODE 16H–1AH) and Table 28."""
        mod = body.com_mod
        if body.ver != 0x30 or mod & 0x71 or mod & 0x0C:  # VER 30H; reserved bits; DTMODE 0 only
            return Err.DATA, False, False
        if mod & 0x80 and self.data_size == 32:  # sub-commands need 64-byte frames (F6-21 = 0)
            return Err.DATA, False, False
        if body.profile_type != PROFILE_TYPE_INVERTER:
            return Err.DATA, False, False
        tim = body.com_tim
        comm = tcycle * tim
        if tim == 0 or tcycle not in VALID_TCYCLES_NS or not _COMM_MIN_NS <= comm <= _COMM_MAX_NS:
            return Err.DATA, False, True
        bit = bool(mod & 0x02)
        sync = not bit if self.options.et3_syncmode_table19 else bit
        return Err.OK, sync, False

    def _connect_echo(self, body: ml3.Connect) -> Any:
        if self.options.et3_connect_echo_at_byte5:  # the printed response table: VER at byte 5 … PROFILE at 8
            echo = bytes((0, body.ver, body.com_mod, body.com_tim, body.profile_type))
            return Unknown(M3Cmd.CONNECT, echo.ljust(len(_ZERO_MAIN), b"\0"))
        return body

    # -- failures, alarms, LEDs ------------------------------------------------------------------
    def _report_failure(self, kind: FailureKind, first: bool) -> None:
        self.alarms.comm(ml3_failure_code(kind, first and kind is not FailureKind.CYCLE, self.phase))

    def _report_wdt(self) -> None:
        self.alarms.comm(CommAlm.WDT_ERROR)

    def _clear_comm_alarms(self) -> None:
        self.alarms.clear()

    def _subcommands_active(self) -> bool:
        return self._subcmd

    def _alarm_view(self) -> tuple[int, str | None, tuple[str, ...], int]:
        code = self.alarms.comm_alm
        name = CommAlm(code).name if code in CommAlm._value2member_map_ and code else None
        warnings: tuple[str, ...] = (f"COMM_ALM {code:X}H",) if 0 < code < 8 else ()
        warnings += tuple(sorted(f.display for f in self.drive.status.minors))
        return code, name, warnings, self._last_cmd_alm

    def _leds(self) -> tuple[dict[str, str], dict[str, str]]:
        """Table 4: R/E green once powered up, red for an error/alarm or a command error (parameter, phase,
        combination); CON lit with a connection; LK1 while frames arrive (the simulated network has one port,
        so LK2 stays unlit)."""
        error = (self.station_error is not None or self.alarms.comm_alarm_active or self.drive.status.faulted
                 or bool(self._last_cmd_alm) or bool(self._last_sub_alm))
        leds = {
            "R/E": "on",
            "CON": "on" if self._source is not None else "off",  # off after a connection loss: "not established"
            "LK1": "on" if self._led_recent(self._any_rx) else "off",
            "LK2": "off",
        }
        return leds, {"R/E": "red" if error else "green", "CON": "green", "LK1": "green", "LK2": "green"}


#: MECHATROLINK-III main commands (Table 11) -> handler; admission by phase in
#: :data:`~mlink_sim.cards.phases.ML3_MAIN_PHASES` (Table 9).
MAIN_HANDLERS: Mapping[int, Handler] = MappingProxyType({
    M3Cmd.NOP: commands.nop,
    M3Cmd.PRM_RD: commands.prm_rd,
    M3Cmd.PRM_WR: commands.prm_wr,
    M3Cmd.ID_RD: SiEt3._handle_id_rd,
    M3Cmd.CONFIG: commands.config,
    M3Cmd.ALM_RD: SiEt3._handle_alm_rd,
    M3Cmd.ALM_CLR: commands.alm_clr,
    M3Cmd.SYNC_SET: commands.sync_set,
    M3Cmd.CONNECT: SiEt3._handle_connect,
    M3Cmd.DISCONNECT: SiEt3._handle_disconnect,
    M3Cmd.INV_CTL: SiEt3._handle_inv_ctl,
})

#: MECHATROLINK-III sub-commands (Table 12) -> handler; admission by phase in
#: :data:`~mlink_sim.cards.phases.ML3_SUB_PHASES` (Table 10).
SUB_HANDLERS: Mapping[int, SubHandler] = MappingProxyType({
    M3Cmd.NOP: commands.sub_nop,
    M3Cmd.PRM_RD: commands.sub_prm_rd,
    M3Cmd.PRM_WR: commands.sub_prm_wr,
    M3Cmd.ALM_RD: SiEt3._handle_sub_alm_rd,
    M3Cmd.INV_IO: commands.sub_inv_io,
})
SiEt3.handlers = MAIN_HANDLERS
SiEt3.sub_handlers = SUB_HANDLERS

#: Every table of the SI-ET3 manual -> where it is implemented (``mlink_sim.``-relative), or None for hardware and
#: installation the simulator does not model. Each target cites the table by its own number ("SI-ET3 Table n");
#: tests/cards/test_manual_tables.py checks titles against the manual, targets and citations.
MANUAL_TABLES: Mapping[int, tuple[str, str | None]] = MappingProxyType({
    1: ("Compatible Products", None),
    2: ("Option Package Contents", None),
    3: ("Communication Connector", None),
    4: ("Option LED States", "cards.si_et3.SiEt3._leds"),
    5: ("Procedures for Installing and Wiring Options on a Drive", None),
    6: ("MECHATROLINK-III Communication Cable", None),
    7: ("Related Parameter Settings", "cards.si_et3.SiEt3._power_up"),
    8: ("Command Format of the Standard Profile Common Commands", "wire.ml3"),
    9: ("Main Command Communication Phases", "cards.phases.ML3_MAIN_PHASES"),
    10: ("Sub-Command Communication Phases", "cards.phases.ML3_SUB_PHASES"),
    11: ("Main Commands", "cards.si_et3.MAIN_HANDLERS"),
    12: ("Sub-Commands", "cards.si_et3.SUB_HANDLERS"),
    13: ("Main Commands and Sub-Commands", "wire.combinations.ML3_COMBINATIONS"),
    14: ("ID_CODE", "cards.idinfo.ml3_id_data"),
    15: ("CONFIG_MOD", "cards.parameters.config"),
    16: ("ALM_RD_MOD", "cards.si_et3.SiEt3._alm_data"),
    17: ("ALM_DATA", "cards.si_et3.SiEt3._alm_data"),
    18: ("COM_MOD", "cards.si_et3.SiEt3._check_connect"),
    19: ("COM_MOD Bits", "cards.si_et3.SiEt3._check_connect"),
    20: ("INVCMD_CTRL Bits", "cards.si_et3.SiEt3._inv_ctl"),
    21: ("SEL_REF Reference Data Codes", "wire.selections.SEL_REF_TABLES"),
    22: ("SEL_MON Monitor Data Codes", "wire.selections.SEL_MON_TABLES"),
    23: ("SUB_CTRL", "cards.si_et3.SiEt3._process_sub"),
    24: ("SUB_STAT", "cards.si_et3.SiEt3._process"),
    25: ("SUBCMD_ALM", "cards.results.Err"),
    26: ("Fault Display and Possible Solutions", "cards.si_et3.SiEt3._handle_connect"),
    27: ("Option Compatibility", None),
    28: ("Option Specifications", "cards.si_et3.VALID_TCYCLES_NS"),
})
