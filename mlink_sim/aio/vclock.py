"""Virtual time: an event queue in simulated nanoseconds and an asyncio loop that runs on it.

:class:`VirtualClock` holds simulated time (``now``, int ns) and a queue of callbacks due at given times (the
in-memory network's deliveries, the master's cycles, the cards' polls; :mod:`mlink_sim.aio.fabric`).
:class:`VirtualEventLoop` is asyncio's selector loop with ``time()`` read from that clock: whenever the loop would
sleep until its next timer (``asyncio.sleep``, ``wait_for`` timeouts …), the clock instead runs its own events in
order of time up to that timer, and stops early at the first event that gives the loop work (a request completed,
a waiter woken). So time advances from one deadline to the next, coroutines (the timeline, the master API) run
unchanged, and nothing ever waits for the wall clock. Real file descriptors (signal wake-ups, a TCP server) are
still polled, without blocking, at least every :data:`SLICE_NS` of simulated time.

Order at equal times is fixed (queue insertion order; the loop's ready callbacks before the clock's events), so a
run is a pure function of its inputs.
"""

from __future__ import annotations

import asyncio
import heapq
import itertools
import math
import selectors
from collections.abc import Callable, Sized
from typing import Any

__all__ = ["VirtualClock", "VirtualEventLoop", "VirtualTimeStalled", "SLICE_NS"]

#: Simulated time between two (non-blocking) polls of the real file descriptors when nothing else stops the clock.
SLICE_NS = 50_000_000


class VirtualTimeStalled(RuntimeError):
    """The loop waits for something, but no timer and no event is left: simulated time cannot advance."""


class VirtualClock:
    """Simulated monotonic time in ns and the callbacks due at given times (``at``), run by :meth:`run_until`."""

    __slots__ = ("now", "_queue", "_seq", "queue", "seq")

    def __init__(self, start_ns: int = 0) -> None:
        self.now = start_ns
        self._queue: list[tuple[int, int, Callable[[Any], None], Any]] = []
        self._seq = itertools.count()
        #: the queue itself, a heap of ``(when, next(seq), fn, arg)`` with ``when >= now``: the in-memory network
        #: (:mod:`.fabric`) pushes its deliveries onto it directly, which is what :meth:`at` does, one call fewer
        self.queue = self._queue
        self.seq = self._seq

    def now_ns(self) -> int:
        return self.now

    def at(self, when: int, fn: Callable[[Any], None], arg: Any = None) -> None:
        """Call ``fn(arg)`` at simulated time *when* (ns; not before ``now``)."""
        heapq.heappush(self._queue, (when if when > self.now else self.now, next(self._seq), fn, arg))

    def next_due(self) -> int | None:
        """When the next callback is due, or None when none is queued."""
        return self._queue[0][0] if self._queue else None

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


class _VirtualSelector(selectors.BaseSelector):
    """The loop's selector: real descriptors are polled without blocking; a wait advances the clock instead."""

    def __init__(self, clock: VirtualClock) -> None:
        self._clock = clock
        self._real = selectors.DefaultSelector()
        self.ready: Sized = ()  #: the loop's queue of callbacks to run now: the clock stops once it is not empty

    def register(self, fileobj: Any, events: int, data: Any = None) -> selectors.SelectorKey:
        return self._real.register(fileobj, events, data)

    def unregister(self, fileobj: Any) -> selectors.SelectorKey:
        return self._real.unregister(fileobj)

    def modify(self, fileobj: Any, events: int, data: Any = None) -> selectors.SelectorKey:
        return self._real.modify(fileobj, events, data)

    def get_map(self) -> Any:
        return self._real.get_map()

    def close(self) -> None:
        self._real.close()

    def select(self, timeout: float | None = None) -> list[tuple[selectors.SelectorKey, int]]:
        ready = self._real.select(0)
        if ready or (timeout is not None and timeout <= 0):
            return ready
        clock = self._clock
        now = clock.now
        if timeout is None and clock.next_due() is None:
            raise VirtualTimeStalled("virtual time stands still: the loop waits, but nothing is scheduled")
        limit = now + SLICE_NS
        if timeout is not None:
            limit = min(limit, now + math.ceil(timeout * 1e9))
        clock.run_until(limit, self.ready)
        return []


class VirtualEventLoop(asyncio.SelectorEventLoop):
    """An asyncio loop on simulated time (see the module docstring); ``loop.clock`` is its :class:`VirtualClock`."""

    def __init__(self, clock: VirtualClock | None = None) -> None:
        self.clock = clock if clock is not None else VirtualClock()
        selector = _VirtualSelector(self.clock)
        super().__init__(selector)
        # asyncio's queue of callbacks to run now: BaseEventLoop's private deque, which typeshed does not declare
        selector.ready = self._ready  # type: ignore[attr-defined]

    def time(self) -> float:
        return self.clock.now / 1e9
