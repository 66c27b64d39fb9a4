"""Virtual time: an event queue in simulated nanoseconds and an asyncio loop that runs on it.

:class:`VirtualClock` (:mod:`.vqueue`, compiled with the cores) holds simulated time (``now``, int ns) and a queue
of callbacks due at given times (the in-memory network's deliveries, the master's cycles, the cards' polls;
:mod:`mlink_sim.aio.virtual.fabric`).
:class:`VirtualEventLoop` is asyncio's selector loop with ``time()`` read from that clock: whenever the loop would
sleep until its next timer (``asyncio.sleep``, ``wait_for`` timeouts …), the clock instead runs its own events in
order of time up to that timer, and stops early at the first event that gives the loop work (a request completed,
a waiter woken). So time advances from one deadline to the next, coroutines (the timeline, the master API) run
unchanged, and nothing ever waits for the wall clock. Real file descriptors (signal wake-ups, a TCP server) are
still polled, without blocking, at least every :data:`SLICE_NS` of simulated time.

Order at equal times is fixed (queue insertion order; the loop's ready callbacks before the clock's events), so a
run is a pure function of its inputs.

Touches: no clock of the operating system: an asyncio loop whose time is the virtual clock's.
"""

from __future__ import annotations

import asyncio
import math
import selectors
from collections.abc import Sized
from typing import Any

from .vqueue import VirtualClock

__all__ = ["VirtualClock", "VirtualEventLoop", "VirtualTimeStalled", "SLICE_NS"]

#: Simulated time between two (non-blocking) polls of the real file descriptors when nothing else stops the clock.
SLICE_NS = 50_000_000


class VirtualTimeStalled(RuntimeError):
    """The loop waits for something, but no timer and no event is left: simulated time cannot advance."""


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
