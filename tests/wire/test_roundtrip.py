"""Hypothesis round trips for every layout and for whole datagrams.

For every region (ml2/ml3 COMMAND_MAIN, RESPONSE_MAIN, COMMAND_SUB, RESPONSE_SUB) and every layout registered in
it, field values are generated from the construct declaration (tests/wire/wire_strategies.py) and

(a) ``Layout.parse(Layout.build(x)) == x``,
(b) the struct fast path and the construct declaration agree both ways: ``build(x) == build_construct(x)`` and
    ``parse_construct(b) == parse(b)`` – on built bytes and on arbitrary region bytes (reserved bytes set).
"""

from __future__ import annotations

from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mlink_sim.wire import Frame, Kind, Link, decode, encode, ml2, ml3
from mlink_sim.wire.fcs import crc16_x25_reference
from mlink_sim.wire.layout import Layout, Slot

from wire_strategies import LAYOUT_IDS, LAYOUTS, SLOTS, body, frames, message, u8, u32

PER_LAYOUT = settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow])
PER_FRAME = settings(max_examples=200, deadline=None)


def test_every_slot_of_both_generations_is_covered() -> None:
    for module in (ml2, ml3):
        declared = {id(v) for v in vars(module).values() if isinstance(v, Slot)}
        assert declared <= {id(s) for s in SLOTS}, f"{module.__name__} has a Slot the tests do not cover"
    assert len(SLOTS) == 8


def test_every_layout_fills_exactly_its_region() -> None:
    for slot, layout in LAYOUTS:
        assert layout.size == slot.size
        assert layout.struct.sizeof() == slot.size
        assert layout._fast.size == slot.size  # the derived struct format covers the whole region


@pytest.mark.parametrize(("slot", "layout"), LAYOUTS, ids=LAYOUT_IDS)
def test_layout_round_trip_and_paths_agree(slot: Slot, layout: Layout[Any]) -> None:
    @PER_LAYOUT
    @given(body(layout), st.binary(min_size=slot.size, max_size=slot.size))
    def check(x: Any, region: bytes) -> None:
        fast = layout.build(x)
        assert len(fast) == slot.size
        assert layout.parse(fast) == x  # (a)
        assert layout.build_construct(x) == fast  # (b) build
        assert layout.parse_construct(fast) == x  # (b) parse
        # the slot dispatches on the code to the same layout
        assert slot.build(x) == (layout.code, fast)
        assert slot.parse(layout.code, fast, 0) == x
        # arbitrary region bytes (reserved bytes set): both parse paths agree, and rebuilding is stable
        y = layout.parse(region)
        assert layout.parse_construct(region) == y
        assert layout.parse(layout.build(y)) == y

    check()


@pytest.mark.parametrize(
    ("link", "kind", "with_sub"),
    [
        (Link.ML1, Kind.COMMAND, False),
        (Link.ML1, Kind.RESPONSE, False),
        (Link.ML2, Kind.COMMAND, False),
        (Link.ML2, Kind.COMMAND, True),
        (Link.ML2, Kind.RESPONSE, False),
        (Link.ML2, Kind.RESPONSE, True),
        (Link.ML3, Kind.COMMAND, False),
        (Link.ML3, Kind.COMMAND, True),
        (Link.ML3, Kind.RESPONSE, False),
        (Link.ML3, Kind.RESPONSE, True),
    ],
    ids=lambda v: v.name if hasattr(v, "name") else ("long" if v else "short"),
)
def test_datagram_round_trip(link: Link, kind: Kind, with_sub: bool) -> None:
    sizes = {Link.ML1: (17, 17), Link.ML2: (17, 32), Link.ML3: (32, 64)}[link]

    @settings(max_examples=40, deadline=None)
    @given(message(link, kind, with_sub), u8, u32, u32)
    def check(msg: Any, station: int, cycle: int, tcycle: int) -> None:
        frame = Frame(link, kind, station, cycle, tcycle, msg)
        dg = encode(frame)
        assert len(dg) == 12 + sizes[with_sub] + 2
        assert decode(dg) == frame
        assert decode(dg, data_size=sizes[with_sub], kind=kind) == frame

    check()


@PER_FRAME
@given(frames())
def test_datagram_round_trip_any_frame(frame: Frame) -> None:
    assert decode(encode(frame)) == frame


@PER_FRAME
@given(
    st.sampled_from([(Link.ML1, 17), (Link.ML2, 17), (Link.ML2, 32), (Link.ML3, 32), (Link.ML3, 64)]),
    st.sampled_from(list(Kind)),
    st.data(),
)
def test_decode_is_canonical_on_arbitrary_data(link_size: tuple[Link, int], kind: Kind, data: st.DataObject) -> None:
    """Any well-enveloped datagram decodes; re-encoding only zeroes reserved bytes, so it decodes to the same."""
    link, size = link_size
    head = bytes([0x4D, link, kind, data.draw(u8)]) + data.draw(st.binary(min_size=8, max_size=8))
    body_ = head + data.draw(st.binary(min_size=size, max_size=size))
    dg = body_ + crc16_x25_reference(body_).to_bytes(2, "little")
    frame = decode(dg)
    again = encode(frame)
    assert len(again) == len(dg) and again[:12] == dg[:12]
    assert decode(again) == frame
