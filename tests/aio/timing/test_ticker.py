"""Behaviour of mlink_sim.aio.timing.ticker.CycleTimer (no assertions on lateness: see docs/timing.md for numbers).

Every strategy available here is run on plain asyncio and on uvloop. Timing-dependent facts are asserted as
invariants that hold whatever the machine's jitter (a skipped cycle is allowed, a wrong number is not).
"""

from __future__ import annotations

import asyncio
import os
import time

import pytest
from structlog.testing import capture_logs

from mlink_sim.aio import STRATEGIES, CycleTimer, available_strategies
from mlink_sim.aio.timing.ticker import learn_wake_error

try:
    import uvloop
except ImportError:  # pragma: no cover
    uvloop = None

MS = 1_000_000
LOOPS = ["asyncio"] + (["uvloop"] if uvloop is not None else [])
AVAILABLE = available_strategies()


def run_on(loop_kind: str, coro_fn):
    loop = uvloop.new_event_loop() if loop_kind == "uvloop" else asyncio.new_event_loop()
    try:
        return loop.run_until_complete(asyncio.wait_for(coro_fn(), timeout=5))
    finally:
        loop.close()


class Recorder:
    """on_cycle that records its arguments and sets an event after `want` calls."""

    def __init__(self, want: int, action=None) -> None:
        self.calls: list[tuple[int, int, int, int]] = []
        self.want = want
        self.action = action
        self.done = asyncio.Event()

    def __call__(self, cycle: int, deadline_ns: int, now_ns: int, skipped: int) -> None:
        self.calls.append((cycle, deadline_ns, now_ns, skipped))
        if len(self.calls) >= self.want:
            self.done.set()
        if self.action is not None:
            self.action(self, cycle)


def assert_schedule(calls, start_ns: int, period_ns: int, first_cycle: int = 0) -> None:
    """Numbering is consecutive up to reported skips; deadlines are exactly start + k*period; no bursts."""
    expected = first_cycle
    for cycle, deadline, now, skipped in calls:
        assert cycle == expected + skipped
        assert deadline == start_ns + cycle * period_ns
        assert deadline <= now < deadline + period_ns  # never early, never a stale catch-up call
        expected = cycle + 1


def test_available_strategies_and_auto():
    assert {"call_at", "call_at+spin"} <= set(AVAILABLE)
    assert set(AVAILABLE) <= set(STRATEGIES)
    timer = CycleTimer(MS, lambda *a: None, strategy="auto")
    assert timer.strategy == ("timerfd+spin" if "timerfd" in AVAILABLE else "call_at+spin")


@pytest.mark.parametrize("loop_kind", LOOPS)
@pytest.mark.parametrize("strategy", AVAILABLE)
def test_each_strategy_runs_20_cycles_at_1ms(strategy, loop_kind):
    async def main():
        rec = Recorder(want=20)
        start = time.monotonic_ns() + 2 * MS
        timer = CycleTimer(MS, rec, strategy=strategy, start_ns=start)
        timer.start()
        await rec.done.wait()
        timer.stop()
        assert timer.strategy == strategy
        assert len(rec.calls) >= 20
        assert_schedule(rec.calls, start, MS)
        last = rec.calls[-1][0]
        assert timer.cycle == last
        # no drift accumulation: after N cycles the next deadline is start + N*period, exactly
        assert timer.next_deadline_ns == start + (last + 1) * MS
        assert timer.skipped_total == sum(c[3] for c in rec.calls)

    run_on(loop_kind, main)


@pytest.mark.parametrize("loop_kind", LOOPS)
def test_deadlines_are_exact_multiples_with_awkward_period(loop_kind):
    period = 333_333  # not a divisor of anything: float arithmetic would drift
    async def main():
        rec = Recorder(want=30)
        start = time.monotonic_ns() + 1 * MS
        timer = CycleTimer(period, rec, start_ns=start)
        timer.start()
        await rec.done.wait()
        timer.stop()
        assert timer.start_ns == start
        assert_schedule(rec.calls, start, period)

    run_on(loop_kind, main)


@pytest.mark.parametrize("loop_kind", LOOPS)
@pytest.mark.parametrize("strategy", AVAILABLE)
def test_blocking_callback_skips_cycles_instead_of_bursting(strategy, loop_kind):
    def block_once(rec, cycle):
        if len(rec.calls) == 3:
            time.sleep(3.5 * MS / 1e9)  # > 2 periods

    async def main():
        rec = Recorder(want=8, action=block_once)
        start = time.monotonic_ns() + 2 * MS
        timer = CycleTimer(MS, rec, strategy=strategy, start_ns=start)
        timer.start()
        await rec.done.wait()
        timer.stop()
        assert_schedule(rec.calls, start, MS)
        after_block = rec.calls[3]
        assert after_block[3] >= 2  # at least the two whole periods the callback blocked for
        assert timer.skipped_total == sum(c[3] for c in rec.calls) >= 2

    run_on(loop_kind, main)


@pytest.mark.parametrize("loop_kind", LOOPS)
def test_start_in_the_past_reports_skipped(loop_kind):
    async def main():
        rec = Recorder(want=3)
        start = time.monotonic_ns() - 10 * MS
        timer = CycleTimer(MS, rec, strategy="auto", start_ns=start)
        timer.start()
        await rec.done.wait()
        timer.stop()
        first = rec.calls[0]
        assert first[0] == first[3] >= 9
        assert_schedule(rec.calls, start, MS)

    run_on(loop_kind, main)


def _open_fds() -> set[str]:
    return set(os.listdir("/proc/self/fd")) if os.path.isdir("/proc/self/fd") else set()




@pytest.mark.parametrize("loop_kind", LOOPS)
@pytest.mark.parametrize("strategy", AVAILABLE)
def test_stop_releases_resources_and_is_idempotent(strategy, loop_kind):
    async def main():
        fds_before = _open_fds()
        rec = Recorder(want=3)
        timer = CycleTimer(MS, rec, strategy=strategy)
        timer.start()
        await rec.done.wait()
        assert timer.running
        if strategy.startswith("timerfd"):  # one timerfd
            assert len(_open_fds() - fds_before) == 1
        timer.stop()
        timer.stop()
        assert not timer.running
        assert _open_fds() - fds_before == set()
        n = len(rec.calls)
        await asyncio.sleep(5 * MS / 1e9)
        assert len(rec.calls) == n  # nothing after stop()
        with pytest.raises(RuntimeError):
            timer.start()

    run_on(loop_kind, main)


@pytest.mark.parametrize("loop_kind", LOOPS)
def test_stop_from_inside_the_callback(loop_kind):
    async def main():
        holder = {}
        rec = Recorder(want=2, action=lambda r, c: holder["t"].stop() if len(r.calls) >= 2 else None)
        timer = holder["t"] = CycleTimer(MS, rec)
        timer.start()
        await rec.done.wait()
        await asyncio.sleep(4 * MS / 1e9)
        assert len(rec.calls) == 2 and not timer.running

    run_on(loop_kind, main)


@pytest.mark.parametrize("loop_kind", LOOPS)
def test_callback_exception_is_logged_and_timer_continues(loop_kind):
    def fail_some(rec, cycle):
        if len(rec.calls) in (2, 4):
            raise ZeroDivisionError("boom")

    async def main():
        with capture_logs() as logs:
            rec = Recorder(want=8, action=fail_some)
            timer = CycleTimer(MS, rec)
            timer.start()
            await rec.done.wait()
            timer.stop()
        failed = [e for e in logs if e["event"] == "on_cycle_failed"]
        assert [e["cycle"] for e in failed] == [rec.calls[1][0], rec.calls[3][0]]
        assert all(e["log_level"] == "error" and e["exc_info"] for e in failed)
        assert failed[0]["strategy"] == timer.strategy and failed[0]["period_ns"] == MS
        assert timer.errors == 2
        assert len(rec.calls) >= 8

    run_on(loop_kind, main)


def test_error_logging_is_rate_limited():
    async def main():
        with capture_logs() as logs:
            rec = Recorder(want=40, action=lambda r, c: 1 / 0)
            timer = CycleTimer(250_000, rec)
            timer.start()
            await rec.done.wait()
            timer.stop()
        n = timer.errors
        logged = [e["errors_total"] for e in logs if e["event"] == "on_cycle_failed"]
        assert n >= 40
        assert logged == [k for k in range(1, n + 1) if k <= 10 or not k & (k - 1)]

    run_on("asyncio", main)


def test_spin_settings():
    assert CycleTimer(MS, lambda *a: None, strategy="call_at").spin_ns == 0
    assert CycleTimer(MS, lambda *a: None, strategy="call_at+spin", spin_ns=30_000).spin_ns == 30_000
    assert CycleTimer(MS, lambda *a: None, strategy="call_at+spin", spin_ns=0).spin_ns == 0
    # an adaptive spin never exceeds its cap (default half a period for timerfd, a whole one for call_at)
    assert CycleTimer(100_000, lambda *a: None, strategy="call_at+spin").spin_ns <= 100_000
    if "timerfd" in AVAILABLE:
        assert CycleTimer(100_000, lambda *a: None, strategy="timerfd+spin").spin_ns <= 50_000


def test_the_adaptive_spin_learns_the_sources_error_not_the_stalls():
    """docs/timing.md, "What the spin learns from": a host that stalls twice a second for 3 ms, each stall followed
    by a few wake-ups late by the catch-up, must not drive the spin to its cap (half a period) as it did."""
    cap = 500_000
    q = 60_000  # timerfd's starting point
    assert learn_wake_error(q, 61_000, cap) > q  # above the estimate: up
    assert learn_wake_error(q, 59_000, cap) < q  # within: down
    assert learn_wake_error(q, 3 * MS, cap) == q  # beyond the cap, a stall: not the source's error
    for k in range(20_000):  # 20 s at 1 ms: the source's error is 20-40 µs; every 500 cycles a 3 ms stall, and the
        phase = k % 500      # catch-up after it makes the next 7 wake-ups late too, each less (counted, it goes to the cap)
        error = 3 * MS - phase * 300_000 if phase < 8 else 20_000 + (k * 7919) % 20_000
        q = learn_wake_error(q, error, cap)
    assert 20_000 <= q <= 45_000  # it follows the source's error, whatever the stalls


@pytest.mark.parametrize("kwargs", [
    {"strategy": "nope"}, {"strategy": "call_at", "spin_ns": 10_000}, {"spin_ns": -1}, {"period_ns": 0}])
def test_invalid_arguments(kwargs):
    kwargs = {"period_ns": MS, **kwargs}
    with pytest.raises(ValueError):
        CycleTimer(kwargs.pop("period_ns"), lambda *a: None, **kwargs)


def test_start_without_running_loop_needs_loop():
    with pytest.raises(RuntimeError):
        CycleTimer(MS, lambda *a: None).start()



# ---------------------------------------------------------------------------------------------- host stalls
@pytest.mark.parametrize("loop_kind", LOOPS)
def test_catch_up_runs_the_cycles_a_stall_delayed_in_order(loop_kind):
    """Host-stall policy "absorb" (docs/timing.md): a stall within catch_up_ns is made good, not skipped."""
    stalls = []

    def block_once(rec, cycle):
        if len(rec.calls) == 3:
            time.sleep(4.5 * MS / 1e9)  # > 3 periods, far within this test's bound (1 s: no host stall reaches it)

    async def main():
        rec = Recorder(want=12, action=block_once)
        start = time.monotonic_ns() + 2 * MS
        timer = CycleTimer(MS, rec, strategy="auto", start_ns=start, catch_up_ns=1000 * MS,
                           on_stall=lambda *a: stalls.append(a))
        timer.start()
        await rec.done.wait()
        timer.stop()
        cycles = [c[0] for c in rec.calls]
        assert cycles == list(range(len(cycles)))  # every cycle, none skipped
        assert all(c[3] == 0 for c in rec.calls)
        assert all(c[1] == start + c[0] * MS for c in rec.calls)  # each with its own deadline
        assert timer.skipped_total == 0 and timer.caught_up_total >= 3
        assert any(absorbed and behind >= 3 and now - deadline >= 3 * MS  # the busy host may add its own
                   for deadline, now, behind, absorbed in stalls)

    run_on(loop_kind, main)


def run_with_a_stall(loop_kind: str, action) -> tuple[list[tuple[int, int, int, int]], CycleTimer]:
    """40 cycles of 1 ms with the policy "absorb", *action(rec, cycle)* after each call (it makes the stall); the
    calls and the stopped timer. The bound (1 s) is one no host stall reaches, and the 40 cycles leave the catch-up
    time to end however busy the machine: what the tests check is the catch-up itself, whatever else delays it."""
    async def main():
        rec = Recorder(want=40, action=action)
        timer = CycleTimer(MS, rec, strategy="auto", start_ns=time.monotonic_ns() + 2 * MS, catch_up_ns=1000 * MS)
        timer.start()
        await rec.done.wait()
        timer.stop()
        return rec.calls, timer

    return run_on(loop_kind, main)


@pytest.mark.parametrize("loop_kind", LOOPS)
def test_each_caught_up_cycle_starts_when_it_runs(loop_kind):
    """A caught-up cycle's now_ns is the time its call begins, not the wake-up's: its commands' round trips count
    from when they go out (docs/timing.md, "The catch-up yields")."""
    def work(rec, cycle):
        _, deadline, now, _ = rec.calls[-1]
        if len(rec.calls) == 3:
            time.sleep(4.5 * MS / 1e9)
        elif now - deadline >= MS:  # a caught-up cycle: takes 0.2 ms, as encoding a full line's commands may
            end = time.monotonic_ns() + MS // 5
            while time.monotonic_ns() < end:
                pass

    calls, _ = run_with_a_stall(loop_kind, work)
    caught = [i for i, (_, deadline, now, _) in enumerate(calls) if now - deadline >= MS]
    assert len(caught) >= 3
    for i in (i for i in caught if i + 1 < len(calls)):  # the call after a caught-up one began after its 0.2 ms
        assert calls[i + 1][2] - calls[i][2] >= MS // 5
        assert calls[i + 1][1] == calls[i][1] + MS and calls[i + 1][1] <= calls[i + 1][2]


def test_the_catch_up_yields_the_cpu_between_its_cycles_and_only_there(monkeypatch):
    """docs/timing.md, "The catch-up yields": a cycle's send wakes its slaves; between two cycles run back to back
    the clock yields once, so that they need not wait behind the whole catch-up. On time, it never yields (the
    clock sleeps or spins then)."""
    events: list[object] = []
    monkeypatch.setattr(os, "sched_yield", lambda: events.append("yield"))

    def block_once(rec, cycle):
        events.append(rec.calls[-1])
        if len(rec.calls) == 3:
            time.sleep(4.5 * MS / 1e9)  # > 3 periods, within the bound

    _, timer = run_with_a_stall("asyncio", block_once)
    yields = [i for i, e in enumerate(events) if e == "yield"]
    assert len(yields) == timer.caught_up_total >= 3  # one after each caught-up cycle
    for i in yields:  # each right after a cycle run late by a period or more, and before the next cycle
        _cycle, deadline, now, _ = events[i - 1]
        assert now - deadline >= MS
        assert i + 1 < len(events) and events[i + 1] != "yield"


@pytest.mark.parametrize("loop_kind", LOOPS)
def test_stall_beyond_the_bound_is_skipped_and_reported(loop_kind):
    stalls = []

    def block_once(rec, cycle):
        if len(rec.calls) == 3:
            time.sleep(6.5 * MS / 1e9)  # beyond the 3 ms bound

    async def main():
        rec = Recorder(want=8, action=block_once)
        start = time.monotonic_ns() + 2 * MS
        timer = CycleTimer(MS, rec, strategy="auto", start_ns=start, catch_up_ns=3 * MS,
                           on_stall=lambda *a: stalls.append(a))
        timer.start()
        await rec.done.wait()
        timer.stop()
        expected = 0
        for cycle, deadline, _now, skipped in rec.calls:  # consecutive up to the skips; a shorter stall (a busy
            assert cycle == expected + skipped  # host) may have been caught up within the bound meanwhile
            assert deadline == start + cycle * MS
            expected = cycle + 1
        assert timer.skipped_total >= 5  # the next deadline was 5.5 periods behind
        assert any(not absorbed and behind >= 5 for _, _, behind, absorbed in stalls)

    run_on(loop_kind, main)
