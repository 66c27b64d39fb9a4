"""Codes and bit fields that travel on the wire, as enums citing the manual tables they encode.

Manuals (``../shared/manuals``):

* SI-T3  – YASKAWA AC Drive Option MECHATROLINK-II Technical Manual, SIEP C730600 50 (with errata)
* SI-ET3 – YASKAWA AC Drive Option MECHATROLINK-III Technical Manual, SIEP C730600 88
* V7     – SI-T/V7 MECHATROLINK-I/II Communications Interface Unit for the VS-606V7

The drive fault/minor-fault codes reported in the MECHATROLINK-II ALARM byte are in
:mod:`mlink_sim.wire.drive_codes`.
"""

from __future__ import annotations

import enum

__all__ = [
    "Link",
    "Kind",
    "M2Cmd",
    "M3Cmd",
    "M2Alarm",
    "M2Status",
    "M2SubStatus",
    "OperationSignal",
    "CmdAlm",
    "CommAlm",
    "SubCmdAlm",
    "InvCmdCtrl",
    "InvCmdStat",
    "ConnectVersion",
    "M2ComMod",
    "M3ComMod",
    "PROFILE_TYPE_INVERTER",
]


class Link(enum.IntEnum):
    """Byte 1 of the datagram envelope (docs/wire-format.md)."""

    ML1 = 0x01  #: MECHATROLINK-I (4 Mbps, 17-byte data only)
    ML2 = 0x02  #: MECHATROLINK-II (10 Mbps, 17- or 32-byte data)
    ML3 = 0x03  #: MECHATROLINK-III (100 Mbps, 32- or 64-byte data)

    @property
    def data_sizes(self) -> tuple[int, ...]:
        """Data sizes *n* allowed on this link (SI-T3 Table 29 note <3>; SI-ET3 Table 28)."""
        return _DATA_SIZES[self]

    @property
    def label(self) -> str:
        return {Link.ML1: "MECHATROLINK-I", Link.ML2: "MECHATROLINK-II", Link.ML3: "MECHATROLINK-III"}[self]

    @property
    def speed_mbps(self) -> int:
        """Transmission speed (SI-T3 Table 4 F6-22: 10 Mbps MECHATROLINK-II, 4 Mbps MECHATROLINK-I; SI-ET3 Table 28:
        100 Mbps)."""
        return _SPEEDS[self]


_DATA_SIZES = {Link.ML1: (17,), Link.ML2: (17, 32), Link.ML3: (32, 64)}
_SPEEDS = {Link.ML1: 4, Link.ML2: 10, Link.ML3: 100}


class Kind(enum.IntEnum):
    """Byte 2 of the datagram envelope."""

    COMMAND = 0x01  #: master -> slave
    RESPONSE = 0x02  #: slave -> master


class M2Cmd(enum.IntEnum):
    """MECHATROLINK-I/II command codes: main commands SI-T3 Table 5 / V7 Table 1, sub-commands SI-T3 Table 6 /
    V7 Table 2 (INV_I/O 41H is a sub-command only; CONFIG as a sub-command exists on the SI-T/V7 only, V7 §7.2)."""

    NOP = 0x00
    PRM_RD = 0x01
    PRM_WR = 0x02
    ID_RD = 0x03
    CONFIG = 0x04
    ALM_RD = 0x05
    ALM_CLR = 0x06
    SYNC_SET = 0x0D
    CONNECT = 0x0E
    DISCONNECT = 0x0F
    INV_CTL = 0x40
    INV_IO = 0x41


class M3Cmd(enum.IntEnum):
    """MECHATROLINK-III command codes: main commands SI-ET3 Table 11, sub-commands SI-ET3 Table 12."""

    NOP = 0x00
    PRM_RD = 0x01
    PRM_WR = 0x02
    ID_RD = 0x03
    CONFIG = 0x04
    ALM_RD = 0x05
    ALM_CLR = 0x06
    SYNC_SET = 0x0D
    CONNECT = 0x0E
    DISCONNECT = 0x0F
    INV_CTL = 0x50
    INV_IO = 0x51


class M2Alarm(enum.IntEnum):
    """Communication warnings and alarms the card itself puts in the MECHATROLINK-II ALARM byte:
    SI-T3 Table 23 and Table 25, V7 Table 8 and "Other Faults"."""

    DATA_SETTING_WARNING = 0x94  #: A.94 – bad data in a command; the command is ignored (SI-T3 Table 25)
    COMMAND_WARNING = 0x95  #: A.95 – command not allowed now; the command is ignored (SI-T3 Table 25)
    COMM_WARNING = 0x96  #: first reception failure (SI-T3 Tables 22/23)
    WDT_ERROR = 0xE5  #: watchdog count fault in phase 3 (SI-T3 Table 23)
    COMM_ERROR = 0xE6  #: consecutive reception failures (SI-T3 Tables 22/23)
    WDC_FAULT = 0xEC  #: WDC fault with drive (SI-T3 Table 25)
    DRIVE_ACCESS_FAULT = 0xED  #: drive access permission fault (SI-T3 Table 25)
    DRIVE_MONITOR_TIMEOUT = 0xEE  #: drive monitor timer over (SI-T3 Table 25)

    @property
    def is_warning(self) -> bool:
        """Warnings are 9xH, alarms ExH (Table 23 "Fault Type" column)."""
        return self < 0xE0


class M2Status(enum.IntFlag):
    """MECHATROLINK-II response STATUS field, bytes 3–4 (SI-T3 "STATUS Field"; V7 §7.3, where bits E/F are unused)."""

    ALM = 1 << 0  #: alarm (fault) status
    WARNG = 1 << 1  #: warning status
    CMDRDY = 1 << 2  #: command ready (0 = busy)
    BB_OFF = 1 << 3  #: baseblock released
    PON = 1 << 4  #: main power supply on
    RUNX = 1 << 5  #: running
    ZSP = 1 << 6  #: zero speed ("0SP")
    REV = 1 << 7  #: reverse run
    RESET = 1 << 8  #: fault reset signal input
    AGREE = 1 << 9  #: speed agreement
    INV_READY = 1 << 10  #: drive ready
    OPE = 1 << 11  #: oPE fault
    UV_R = 1 << 12  #: recovery after momentary power loss
    REMOTE = 1 << 13  #: remote (run/reference from the option)
    SEL_M = 1 << 14  #: motor 2 selected (SI-T3 only)
    ZERO_SERVO = 1 << 15  #: zero servo complete (SI-T3 only)


class M2SubStatus(enum.IntFlag):
    """MECHATROLINK-II SUBSTATUS field, byte 18 (SI-T3 "SUBSTATUS Field"; V7 §7.3)."""

    SUBALM = 1 << 0
    SUBWARNG = 1 << 1
    SUBCMDRDY = 1 << 2


class OperationSignal(enum.IntFlag):
    """INV_CTL operation signals, bytes 3–4 (SI-T3 Table 16; V7 Table 3, which has no terminal S8: bit 7 unused)."""

    FORWARD = 1 << 0
    REVERSE = 1 << 1
    MFI3 = 1 << 2  #: multi-function input S3 (H1-03 / n052)
    MFI4 = 1 << 3
    MFI5 = 1 << 4
    MFI6 = 1 << 5
    MFI7 = 1 << 6
    MFI8 = 1 << 7  #: SI-T3 only
    EF0 = 1 << 8  #: external fault from the option
    FAULT_RESET = 1 << 9
    FAULT_HISTORY_CLEAR = 1 << 14
    EXT_BB = 1 << 15  #: external baseblock command


class CmdAlm(enum.IntEnum):
    """MECHATROLINK-III CMD_ALM, CMD_STAT bits 8–11 (SI-ET3 "CMD_ALM" table)."""

    NORMAL = 0x0
    INVALID_DATA_WARNING = 0x1
    UNSUPPORTED_COMMAND = 0x8
    INVALID_DATA = 0x9
    EXECUTION_CONDITION = 0xA
    SUBCMD_COMBINATION = 0xB  #: SI-ET3 Table 13
    PHASE_ERROR = 0xC  #: SI-ET3 Tables 9/10 "–"


class CommAlm(enum.IntEnum):
    """MECHATROLINK-III COMM_ALM, CMD_STAT bits 12–15 (SI-ET3 "COMM_ALM" table). Warnings 1–3, alarms 8–C."""

    NORMAL = 0x0
    FCS_WARNING = 0x1
    NOT_RECEIVED_WARNING = 0x2
    SYNC_NOT_RECEIVED_WARNING = 0x3
    FCS_ERROR = 0x8
    NOT_RECEIVED = 0x9
    SYNC_NOT_RECEIVED = 0xA
    SYNC_INTERVAL_ERROR = 0xB
    WDT_ERROR = 0xC


class SubCmdAlm(enum.IntEnum):
    """MECHATROLINK-III SUBCMD_ALM, SUB_STAT bits 8–11 (SI-ET3 Table 25)."""

    NORMAL = 0x0
    INVALID_DATA_WARNING = 0x1
    UNSUPPORTED_COMMAND = 0x8
    INVALID_DATA = 0x9
    INVALID_DATA_A = 0xA
    SUBCMD_COMBINATION = 0xB
    PHASE_ERROR = 0xC


class InvCmdCtrl(enum.IntFlag):
    """MECHATROLINK-III INV_CTL INVCMD_CTRL, bytes 4–7 (SI-ET3 Table 20)."""

    FORWARD = 1 << 0
    REVERSE = 1 << 1
    FAULT_RESET = 1 << 9
    EF0 = 1 << 10
    FAULT_HISTORY_CLEAR = 1 << 11
    EXT_BB = 1 << 12
    MFI3 = 1 << 16
    MFI4 = 1 << 17
    MFI5 = 1 << 18
    MFI6 = 1 << 19
    MFI7 = 1 << 20
    MFI8 = 1 << 21


class InvCmdStat(enum.IntFlag):
    """MECHATROLINK-III INV_CTL response INVCMD_STAT, bytes 4–7 (SI-ET3 "INVCMD_STAT" table)."""

    FORWARD = 1 << 0  #: forward operation in progress
    REVERSE = 1 << 1  #: reverse operation in progress
    BB_RELEASED = 1 << 2
    PON = 1 << 3
    ZSP = 1 << 4
    AGREE = 1 << 5
    READY = 1 << 6
    OPE = 1 << 7
    RESET = 1 << 9  #: fault reset signal being input
    UV_R = 1 << 10
    REMOTE = 1 << 11
    MOTOR2 = 1 << 12
    ZERO_SERVO = 1 << 13
    SEL_MON1 = 1 << 24  #: SEL_MON1 status: monitor 1 enabled
    SEL_MON2 = 1 << 25


class ConnectVersion(enum.IntEnum):
    """CONNECT VER byte: SI-T3 "CONNECT" (21H MECHATROLINK-II, 10H MECHATROLINK-I); SI-ET3 CONNECT (30H)."""

    ML1 = 0x10
    ML2 = 0x21
    ML3 = 0x30


class M2ComMod(enum.IntFlag):
    """MECHATROLINK-II CONNECT COM_MOD (SI-T3 "CONNECT", VER 21H; V7 §7.1). Bits 0, 4, 5, 6 are reserved (A.94);
    DTMOD occupies bits 3–2 (only 00 = single transfer is supported; V7 §7.1: 10/11 -> A.94)."""

    SYNCMOD = 1 << 1  #: 1 = move to phase 3 (synchronous)
    DTMOD = (1 << 3) | (1 << 2)
    SUBCMD = 1 << 7
    RESERVED = (1 << 0) | (1 << 4) | (1 << 5) | (1 << 6)


class M3ComMod(enum.IntFlag):
    """MECHATROLINK-III CONNECT COM_MOD (SI-ET3 Tables 18/19). Note SI-ET3 Table 19 reads SYNCMODE 0 = synchronous,
    the reverse of the MECHATROLINK-II manuals: see docs/cards.md for the choice the cards make."""

    SYNCMODE = 1 << 1
    DTMODE = (1 << 3) | (1 << 2)  #: Table 18 shows DTMODE over bits 3–2; Table 19 lists the single value 0
    SUBCMD = 1 << 7
    RESERVED = (1 << 0) | (1 << 4) | (1 << 5) | (1 << 6)


#: CONNECT PROFILE_TYPE for the standard inverter profile (SI-ET3 CONNECT byte 7; ID_CODE 10H in Table 14).
PROFILE_TYPE_INVERTER = 0x20
