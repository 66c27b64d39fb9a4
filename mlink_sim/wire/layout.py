"""Layouts declared once: a construct ``Struct`` per body, bound to a frozen dataclass.

Every command/response body of the three manuals is declared as a construct ``Struct`` – the single source of
truth, readable next to the manual's byte table – and bound to a frozen dataclass that is the typed result.
From that one declaration two codecs are derived:

* the construct codec itself (``Layout.struct.parse/build``), used by tests as the oracle, and
* a ``struct.Struct`` fast path, derived mechanically from the same declaration (``Int16ul`` -> ``H``,
  ``Bytes(8)`` -> ``8s``, ``Padding(2)`` -> ``2x`` …), used on the per-cycle hot path, where construct's
  parse, microseconds each, would cost more than the whole rest of a station's cycle.

The tests check that both agree for every layout (hypothesis round trips), so the fast path can never drift from
the declaration.
"""

from __future__ import annotations

import dataclasses
import struct
from collections.abc import Callable, Mapping
from typing import Any, Generic, TypeVar

import construct as cs

__all__ = ["Layout", "Slot", "Unknown", "fast_format", "fast_struct", "field_offset"]

T = TypeVar("T")


def _subcon_format(sub: cs.Construct) -> str:
    """``struct`` format of one construct field (only fixed-size little-endian primitives are allowed)."""
    if isinstance(sub, cs.FormatField):
        fmt = sub.fmtstr
        if fmt[0] not in "<":
            raise TypeError(f"layouts are little-endian only, got {fmt!r}")
        return fmt[1:]
    if isinstance(sub, cs.Bytes) and isinstance(sub.length, int):
        return f"{sub.length}s"
    if isinstance(sub, cs.Padded) and isinstance(sub.subcon, type(cs.Pass)) and isinstance(sub.length, int):
        return f"{sub.length}x"
    raise TypeError(f"unsupported field in a layout: {sub!r}")


def fast_format(declaration: cs.Struct, size: int,
                inline: Mapping[str, tuple[cs.Struct, int]] | None = None) -> tuple[str, tuple[str, ...]]:
    """Derive ``(struct format, field names)`` from a construct ``Struct`` and pad it to *size* bytes.

    *inline* (``name: (declaration, size)``, e.g. a frame's ``main`` region and the command body that fills it)
    lays out each bytes field it names by that declaration's own fields: one format for a frame and its body, so
    a hot path packs or unpacks them in one call."""
    fmt = ["<"]
    names: list[str] = []
    for sub in declaration.subcons:
        con = sub.subcon if isinstance(sub, cs.Renamed) else sub
        part = _subcon_format(con)
        if inline and isinstance(sub, cs.Renamed) and sub.name in inline:
            body, body_size = inline[sub.name]
            if struct.calcsize("<" + part) != body_size:
                raise ValueError(f"field {sub.name!r} is {struct.calcsize('<' + part)} bytes, not {body_size}")
            body_fmt, body_names = fast_format(body, body_size)
            fmt.append(body_fmt[1:])
            names.extend(body_names)
        else:
            fmt.append(part)
            if isinstance(sub, cs.Renamed):
                names.append(sub.name)
    used = struct.calcsize("".join(fmt))
    if used > size:
        raise ValueError(f"layout of {used} bytes does not fit its {size}-byte region")
    if used < size:
        fmt.append(f"{size - used}x")
    return "".join(fmt), tuple(names)


def fast_struct(declaration: cs.Struct, size: int) -> struct.Struct:
    """``struct.Struct`` of :func:`fast_format` (for hot paths that unpack a whole region at once)."""
    return struct.Struct(fast_format(declaration, size)[0])


def field_offset(declaration: cs.Struct, name: str) -> int:
    """Byte offset of field *name* in a construct ``Struct`` (fixed-size little-endian fields only)."""
    fmt = "<"
    for sub in declaration.subcons:
        if isinstance(sub, cs.Renamed) and sub.name == name:
            return struct.calcsize(fmt)
        fmt += _subcon_format(sub.subcon if isinstance(sub, cs.Renamed) else sub)
    raise KeyError(f"no field {name!r} in the layout")


@dataclasses.dataclass(frozen=True, slots=True)
class Unknown:
    """A body whose code no layout declares (e.g. an unsupported command): its code and raw region bytes.

    Decoding never fails on an unknown code; the card answers it with the protocol's own alarm (A.95 on
    MECHATROLINK-II, CMD_ALM 8 on MECHATROLINK-III)."""

    code: int
    raw: bytes


class Layout(Generic[T]):
    """One body layout: a dataclass, its code and its declaration, padded to a fixed region size."""

    __slots__ = ("cls", "code", "struct", "size", "_fast", "_names", "_ctor", "_bytes_fields")

    def __init__(self, cls: type[T], code: int, declaration: cs.Struct, size: int) -> None:
        self.cls = cls
        self.code = code
        self.size = size
        fmt, names = fast_format(declaration, size)
        self.struct = cs.Padded(size, declaration)
        self._fast = struct.Struct(fmt)
        self._names = names
        fields = tuple(f.name for f in dataclasses.fields(cls))  # type: ignore[arg-type]
        if fields != names:
            raise TypeError(f"{cls.__name__}: dataclass fields {fields} differ from the layout's {names}")
        self._ctor: Callable[..., T] = cls
        self._bytes_fields = tuple(
            (sub.name, sub.subcon.length)
            for sub in declaration.subcons
            if isinstance(sub, cs.Renamed) and isinstance(sub.subcon, cs.Bytes)
        )

    def parse(self, buf: bytes | memoryview, offset: int = 0) -> T:
        """Fast path: region bytes at *offset* -> dataclass."""
        return self._ctor(*self._fast.unpack_from(buf, offset))

    def build(self, body: T) -> bytes:
        """Fast path: dataclass -> region bytes (reserved bytes are zero).

        Raises ValueError for a value that does not fit its field, including a bytes field of the wrong length
        (``struct`` would silently pad or truncate it)."""
        for name, length in self._bytes_fields:
            if len(getattr(body, name)) != length:
                raise ValueError(f"{self.cls.__name__}.{name} must be exactly {length} bytes")
        try:
            return self._fast.pack(*[getattr(body, n) for n in self._names])
        except struct.error as exc:
            raise ValueError(f"{self.cls.__name__}: {exc}") from None

    def parse_construct(self, buf: bytes) -> T:
        """Reference path through construct (tests)."""
        c = self.struct.parse(buf)
        return self._ctor(**{n: c[n] for n in self._names})

    def build_construct(self, body: T) -> bytes:
        return self.struct.build({n: getattr(body, n) for n in self._names})


class Slot:
    """A fixed region of a message (e.g. "MECHATROLINK-II main command body, bytes 3–15") and the layouts that
    can occupy it, keyed by command code (a handler table in the spirit of pymodbus' PDU decoders)."""

    def __init__(self, name: str, size: int) -> None:
        self.name = name
        self.size = size
        self.by_code: dict[int, Layout[Any]] = {}
        self.by_class: dict[type, Layout[Any]] = {}

    def add(self, code: int, declaration: cs.Struct) -> Callable[[type[T]], type[T]]:
        """Class decorator registering *cls* as the body for *code* in this slot."""

        def register(cls: type[T]) -> type[T]:
            if code in self.by_code:
                raise ValueError(f"{self.name}: code {code:#04x} declared twice")
            layout = Layout(cls, code, declaration, self.size)
            self.by_code[code] = layout
            self.by_class[cls] = layout
            layouts = getattr(cls, "__layouts__", None)
            if layouts is None:
                layouts = {}
                type.__setattr__(cls, "__layouts__", layouts)
            layouts[self.name] = layout
            return cls

        return register

    def parse(self, code: int, buf: bytes | memoryview, offset: int) -> Any:
        layout = self.by_code.get(code)
        if layout is None:
            return Unknown(code, bytes(buf[offset : offset + self.size]))
        return layout.parse(buf, offset)

    def build(self, body: Any) -> tuple[int, bytes]:
        """``(code, region bytes)`` of *body*."""
        if type(body) is Unknown:
            if len(body.raw) != self.size:
                raise ValueError(f"Unknown.raw must be exactly {self.size} bytes in the {self.name}")
            return body.code, body.raw
        layout = self.by_class.get(type(body))
        if layout is None:
            raise TypeError(f"{type(body).__name__} cannot travel in the {self.name}")
        return layout.code, layout.build(body)

    def code_of(self, body: Any) -> int:
        if type(body) is Unknown:
            return body.code
        return self.by_class[type(body)].code
