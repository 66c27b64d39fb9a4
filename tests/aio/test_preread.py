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


async def test_arm_after_a_deadline_is_the_next_cycle_s_read() -> None:
    loop = asyncio.get_running_loop()
    reads: list[int] = []
    pre = PreRead.create(loop, lambda: reads.append(time.monotonic_ns()), 40_000_000, spin_ns=70_000)
    assert pre is not None
    try:
        deadline = time.monotonic_ns()  # this cycle's: the next is 40 ms on, its read 10 ms before it
        pre.arm_after(deadline)
        await asyncio.sleep(0.045)
        assert len(reads) == 1 and deadline + 30_000_000 <= reads[0] < deadline + 45_000_000
    finally:
        pre.close()


def test_none_inside_the_spin() -> None:
    loop = asyncio.new_event_loop()
    try:
        assert PreRead.create(loop, lambda: None, 250_000, spin_ns=70_000) is None  # 62.5 µs <= the spin
        pre = PreRead.create(loop, lambda: None, 1_000_000, spin_ns=70_000)
        assert pre is not None
        pre.close()
    finally:
        loop.close()


def test_for_stamped_only_where_asked_and_the_socket_can_stamp(monkeypatch: pytest.MonkeyPatch) -> None:
    """The master's and the floor's one choice: off by default; on with MLINK_RX_STAMPS=1 for a socket that
    switches its stamps on; never for one that refuses them (a tapped socket) or has no such call."""
    import socket

    from mlink_sim.aio import mmsg

    class Refuses:
        def enable_stamps(self) -> bool:
            return False

    loop = asyncio.new_event_loop()
    raw = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        raw.bind(("127.0.0.1", 0))
        sock = mmsg.wrap(raw)
        monkeypatch.delenv("MLINK_RX_STAMPS", raising=False)
        assert PreRead.for_stamped(loop, sock, lambda: None, 1_000_000, 70_000) is None
        monkeypatch.setenv("MLINK_RX_STAMPS", "1")
        assert PreRead.for_stamped(loop, Refuses(), lambda: None, 1_000_000, 70_000) is None
        assert PreRead.for_stamped(loop, raw, lambda: None, 1_000_000, 70_000) is None  # no enable_stamps
        pre = PreRead.for_stamped(loop, sock, lambda: None, 1_000_000, 70_000)
        assert (pre is not None) == mmsg.stamps_supported()
        assert getattr(sock, "stamped", False) == (pre is not None)
        if pre is not None:
            pre.close()
    finally:
        raw.close()
        loop.close()
