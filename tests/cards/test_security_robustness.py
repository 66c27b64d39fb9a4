"""Security and robustness: the connected master owns the station; other stations' datagrams are counted;
no datagram, however malformed, raises out of receive() or stops the station answering its master."""

from __future__ import annotations

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mlink_sim.profiles import BUILTIN
from mlink_sim.wire import Frame, Kind, Link, encode, ml2, ml3

from .helpers import INTRUDER, MASTER, MS, Master, station

A = ("b1-01=3", "b1-02=3")


def test_foreign_source_ignored_after_connect() -> None:
    m = Master(station("si-t3", params=A))
    m.bring_up()
    intruder = Master(m.st, source=INTRUDER, now=m.now)
    intruder.cycle, intruder.count = m.cycle, m.count
    assert intruder.send(ml2.InvCtl(signals=1, speed_ref=6000)) is None
    assert intruder.send(ml2.Disconnect()) is None
    assert m.st.counters.foreign_source == 2 and m.st.phase == 3
    m.now, m.cycle, m.count = intruder.now, intruder.cycle, intruder.count
    assert m.nop() is not None  # the master is still served
    m.send(ml2.Disconnect())
    intruder.now, intruder.cycle = m.now, m.cycle
    assert intruder.connect() is not None  # after DISCONNECT anyone may connect
    assert m.st.snapshot().connected_source == INTRUDER


def test_connection_lost_releases_the_lock() -> None:
    """After bUS a NOP binds nothing (a status query); only CONNECT does (tests/cards/test_ownership.py)."""
    m = Master(station("si-et3", params=A))
    m.bring_up()
    m.st.poll(m.now + 10 * MS)  # F6-26 communication alarms: bUS, "the connection was lost"
    assert m.st.snapshot().connected_source is None
    other = Master(m.st, source=INTRUDER, now=m.now + 10 * MS)
    other.cycle, other.count = m.cycle + 10, m.count + 10
    assert other.nop() is not None and m.st.snapshot().connected_source is None
    assert other.connect() is not None and m.st.snapshot().connected_source == INTRUDER


def test_other_station_datagrams_counted() -> None:
    st22 = station("si-t3", station=0x22)
    m = Master(station("si-t3"))
    raw = encode(Frame(Link.ML2, Kind.COMMAND, 0x22, 1, MS, ml2.M2Command(ml2.Nop(), 0, ml2.Nop())))
    assert m.st.receive(raw, MASTER, 1) is None and m.st.counters.other_station == 1
    assert st22.receive(raw, MASTER, 1) is not None


def test_wrong_link_and_size_are_drops() -> None:
    st = station("si-t3")
    raw = encode(Frame(Link.ML3, Kind.COMMAND, 0x21, 1, MS, ml3.M3Command(ml3.Nop())))
    assert st.receive(raw, MASTER, 1) is None
    raw17 = encode(Frame(Link.ML2, Kind.COMMAND, 0x21, 1, MS, ml2.M2Command(ml2.Nop())))
    assert st.receive(raw17, MASTER, 1) is None
    resp = encode(Frame(Link.ML2, Kind.RESPONSE, 0x21, 1, MS, ml2.M2Response(ml2.Nop(), sub=ml2.Nop())))
    assert st.receive(resp, MASTER, 1) is None
    assert st.counters.dropped_by_reason == {"WRONG_LINK": 1, "BAD_SIZE": 1, "WRONG_KIND": 1}


def test_aer_station_does_not_answer() -> None:
    """SI-T3 Table 4 <4>: F6-20 = 20H/3FH -> AEr, ERR on; SI-T/V7: ERR blinks, RUN off."""
    for card in ("si-t3", "si-t-v7"):
        st = station(card, station=0x20)
        m = Master(st)
        assert m.nop() is None and st.counters.dropped_by_reason == {"AER": 1}
        snap = st.snapshot()
        assert snap.station_error == "AEr" and "AEr" in snap.drive.minors
        assert snap.leds["ERR"] == ("on" if card == "si-t3" else "blink")
        assert snap.leds["RUN"] == ("on" if card == "si-t3" else "off")


CARD_NAMES = sorted(p.key for p in BUILTIN)


@pytest.mark.parametrize("card", CARD_NAMES)
@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.lists(st.binary(min_size=0, max_size=90), min_size=1, max_size=8))
def test_arbitrary_bytes_never_raise(card: str, data: list[bytes]) -> None:
    m = Master(station(card))
    m.connect()
    for blob in data:
        m.st.receive(blob, MASTER, m.now)
    assert m.st.counters.internal_errors == 0
    assert m.nop() is not None  # still answering


def _valid_envelope(card: str) -> st.SearchStrategy[bytes]:
    """Structurally valid datagrams for the card's link and size with random data (FCS correct)."""
    from mlink_sim.wire import HEADER_SIZE, crc16_x25

    link, size = {"si-t3": (2, 32), "si-t-v7": (2, 32), "si-et3": (3, 64)}[card]

    def build(data: bytes, cycle: int) -> bytes:
        body = bytes((0x4D, link, 1, 0x21)) + cycle.to_bytes(4, "little") + MS.to_bytes(4, "little") + data
        assert len(body) == HEADER_SIZE + size
        return body + crc16_x25(body).to_bytes(2, "little")

    return st.builds(build, st.binary(min_size=size, max_size=size), st.integers(0, 0xFFFF_FFFF))


@pytest.mark.parametrize("card", CARD_NAMES)
@settings(max_examples=300, deadline=None)
@given(data=st.data())
def test_arbitrary_commands_never_raise(card: str, data: st.DataObject) -> None:
    m = Master(station(card, params=A if card != "si-t-v7" else ("n003=3", "n004=9")))
    m.connect()
    now = m.now
    for _ in range(data.draw(st.integers(1, 6))):
        now += MS
        m.st.receive(data.draw(_valid_envelope(card)), MASTER, now)
        m.st.poll(now)
        m.st.snapshot()
    assert m.st.counters.internal_errors == 0
    m.st.receive(b"", MASTER, now)
    assert m.st.counters.internal_errors == 0


@pytest.mark.parametrize("card", ["si-t3", "si-t-v7", "si-et3"])
def test_foreign_nop_is_a_status_query_that_changes_nothing(card: str) -> None:
    """A health check (``mlink-sim probe``) may ask a connected station for its status with a NOP: it is answered
    with the status as it stands, nothing is executed and the master's WDT/RWDT sequence is untouched."""
    m = Master(station(card, params=A if card != "si-t-v7" else ("n003=3", "n004=9")))
    m.bring_up()
    before = m.st.snapshot()
    intruder = Master(m.st, source=INTRUDER, now=m.now)
    intruder.cycle, intruder.count = m.cycle, m.count
    answer = intruder.nop()
    assert answer is not None and answer.station == 0x21
    rwdt = answer.message.rwdt
    assert m.st.counters.status_queries == 1 and m.st.counters.foreign_source == 0
    assert m.st.snapshot().phase == before.phase == 3
    assert m.st.snapshot().connected_source == MASTER
    m.now, m.cycle, m.count = intruder.now, intruder.cycle, intruder.count
    served = m.nop()
    assert served is not None and served.message.rwdt & 0xF == (rwdt + 1) & 0xF  # the status reply did not count
    assert m.st.counters.wdt_errors == 0
    # anything but a NOP from another source is still ignored
    assert intruder.send(ml3.SyncSet() if card == "si-et3" else ml2.SyncSet()) is None
    assert m.st.counters.foreign_source == 1
