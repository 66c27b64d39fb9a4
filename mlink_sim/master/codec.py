"""Per-generation command building and response reading for the master core.

MECHATROLINK-I/II and MECHATROLINK-III report the same facts in different places; :class:`Reply` is the common
reading the state machine works on:

==================  ===========================================  ==============================================
fact                MECHATROLINK-I/II (SI-T3, SI-T/V7)            MECHATROLINK-III (SI-ET3)
==================  ===========================================  ==============================================
command ready       STATUS.CMDRDY (SI-T3 "STATUS Field")          CMD_STAT.CMDRDY
command refused     ALARM 94H/95H with STATUS.WARNG (Table 25)    CMD_ALM != 0 ("CMD_ALM" table)
not connected       95H to INV_CTL/SYNC_SET/ALM_CLR ("If not in   CMD_ALM CH, phase error (Table 9)
                    phase 2 or 3: Command warning (A.95)")
comm. alarm         ALARM E5H/E6H (Table 23)                      COMM_ALM 8H–CH ("COMM_ALM" table)
sub ready / error   SUBSTATUS SUBCMDRDY / SUBALM, SUBWARNG        SUB_STAT SUBCMDRDY / SUBCMD_ALM (Tables 24/25)
==================  ===========================================  ==============================================
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from ..wire import (
    CmdAlm,
    CommAlm,
    InvCmdCtrl,
    Link,
    M2Alarm,
    M2Cmd,
    M2Status,
    M2SubStatus,
    M3Cmd,
    OperationSignal,
    SubCmdAlm,
    ml2,
    ml3,
)
from ..wire.combinations import ML2_COMBINATIONS, ML3_COMBINATIONS, V7_COMBINATIONS, forbids
from ..wire.drive_codes import FAMILY_CODES, SiT3DriveWarning
from .commands import Cmd, cmd_of
from .plan import StationPlan
from .types import Control

__all__ = ["Reply", "Codec", "compatible", "command_name"]

_NOT_CONNECTED_ML2 = {int(M2Cmd.INV_CTL), int(M2Cmd.SYNC_SET), int(M2Cmd.ALM_CLR)}
_COMM_ALARMS_ML2 = {int(M2Alarm.WDT_ERROR), int(M2Alarm.COMM_ERROR)}
_REFUSALS_ML2 = {int(M2Alarm.DATA_SETTING_WARNING), int(M2Alarm.COMMAND_WARNING)}
_CARD_CODES = {int(m) for m in M2Alarm}
#: The drive's own reaction to a communication fault can be the most recent alarm in the ALARM byte and hide E5H/E6H
#: (SI-T3 Table 21): faults and minor faults E5 and bUS of the drive's code tables (SI-T3 Table 26 E5 39H, "SI-T3
#: Watchdog Timer Error", and bUS 22H; Table 27 E5 31H and bUS 15H) are communication faults the master recovers
#: (Table 28 "E5"). On the VS-606V7 they are E5H and E6H themselves (V7 Table 10), the card's own codes.
_DRIVE_COMM = ("E5", "BUS")
_CYC = int(SiT3DriveWarning.CYC)
#: CONNECT answers meaning "these VER/COM_MOD/COM_TIM do not suit me": A.94 (SI-T3 Table 25) or CyC (Table 27) /
#: CMD_ALM 1H or 9H (SI-ET3 "CMD_ALM" table).
_PLAN_REFUSED_ML2 = frozenset({int(M2Alarm.DATA_SETTING_WARNING), _CYC})
_PLAN_REFUSED_ML3 = frozenset({int(CmdAlm.INVALID_DATA_WARNING), int(CmdAlm.INVALID_DATA)})

def compatible(main: str, sub: str) -> bool:
    """Whether main command *main* may travel with sub-command *sub* (names as in :class:`M2Cmd`): False only
    where the combination table marks the pair NG (SI-T3 Table 7, SI-ET3 Table 13: the same rows; read from
    :mod:`mlink_sim.wire.combinations`, on the SI-T/V7's version, which adds its CONFIG sub-command column).
    A main command the table does not know forbids nothing (the slave refuses an unknown code itself)."""
    main_code = M2Cmd.__members__.get(main)
    if main_code is None:
        return True
    sub_code = M2Cmd.__members__.get(sub)
    return not forbids(V7_COMBINATIONS, main_code, -1 if sub_code is None else sub_code)


def command_name(link: Link, code: int) -> str:
    """The name of command *code* on *link* ("PRM_RD"), or its code for one the manuals do not define ("30H")."""
    kind = cmd_of(link, code)
    return kind.value if kind is not None else f"{code:02X}H"


@dataclass(frozen=True, slots=True)
class Reply:
    """One response, read the same way on every generation, with the verdicts the state machine acts on: the
    core reads these fields and asks the codec nothing more."""

    code: int
    kind: Cmd | None  #: the command kind the response echoes (None: a code the manuals do not define)
    body: Any
    ready: bool
    error: tuple[int, str] | None  #: the main command was refused (code, name)
    phase_error: bool  #: the slave says it is not connected (ML-III CMD_ALM CH)
    not_connected: bool  #: the slave is in phase 1 although a phase-2/3 command was sent (A.95 / CMD_ALM CH)
    connect_refusal: tuple[int, str] | None  #: why a CONNECT was refused: *error*, or SI-T3 CyC (33H)
    plan_refused: bool  #: that refusal says the plan's VER/COM_MOD/COM_TIM do not suit (A.94, CMD_ALM 1/9, CyC)
    comm_alarm: tuple[int, str] | None  #: communication alarm (ML-II E5H/E6H, ML-III COMM_ALM >= 8)
    sub_code: int | None
    sub_body: Any
    sub_ready: bool
    sub_error: tuple[int, str] | None
    # for the view
    status_valid: bool  #: False for an ML-II PRM_RD answer: only CMDRDY is valid (SI-T3 "STATUS Field" note)
    alarm: int
    comm_alm: int
    cmd_alm: int
    fault: bool
    warning: bool
    status: int | None  #: ML-II STATUS (any response) / ML-III INVCMD_STAT (INV_CTL response only)


def _enum_name(enum_type: Any, code: int) -> str:
    try:
        return enum_type(code).name
    except ValueError:
        return f"{code:02X}H"


class Codec:
    """Builds command messages and reads responses for one station's generation."""

    __slots__ = ("plan", "link", "cmd", "mod", "main_slot", "sub_slot", "combinations", "prm_as_subcommand",
                 "drive_alarms", "drive_warnings", "comm_faults", "comm_minors", "cyc", "_nop")

    def __init__(self, plan: StationPlan) -> None:
        self.plan = plan
        self.link = plan.link
        ml3_link = plan.link is Link.ML3
        self.cmd = M3Cmd if ml3_link else M2Cmd
        self.mod = ml3 if ml3_link else ml2
        self.main_slot = self.mod.COMMAND_MAIN
        self.sub_slot = self.mod.COMMAND_SUB
        profile = plan.profile  # None: a card the plan does not name, no card's own rules
        #: PRM_RD/PRM_WR go as sub-commands where sub-commands are on (V7 §7.1, CardProfile.prm_as_subcommand)
        self.prm_as_subcommand = profile is not None and profile.prm_as_subcommand
        config_sub = profile is not None and profile.config_subcommand  # V7 §7.2
        self.combinations = ML3_COMBINATIONS if ml3_link else V7_COMBINATIONS if config_sub else ML2_COMBINATIONS
        #: the drive's fault and minor fault codes (SI-T3 Tables 26/27, V7 Tables 10/11), by the card's drive family
        alarms, warnings = FAMILY_CODES[plan.family]
        self.drive_alarms: Any = alarms
        self.drive_warnings: Any = warnings
        self.comm_faults = frozenset(int(alarms[n]) for n in _DRIVE_COMM if n in alarms.__members__)
        self.comm_minors = frozenset(int(warnings[n]) for n in _DRIVE_COMM if n in warnings.__members__)
        #: the minor fault CyC, which hides a refused CONNECT's A.94 (SI-T3 Table 27); -1: the drive has none
        self.cyc = int(warnings["CYC"]) if "CYC" in warnings.__members__ else -1
        self._nop = self.mod.Nop()

    # --- bodies ---------------------------------------------------------------------------------------------
    def nop(self) -> Any:
        return self._nop

    def connect(self) -> Any:
        p = self.plan
        if self.link is Link.ML3:
            return ml3.Connect(p.ver, p.com_mod, p.com_tim, p.profile_type)
        return ml2.Connect(p.ver, p.com_mod, p.com_tim)

    def sync_set(self) -> Any:
        return self.mod.SyncSet()

    def disconnect(self) -> Any:
        return self.mod.Disconnect()

    def alm_clr(self) -> Any:
        """ALM_CLR mode 0: clear present faults and alarms (SI-T3 Table 15, SI-ET3 "ALM_CLR")."""
        return self.mod.AlmClr(0)

    def prm_rd(self, register: int, size: int) -> Any:
        """PRM_RD of *size* bytes from MEMOBUS *register* (SI-T3 Table 8, SI-ET3 "PRM_RD")."""
        return self.mod.PrmRd(register, size)

    def prm_wr(self, register: int, size: int, data: bytes) -> Any:
        """PRM_WR of *data* (*size* bytes, LSB first) to *register*: the DATA field is 8 bytes, the bytes past
        SIZE zero (SI-T3 Table 9, SI-ET3 "PRM_WR")."""
        return self.mod.PrmWr(register, size, data.ljust(8, b"\0"))

    def config(self, mode: int) -> Any:
        """CONFIG: 0 enables the written parameters (RAM), 1 also stores them to EEPROM (SI-T3 Table 12, SI-ET3
        Table 15)."""
        return self.mod.Config(mode)

    def id_rd(self, code: int, offset: int, size: int) -> Any:
        """ID_RD: *size* bytes of ID *code* from *offset* (DEVICE_CODE, SI-T3 Table 10; ID_CODE, SI-ET3
        Table 14)."""
        return self.mod.IdRd(code, offset, size)

    def alm_rd(self, mode: int, index: int) -> Any:
        """ALM_RD of mode *mode* from *index* (SI-T3 Table 14, SI-ET3 Tables 16/17)."""
        return self.mod.AlmRd(mode, index)

    def inv_ctl(self, c: Control) -> Any:
        """INV_CTL 40H (SI-T3 Table 16 operation signals) or 50H (SI-ET3 Table 20 INVCMD_CTRL)."""
        if self.link is Link.ML3:
            ctrl = (
                (InvCmdCtrl.FORWARD if c.forward else 0)
                | (InvCmdCtrl.REVERSE if c.reverse else 0)
                | (InvCmdCtrl.FAULT_RESET if c.fault_reset else 0)
                | (InvCmdCtrl.EF0 if c.ef0 else 0)
                | (InvCmdCtrl.FAULT_HISTORY_CLEAR if c.fault_history_clear else 0)
                | (InvCmdCtrl.EXT_BB if c.ext_bb else 0)
                | (c.multi_inputs << 16)
            )
            return ml3.InvCtl(int(ctrl), 0, c.speed_ref, c.torque_ref, c.sel_ref, c.sel_mon, c.ref1, c.ref2)
        signals = (
            (OperationSignal.FORWARD if c.forward else 0)
            | (OperationSignal.REVERSE if c.reverse else 0)
            | (c.multi_inputs << 2)
            | (OperationSignal.EF0 if c.ef0 else 0)
            | (OperationSignal.FAULT_RESET if c.fault_reset else 0)
            | (OperationSignal.FAULT_HISTORY_CLEAR if c.fault_history_clear else 0)
            | (OperationSignal.EXT_BB if c.ext_bb else 0)
        )
        return ml2.InvCtl(int(signals), c.speed_ref, c.torque_ref, c.sel_ref, c.sel_mon, c.ref1, c.ref2)

    # --- messages -------------------------------------------------------------------------------------------
    def message(self, body: Any, wdt: int, sub: Any) -> Any:
        """The command message; *sub* is ignored (and must be None) on frames without a sub-command area."""
        if self.plan.has_sub and sub is None:
            sub = self._nop
        elif not self.plan.has_sub:
            sub = None
        if self.link is Link.ML3:
            # DISCONNECT: byte 1 is reserved (SI-ET3 "DISCONNECT Command"), so no WDT.
            if type(body) is ml3.Disconnect:
                wdt = 0
            return ml3.M3Command(body, wdt, 0, sub, 0)
        return ml2.M2Command(body, wdt, sub)

    def code_of(self, body: Any, sub: bool = False) -> int:
        return (self.sub_slot if sub else self.main_slot).code_of(body)

    def kind_of(self, code: int) -> Cmd | None:
        return cmd_of(self.link, code)

    def forbids(self, main: int, sub: int) -> bool:
        """The combination table marks main command *main* with sub-command *sub* NG (SI-T3 Table 7, SI-T/V7's
        version of it, SI-ET3 Table 13: :mod:`mlink_sim.wire.combinations`)."""
        return forbids(self.combinations, main, sub)

    # --- responses ------------------------------------------------------------------------------------------
    def reply(self, msg: Any, sent_code: int | None = None) -> Reply:
        """The reading of response *msg* to the command of code *sent_code* (default: the code it echoes)."""
        if self.link is Link.ML3:
            return self._reply3(msg)
        return self._reply2(msg, sent_code)

    def alarm_name(self, code: int, status: int) -> str:
        """Name of an ML-II ALARM byte value: the card's own codes (SI-T3 Tables 23/25, V7 Table 8) unless STATUS.ALM
        marks a drive fault sharing the value (V7 CPF23 = 94H); else the drive tables (SI-T3 Tables 26/27, V7
        Tables 10/11) picked by STATUS.ALM."""
        if code in _CARD_CODES and not (code in _REFUSALS_ML2 and status & M2Status.ALM):
            return M2Alarm(code).name
        return _enum_name(self.drive_alarms if status & M2Status.ALM else self.drive_warnings, code)

    def _reply2(self, m: ml2.M2Response, sent_code: int | None) -> Reply:
        status = m.status
        alarm = m.alarm
        sub_error = None
        sub_code = None
        sub_ready = True
        if m.sub is not None:
            sub_code = ml2.RESPONSE_SUB.code_of(m.sub)
            ss = m.substatus
            sub_ready = bool(ss & M2SubStatus.SUBCMDRDY)
            if ss & (M2SubStatus.SUBALM | M2SubStatus.SUBWARNG):
                sub_error = (alarm, self.alarm_name(alarm, M2Status.WARNG))
        error = None
        if alarm in _REFUSALS_ML2 and status & M2Status.WARNG and sub_error is None:
            error = (alarm, M2Alarm(alarm).name)
        comm = None
        if alarm in _COMM_ALARMS_ML2:
            comm = (alarm, M2Alarm(alarm).name)
        elif (alarm in self.comm_faults if status & M2Status.ALM else
              alarm in self.comm_minors and status & M2Status.WARNG):
            comm = (alarm, self.alarm_name(alarm, status))
        code = ml2.RESPONSE_MAIN.code_of(m.body)
        warning = bool(status & M2Status.WARNG)
        # A CONNECT refused: its own error, or on the SI-T3 the minor fault CyC (33H, "SI-T3 Transmission Cycle
        # Error", Table 27), which as the lower warning code hides the A.94 (Table 21).
        refusal = error
        if refusal is None and alarm == self.cyc and warning:
            refusal = (alarm, "CYC")
        return Reply(
            code=code,
            kind=cmd_of(self.link, code),
            body=m.body,
            ready=bool(status & M2Status.CMDRDY),
            error=error,
            phase_error=False,
            # "If not in phase 2 or 3: Command warning (A.95)" (SI-T3 INV_CTL, SYNC_SET, ALM_CLR)
            not_connected=(error is not None and error[0] == M2Alarm.COMMAND_WARNING
                           and (code if sent_code is None else sent_code) in _NOT_CONNECTED_ML2),
            connect_refusal=refusal,
            plan_refused=refusal is not None and refusal[0] in _PLAN_REFUSED_ML2,
            comm_alarm=comm,
            sub_code=sub_code,
            sub_body=m.sub,
            sub_ready=sub_ready,
            sub_error=sub_error,
            status_valid=code != M2Cmd.PRM_RD,
            alarm=alarm,
            comm_alm=0,
            cmd_alm=0,
            fault=bool(status & M2Status.ALM),
            warning=warning,
            status=status,
        )

    def _reply3(self, m: ml3.M3Response) -> Reply:
        v = m.cmd_stat
        cmd_alm = (v >> 8) & 0xF
        comm_alm = (v >> 12) & 0xF
        sub_code = None
        sub_ready = True
        sub_error = None
        if m.sub is not None:
            sub_code = ml3.RESPONSE_SUB.code_of(m.sub)
            ss = m.sub_stat
            sub_ready = bool(ss & 4)
            sub_alm = (ss >> 8) & 0xF
            if sub_alm:
                sub_error = (sub_alm, _enum_name(SubCmdAlm, sub_alm))
        body = m.body
        code = ml3.RESPONSE_MAIN.code_of(body)
        error = (cmd_alm, _enum_name(CmdAlm, cmd_alm)) if cmd_alm else None
        phase_error = cmd_alm == CmdAlm.PHASE_ERROR
        return Reply(
            code=code,
            kind=cmd_of(self.link, code),
            body=body,
            ready=bool(v & 4),
            error=error,
            phase_error=phase_error,
            not_connected=phase_error,  # CMD_ALM CH, SI-ET3 Table 9 "–"
            connect_refusal=error,
            plan_refused=cmd_alm in _PLAN_REFUSED_ML3,
            comm_alarm=(comm_alm, _enum_name(CommAlm, comm_alm)) if comm_alm >= 8 else None,
            sub_code=sub_code,
            sub_body=m.sub,
            sub_ready=sub_ready,
            sub_error=sub_error,
            status_valid=True,
            alarm=0,
            comm_alm=comm_alm,
            cmd_alm=cmd_alm,
            fault=bool(v & 1),
            warning=bool(v & 2),
            status=body.invcmd_stat if type(body) is ml3.InvCtlResponse else None,
        )

    @staticmethod
    def connect_refusal(reply: Reply) -> tuple[int, str] | None:
        """Why a CONNECT was refused, if it was (:attr:`Reply.connect_refusal`)."""
        return reply.connect_refusal
