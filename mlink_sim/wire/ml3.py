"""MECHATROLINK-III data layouts (SI-ET3 §8–§10, standard inverter profile).

The manual numbers data bytes from 0; manual byte *k* sits at offset ``12 + k`` of the datagram. 32-byte frames
carry the main command only; 64-byte frames add the sub-command (SI-ET3 Table 8)::

    command                                   response
    byte  0      CMD                          byte  0      RCMD
    byte  1      WDT                          byte  1      RWDT
    bytes 2–3    CMD_CTRL (LE)                bytes 2–3    CMD_STAT (LE)
    bytes 4–31   main body (28 bytes)         bytes 4–31   main body (28 bytes)
    ---- 32-byte frame ends here ----------------------------------------------
    byte 32      SUBCMD                       byte 32      RSUBCMD
    bytes 33–35  SUB_CTRL (Table 23)          bytes 33–35  SUB_STAT (Table 24)
    bytes 36–63  sub body (28 bytes)          bytes 36–63  sub body (28 bytes)

    CMD_CTRL  bit 3 ALM_CLR · bits 6–7 CMD_ID
    CMD_STAT  bit 0 D_ALM · 1 D_WAR · 2 CMDRDY · 3 ALM_CLR_CMP · 6–7 RCMD_ID · 8–11 CMD_ALM · 12–15 COMM_ALM
    SUB_STAT  bit 2 SUBCMDRDY · bits 8–11 SUBCMD_ALM (Table 25)

Main bodies (manual bytes)::

    PRM_RD   01H  4–5 NO · 6 SIZE                 resp. + 8–15 PARAMETER
    PRM_WR   02H  4–5 NO · 6 SIZE · 8–15 PARAMETER (echoed)
    ID_RD    03H  4 ID_CODE · 5 OFFSET · 6–7 SIZE  resp. + 8–31 ID (Table 14)
    CONFIG   04H  4 CONFIG_MOD (Table 15)
    ALM_RD   05H  4–5 ALM_RD_MOD · 6–7 ALM_INDEX   resp. + 8–27 ALM_DATA (Tables 16/17)
    ALM_CLR  06H  4–5 ALM_CLR_MOD
    CONNECT  0EH  4 VER · 5 COM_MOD · 6 COM_TIM · 7 PROFILE_TYPE (echoed)
    INV_CTL  50H  4–7 INVCMD_CTRL (Table 20) · 8–11 INVCMD_IO · 12–13 speed ref · 16–17 torque ref ·
                  20 SEL_REF1/2 · 21 SEL_MON1/2 · 24–25 REF1 · 28–29 REF2
             resp 4–7 INVCMD_STAT · 8–11 INVCMD_IO · 12–13 output frequency · 16–17 output current ·
                  20/21 echoed · 24–25 MON1 · 28–29 MON2
    NOP 00H, SYNC_SET 0DH, DISCONNECT 0FH: no data

Sub bodies start at byte 36 with the same relative layout for PRM_RD/PRM_WR/ALM_RD (ALM_DATA 40–59);
INV_I/O 51H: 36 SEL_REF3/4 · 37 SEL_REF5/6 · 38 SEL_MON3/4 · 39 SEL_MON5/6 · 40/44/48/52 REF3–6 or MON3–6.

The CONNECT *response* table of the manual is printed one byte lower than the command (VER at byte 5); that is a
flattening slip against "The value set in the command": the echo sits at the command's offsets (docs/cards.md).
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from typing import Any, final

from construct import Bytes, Int8ul, Int16sl, Int16ul, Int32ul, Padding, Struct

from .codes import M3Cmd
from .layout import Slot, fast_format

__all__ = [
    "COMMAND_MAIN",
    "RESPONSE_MAIN",
    "COMMAND_SUB",
    "RESPONSE_SUB",
    "M3Command",
    "M3Response",
    "CmdCtrl",
    "CmdStat",
    "SubStat",
    "Nop",
    "PrmRd",
    "PrmRdResponse",
    "PrmWr",
    "IdRd",
    "IdRdResponse",
    "Config",
    "AlmRd",
    "AlmRdResponse",
    "AlmClr",
    "SyncSet",
    "Connect",
    "Disconnect",
    "InvCtl",
    "InvCtlResponse",
    "InvIo",
    "InvIoResponse",
    "encode_data",
    "decode_command",
    "decode_response",
]

COMMAND_MAIN = Slot("MECHATROLINK-III main command, bytes 4-31", 28)
RESPONSE_MAIN = Slot("MECHATROLINK-III main response, bytes 4-31", 28)
COMMAND_SUB = Slot("MECHATROLINK-III sub-command, bytes 36-63", 28)
RESPONSE_SUB = Slot("MECHATROLINK-III sub-command response, bytes 36-63", 28)

_C, _R, _SC, _SR = COMMAND_MAIN.add, RESPONSE_MAIN.add, COMMAND_SUB.add, RESPONSE_SUB.add
_EMPTY = Struct()


@_C(M3Cmd.NOP, _EMPTY)
@_R(M3Cmd.NOP, _EMPTY)
@_SC(M3Cmd.NOP, _EMPTY)
@_SR(M3Cmd.NOP, _EMPTY)
@dataclass(frozen=True, slots=True)
class Nop:
    """NOP 00H – main and sub-command, command and response."""


_PRM_RD = Struct("no" / Int16ul, "size" / Int8ul)
_PRM_RD_R = Struct("no" / Int16ul, "size" / Int8ul, Padding(1), "parameter" / Bytes(8))
_PRM_WR = Struct("no" / Int16ul, "size" / Int8ul, Padding(1), "data" / Bytes(8))


@_C(M3Cmd.PRM_RD, _PRM_RD)
@_SC(M3Cmd.PRM_RD, _PRM_RD)
@dataclass(frozen=True, slots=True)
class PrmRd:
    """PRM_RD 01H: MEMOBUS register NO, SIZE 2/4/6/8 (SI-ET3 §9 PRM_RD, example C1-01 = 0200H)."""

    no: int
    size: int


@_R(M3Cmd.PRM_RD, _PRM_RD_R)
@_SR(M3Cmd.PRM_RD, _PRM_RD_R)
@dataclass(frozen=True, slots=True)
class PrmRdResponse:
    """PRM_RD 01H response: NO, SIZE echoed, PARAMETER LSB first (zero on a command error)."""

    no: int
    size: int
    parameter: bytes = bytes(8)


@_C(M3Cmd.PRM_WR, _PRM_WR)
@_R(M3Cmd.PRM_WR, _PRM_WR)
@_SC(M3Cmd.PRM_WR, _PRM_WR)
@_SR(M3Cmd.PRM_WR, _PRM_WR)
@dataclass(frozen=True, slots=True)
class PrmWr:
    """PRM_WR 02H command and response: NO, SIZE, PARAMETER (named ``data`` as on MECHATROLINK-II)."""

    no: int
    size: int
    data: bytes = bytes(8)


@_C(M3Cmd.ID_RD, Struct("id_code" / Int8ul, "offset" / Int8ul, "size" / Int16ul))
@dataclass(frozen=True, slots=True)
class IdRd:
    """ID_RD 03H: ID_CODE (Table 14), OFFSET, SIZE."""

    id_code: int
    offset: int
    size: int


@_R(M3Cmd.ID_RD, Struct("id_code" / Int8ul, "offset" / Int8ul, "size" / Int16ul, "id" / Bytes(24)))
@dataclass(frozen=True, slots=True)
class IdRdResponse:
    """ID_RD 03H response: the echoed request and up to 24 ID bytes (bytes 8–31)."""

    id_code: int
    offset: int
    size: int
    id: bytes = bytes(24)


@_C(M3Cmd.CONFIG, Struct("config_mod" / Int8ul))
@_R(M3Cmd.CONFIG, Struct("config_mod" / Int8ul))
@dataclass(frozen=True, slots=True)
class Config:
    """CONFIG 04H: CONFIG_MOD 0 = RAM, 1 = EEPROM (SI-ET3 Table 15)."""

    config_mod: int


_ALM_RD = Struct("alm_rd_mod" / Int16ul, "alm_index" / Int16ul)
_ALM_RD_R = Struct("alm_rd_mod" / Int16ul, "alm_index" / Int16ul, "alm_data" / Bytes(20))


@_C(M3Cmd.ALM_RD, _ALM_RD)
@_SC(M3Cmd.ALM_RD, _ALM_RD)
@dataclass(frozen=True, slots=True)
class AlmRd:
    """ALM_RD 05H: ALM_RD_MOD 0/1/2, ALM_INDEX (mode 2) – SI-ET3 Table 16."""

    alm_rd_mod: int
    alm_index: int = 0


@_R(M3Cmd.ALM_RD, _ALM_RD_R)
@_SR(M3Cmd.ALM_RD, _ALM_RD_R)
@dataclass(frozen=True, slots=True)
class AlmRdResponse:
    """ALM_RD 05H response: ALM_DATA as 2-byte codes from byte 8 (SI-ET3 Tables 16/17)."""

    alm_rd_mod: int
    alm_index: int
    alm_data: bytes = bytes(20)


@_C(M3Cmd.ALM_CLR, Struct("alm_clr_mod" / Int16ul))
@_R(M3Cmd.ALM_CLR, Struct("alm_clr_mod" / Int16ul))
@dataclass(frozen=True, slots=True)
class AlmClr:
    """ALM_CLR 06H: ALM_CLR_MOD 0 = clear present faults and alarms."""

    alm_clr_mod: int = 0


@_C(M3Cmd.SYNC_SET, _EMPTY)
@_R(M3Cmd.SYNC_SET, _EMPTY)
@dataclass(frozen=True, slots=True)
class SyncSet:
    """SYNC_SET 0DH – start synchronous communication; starts watchdog checking."""


_CONNECT = Struct("ver" / Int8ul, "com_mod" / Int8ul, "com_tim" / Int8ul, "profile_type" / Int8ul)


@_C(M3Cmd.CONNECT, _CONNECT)
@_R(M3Cmd.CONNECT, _CONNECT)
@dataclass(frozen=True, slots=True)
class Connect:
    """CONNECT 0EH: VER 30H, COM_MOD (Tables 18/19), COM_TIM 1–255, PROFILE_TYPE 20H; echoed."""

    ver: int
    com_mod: int
    com_tim: int
    profile_type: int


@_C(M3Cmd.DISCONNECT, _EMPTY)
@_R(M3Cmd.DISCONNECT, _EMPTY)
@dataclass(frozen=True, slots=True)
class Disconnect:
    """DISCONNECT 0FH – release the connection (byte 1 is reserved: no WDT)."""


@_C(
    M3Cmd.INV_CTL,
    Struct(
        "invcmd_ctrl" / Int32ul,
        "invcmd_io" / Int32ul,
        "speed_ref" / Int16ul,
        Padding(2),
        "torque_ref" / Int16sl,
        Padding(2),
        "sel_ref" / Int8ul,
        "sel_mon" / Int8ul,
        Padding(2),
        "ref1" / Int16ul,
        Padding(2),
        "ref2" / Int16ul,
    ),
)
@dataclass(frozen=True, slots=True)
class InvCtl:
    """INV_CTL 50H: INVCMD_CTRL (Table 20), INVCMD_IO, speed reference (o1-03 units), torque reference (0.1 %),
    SEL_REF1/2 (Table 21), SEL_MON1/2 (Table 22), REF1, REF2."""

    invcmd_ctrl: int = 0
    invcmd_io: int = 0
    speed_ref: int = 0
    torque_ref: int = 0
    sel_ref: int = 0
    sel_mon: int = 0
    ref1: int = 0
    ref2: int = 0


@_R(
    M3Cmd.INV_CTL,
    Struct(
        "invcmd_stat" / Int32ul,
        "invcmd_io" / Int32ul,
        "output_freq" / Int16ul,
        Padding(2),
        "output_current" / Int16ul,
        Padding(2),
        "sel_ref" / Int8ul,
        "sel_mon" / Int8ul,
        Padding(2),
        "mon1" / Int16ul,
        Padding(2),
        "mon2" / Int16ul,
    ),
)
@dataclass(frozen=True, slots=True)
class InvCtlResponse:
    """INV_CTL 50H response: INVCMD_STAT, INVCMD_IO, output frequency, output current (0.1 A, ID_CODE 4AH),
    SEL_REF/SEL_MON echoed, MON1, MON2."""

    invcmd_stat: int = 0
    invcmd_io: int = 0
    output_freq: int = 0
    output_current: int = 0
    sel_ref: int = 0
    sel_mon: int = 0
    mon1: int = 0
    mon2: int = 0


_SEL = ("sel_ref34" / Int8ul, "sel_ref56" / Int8ul, "sel_mon34" / Int8ul, "sel_mon56" / Int8ul)


def _words(*names: str) -> tuple[Any, ...]:
    out: list[Any] = []
    for name in names:
        out += [name / Int16ul, Padding(2)]
    return tuple(out)


@_SC(M3Cmd.INV_IO, Struct(*_SEL, *_words("ref3", "ref4", "ref5", "ref6")))
@dataclass(frozen=True, slots=True)
class InvIo:
    """INV_I/O 51H sub-command: SEL_REF3/4, SEL_REF5/6, SEL_MON3/4, SEL_MON5/6, REF3–REF6."""

    sel_ref34: int = 0
    sel_ref56: int = 0
    sel_mon34: int = 0
    sel_mon56: int = 0
    ref3: int = 0
    ref4: int = 0
    ref5: int = 0
    ref6: int = 0


@_SR(M3Cmd.INV_IO, Struct(*_SEL, *_words("mon3", "mon4", "mon5", "mon6")))
@dataclass(frozen=True, slots=True)
class InvIoResponse:
    """INV_I/O 51H response: selections echoed and MON3–MON6."""

    sel_ref34: int = 0
    sel_ref56: int = 0
    sel_mon34: int = 0
    sel_mon56: int = 0
    mon3: int = 0
    mon4: int = 0
    mon5: int = 0
    mon6: int = 0


# --- control and status fields ----------------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class CmdCtrl:
    """CMD_CTRL (SI-ET3 "Command Control"): ALM_CLR bit 3, CMD_ID bits 6–7."""

    alm_clr: bool = False
    cmd_id: int = 0

    def to_int(self) -> int:
        return (self.alm_clr << 3) | ((self.cmd_id & 3) << 6)

    @classmethod
    def from_int(cls, value: int) -> CmdCtrl:
        return cls(bool(value & 0x08), (value >> 6) & 3)


@dataclass(frozen=True, slots=True)
class CmdStat:
    """CMD_STAT (SI-ET3 "Command Status"): D_ALM, D_WAR, CMDRDY, ALM_CLR_CMP, RCMD_ID, CMD_ALM, COMM_ALM."""

    d_alm: bool = False
    d_war: bool = False
    cmdrdy: bool = True
    alm_clr_cmp: bool = False
    rcmd_id: int = 0
    cmd_alm: int = 0
    comm_alm: int = 0

    def to_int(self) -> int:
        return (
            self.d_alm
            | self.d_war << 1
            | self.cmdrdy << 2
            | self.alm_clr_cmp << 3
            | (self.rcmd_id & 3) << 6
            | (self.cmd_alm & 0xF) << 8
            | (self.comm_alm & 0xF) << 12
        )

    @classmethod
    def from_int(cls, v: int) -> CmdStat:
        return cls(bool(v & 1), bool(v & 2), bool(v & 4), bool(v & 8), (v >> 6) & 3, (v >> 8) & 0xF, (v >> 12) & 0xF)


@dataclass(frozen=True, slots=True)
class SubStat:
    """SUB_STAT (SI-ET3 Table 24): SUBCMDRDY bit 2, SUBCMD_ALM bits 8–11 (Table 25)."""

    subcmdrdy: bool = True
    subcmd_alm: int = 0

    def to_int(self) -> int:
        return self.subcmdrdy << 2 | (self.subcmd_alm & 0xF) << 8

    @classmethod
    def from_int(cls, v: int) -> SubStat:
        return cls(bool(v & 4), (v >> 8) & 0xF)


# --- messages ---------------------------------------------------------------------------------------------------


@final  # mypy narrows `type(message) is M3Command` in both branches
@dataclass(frozen=True, slots=True)
class M3Command:
    """A MECHATROLINK-III command. ``sub is None`` means a 32-byte frame; otherwise a 64-byte one.
    ``cmd_ctrl``/``sub_ctrl`` are the raw fields; :attr:`ctrl` is the typed view."""

    body: Any
    wdt: int = 0
    cmd_ctrl: int = 0
    sub: Any = None
    sub_ctrl: int = 0

    @property
    def code(self) -> int:
        return COMMAND_MAIN.code_of(self.body)

    @property
    def size(self) -> int:
        return 32 if self.sub is None else 64

    @property
    def ctrl(self) -> CmdCtrl:
        return CmdCtrl.from_int(self.cmd_ctrl)


@final  # mypy narrows `type(message) is M3Response` in both branches
@dataclass(frozen=True, slots=True)
class M3Response:
    """A MECHATROLINK-III response; :attr:`stat`/:attr:`substat` are typed views of the raw status fields."""

    body: Any
    rwdt: int = 0
    cmd_stat: int = 0
    sub: Any = None
    sub_stat: int = 0

    @property
    def code(self) -> int:
        return RESPONSE_MAIN.code_of(self.body)

    @property
    def size(self) -> int:
        return 32 if self.sub is None else 64

    @property
    def stat(self) -> CmdStat:
        return CmdStat.from_int(self.cmd_stat)

    @property
    def substat(self) -> SubStat:
        return SubStat.from_int(self.sub_stat)


COMMAND_FRAME_32 = Struct("code" / Int8ul, "wdt" / Int8ul, "cmd_ctrl" / Int16ul, "main" / Bytes(28))
COMMAND_FRAME_64 = Struct(
    "code" / Int8ul, "wdt" / Int8ul, "cmd_ctrl" / Int16ul, "main" / Bytes(28),
    "subcode" / Int8ul, "sub_ctrl" / Int16ul, Padding(1), "sub" / Bytes(28),
)  # fmt: skip
RESPONSE_FRAME_32 = Struct("code" / Int8ul, "rwdt" / Int8ul, "cmd_stat" / Int16ul, "main" / Bytes(28))
RESPONSE_FRAME_64 = Struct(
    "code" / Int8ul, "rwdt" / Int8ul, "cmd_stat" / Int16ul, "main" / Bytes(28),
    "subcode" / Int8ul, "sub_stat" / Int16ul, Padding(1), "sub" / Bytes(28),
)  # fmt: skip

_CF32 = struct.Struct(fast_format(COMMAND_FRAME_32, 32)[0])
_CF64 = struct.Struct(fast_format(COMMAND_FRAME_64, 64)[0])
_RF32 = struct.Struct(fast_format(RESPONSE_FRAME_32, 32)[0])
_RF64 = struct.Struct(fast_format(RESPONSE_FRAME_64, 64)[0])


def encode_data(message: M3Command | M3Response) -> bytes:
    """The 32- or 64-byte data area of *message*."""
    if type(message) is M3Command:
        code, main = COMMAND_MAIN.build(message.body)
        if message.sub is None:
            return _CF32.pack(code, message.wdt, message.cmd_ctrl, main)
        subcode, sub = COMMAND_SUB.build(message.sub)
        return _CF64.pack(code, message.wdt, message.cmd_ctrl, main, subcode, message.sub_ctrl, sub)
    code, main = RESPONSE_MAIN.build(message.body)
    if message.sub is None:
        return _RF32.pack(code, message.rwdt, message.cmd_stat, main)
    subcode, sub = RESPONSE_SUB.build(message.sub)
    return _RF64.pack(code, message.rwdt, message.cmd_stat, main, subcode, message.sub_stat, sub)


def decode_command(data: bytes | memoryview) -> M3Command:
    if len(data) == 32:
        code, wdt, ctrl, main = _CF32.unpack(data)
        return M3Command(COMMAND_MAIN.parse(code, main, 0), wdt, ctrl)
    code, wdt, ctrl, main, subcode, sub_ctrl, sub = _CF64.unpack(data)
    return M3Command(COMMAND_MAIN.parse(code, main, 0), wdt, ctrl, COMMAND_SUB.parse(subcode, sub, 0), sub_ctrl)


def decode_response(data: bytes | memoryview) -> M3Response:
    if len(data) == 32:
        code, rwdt, stat, main = _RF32.unpack(data)
        return M3Response(RESPONSE_MAIN.parse(code, main, 0), rwdt, stat)
    code, rwdt, stat, main, subcode, sub_stat, sub = _RF64.unpack(data)
    return M3Response(RESPONSE_MAIN.parse(code, main, 0), rwdt, stat, RESPONSE_SUB.parse(subcode, sub, 0), sub_stat)
