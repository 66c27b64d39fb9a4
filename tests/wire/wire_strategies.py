"""Hypothesis strategies for the wire layer, derived from the construct declarations (shared by tests/wire).

Field values are generated from each layout's construct declaration, not from the dataclass, so a field whose
declared type changes is generated accordingly: ``Int8ul`` 0..255, ``Int16ul`` 0..65535, ``Int16sl``
-32768..32767, ``Int32ul`` 0..2**32-1, ``Bytes(n)`` exactly *n* bytes.
"""

from __future__ import annotations

import functools
import struct
from typing import Any

import construct as cs
from hypothesis import strategies as st

from mlink_sim.wire import Frame, Kind, Link, Unknown, ml2, ml3
from mlink_sim.wire.layout import Layout, Slot

__all__ = [
    "SLOT_LABELS",
    "SLOTS",
    "LAYOUTS",
    "LAYOUT_IDS",
    "field_strategies",
    "body",
    "unknown",
    "message",
    "frames",
    "u8",
    "u32",
]

#: Every region of a message, per generation, with a short label for test ids.
SLOT_LABELS: dict[str, Slot] = {
    "ml2-cmd-main": ml2.COMMAND_MAIN,
    "ml2-rsp-main": ml2.RESPONSE_MAIN,
    "ml2-cmd-sub": ml2.COMMAND_SUB,
    "ml2-rsp-sub": ml2.RESPONSE_SUB,
    "ml3-cmd-main": ml3.COMMAND_MAIN,
    "ml3-rsp-main": ml3.RESPONSE_MAIN,
    "ml3-cmd-sub": ml3.COMMAND_SUB,
    "ml3-rsp-sub": ml3.RESPONSE_SUB,
}
SLOTS: tuple[Slot, ...] = tuple(SLOT_LABELS.values())

#: ``(slot, layout)`` for every registered layout, and matching pytest ids (``ml2-cmd-main-01H-PrmRd``).
LAYOUTS: tuple[tuple[Slot, Layout[Any]], ...] = tuple(
    (slot, layout) for slot in SLOTS for _, layout in sorted(slot.by_code.items())
)
LAYOUT_IDS: list[str] = [
    f"{label}-{code:02X}H-{layout.cls.__name__}"
    for label, slot in SLOT_LABELS.items()
    for code, layout in sorted(slot.by_code.items())
]

u8 = st.integers(0, 0xFF)
u32 = st.integers(0, 0xFFFF_FFFF)


def _field_strategy(sub: cs.Construct) -> st.SearchStrategy[Any]:
    if isinstance(sub, cs.FormatField):
        fmt = sub.fmtstr
        assert fmt[0] == "<", fmt
        bits = 8 * struct.calcsize(fmt)
        if fmt[1].islower():  # signed: b h i q
            return st.integers(-(1 << (bits - 1)), (1 << (bits - 1)) - 1)
        return st.integers(0, (1 << bits) - 1)
    if isinstance(sub, cs.Bytes):
        return st.binary(min_size=sub.length, max_size=sub.length)
    raise TypeError(f"no strategy for {sub!r}")


def field_strategies(layout: Layout[Any]) -> dict[str, st.SearchStrategy[Any]]:
    """``{field name: strategy}`` read off the layout's construct declaration (padding is skipped)."""
    declaration = layout.struct.subcon  # Layout.struct is Padded(size, declaration)
    out: dict[str, st.SearchStrategy[Any]] = {}
    for sub in declaration.subcons:
        if isinstance(sub, cs.Renamed):
            out[sub.name] = _field_strategy(sub.subcon)
    return out


def body(layout: Layout[Any]) -> st.SearchStrategy[Any]:
    """Instances of the layout's dataclass with every field drawn from its declared type."""
    return st.builds(layout.cls, **field_strategies(layout))


def unknown(slot: Slot) -> st.SearchStrategy[Unknown]:
    """An :class:`Unknown` body: a code no layout of *slot* declares and exactly ``slot.size`` raw bytes."""
    codes = st.sampled_from([c for c in range(256) if c not in slot.by_code])
    return st.builds(Unknown, codes, st.binary(min_size=slot.size, max_size=slot.size))


@functools.cache
def _any_body(slot: Slot) -> st.SearchStrategy[Any]:
    """Any body of *slot*: one of its declared layouts (each equally likely), or now and then an unknown code."""
    known = [body(layout) for _, layout in sorted(slot.by_code.items())]
    return st.one_of(*known, unknown(slot))


@functools.cache
def message(link: Link, kind: Kind, with_sub: bool) -> st.SearchStrategy[Any]:
    """A message of *kind* for *link*; ``with_sub`` selects the long frame (32 bytes ML-II, 64 bytes ML-III)."""
    none = st.none()
    if link is Link.ML3:
        if kind is Kind.COMMAND:
            return st.builds(
                ml3.M3Command,
                _any_body(ml3.COMMAND_MAIN),
                wdt=u8,
                cmd_ctrl=st.integers(0, 0xFFFF),
                sub=_any_body(ml3.COMMAND_SUB) if with_sub else none,
                sub_ctrl=st.integers(0, 0xFFFF) if with_sub else st.just(0),
            )
        return st.builds(
            ml3.M3Response,
            _any_body(ml3.RESPONSE_MAIN),
            rwdt=u8,
            cmd_stat=st.integers(0, 0xFFFF),
            sub=_any_body(ml3.RESPONSE_SUB) if with_sub else none,
            sub_stat=st.integers(0, 0xFFFF) if with_sub else st.just(0),
        )
    if kind is Kind.COMMAND:
        return st.builds(
            ml2.M2Command,
            _any_body(ml2.COMMAND_MAIN),
            wdt=u8,
            sub=_any_body(ml2.COMMAND_SUB) if with_sub else none,
        )
    return st.builds(
        ml2.M2Response,
        _any_body(ml2.RESPONSE_MAIN),
        alarm=u8,
        status=st.integers(0, 0xFFFF),
        rwdt=u8,
        sub=_any_body(ml2.RESPONSE_SUB) if with_sub else none,
        substatus=u8 if with_sub else st.just(0),
    )


def frames(link: Link | None = None, kind: Kind | None = None) -> st.SearchStrategy[Frame]:
    """Whole frames: every link, both kinds, both data sizes of the link (ML-I: 17 bytes only)."""
    links = st.just(link) if link is not None else st.sampled_from(list(Link))
    kinds = st.just(kind) if kind is not None else st.sampled_from(list(Kind))

    @st.composite
    def build(draw: st.DrawFn) -> Frame:
        lk = draw(links)
        kd = draw(kinds)
        with_sub = False if lk is Link.ML1 else draw(st.booleans())
        msg = draw(message(lk, kd, with_sub))
        return Frame(lk, kd, draw(u8), draw(u32), draw(u32), msg)

    return build()
