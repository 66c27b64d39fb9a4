"""Frame check sequence of the UDP wire contract: CRC-16/X-25.

Parameters (docs/wire-format.md): width 16, polynomial 0x1021 reflected (0x8408), init 0xFFFF,
reflected input and output, xorout 0xFFFF; check value of ``b"123456789"`` is ``0x906E``.

Two implementations, one result:

* **compiled cores** (:mod:`mlink_sim._accel`): the C module ``mlink_sim.wire._fcsc`` (mlink_sim/wire/_fcsc.c), a
  table-driven reflected CRC. :data:`NATIVE` is that module: :func:`mlink_sim.wire.frame.with_fcs`,
  :func:`~mlink_sim.wire.frame.fcs_ok` and :func:`~mlink_sim.wire.frame.patch_seal` call it directly, so a
  datagram is sealed or checked in one call, without a copy. It is written by hand because the FCS was most of
  the fast paths' byte work (docs/wire-format.md, "Frame check sequence") and no maintained library seals, checks or
  patches a datagram in one call.
* **pure Python** (the fallback, and the only one with ``MLINK_PURE=1`` or without a compiler):
  :func:`binascii.crc_hqx` is the *non-reflected* CRC-16/CCITT with the same polynomial, so X-25 is obtained by
  bit-reversing every input byte (``bytes.translate``), running ``crc_hqx`` with init 0xFFFF, bit-reversing the
  16-bit result and applying the xorout. This costs well under a microsecond for a 78-byte datagram, where a
  bitwise Python loop costs several.

tests/wire/test_fcs_native.py pins the C functions to the pure ones, byte for byte.
"""

from __future__ import annotations

import binascii
import importlib
from typing import Any, Final

__all__ = ["NATIVE", "crc16_x25", "crc16_x25_pure", "crc16_x25_reference"]


def _native() -> Any:
    """The C module, or None: not built, or pure cores chosen (mlink_sim._accel refuses the import then)."""
    try:
        return importlib.import_module("mlink_sim.wire._fcsc")
    except ImportError:
        return None


#: ``mlink_sim.wire._fcsc`` when the compiled cores run, else None (see the module docstring).
NATIVE: Final[Any] = _native()

_REVERSE_BYTE = bytes(int(f"{i:08b}"[::-1], 2) for i in range(256))


def crc16_x25(data: bytes | bytearray | memoryview) -> int:
    """CRC-16/X-25 of *data* (the FCS of the wire contract)."""
    if NATIVE is not None:
        return NATIVE.crc16_x25(data)
    return crc16_x25_pure(data)


def crc16_x25_pure(data: bytes | bytearray | memoryview, _rev: bytes = _REVERSE_BYTE,
                   _crc: Any = binascii.crc_hqx) -> int:
    """CRC-16/X-25 of *data* in Python (``binascii``): the fallback."""
    if type(data) is not bytes and type(data) is not bytearray:  # bytes(b) copies even when b is bytes
        data = bytes(data)
    crc = _crc(data.translate(_rev), 0xFFFF)
    return ((_rev[crc & 0xFF] << 8) | _rev[crc >> 8]) ^ 0xFFFF


def crc16_x25_reference(data: bytes | bytearray | memoryview) -> int:
    """Bit-by-bit textbook implementation, kept as the oracle for the fast one in tests."""
    crc = 0xFFFF
    for byte in bytes(data):
        crc ^= byte
        for _ in range(8):
            crc = (crc >> 1) ^ 0x8408 if crc & 1 else crc >> 1
    return crc ^ 0xFFFF
