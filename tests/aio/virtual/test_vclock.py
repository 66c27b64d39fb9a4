"""mlink_sim.aio.virtual.vclock: simulated time, its event queue, and the asyncio loop that runs on it."""

from __future__ import annotations

import asyncio
import os
import signal
import time

import pytest

from mlink_sim.aio.virtual.vclock import SLICE_NS, VirtualClock, VirtualEventLoop, VirtualTimeStalled


def test_clock_runs_callbacks_in_time_order_then_insertion_order():
    clock = VirtualClock()
    seen = []
    clock.at(30, lambda a: seen.append((clock.now, a)), "c")
    clock.at(10, lambda a: seen.append((clock.now, a)), "a")
    clock.at(10, lambda a: seen.append((clock.now, a)), "b")
    assert clock.next_due() == 10
    assert clock.run_until(20) is False
    assert seen == [(10, "a"), (10, "b")] and clock.now == 20
    clock.run_until(30)
    assert seen[-1] == (30, "c") and clock.next_due() is None


def test_clock_stops_after_the_callback_that_made_work_and_never_runs_backwards():
    clock = VirtualClock(start_ns=100)
    work = []
    clock.at(50, work.append, "late")  # in the past: runs now, not at 50
    clock.at(200, work.append, "x")
    assert clock.run_until(1_000, stop=work) is True
    assert work == ["late"] and clock.now == 100
    work.clear()
    assert clock.run_until(1_000, stop=work) is True
    assert clock.now == 200


def test_loop_sleeps_take_no_wall_time():
    loop = VirtualEventLoop()
    try:
        async def main():
            t0 = loop.time()
            await asyncio.sleep(3600)
            return loop.time() - t0

        wall = time.perf_counter()
        assert loop.run_until_complete(main()) == pytest.approx(3600)
        assert time.perf_counter() - wall < 5  # an hour of simulated time, no waiting (loose: busy CI)
    finally:
        loop.close()


def test_a_clock_event_wakes_a_coroutine_at_its_own_time_not_at_the_next_timer():
    loop = VirtualEventLoop()
    clock = loop.clock
    try:
        async def main():
            fut = loop.create_future()
            clock.at(clock.now + 2_500_000_000, lambda _: fut.set_result(loop.time()))
            return await asyncio.wait_for(fut, timeout=10), loop.time()

        woke, after = loop.run_until_complete(main())
        assert woke == after == pytest.approx(2.5)
    finally:
        loop.close()


def test_wait_for_times_out_in_simulated_time():
    loop = VirtualEventLoop()
    try:
        async def main():
            with pytest.raises(TimeoutError):
                await asyncio.wait_for(loop.create_future(), timeout=7)
            return loop.time()

        assert loop.run_until_complete(main()) == pytest.approx(7, abs=1e-6)
    finally:
        loop.close()


def test_waiting_with_nothing_scheduled_is_an_error_not_a_hang():
    loop = VirtualEventLoop()
    try:
        with pytest.raises(VirtualTimeStalled):
            loop.run_until_complete(loop.create_future())
    finally:
        loop.close()


def test_signal_handlers_still_fire_while_the_clock_runs():
    loop = VirtualEventLoop()
    clock = loop.clock
    try:
        async def main():
            got = asyncio.Event()
            loop.add_signal_handler(signal.SIGUSR1, got.set)

            def tick(_):
                if clock.now == SLICE_NS:
                    os.kill(os.getpid(), signal.SIGUSR1)
                clock.at(clock.now + 1_000_000, tick)

            clock.at(0, tick)
            await got.wait()
            loop.remove_signal_handler(signal.SIGUSR1)
            return loop.time()

        assert SLICE_NS / 1e9 <= loop.run_until_complete(main()) <= 3 * SLICE_NS / 1e9
    finally:
        loop.close()
