"""mlink_sim.aio._timerfd.LookaheadTimer: two timerfds in turn, the next wake-up armed a period ahead. Each target
wakes its owner once, at or after it; a target already set a period ago is kept (no timerfd call for it), one
outside the tolerances is re-armed; a timerfd that expired during a stall, or was set for a wake-up that is no
longer wanted, wakes nobody. Real timerfds on a real loop; times are checked for order, never for speed."""

from __future__ import annotations

import asyncio
import time

import pytest

from mlink_sim.aio._timerfd import LookaheadTimer, timerfd_supported

pytestmark = pytest.mark.skipif(not timerfd_supported(), reason="no timerfd here")

MS = 1_000_000
_mono = time.monotonic_ns


class _Owner:
    """Wakes recorded with their time; :meth:`run` serves the loop until *until_ns* has passed."""

    def __init__(self, loop: asyncio.AbstractEventLoop, period_ns: int, on_wake=None) -> None:
        self.loop = loop
        self.timer = LookaheadTimer(period_ns)
        self.wakes: list[int] = []
        self._on_wake = on_wake
        self.timer.watch(loop, self._woke)

    def _woke(self) -> None:
        self.wakes.append(_mono())
        if self._on_wake is not None:
            self._on_wake(self)

    def run(self, until_ns: int) -> None:
        self.loop.run_until_complete(asyncio.sleep(max(0, until_ns - _mono()) / 1e9))

    def close(self) -> None:
        self.timer.close_watched(self.loop)


@pytest.fixture
def loop():
    loop = asyncio.new_event_loop()
    yield loop
    loop.close()


def test_each_target_wakes_once_and_after_the_first_each_was_already_set(loop) -> None:
    period = 5 * MS
    start = _mono() + 5 * MS
    targets = [start + k * period for k in range(6)]

    def next_target(owner: _Owner) -> None:
        n = len(owner.wakes)
        if n < len(targets):
            owner.timer.set_abs(targets[n])  # the next one: armed a period ago by the call before

    owner = _Owner(loop, period, next_target)
    try:
        owner.timer.set_abs(targets[0])
        owner.run(targets[-1] + 3 * period)  # the one armed after the last (targets[-1] + period) wakes too
        assert len(owner.wakes) == len(targets) + 1
        assert all(w >= t for w, t in zip(owner.wakes, targets))
        assert (owner.timer.rearmed, owner.timer.kept) == (1, len(targets) - 1)
    finally:
        owner.close()


def test_a_target_moved_beyond_the_tolerance_is_re_armed_and_the_old_time_wakes_nobody(loop) -> None:
    period = 20 * MS  # margins of milliseconds: a selector loop's sleep may end a millisecond late
    owner = _Owner(loop, period)
    try:
        t0 = _mono() + 5 * MS
        owner.timer.set_abs(t0)
        owner.run(t0 + period // 2)
        assert len(owner.wakes) == 1
        moved = t0 + period + period // 2  # half a period after the one armed ahead: far outside 5 µs / 1 µs
        owner.timer.set_abs(moved)
        assert (owner.timer.rearmed, owner.timer.kept) == (2, 0)
        owner.run(moved - period // 4)
        assert len(owner.wakes) == 1  # nothing at t0 + period
        owner.run(moved + period // 2)
        assert len(owner.wakes) == 2 and owner.wakes[1] >= moved
        # within the tolerance (2 µs early of the one armed ahead): kept, no timerfd call
        owner.timer.set_abs(moved + period + 2_000)
        assert owner.timer.kept == 1
    finally:
        owner.close()


def test_after_a_stall_the_expired_timerfds_wake_the_owner_once_and_then_only_the_new_target(loop) -> None:
    period = 12 * MS
    later: list[int] = []

    def catch_up(owner: _Owner) -> None:  # as the clock does: after the catch-up, the next future target
        if len(owner.wakes) == 1:
            later.append(_mono() + 2 * period)
            owner.timer.set_abs(later[0])  # the other, stale one is re-armed: its expiration is cleared

    owner = _Owner(loop, period, catch_up)
    try:
        t0 = _mono() + 2 * MS
        owner.timer.set_abs(t0)
        time.sleep((t0 + 3 * period - _mono()) / 1e9)  # the loop held: t0 and t0 + period both expire
        owner.run(_mono() + 2 * MS)
        assert len(owner.wakes) == 1  # both were readable together; the owner woke once
        owner.run(later[0] - 5 * MS)
        assert len(owner.wakes) == 1
        owner.run(later[0] + 5 * MS)
        assert len(owner.wakes) == 2 and owner.wakes[1] >= later[0]
    finally:
        owner.close()


def test_a_second_target_before_the_first_woke_moves_the_first(loop) -> None:
    # The arrival poll's case: the reader had the burst before its poll began, so the poll is set for the next one.
    period = 20 * MS
    owner = _Owner(loop, period)
    try:
        t1 = _mono() + 10 * MS
        owner.timer.set_abs(t1)
        t2 = t1 + period + 1_500  # the next burst came 1.5 µs late: the one armed ahead is within 5 µs early
        owner.timer.set_abs(t2)
        assert owner.timer.kept == 1
        owner.run(t2 - 5 * MS)
        assert owner.wakes == []  # t1 woke nobody: that timerfd now holds the one after t2
        owner.run(t2 + 5 * MS)
        assert len(owner.wakes) == 1 and owner.wakes[0] >= t2 - 1_500
    finally:
        owner.close()
