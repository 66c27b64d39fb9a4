"""Reception failures counted from cycle-number gaps are bounded by time (SI-T3 Tables 22–24, SI-T/V7 Tables 7–9,
SI-ET3 COMM_ALM): a gap counts at most the cycles the elapsed time allows; a larger jump, or one backwards, is a
discontinuity that counts one failure. The cards are driven on explicit time (tests/cards/helpers.py)."""

from __future__ import annotations

import pytest

from mlink_sim.cards.reception import ReceptionMonitor
from mlink_sim.wire import ml2, ml3

from .helpers import MS, Master, station

CARDS = ("si-t3", "si-et3", "si-t-v7")


def _connected(card: str) -> Master:
    m = Master(station(card, params=() if card == "si-t-v7" else ("F6-26=10",)))  # bUS after 10 E6
    m.bring_up()
    for _ in range(5):
        m.nop()
    assert m.st.counters.reception_failures == 0
    return m


def _jump(m: Master, ahead: int, *, cycles: int = 1) -> None:
    """One command whose cycle number is *ahead* (mod 2^32, the envelope's u32) past the last, *cycles*
    transmission cycles of time after it."""
    m.now += cycles * m.tcycle_ns
    m.cycle = (m.cycle + ahead) & 0xFFFF_FFFF
    m.count += 1
    m.send(ml3.Nop() if m.ml3 else ml2.Nop(), step=False)


@pytest.mark.parametrize("card", CARDS)
def test_gap_within_the_elapsed_time_counts_every_missed_cycle(card: str) -> None:
    """SI-T3 Table 22 / SI-T/V7 Table 7 / SI-ET3 COMM_ALM 2–9: three commands not received, three failures."""
    m = _connected(card)
    m.tick(3)
    m.nop()
    assert m.st.counters.reception_failures == 3


@pytest.mark.parametrize("card", CARDS)
@pytest.mark.parametrize("ahead", [10**12, 2**31 - 1, 2**31, 1000, 2**32 - 5])
def test_a_cycle_number_the_time_does_not_allow_is_one_failure(card: str, ahead: int) -> None:
    """10^12 ahead (its u32 residue), the furthest a u32 reaches forward, a number behind: one failure each."""
    m = _connected(card)
    _jump(m, ahead)
    assert m.st.counters.reception_failures == 1
    assert m.st.counters.bus_alarms <= 1


@pytest.mark.parametrize("card", CARDS)
def test_a_gap_one_beyond_the_elapsed_time_is_a_discontinuity(card: str) -> None:
    """Four cycles of time allow a jump of 4 / 1 + 1 = five (four missed); a jump of six counts one failure."""
    m = _connected(card)
    _jump(m, 5, cycles=4)
    assert m.st.counters.reception_failures == 4
    m2 = _connected(card)
    _jump(m2, 6, cycles=4)
    assert m2.st.counters.reception_failures == 1


@pytest.mark.parametrize("card", CARDS)
def test_jumping_frames_add_no_more_failures_than_frames(card: str) -> None:
    """A peer in the master's place sending ever-jumping numbers, one per cycle: the counts grow by at most one per
    frame, however large each jump."""
    m = _connected(card)
    for _ in range(50):
        _jump(m, 2**31 - 1)
    c = m.st.counters
    assert c.reception_failures <= 50 and c.bus_alarms <= 50


def test_the_monitor_bounds_the_gap_by_now() -> None:
    """ReceptionMonitor.on_command on explicit time: 2 ms transmission cycle, COM_TIM 1."""
    r = ReceptionMonitor()
    r.start(100, 0, 2 * MS, 1, None)
    assert r.on_command(101, 2 * MS) == (0, 0, 1, False)
    assert r.on_command(111, 22 * MS) == (9, 0, 10, False)  # ten cycles of time, ten cycles on
    assert r.on_command(111 + 10**6, 24 * MS) == (1, 0, 1, True)  # a million cycles in one
    assert r.on_command(50, 26 * MS) == (1, 0, 1, True)  # behind
    assert r.on_command(51, 26 * MS) == (0, 0, 1, False)  # a backlog read at one instant: one step each


def test_a_backlog_at_one_instant_is_no_discontinuity_with_com_tim() -> None:
    """SI-ET3 CONNECT COM_TIM 4: the cycle number steps by four per command; commands read together are no gap."""
    r = ReceptionMonitor()
    r.start(0, 0, 4 * MS, 4, None)
    for k in range(1, 6):
        assert r.on_command(4 * k, 0) == (0, 0, 1, False)
