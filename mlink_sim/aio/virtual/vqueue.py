"""The virtual clock's event queue: simulated time in ns and the callbacks due at given times.

:class:`VirtualClock` is what :mod:`mlink_sim.aio.virtual.vclock`'s loop and the in-memory network
(:mod:`mlink_sim.aio.virtual.fabric`) run on: every datagram delivery, cycle and card poll of a virtual run is one event
here, so the module is compiled with the cores (``mlink_sim._accel.COMPILED_MODULES``, docs/performance.md). It lives
apart from the asyncio loop, whose classes derive from asyncio's and stay Python.

Order at equal times is fixed (insertion order), so a run is a pure function of its inputs.

Touches: nothing but its own queue (compiled with the cores).
"""

from __future__ import annotations

import heapq
from collections.abc import Callable, Sized
from typing import Any

__all__ = ["VirtualClock"]


class VirtualClock:
    """Simulated monotonic time in ns and the callbacks due at given times (``at``), run by :meth:`run_until`."""

    def __init__(self, start_ns: int = 0) -> None:
        self.now: int = start_ns
        #: a heap of ``(when, seq, fn, arg)`` with ``when >= now``; ``seq`` orders equal times by insertion
        self._queue: list[tuple[int, int, Callable[[Any], None], Any]] = []
        self._seq: int = 0

    def now_ns(self) -> int:
        return self.now

    def at(self, when: int, fn: Callable[[Any], None], arg: Any = None) -> None:
        """Call ``fn(arg)`` at simulated time *when* (ns; not before ``now``)."""
        seq = self._seq
        self._seq = seq + 1
        heapq.heappush(self._queue, (when if when > self.now else self.now, seq, fn, arg))

    def next_due(self) -> int | None:
        """When the next callback is due, or None when none is queued."""
        queue = self._queue
        return queue[0][0] if queue else None

    def run_until(self, limit: int, stop: Sized = ()) -> bool:
        """Run the callbacks due up to *limit* (inclusive) in order of time, ``now`` following each; ``True`` when
        *stop* (a container: the loop's ready queue) is not empty after one of them (``now`` is then that
        callback's time), else ``now = limit``."""
        queue = self._queue
        pop = heapq.heappop
        while queue and queue[0][0] <= limit:
            when, _, fn, arg = pop(queue)
            self.now = when
            fn(arg)
            if stop:
                return True
        if limit > self.now:
            self.now = limit
        return False
