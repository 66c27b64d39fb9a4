"""MECHATROLINK-I/II data layouts (SI-T3 §8 "MECHATROLINK-II Commands", SI-T/V7 §7).

The manuals number data bytes from 1; manual byte *k* sits at offset ``11 + k`` of the datagram (offset ``k - 1``
of the data). 17-byte frames carry the main command only; 32-byte frames add the sub-command::

    command                                   response
    byte  1      command code                 byte  1      command code (echo)
    byte  2      0                            byte  2      ALARM
    bytes 3–15   main body (13 bytes)         bytes 3–4    STATUS (LE)
                                              bytes 5–15   main body (11 bytes)
    byte 16      WDT                          byte 16      RWDT
    ---- 17-byte frame: byte 17 reserved (0) ----------------------------------
    byte 17      sub-command code             byte 17      sub-command code (echo)
    byte 18      0                            byte 18      SUBSTATUS
    bytes 19–30  sub body (12 bytes)          bytes 19–30  sub body (12 bytes)
    bytes 31–32  reserved (0)                 bytes 31–32  reserved (0)

Main-command bodies, command side (offsets are manual bytes)::

    PRM_RD   01H  5–6 NO (LE) · 7 SIZE                              (SI-T3 Table 8)
    PRM_WR   02H  5–6 NO · 7 SIZE · 8–15 DATA                       (SI-T3 Table 9)
    ID_RD    03H  5 DEVICE_CODE · 6 OFFSET · 7 SIZE                 (SI-T3 Tables 10/11)
    CONFIG   04H  5 CONFIG_MOD                                       (SI-T3 Table 12)
    ALM_RD   05H  5 ALM_RD_MOD · 6 alarm index (mode 2)                (SI-T3 Tables 13/14)
    ALM_CLR  06H  5 ALM_CLR_MOD                                      (SI-T3 Table 15)
    CONNECT  0EH  5 VER · 6 COM_MOD · 7 COM_TIM
    INV_CTL  40H  3–4 operation signals (Table 16) · 5–6 speed reference · 7–8 torque reference ·
                  9 SEL_REF1/2 · 10 SEL_MON1/2 · 11–12 REF1 · 13–14 REF2
    NOP 00H, SYNC_SET 0DH, DISCONNECT 0FH: no data

Response bodies echo the command's fields at the same manual bytes and add: PRM_RD 8–15 PARAMETER, ID_RD 8–15 ID,
ALM_RD 6–15 ALM_DATA, INV_CTL 5–6 output frequency · 7–8 output current · 11–12 MON1 · 13–14 MON2.

Sub-command bodies (32-byte frames, manual bytes 19–30): PRM_RD/PRM_WR 19–20 NO · 21 SIZE · 22–29 PARAMETER;
ALM_RD 19 ALM_RD_MOD · 20 alarm index (command) · 20–29 ALM_DATA (response); CONFIG (SI-T/V7 only) 19 CONFIG_MOD; INV_I/O 41H 19 SEL_REF3/4 ·
20 SEL_REF5/6 · 21 SEL_MON3/4 · 22 SEL_MON5/6 · 23–30 REF3…REF6 / MON3…MON6.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from typing import Any, final

from construct import Bytes, Int8ul, Int16sl, Int16ul, Padding, Struct

from .codes import M2Cmd
from .layout import Slot, fast_format

__all__ = [
    "COMMAND_MAIN",
    "RESPONSE_MAIN",
    "COMMAND_SUB",
    "RESPONSE_SUB",
    "M2Command",
    "M2Response",
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

COMMAND_MAIN = Slot("MECHATROLINK-II main command, bytes 3-15", 13)
RESPONSE_MAIN = Slot("MECHATROLINK-II main response, bytes 5-15", 11)
COMMAND_SUB = Slot("MECHATROLINK-II sub-command, bytes 19-30", 12)
RESPONSE_SUB = Slot("MECHATROLINK-II sub-command response, bytes 19-30", 12)

_C, _R, _SC, _SR = COMMAND_MAIN.add, RESPONSE_MAIN.add, COMMAND_SUB.add, RESPONSE_SUB.add
_EMPTY = Struct()


# --- bodies -----------------------------------------------------------------------------------------------------


@_C(M2Cmd.NOP, _EMPTY)
@_R(M2Cmd.NOP, _EMPTY)
@_SC(M2Cmd.NOP, _EMPTY)
@_SR(M2Cmd.NOP, _EMPTY)
@dataclass(frozen=True, slots=True)
class Nop:
    """NOP 00H – main and sub-command, command and response."""


@_C(M2Cmd.PRM_RD, Struct(Padding(2), "no" / Int16ul, "size" / Int8ul))
@_SC(M2Cmd.PRM_RD, Struct("no" / Int16ul, "size" / Int8ul))
@dataclass(frozen=True, slots=True)
class PrmRd:
    """PRM_RD 01H command: MEMOBUS register NO and SIZE in bytes (2, 4, 6 or 8) – SI-T3 Table 8."""

    no: int
    size: int


@_R(M2Cmd.PRM_RD, Struct("no" / Int16ul, "size" / Int8ul, "parameter" / Bytes(8)))
@_SR(M2Cmd.PRM_RD, Struct("no" / Int16ul, "size" / Int8ul, "parameter" / Bytes(8)))
@dataclass(frozen=True, slots=True)
class PrmRdResponse:
    """PRM_RD 01H response: NO, SIZE echoed; PARAMETER LSB first – SI-T3 Table 8."""

    no: int
    size: int
    parameter: bytes = bytes(8)


@_C(M2Cmd.PRM_WR, Struct(Padding(2), "no" / Int16ul, "size" / Int8ul, "data" / Bytes(8)))
@_R(M2Cmd.PRM_WR, Struct("no" / Int16ul, "size" / Int8ul, "data" / Bytes(8)))
@_SC(M2Cmd.PRM_WR, Struct("no" / Int16ul, "size" / Int8ul, "data" / Bytes(8)))
@_SR(M2Cmd.PRM_WR, Struct("no" / Int16ul, "size" / Int8ul, "data" / Bytes(8)))
@dataclass(frozen=True, slots=True)
class PrmWr:
    """PRM_WR 02H command and response (NO, SIZE, DATA echoed) – SI-T3 Table 9."""

    no: int
    size: int
    data: bytes = bytes(8)


@_C(M2Cmd.ID_RD, Struct(Padding(2), "device_code" / Int8ul, "offset" / Int8ul, "size" / Int8ul))
@dataclass(frozen=True, slots=True)
class IdRd:
    """ID_RD 03H command: DEVICE_CODE (00H model, 02H version, 0FH vendor), OFFSET, SIZE ≤ 8 – SI-T3 Table 10."""

    device_code: int
    offset: int
    size: int


@_R(M2Cmd.ID_RD, Struct("device_code" / Int8ul, "offset" / Int8ul, "size" / Int8ul, "id" / Bytes(8)))
@dataclass(frozen=True, slots=True)
class IdRdResponse:
    """ID_RD 03H response: the echoed window and up to 8 bytes of ID – SI-T3 Tables 10/11."""

    device_code: int
    offset: int
    size: int
    id: bytes = bytes(8)


@_C(M2Cmd.CONFIG, Struct(Padding(2), "config_mod" / Int8ul))
@_R(M2Cmd.CONFIG, Struct("config_mod" / Int8ul))
@_SC(M2Cmd.CONFIG, Struct("config_mod" / Int8ul))
@_SR(M2Cmd.CONFIG, Struct("config_mod" / Int8ul))
@dataclass(frozen=True, slots=True)
class Config:
    """CONFIG 04H: CONFIG_MOD 0 = RAM, 1 = EEPROM (SI-T3 Table 12). As a sub-command on the SI-T/V7 only (V7 §7.2)."""

    config_mod: int


@_C(M2Cmd.ALM_RD, Struct(Padding(2), "alm_rd_mod" / Int8ul, "alm_index" / Int8ul))
@_SC(M2Cmd.ALM_RD, Struct("alm_rd_mod" / Int8ul, "alm_index" / Int8ul))
@dataclass(frozen=True, slots=True)
class AlmRd:
    """ALM_RD 05H command: ALM_RD_MOD 0/1/2 (SI-T3 Table 13). SI-T3 Table 14 puts the "Alarm Index" of mode 2 at
    byte 6; the manual leaves the command side of byte 6 as "0", so the index travels in command byte 6 (sub: 20)
    and is echoed in the response (docs/cards.md)."""

    alm_rd_mod: int
    alm_index: int = 0


@_R(M2Cmd.ALM_RD, Struct("alm_rd_mod" / Int8ul, "alm_data" / Bytes(10)))
@_SR(M2Cmd.ALM_RD, Struct("alm_rd_mod" / Int8ul, "alm_data" / Bytes(10)))
@dataclass(frozen=True, slots=True)
class AlmRdResponse:
    """ALM_RD 05H response: ALM_RD_MOD echoed, ALM_DATA bytes 6–15 (SI-T3 Table 14)."""

    alm_rd_mod: int
    alm_data: bytes = bytes(10)


@_C(M2Cmd.ALM_CLR, Struct(Padding(2), "alm_clr_mod" / Int8ul))
@_R(M2Cmd.ALM_CLR, Struct("alm_clr_mod" / Int8ul))
@dataclass(frozen=True, slots=True)
class AlmClr:
    """ALM_CLR 06H: ALM_CLR_MOD 0 = clear present faults and alarms (SI-T3 Table 15)."""

    alm_clr_mod: int = 0


@_C(M2Cmd.SYNC_SET, _EMPTY)
@_R(M2Cmd.SYNC_SET, _EMPTY)
@dataclass(frozen=True, slots=True)
class SyncSet:
    """SYNC_SET 0DH – start synchronous communication (phase 2 -> 3)."""


@_C(M2Cmd.CONNECT, Struct(Padding(2), "ver" / Int8ul, "com_mod" / Int8ul, "com_tim" / Int8ul))
@_R(M2Cmd.CONNECT, Struct("ver" / Int8ul, "com_mod" / Int8ul, "com_tim" / Int8ul))
@dataclass(frozen=True, slots=True)
class Connect:
    """CONNECT 0EH: VER (21H MECHATROLINK-II, 10H MECHATROLINK-I), COM_MOD, COM_TIM; echoed in the response."""

    ver: int
    com_mod: int
    com_tim: int


@_C(M2Cmd.DISCONNECT, _EMPTY)
@_R(M2Cmd.DISCONNECT, _EMPTY)
@dataclass(frozen=True, slots=True)
class Disconnect:
    """DISCONNECT 0FH – back to phase 1; clears the control command and resets faults."""


@_C(
    M2Cmd.INV_CTL,
    Struct(
        "signals" / Int16ul,
        "speed_ref" / Int16ul,
        "torque_ref" / Int16sl,
        "sel_ref" / Int8ul,
        "sel_mon" / Int8ul,
        "ref1" / Int16ul,
        "ref2" / Int16ul,
    ),
)
@dataclass(frozen=True, slots=True)
class InvCtl:
    """INV_CTL 40H command: operation signals (SI-T3 Table 16 / V7 Table 3), speed reference (o1-03 / n035 units),
    torque reference or limit (0.1 %), SEL_REF1/2 (Table 17 / V7 Table 4), SEL_MON1/2 (Table 18 / V7 Table 5), REF1,
    REF2."""

    signals: int = 0
    speed_ref: int = 0
    torque_ref: int = 0
    sel_ref: int = 0
    sel_mon: int = 0
    ref1: int = 0
    ref2: int = 0


@_R(
    M2Cmd.INV_CTL,
    Struct(
        "output_freq" / Int16ul,
        "output_current" / Int16ul,
        "sel_ref" / Int8ul,
        "sel_mon" / Int8ul,
        "mon1" / Int16ul,
        "mon2" / Int16ul,
    ),
)
@dataclass(frozen=True, slots=True)
class InvCtlResponse:
    """INV_CTL 40H response: output frequency (o1-03 units), output current (0.1 A on A1000 – A1000 TM U1-03;
    0.1 A on the V7 – V7 TM U-03), SEL_REF/SEL_MON echoed, MON1, MON2 (raw 16-bit words)."""

    output_freq: int = 0
    output_current: int = 0
    sel_ref: int = 0
    sel_mon: int = 0
    mon1: int = 0
    mon2: int = 0


_INV_IO_SEL = ("sel_ref34" / Int8ul, "sel_ref56" / Int8ul, "sel_mon34" / Int8ul, "sel_mon56" / Int8ul)


@_SC(M2Cmd.INV_IO, Struct(*_INV_IO_SEL, "ref3" / Int16ul, "ref4" / Int16ul, "ref5" / Int16ul, "ref6" / Int16ul))
@dataclass(frozen=True, slots=True)
class InvIo:
    """INV_I/O 41H sub-command: SEL_REF3/4, SEL_REF5/6, SEL_MON3/4, SEL_MON5/6, REF3–REF6 (SI-T3 §8 Sub-commands)."""

    sel_ref34: int = 0
    sel_ref56: int = 0
    sel_mon34: int = 0
    sel_mon56: int = 0
    ref3: int = 0
    ref4: int = 0
    ref5: int = 0
    ref6: int = 0


@_SR(M2Cmd.INV_IO, Struct(*_INV_IO_SEL, "mon3" / Int16ul, "mon4" / Int16ul, "mon5" / Int16ul, "mon6" / Int16ul))
@dataclass(frozen=True, slots=True)
class InvIoResponse:
    """INV_I/O 41H response: the selections echoed and MON3–MON6."""

    sel_ref34: int = 0
    sel_ref56: int = 0
    sel_mon34: int = 0
    sel_mon56: int = 0
    mon3: int = 0
    mon4: int = 0
    mon5: int = 0
    mon6: int = 0


# --- messages ---------------------------------------------------------------------------------------------------


@final  # mypy narrows `type(message) is M2Command` in both branches
@dataclass(frozen=True, slots=True)
class M2Command:
    """A MECHATROLINK-I/II command. ``sub is None`` means a 17-byte frame; otherwise a 32-byte one."""

    body: Any
    wdt: int = 0
    sub: Any = None

    @property
    def code(self) -> int:
        return COMMAND_MAIN.code_of(self.body)

    @property
    def size(self) -> int:
        return 17 if self.sub is None else 32


@final  # mypy narrows `type(message) is M2Response` in both branches
@dataclass(frozen=True, slots=True)
class M2Response:
    """A MECHATROLINK-I/II response: ALARM byte, STATUS bits (:class:`~mlink_sim.wire.codes.M2Status`), RWDT."""

    body: Any
    alarm: int = 0
    status: int = 0
    rwdt: int = 0
    sub: Any = None
    substatus: int = 0

    @property
    def code(self) -> int:
        return RESPONSE_MAIN.code_of(self.body)

    @property
    def size(self) -> int:
        return 17 if self.sub is None else 32


# Framing of the data area, declared once like the bodies (offsets are data offsets = manual byte - 1).
COMMAND_FRAME_17 = Struct("code" / Int8ul, Padding(1), "main" / Bytes(13), "wdt" / Int8ul, Padding(1))
COMMAND_FRAME_32 = Struct(
    "code" / Int8ul, Padding(1), "main" / Bytes(13), "wdt" / Int8ul,
    "subcode" / Int8ul, Padding(1), "sub" / Bytes(12), Padding(2),
)  # fmt: skip
RESPONSE_FRAME_17 = Struct(
    "code" / Int8ul, "alarm" / Int8ul, "status" / Int16ul, "main" / Bytes(11), "rwdt" / Int8ul, Padding(1)
)
RESPONSE_FRAME_32 = Struct(
    "code" / Int8ul, "alarm" / Int8ul, "status" / Int16ul, "main" / Bytes(11), "rwdt" / Int8ul,
    "subcode" / Int8ul, "substatus" / Int8ul, "sub" / Bytes(12), Padding(2),
)  # fmt: skip

_CF17 = struct.Struct(fast_format(COMMAND_FRAME_17, 17)[0])
_CF32 = struct.Struct(fast_format(COMMAND_FRAME_32, 32)[0])
_RF17 = struct.Struct(fast_format(RESPONSE_FRAME_17, 17)[0])
_RF32 = struct.Struct(fast_format(RESPONSE_FRAME_32, 32)[0])


def encode_data(message: M2Command | M2Response) -> bytes:
    """The 17- or 32-byte data area of *message*."""
    if type(message) is M2Command:
        code, main = COMMAND_MAIN.build(message.body)
        if message.sub is None:
            return _CF17.pack(code, main, message.wdt)
        subcode, sub = COMMAND_SUB.build(message.sub)
        return _CF32.pack(code, main, message.wdt, subcode, sub)
    code, main = RESPONSE_MAIN.build(message.body)
    if message.sub is None:
        return _RF17.pack(code, message.alarm, message.status, main, message.rwdt)
    subcode, sub = RESPONSE_SUB.build(message.sub)
    return _RF32.pack(code, message.alarm, message.status, main, message.rwdt, subcode, message.substatus, sub)


def decode_command(data: bytes | memoryview) -> M2Command:
    """Parse a 17- or 32-byte command data area (the length has been checked by the envelope)."""
    if len(data) == 17:
        code, main, wdt = _CF17.unpack(data)
        return M2Command(COMMAND_MAIN.parse(code, main, 0), wdt)
    code, main, wdt, subcode, sub = _CF32.unpack(data)
    return M2Command(COMMAND_MAIN.parse(code, main, 0), wdt, COMMAND_SUB.parse(subcode, sub, 0))


def decode_response(data: bytes | memoryview) -> M2Response:
    """Parse a 17- or 32-byte response data area."""
    if len(data) == 17:
        code, alarm, status, main, rwdt = _RF17.unpack(data)
        return M2Response(RESPONSE_MAIN.parse(code, main, 0), alarm, status, rwdt)
    code, alarm, status, main, rwdt, subcode, substatus, sub = _RF32.unpack(data)
    return M2Response(
        RESPONSE_MAIN.parse(code, main, 0), alarm, status, rwdt, RESPONSE_SUB.parse(subcode, sub, 0), substatus
    )
