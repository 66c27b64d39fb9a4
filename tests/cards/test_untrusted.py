"""A datagram from a source the I/O layer does not let change the station (``mlink-sim slave --allow-master``):
``Station.receive_untrusted`` answers a status query read-only and counts anything else in ``foreign_source``
(docs/cards.md, "Who may change a station")."""

from __future__ import annotations

import pytest

from mlink_sim.wire import Kind, decode, encode, ml2, ml3

from .helpers import INTRUDER, Master, station


@pytest.mark.parametrize("card", ["si-t3", "si-et3", "si-t-v7"])
def test_an_untrusted_connect_binds_nothing_and_its_nop_is_answered_read_only(card: str) -> None:
    st = station(card)
    m = Master(st, source=INTRUDER)
    connect = ml3.Connect(0x30, 0x80, 1, 0x20) if m.ml3 else ml2.Connect(0x21, 0x80, 1)
    assert st.receive_untrusted(encode(m.command(connect)), INTRUDER, 0) is None
    assert st.phase == 1 and st.snapshot().connected_source is None
    assert st.counters.foreign_source == 1 and st.counters.rx_ok == 0
    m.tick()
    answer = st.receive_untrusted(encode(m.command(ml3.Nop() if m.ml3 else ml2.Nop())), INTRUDER, m.now)
    assert answer is not None and decode(answer, kind=Kind.RESPONSE).station == st.address
    assert st.counters.status_queries == 1 and st.phase == 1
    assert st.receive_untrusted(b"\x4d\x02\x01\x21garbage", INTRUDER, m.now) is None  # a counted drop
    assert sum(st.counters.dropped_by_reason.values()) == 1
