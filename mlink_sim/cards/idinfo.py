"""ID_RD data.

MECHATROLINK-II (SI-T3 Tables 10/11, SI-T/V7 ID_RD table): ASCII areas per DEVICE_CODE, read in windows of
OFFSET/SIZE (SIZE 1–8, "no more than eight bytes can be read"):

* 00H drive model – SI-T3 ``C I M R – A <region> <voltage class> <structure> <4 digits>`` then 00H; the
  modelled drive is a 200 V class standard model (docs/cards.md): ``"CIMR-A 2 0000"``. SI-T/V7
  ``C I M R – V 7 *1 <voltage class> <capacity>``: ``"CIMR-V7 21P5"`` (1.5 kW, the VS-606V7 the parameter
  table assumes).
* 02H software version – ``S<card software>S<drive software>``: the card software is simulated as 0001;
  the drive software is A1000 PRG 1021 (named in SI-ET3 Table 7 <4>) and VS-606V7 573X (V7 §1, "X" = 0).
* 0FH vendor (SI-T3 Table 11 only): vendor ID ``"08100000"`` at 00H, name ``"YASKAWA ELECTRIC CORPORATION"``
  at 10H. The SI-T/V7 lists only 00H and 02H; other codes are refused (A.94).

An OFFSET past the area, or a SIZE of 0 or above the window, is refused; bytes past the end of the text read
00H.

MECHATROLINK-III (SI-ET3 Table 14): 4-byte values per ID_CODE (little endian) and three 32-byte lists, read
in windows of up to 24 bytes (response bytes 8–31).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from types import MappingProxyType

from mlink_sim.wire import M3Cmd

__all__ = [
    "ML2_ID_AREAS", "V7_ID_AREAS", "ML3_ID_WINDOW", "bitmap", "ml2_id_window", "ml3_id_data", "ml3_id_window",
]

ML3_ID_WINDOW = 24


def _area(text: str, size: int) -> bytes:
    return text.encode("ascii").ljust(size, b"\0")


_VENDOR = _area("08100000", 16) + _area("YASKAWA ELECTRIC", 16) + _area("CORPORATION", 16)

#: SI-T3 Table 10 / Table 11: DEVICE_CODE -> ID area.
ML2_ID_AREAS: Mapping[int, bytes] = MappingProxyType({
    0x00: _area("CIMR-A 2 0000", 16),
    0x02: _area("S0001S1021", 16),
    0x0F: _VENDOR,
})

#: SI-T/V7 ID_RD table: DEVICE_CODE -> ID area.
V7_ID_AREAS: Mapping[int, bytes] = MappingProxyType({
    0x00: _area("CIMR-V7 21P5", 16),
    0x02: _area("S0001S5730", 16),
})


def ml2_id_window(areas: Mapping[int, bytes], device_code: int, offset: int, size: int) -> bytes | None:
    """Up to 8 ID bytes (zero padded to 8), or None for a refused request (A.94)."""
    area = areas.get(device_code)
    if area is None or not 1 <= size <= 8 or offset >= len(area):
        return None
    return area[offset : offset + size].ljust(8, b"\0")


def bitmap(codes: Iterable[int], size: int = 32) -> bytes:
    """A list of supported command codes as a bitmap: bit (code mod 8) of byte (code // 8)."""
    out = bytearray(size)
    for code in codes:
        out[code // 8] |= 1 << (code % 8)
    return bytes(out)


_MAIN = (M3Cmd.NOP, M3Cmd.PRM_RD, M3Cmd.PRM_WR, M3Cmd.ID_RD, M3Cmd.CONFIG, M3Cmd.ALM_RD, M3Cmd.ALM_CLR,
         M3Cmd.SYNC_SET, M3Cmd.CONNECT, M3Cmd.DISCONNECT, M3Cmd.INV_CTL)
_SUB = (M3Cmd.NOP, M3Cmd.PRM_RD, M3Cmd.PRM_WR, M3Cmd.ALM_RD, M3Cmd.INV_IO)


def _u32(v: int) -> bytes:
    return (v & 0xFFFF_FFFF).to_bytes(4, "little")


#: SI-ET3 Table 14, the fixed entries.
_ML3_FIXED: Mapping[int, bytes] = MappingProxyType({
    0x01: _u32(0x0000),  # vendor ID code
    0x02: _u32(0x0400_0001),  # device code, 1000-series drives
    0x03: _u32(0x0001),  # device version: simulated (docs/cards.md)
    0x04: _u32(0x0000),  # device definition file version
    0x05: _u32(0x0001),  # extended address setting: multi-slave not available
    0x10: _u32(0x0020),  # profile type 1: inverter profile
    0x11: _u32(0x0100),  # profile version 1
    0x12: _u32(0x00FF),
    0x13: _u32(0x0000),
    0x14: _u32(0x00FF),
    0x15: _u32(0x0000),
    0x16: _u32(25_000),  # minimum transmission cycle, 0.01 µs units (250 µs)
    0x17: _u32(800_000),  # maximum transmission cycle (8 ms)
    0x18: _u32(0x03),  # transmission cycle granularity
    0x19: _u32(25_000),  # minimum communication cycle (250 µs)
    0x1A: _u32(3_200_000),  # maximum communication cycle (32 ms)
    0x1B: _u32(0x14),  # transmission bytes: 64 and 32
    0x20: _u32(0x03),  # cyclic and event driven communication
    0x30: bitmap(_MAIN),
    0x38: bitmap(_SUB),
    0x40: bytes(32),
    0x49: _u32(0),  # torque reference unit: 0.1 %
    0x4A: _u32(0),  # output current unit: 0.1 A
})

#: ID_CODE 1BH lists 64 and 32 bytes as 00000014H: bit 4 = 64 bytes, bit 2 = 32 bytes (docs/cards.md).
_BYTES_BIT = {32: 0x04, 64: 0x10}


def ml3_id_data(id_code: int, *, data_size: int, profile: int, speed_unit: int) -> bytes | None:
    """The ID of *id_code* (SI-ET3 Table 14), or None for an ID_CODE the card does not have.

    *data_size*: the frame size in use (1CH); *profile*: the profile selected by CONNECT, 0 before (1DH);
    *speed_unit*: o1-03 (48H: 0 = 0.01 Hz, 1 = 0.01 %, 2 = min⁻¹, 3 = product units)."""
    fixed = _ML3_FIXED.get(id_code)
    if fixed is not None:
        return fixed
    if id_code == 0x1C:
        return _u32(_BYTES_BIT.get(data_size, 0))
    if id_code == 0x1D:
        return _u32(profile)
    if id_code == 0x48:
        return _u32(speed_unit)
    return None


def ml3_id_window(data: bytes, offset: int, size: int) -> bytes | None:
    """The window of *data* (zero padded to 24 bytes), or None for a refused OFFSET/SIZE (CMD_ALM 9H)."""
    if not 1 <= size <= ML3_ID_WINDOW or offset >= len(data):
        return None
    return data[offset : offset + size].ljust(ML3_ID_WINDOW, b"\0")
