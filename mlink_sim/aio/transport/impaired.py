"""The impairment layer on a real socket (docs/faults.md): :class:`DelayLine` holds delayed datagrams until
their time (a one-shot timerfd, so a 300 µs delay is 300 µs and not the loop's 1 ms timer resolution), and
:class:`ImpairedSocket` stands in for the master's UDP socket while an impairment is active.

The master's socket is wrapped only while the layer has a fault (``Master.impair_with``): with no impairment,
datagrams take the master's own path and the layer costs nothing. Once every fault has ended and nothing is
held any more, the wrapper puts the master's socket back.

Touches: the socket it wraps and a timerfd for the delayed datagrams.
"""

from __future__ import annotations

import asyncio
import heapq
import itertools
import time
from collections import deque
from collections.abc import Callable
from typing import Any

from ...impair import Direction, ImpairmentLayer
from ..timing.timerfd import TimerFD, timerfd_supported
from .ports import DatagramPort

__all__ = ["DelayLine", "ImpairedSocket"]

_mono = time.monotonic_ns


class DelayLine:
    """Items due at a monotonic time: ``push(at_ns, item)``; *on_due(now)* is called when the earliest is due,
    and takes them with :meth:`pop_due`. Woken by a timerfd where there is one, else by ``loop.call_at``."""

    def __init__(self, loop: asyncio.AbstractEventLoop, on_due: Callable[[int], None]) -> None:
        self._loop = loop
        self._on_due = on_due
        self._heap: list[tuple[int, int, Any]] = []
        self._seq = itertools.count()  # equal times keep their order (a duplicate right behind its original)
        self._armed: int | None = None
        self._handle: asyncio.TimerHandle | None = None
        self._fd: TimerFD | None = None
        if timerfd_supported():
            self._fd = TimerFD()
            loop.add_reader(self._fd.fileno(), self._on_timer)

    def __len__(self) -> int:
        return len(self._heap)

    def push(self, at_ns: int, item: Any) -> None:
        heapq.heappush(self._heap, (at_ns, next(self._seq), item))
        if self._armed is None or at_ns < self._armed:
            self._arm(at_ns)

    def pop_due(self, now: int) -> list[Any]:
        """The items due by *now*, in order of time (and of pushing)."""
        heap = self._heap
        out = []
        while heap and heap[0][0] <= now:
            out.append(heapq.heappop(heap)[2])
        if out:
            self._armed = None
            if heap:
                self._arm(heap[0][0])
        return out

    def _arm(self, at_ns: int) -> None:
        self._armed = at_ns
        if self._fd is not None:
            self._fd.set_abs(at_ns)
        else:
            if self._handle is not None:
                self._handle.cancel()
            self._handle = self._loop.call_at(at_ns / 1e9, self._on_timer)

    def _on_timer(self) -> None:
        if self._fd is not None:
            self._fd.drain()
        self._armed = None
        now = _mono()
        self._on_due(now)
        if self._heap and self._armed is None:
            self._arm(self._heap[0][0])

    def close(self) -> None:
        self._heap.clear()
        if self._handle is not None:
            self._handle.cancel()
        fd, self._fd = self._fd, None
        if fd is not None:
            try:
                self._loop.remove_reader(fd.fileno())
            except (RuntimeError, ValueError, OSError):
                pass
            fd.close()


class ImpairedSocket:
    """The master's socket seen through an :class:`~mlink_sim.impair.ImpairmentLayer`: ``sendto`` puts commands
    through the layer (to-station), ``recv`` puts responses through it (to-master). Delayed datagrams wait in a
    :class:`DelayLine`; a delayed response is handed to *on_ready* (the master's ``read_responses``) when due.
    *on_error* counts a send that failed later (the master's transport errors); *on_idle* is called once every
    fault has ended and nothing is held (the master then takes its own socket back)."""

    def __init__(self, sock: DatagramPort, layer: ImpairmentLayer, loop: asyncio.AbstractEventLoop, *,
                 on_ready: Callable[[], None], on_error: Callable[[Exception], None],
                 on_idle: Callable[[], None]) -> None:
        self.sock = sock
        self.layer = layer
        self._ready: deque[bytes] = deque()
        self._on_ready = on_ready
        self._on_error = on_error
        self._on_idle = on_idle
        self._line = DelayLine(loop, self._due)
        self._idle = False  #: on_idle was called: the master has its own socket back

    # -- the socket interface the master uses -----------------------------------------------------------------
    def sendto(self, data: bytes, addr: Any) -> int:
        now = _mono()
        layer = self.layer
        items = layer.process(data, Direction.TO_STATION, data[3] if len(data) > 3 else -1, now) \
            if layer.active else [(0, data)]
        for delay, out in items:
            if delay <= 0:
                self.sock.sendto(out, addr)
            else:
                self._line.push(now + delay, (addr, out))
        self._maybe_idle()
        return len(data)

    def recv(self, bufsize: int) -> bytes:
        ready = self._ready
        while not ready:
            data = self.sock.recv(bufsize)  # BlockingIOError: nothing waiting
            layer = self.layer
            if not layer.active:
                return data
            now = _mono()
            for delay, out in layer.process(data, Direction.TO_MASTER, data[3] if len(data) > 3 else -1, now):
                if delay <= 0:
                    ready.append(out)
                else:
                    self._line.push(now + delay, (None, out))
        return ready.popleft()

    def fileno(self) -> int:
        return self.sock.fileno()

    def getsockname(self) -> Any:
        return self.sock.getsockname()

    def close(self) -> None:
        self._line.close()
        self.sock.close()

    # -- held datagrams ---------------------------------------------------------------------------------------
    def _due(self, now: int) -> None:
        got_response = False
        for addr, data in self._line.pop_due(now):
            if addr is None:
                self._ready.append(data)
                got_response = True
            else:
                try:
                    self.sock.sendto(data, addr)
                except OSError as exc:
                    self._on_error(exc)
        if got_response:
            self._on_ready()
        self.layer.expire(now)
        self._maybe_idle()

    def _maybe_idle(self) -> None:
        if not self._idle and not self.layer.active and not self._line and not self._ready:
            self._idle = True
            self._line.close()
            self._on_idle()
