"""mlink_sim.aio.preread.PreRead: one read per cycle, a quarter period before the next deadline, none where that
would fall inside the clock's spin; closing stops it."""

from __future__ import annotations

import asyncio
import time

import pytest

from mlink_sim.aio._timerfd import timerfd_supported
from mlink_sim.aio.preread import PreRead

pytestmark = pytest.mark.skipif(not timerfd_supported(), reason="no timerfd here")


async def test_one_read_a_quarter_period_before_the_deadline() -> None:
    loop = asyncio.get_running_loop()
    reads: list[int] = []
    pre = PreRead.create(loop, lambda: reads.append(time.monotonic_ns()), 40_000_000, spin_ns=70_000)
    assert pre is not None and pre.lead_ns == 10_000_000
    try:
        deadline = time.monotonic_ns() + 40_000_000
        pre.arm(deadline)
        await asyncio.sleep(0.045)
        assert len(reads) == 1 and deadline - 10_000_000 <= reads[0] < deadline + 5_000_000  # 5 ms: a busy machine
        pre.arm(deadline + 40_000_000)
        pre.arm(deadline + 40_000_000)  # armed again: still one read
        await asyncio.sleep(0.045)
        assert len(reads) == 2
        pre.arm(time.monotonic_ns() + 20_000_000)
    finally:
        pre.close()
        pre.close()
    await asyncio.sleep(0.03)
    assert len(reads) == 2  # closed before it fell due


def test_none_inside_the_spin() -> None:
    loop = asyncio.new_event_loop()
    try:
        assert PreRead.create(loop, lambda: None, 250_000, spin_ns=70_000) is None  # 62.5 µs <= the spin
        pre = PreRead.create(loop, lambda: None, 1_000_000, spin_ns=70_000)
        assert pre is not None
        pre.close()
    finally:
        loop.close()
