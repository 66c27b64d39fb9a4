"""The UDP datagram envelope (docs/wire-format.md) and the top-level codec.

::

    offset  size  field
    0       1     magic 0x4D ('M')
    1       1     link: 01H MECHATROLINK-I, 02H MECHATROLINK-II, 03H MECHATROLINK-III
    2       1     kind: 01H command (master -> slave), 02H response (slave -> master)
    3       1     station address of the slave (both directions)
    4       4     cycle number, u32 LE (a response echoes the command's)
    8       4     transmission cycle in ns, u32 LE (echoed in the response)
    12      n     data: 17/32 bytes (MECHATROLINK-I/II), 32/64 bytes (MECHATROLINK-III)
    12+n    2     FCS: CRC-16/X-25 over bytes 0 … 11+n, LE

Everything that can be wrong with a datagram raises :class:`WireError` carrying a :class:`DropReason`; receivers
count it as a reception failure (a MECHATROLINK-III slave reports a bad FCS as COMM_ALM 1/8).
"""

from __future__ import annotations

import enum
import struct
from dataclasses import dataclass
from typing import Any, Final

from construct import Int8ul, Int16ul, Int32ul, Struct

from . import ml2, ml3
from .codes import Kind, Link
from .fcs import NATIVE, crc16_x25_pure
from .layout import fast_format, fast_struct, field_offset
from .sealed import Sealed as _Sealed

__all__ = [
    "MAGIC",
    "HEADER_SIZE",
    "FCS_SIZE",
    "ENVELOPE",
    "Frame",
    "Message",
    "DropReason",
    "WireError",
    "encode",
    "decode",
    "datagram_size",
    "HEADER",
    "with_fcs",
    "fcs_ok",
    "patch_seal",
    "CYCLE_AT",
    "cycle_of",
    "steady_delta",
    "Template",
    "datagram_struct",
    "datagram_offset",
]

MAGIC: Final = 0x4D
HEADER_SIZE: Final = 12
FCS_SIZE: Final = 2

#: The envelope header, declared once (the FCS trails the data).
ENVELOPE = Struct(
    "magic" / Int8ul,
    "link" / Int8ul,
    "kind" / Int8ul,
    "station" / Int8ul,
    "cycle" / Int32ul,
    "tcycle_ns" / Int32ul,
)
#: ``struct`` codec of :data:`ENVELOPE`: ``HEADER.unpack_from(datagram)`` -> (magic, link, kind, station, cycle,
#: tcycle_ns). The per-cycle fast paths (cards, master) use it with :func:`with_fcs` and :func:`fcs_ok`.
HEADER: Final = fast_struct(ENVELOPE, HEADER_SIZE)
CYCLE_AT: Final = field_offset(ENVELOPE, "cycle")  #: the envelope's cycle number (u32 LE), commands and responses


def datagram_offset(name: str, *frames: Any) -> int:
    """Offset in the datagram (envelope included) of data-frame field *name*, which must sit at the same place in
    each of *frames* (the ``COMMAND_FRAME_*`` / ``RESPONSE_FRAME_*`` declarations of ml2/ml3): the fast paths'
    and the fault stage's byte offsets, derived from the one declaration."""
    offsets = {field_offset(frame, name) for frame in frames}
    if len(offsets) != 1:
        raise ValueError(f"field {name!r} is not at one place in every frame size: {sorted(offsets)}")
    return HEADER_SIZE + offsets.pop()


_FCS: Final = fast_struct(Struct("fcs" / Int16ul), FCS_SIZE)


#: The C module's functions (mlink_sim.wire.fcs.NATIVE), or None: pure Python.
_SEAL: Final[Any] = None if NATIVE is None else NATIVE.seal
_FCS_OK: Final[Any] = None if NATIVE is None else NATIVE.fcs_ok
_PATCH_SEAL: Final[Any] = None if NATIVE is None else NATIVE.patch_seal
_STEADY_DELTA: Final[Any] = None if NATIVE is None else NATIVE.steady_delta
_U32: Final = struct.Struct("<I")


def cycle_of(datagram: bytes) -> int:
    """The envelope's cycle number (u32 LE at :data:`CYCLE_AT`) of a datagram at least a header long. Four byte
    reads: compiled, that allocates nothing (``struct.unpack_from`` made a tuple per answer)."""
    at = CYCLE_AT
    return datagram[at] | datagram[at + 1] << 8 | datagram[at + 2] << 16 | datagram[at + 3] << 24


def with_fcs(body: bytes | bytearray) -> bytes:
    """*body* (envelope + data) with its FCS appended: the datagram. In C (compiled cores) a plain ``bytes``: the
    C check costs less than making a :class:`~mlink_sim.wire.sealed.Sealed`; in Python a ``Sealed``."""
    if _SEAL is not None:
        return _SEAL(body)
    return _Sealed(body + _FCS.pack(crc16_x25_pure(body)))


def patch_seal(template: bytes | bytearray, cycle_at: int, cycle: int, wdt_at: int, wdt: int) -> bytes:
    """A sealed copy of *template* (a datagram without its FCS) with the u32 LE *cycle* at *cycle_at* and the
    byte *wdt* at *wdt_at*: the master's cyclic command from its per-station template. *template* is not
    changed. In C (compiled cores) one call does the copy, both patches and the FCS."""
    if _PATCH_SEAL is not None:
        return _PATCH_SEAL(template, cycle_at, cycle, wdt_at, wdt)
    buf = bytearray(template)
    _U32.pack_into(buf, cycle_at, cycle)
    buf[wdt_at] = wdt
    return with_fcs(buf)


def steady_delta(datagram: bytes, previous: bytes, cycle_at: int, wdt_at: int) -> int:
    """The inverse of :func:`patch_seal`, for a cyclic datagram in the steady state: ``cycle | wdt << 32`` (the u32
    LE at *cycle_at*, the byte at *wdt_at*) when *datagram* is as long as *previous* and differs from it in nothing
    else but its FCS, which is right; else -1 (the caller parses it in full). The slave cards' and the master's
    fast paths keep the last datagram they parsed, so a command (or an answer) whose only news is its cycle and
    watchdog is neither unpacked nor checked field by field again. In C (compiled cores) one call."""
    if _STEADY_DELTA is not None:
        return _STEADY_DELTA(datagram, previous, cycle_at, wdt_at)
    n = len(datagram)
    if n != len(previous) or n < FCS_SIZE:
        return -1
    body = n - FCS_SIZE
    if cycle_at < 0 or wdt_at < 0 or cycle_at + 4 > body or wdt_at >= body:
        raise ValueError(f"steady_delta: offsets {cycle_at} (cycle) and {wdt_at} (wdt) outside a {n}-byte datagram")
    now, before = bytearray(datagram[:body]), previous[:body]
    now[cycle_at:cycle_at + 4] = before[cycle_at:cycle_at + 4]
    now[wdt_at] = before[wdt_at]
    if now != before or not fcs_ok(datagram):
        return -1
    return int(_U32.unpack_from(datagram, cycle_at)[0]) | datagram[wdt_at] << 32


class Template:
    """A cyclic datagram kept as a template (the cards' steady-state answers, docs/cards.md, "Performance: the cyclic path"):
    :attr:`body` is the datagram without its FCS, with its cycle and its (R)WDT byte at *wdt_at* zero. It is packed
    again by the caller only when :meth:`stale` says one of the nine fields it was packed from changed; each
    datagram is then :meth:`seal`: the body with the cycle and the WDT patched in, sealed (:func:`patch_seal`).
    Nine native ints and no tuple, so the check costs no allocation per datagram.

    The last datagram sealed is kept: sealing the same cycle and WDT from the same body again returns that object,
    with no copy and no FCS. A card's answer made ahead (:mod:`mlink_sim.cards.prediction`) is sealed here for the
    next cycle; when the card then takes that cycle's command, its own answer is the same object, and the worker's
    check that the two are equal (``aio.slave.bus.Port.settle``) is an identity test."""

    def __init__(self, wdt_at: int) -> None:
        self.wdt_at = wdt_at
        self.body = b""
        self._field0 = self._field1 = self._field2 = self._field3 = self._field4 = 0
        self._field5 = self._field6 = self._field7 = self._field8 = 0
        self._sealed = b""  # the last datagram seal() returned, of _sealed_body with _sealed_cycle and _sealed_wdt
        self._sealed_body = b""
        self._sealed_cycle = self._sealed_wdt = -1

    def stale(self, k0: int, k1: int, k2: int, k3: int, k4: int, k5: int, k6: int, k7: int, k8: int) -> bool:
        """True when :attr:`body` must be packed again: there is none yet, or one of the nine fields it is packed
        from (everything but the cycle and the WDT, in the caller's order) changed; the new ones are kept."""
        if (self.body and k0 == self._field0 and k1 == self._field1 and k2 == self._field2 and k3 == self._field3
                and k4 == self._field4 and k5 == self._field5 and k6 == self._field6 and k7 == self._field7
                and k8 == self._field8):
            return False
        self._field0, self._field1, self._field2, self._field3, self._field4 = k0, k1, k2, k3, k4
        self._field5, self._field6, self._field7, self._field8 = k5, k6, k7, k8
        return True

    def seal(self, cycle: int, wdt: int) -> bytes:
        """The datagram of *cycle* (u32) with *wdt* (a byte) and its FCS."""
        body = self.body
        if cycle == self._sealed_cycle and wdt == self._sealed_wdt and body is self._sealed_body:
            return self._sealed
        sealed = self._sealed = patch_seal(body, CYCLE_AT, cycle, self.wdt_at, wdt)
        self._sealed_body, self._sealed_cycle, self._sealed_wdt = body, cycle, wdt
        return sealed


def datagram_struct(frame: Struct, size: int, **inline: tuple[Struct, int]) -> tuple[struct.Struct, tuple[str, ...]]:
    """``(struct, field names)`` of a whole datagram but its FCS: the envelope, then the data frame *frame* of
    *size* bytes with the regions named in *inline* laid out by their body's declaration
    (:func:`~mlink_sim.wire.layout.fast_format`). The per-cycle fast paths pack or unpack a datagram in
    one call with it."""
    head, head_names = fast_format(ENVELOPE, HEADER_SIZE)
    body, body_names = fast_format(frame, size, inline)
    return struct.Struct(head + body[1:]), head_names + body_names


def fcs_ok(datagram: bytes | bytearray | memoryview) -> bool:
    """The datagram's trailing FCS matches its contents (callers check the length first)."""
    if _FCS_OK is not None:
        return _FCS_OK(datagram)
    if type(datagram) is _Sealed:
        return True
    return crc16_x25_pure(datagram[:-FCS_SIZE]) == _FCS.unpack_from(datagram, len(datagram) - FCS_SIZE)[0]

Message = ml2.M2Command | ml2.M2Response | ml3.M3Command | ml3.M3Response


class DropReason(enum.Enum):
    """Why a datagram was not accepted (a counted reception failure, never an exception escaping the loop)."""

    TOO_SHORT = "too short"
    TOO_LONG = "too long"
    BAD_SIZE = "wrong data size"
    BAD_MAGIC = "bad magic"
    BAD_LINK = "unknown link"
    BAD_KIND = "unknown kind"
    BAD_FCS = "bad FCS"
    WRONG_KIND = "unexpected kind"


class WireError(ValueError):
    """A datagram that cannot be accepted; :attr:`reason` says why, ``str(err)`` is a one-line message."""

    def __init__(self, reason: DropReason, detail: str) -> None:
        super().__init__(f"{reason.value}: {detail}")
        self.reason = reason
        self.detail = detail


@dataclass(frozen=True, slots=True)
class Frame:
    """One decoded datagram: envelope fields and the typed message."""

    link: Link
    kind: Kind
    station: int
    cycle: int
    tcycle_ns: int
    message: Message

    @property
    def data_size(self) -> int:
        return self.message.size


def datagram_size(data_size: int) -> int:
    """Datagram length for a data area of *data_size* bytes."""
    return HEADER_SIZE + data_size + FCS_SIZE


_ML2_TYPES = (ml2.M2Command, ml2.M2Response)
_ML3_TYPES = (ml3.M3Command, ml3.M3Response)
_MAX_DATAGRAM: Final = datagram_size(64)
_MIN_DATAGRAM: Final = datagram_size(17)
_LINKS: Final = {int(v): v for v in Link}


def encode(frame: Frame) -> bytes:
    """Datagram bytes of *frame* (FCS appended)."""
    msg = frame.message
    if frame.link is Link.ML3:
        if not isinstance(msg, _ML3_TYPES):
            raise TypeError("a MECHATROLINK-III frame needs an M3Command or M3Response")
        data = ml3.encode_data(msg)
    else:
        if not isinstance(msg, _ML2_TYPES):
            raise TypeError("a MECHATROLINK-I/II frame needs an M2Command or M2Response")
        if frame.link is Link.ML1 and msg.sub is not None:
            raise ValueError("MECHATROLINK-I carries 17-byte data only")
        data = ml2.encode_data(msg)
    kind = Kind.COMMAND if isinstance(msg, (ml2.M2Command, ml3.M3Command)) else Kind.RESPONSE
    if frame.kind is not kind:
        raise ValueError(f"a {kind.name.lower()} message in a frame of kind {Kind(frame.kind).name.lower()}")
    try:
        head = HEADER.pack(MAGIC, frame.link, kind, frame.station, frame.cycle, frame.tcycle_ns)
    except struct.error as exc:
        raise ValueError(f"envelope field out of range: {exc}") from None
    return with_fcs(head + data)


def decode(datagram: bytes | bytearray | memoryview, *, data_size: int | None = None,
           kind: Kind | None = None) -> Frame:
    """Decode and check one datagram.

    *data_size* is the station's configured frame size, if known: a datagram of any other size is rejected.
    *kind* restricts the accepted kind (a slave accepts commands only).
    Raises :class:`WireError` for every malformed input.
    """
    n = len(datagram)
    if n < _MIN_DATAGRAM:
        raise WireError(DropReason.TOO_SHORT, f"{n} bytes, the shortest datagram is {_MIN_DATAGRAM}")
    if n > _MAX_DATAGRAM:
        raise WireError(DropReason.TOO_LONG, f"{n} bytes, the longest datagram is {_MAX_DATAGRAM}")
    magic, link_b, kind_b, station, cycle, tcycle = HEADER.unpack_from(datagram)
    if magic != MAGIC:
        raise WireError(DropReason.BAD_MAGIC, f"{magic:#04x}, expected {MAGIC:#04x}")
    # The FCS is checked before the header fields it protects, so a corrupted link/kind byte counts as a bad FCS
    # (an ML-III slave reports COMM_ALM 1/8 for it) rather than as an unknown link.
    if not fcs_ok(datagram):
        (fcs,) = _FCS.unpack_from(datagram, n - FCS_SIZE)
        want = crc16_x25_pure(datagram[: n - FCS_SIZE])  # the error path: the same CRC, either way
        raise WireError(DropReason.BAD_FCS, f"{fcs:#06x}, computed {want:#06x}")
    link = _LINKS.get(link_b)
    if link is None:
        raise WireError(DropReason.BAD_LINK, f"{link_b:#04x}, expected 01H, 02H or 03H")
    if kind_b not in (1, 2):
        raise WireError(DropReason.BAD_KIND, f"{kind_b:#04x}, expected 01H (command) or 02H (response)")
    size = n - HEADER_SIZE - FCS_SIZE
    sizes = link.data_sizes
    if size not in sizes:
        expected = " or ".join(map(str, sizes))
        raise WireError(DropReason.BAD_SIZE, f"{size} data bytes on {link.label}, expected {expected}")
    if data_size is not None and size != data_size:
        raise WireError(DropReason.BAD_SIZE, f"{size} data bytes, this station uses {data_size}-byte frames")
    knd = Kind.COMMAND if kind_b == 1 else Kind.RESPONSE
    if kind is not None and knd is not kind:
        raise WireError(DropReason.WRONG_KIND, f"got a {knd.name.lower()}, expected a {kind.name.lower()}")
    data: Any = datagram[HEADER_SIZE : n - FCS_SIZE]  # bytes, bytearray or memoryview, as given
    if link is Link.ML3:
        msg: Message = ml3.decode_command(data) if knd is Kind.COMMAND else ml3.decode_response(data)
    else:
        msg = ml2.decode_command(data) if knd is Kind.COMMAND else ml2.decode_response(data)
    return Frame(link, knd, station, cycle, tcycle, msg)
