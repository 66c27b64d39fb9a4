"""One read of a socket's waiting datagrams per cycle, ahead of the cycle's deadline (docs/performance.md, "Fewer
wake-ups of the master").

A reader whose datagrams carry the kernel's receive timestamps (``mmsg.BurstSocket.recv_burst_stamped``) need not
be woken by each of them: the time each came is kept. The master then reads its answers at the clock's wake-up,
in its spin and at each cycle's start. Left to those reads alone, the answers of a whole cycle would be decoded
just before the next cycle's commands go out, on the cycle's critical path. :class:`PreRead` adds one wake-up per
cycle at a fixed point before the next deadline (a quarter period by default), so most answers are decoded
there: two wake-ups per cycle (this one and the clock's) at any number of stations, where a reader woken by
every answer wakes up to once per answer.
"""

from __future__ import annotations

import asyncio
from collections.abc import Callable
from typing import Any

from . import mmsg
from ._timerfd import TimerFD, timerfd_supported

__all__ = ["PreRead"]


class PreRead:
    """Calls *read* once per cycle of *period_ns*, *lead_ns* before the next deadline (a Linux timerfd watched by
    *loop*). :meth:`arm_after` after each cycle's commands; :meth:`close` to stop. Where no timerfd can be made,
    :meth:`create` gives None and the caller keeps its reads at the clock's wake-up."""

    def __init__(self, loop: asyncio.AbstractEventLoop, read: Callable[[], None], lead_ns: int,
                 period_ns: int) -> None:
        self._loop = loop
        self.lead_ns = lead_ns
        self._after = period_ns - lead_ns  # from a cycle's deadline to the next cycle's pre-read
        self._tfd: TimerFD | None = TimerFD()
        self._tfd.watch(loop, read)

    @classmethod
    def create(cls, loop: asyncio.AbstractEventLoop, read: Callable[[], None], period_ns: int,
               spin_ns: int = 0) -> PreRead | None:
        """A pre-read a quarter *period_ns* before each deadline; None where it would fall inside the clock's spin
        (*spin_ns*: the spin reads then anyway) or no timerfd is available."""
        lead = period_ns // 4
        if lead <= spin_ns or not timerfd_supported():
            return None
        return cls(loop, read, lead, period_ns)

    @classmethod
    def for_stamped(cls, loop: asyncio.AbstractEventLoop, sock: Any, read: Callable[[], None], period_ns: int,
                    spin_ns: int = 0) -> PreRead | None:
        """The reader's choice, made in one place (the master, ``scripts/bench_floor.py``'s client): a pre-read
        calling *read*, with *sock*'s kernel stamps switched on, where :func:`mmsg.stamps_enabled
        <mlink_sim.aio.mmsg.stamps_enabled>` (``MLINK_RX_STAMPS=1``), *sock* can stamp (``enable_stamps``) and
        :meth:`create` gives one; else None, and the caller reads on every arrival."""
        enable = getattr(sock, "enable_stamps", None)
        if enable is None or not mmsg.stamps_enabled():
            return None
        pre = cls.create(loop, read, period_ns, spin_ns)
        if pre is not None and not enable():
            pre.close()
            return None
        return pre

    def arm(self, next_deadline_ns: int) -> None:
        """The read, *lead_ns* before *next_deadline_ns* (replacing one armed before)."""
        tfd = self._tfd
        if tfd is not None:
            tfd.set_abs(next_deadline_ns - self.lead_ns)

    def arm_after(self, deadline_ns: int) -> None:
        """The read before the deadline one period after *deadline_ns* (the cycle whose commands just went out)."""
        tfd = self._tfd
        if tfd is not None:
            tfd.set_abs(deadline_ns + self._after)

    def close(self) -> None:
        tfd, self._tfd = self._tfd, None
        if tfd is not None:
            tfd.close_watched(self._loop)
