"""The worker's arrival poll: a socket read in a short busy-poll around the time the next burst of commands is due,
instead of a wake-up when it comes (docs/performance.md).

A master sends its commands once per transmission cycle, so a slave worker knows when the next burst will come:
one cycle after the last. Left to the event loop, the worker sleeps until the burst arrives and is then woken;
on a virtual machine whose idle CPU halts, that wake-up is a large part of a 250 µs cycle, and in stretches it
comes late enough that one read holds two cycles' commands (docs/performance.md, "Timer wake-up").
:class:`ArrivalPoll` learns the cycle from the bursts' arrivals, wakes *lead_ns* before the next one is due (a
timerfd) and reads the socket without blocking until the burst is there, for at most *lead_ns* past its due time;
then the reader (``loop.add_reader``) has it again. A wake-up before the burst costs the worker its spin; a
wake-up when the burst comes costs the chain of the exchange.

Between two empty reads the poll yields its CPU (``os.sched_yield``). The master that sends the burst may be
queued on that very CPU: Linux packs the two processes on one CPU on a small machine, and a spinning worker would
hold the master's cycle up until its poll gave up, a lead past the burst's due time (docs/performance.md,
"Timer wake-up"). Where nothing else is queued, the call returns at once.

The lead adapts: a poll that begins *lead_ns* ahead spins for that long less the timer's own wake-up, so the
poll begins, instead, the timer's late wake-up (the second latest of the last :data:`LATE_SAMPLES`, about p97) plus
:data:`LEAD_MARGIN_NS` ahead, at most *lead_ns*; a burst the reader had instead of the poll sets it back to
*lead_ns*. So the spin is what the timer's lateness asks for and no more, and the bursts are still read in the
poll (docs/performance.md, "Timer wake-up"). Where the CPUs do not halt (``--realtime``'s CPU wake-up latency of
0), the timer is on time and the spin shrinks to the margin.

The learned cycle is the median of the gaps between the last :data:`SAMPLES` bursts (reads less than
:data:`SAME_BURST_NS` apart are one burst). With a ``max_period_ns`` (as "auto" sets) the poll is armed only while
that cycle is at most it: at 1 ms the wake-up is a small part of the cycle, and a poll there did not lower the
missed exchanges at 62 ML-III stations (docs/performance.md). Such a poll also stands down while the kernel holds
the CPU wake-up latency at 0 (``mlink-sim up --realtime``, or any other holder of it; asked once a second): idle CPUs
then poll, the timer wakes the worker on time, and the poll would only cost CPU and hold the master's clock up
(docs/performance.md, "Timer wake-up"). The setting
(``auto``, ``off``, a lead) is parsed by :func:`mlink_sim.config.units.parse_arrival_poll`. "auto" polls from at most
:data:`~mlink_sim.config.units.AUTO_POLL_LEAD_NS` before the burst is due, at cycles up to
:data:`~mlink_sim.config.units.AUTO_POLL_MAX_PERIOD_NS` (500 µs). 80 µs, because a timerfd wakes a halted worker
tens of microseconds late, and the lead must cover that for the poll to read the burst (docs/performance.md,
"Timer wake-up").

Touches a timerfd and the CPU wake-up latency device (read only, :mod:`.realtime`); the socket only through the
*read* callback its owner (the transport's batch endpoint) hands it.
"""

from __future__ import annotations

import asyncio
import time
from collections.abc import Callable

from .timerfd import TimerFD, timerfd_supported
from .realtime import wakeup_latency_limit, yield_after_send

__all__ = ["ArrivalPoll"]

SAMPLES = 16  #: gaps between bursts from which the cycle is learned (their median)
SAME_BURST_NS = 20_000  #: reads closer than this are one burst (the rest of a burst read a moment later)
LATE_SAMPLES = 32  #: polls from whose timer wake-ups the lead is adapted (the second latest of them, about p97)
LEAD_MARGIN_NS = 15_000  #: the lead: that wake-up's lateness and this much more (the shortest lead)
#: how often a poll with a longest cycle ("auto") asks the kernel whether idle CPUs poll (its CPU wake-up latency
#: held at 0: ``realtime.wakeup_latency_limit``); while they do, it stands down
QOS_RECHECK_NS = 1_000_000_000
_mono = time.monotonic_ns


class ArrivalPoll:
    """Polls with *read* (non-blocking: True when it handed a burst over) from *lead_ns* before the next burst is
    due to *lead_ns* after. The owner calls :meth:`arrived` with the time of every burst read (by the poll or by
    the reader); :meth:`close` stops it. *max_period_ns*: poll only while the learned cycle is at most this and
    idle CPUs halt (the kernel does not hold the CPU wake-up latency at 0; asked once a second); None: at any
    cycle, always. :meth:`create` gives None where no timerfd can be made (the reader alone then)."""

    def __init__(self, loop: asyncio.AbstractEventLoop, read: Callable[[], bool], lead_ns: int,
                 max_period_ns: int | None) -> None:
        self._loop = loop
        self._read = read
        self.lead_ns = lead_ns
        self.max_period_ns = max_period_ns
        self.period_ns = 0  #: the cycle learned from the bursts (0: not yet)
        self.windows = 0  #: polls begun
        self.caught = 0  #: of those, the burst read by the poll
        self.spun_ns = 0  #: time spent polling before the burst (or to the end of a window without one)
        self.poll_at_ns = 0  #: when the last poll set begins (monotonic ns)
        self.wake_lead_ns = lead_ns  #: how long before the burst is due the poll begins now (adapted, ≤ *lead_ns*)
        self._lates: list[int] = []
        self._last = 0
        self._due = 0
        self._polling = False
        self._gaps: list[int] = []
        self._until = 0  # the end of the poll set: the due time plus the lead
        self.idle_cpus_poll = False  #: an "auto" poll stands down: the kernel holds the CPU wake-up latency at 0
        self._qos_at = 0  # when an "auto" poll asks that again
        self._tfd: TimerFD | None = TimerFD()  # one timerfd, armed after each burst for the next poll
        self._tfd.watch(loop, self._on_timer)
        self._pause = yield_after_send()  #: os.sched_yield between two empty reads (None where it does not exist)

    @classmethod
    def create(cls, loop: asyncio.AbstractEventLoop, read: Callable[[], bool],
               setting: tuple[int, int | None] | None) -> ArrivalPoll | None:
        """A poll for *setting* (:func:`~mlink_sim.config.units.parse_arrival_poll`); None for off or where timerfd is missing."""
        if setting is None or not timerfd_supported():
            return None
        return cls(loop, read, *setting)

    @property
    def armed(self) -> bool:
        """True while a next burst's poll is set (a cycle learned and within ``max_period_ns``)."""
        return self._due > 0

    def arrived(self, now_ns: int) -> None:
        """A burst was read at *now_ns*: learn the cycle, and set the poll for the next one."""
        last = self._last
        if now_ns - last < SAME_BURST_NS:
            return
        self._last = now_ns
        if last:
            gaps = self._gaps
            gaps.append(now_ns - last)
            if len(gaps) == SAMPLES:
                gaps.sort()
                self.period_ns = gaps[SAMPLES // 2]
                gaps.clear()
        period, tfd, longest = self.period_ns, self._tfd, self.max_period_ns
        if longest is not None and period and now_ns >= self._qos_at:
            self._qos_at = now_ns + QOS_RECHECK_NS
            self.idle_cpus_poll = wakeup_latency_limit() == 0
        if tfd is None or not period or (longest is not None and (period > longest or self.idle_cpus_poll)):
            self._due = 0
            return
        lead = min(self.lead_ns, period // 2)
        due = self._due
        if due and not self._polling:  # the reader had it, not the poll: back to the full lead, learn again
            self.wake_lead_ns = self.lead_ns
            self._lates.clear()
        # Read by the reader a little after it was due: the burst most likely came on time and the wake-up was late,
        # so the next is due a cycle after this one was; read in the poll, or far from its time: a cycle after now.
        anchor = due if due and not self._polling and 0 <= now_ns - due <= lead else now_ns
        self._due = anchor + period
        self._until = self._due + lead
        self.poll_at_ns = self._due - min(self.wake_lead_ns, lead)
        tfd.set_abs(self.poll_at_ns)

    def _on_timer(self) -> None:
        if not self._due:
            return
        self.windows += 1
        read = self._read
        start = now = _mono()
        self.woke(start - self.poll_at_ns)
        end = self._until
        self._polling = True
        pause = self._pause
        try:
            while now < end:
                if read():
                    self.caught += 1
                    break
                if pause is not None:
                    pause()
                now = _mono()
        finally:
            self._polling = False
        self.spun_ns += now - start

    def woke(self, late_ns: int) -> None:
        """A poll's timer woke the worker *late_ns* after it was set for: every :data:`LATE_SAMPLES` polls the lead
        becomes the second latest of their wake-ups (≈ p97) plus :data:`LEAD_MARGIN_NS`, at most *lead_ns*."""
        lates = self._lates
        lates.append(late_ns)
        if len(lates) == LATE_SAMPLES:
            lates.sort()
            self.wake_lead_ns = min(self.lead_ns, max(0, lates[-2]) + LEAD_MARGIN_NS)
            lates.clear()

    def stats(self) -> dict[str, int]:
        """The poll's counters, for the worker's stats."""
        return {"period_ns": self.period_ns, "windows": self.windows, "caught": self.caught,
                "spun_ns": self.spun_ns, "lead_ns": self.wake_lead_ns, "idle_cpus_poll": int(self.idle_cpus_poll)}

    def close(self) -> None:
        tfd, self._tfd = self._tfd, None
        self._due = 0
        if tfd is not None:
            tfd.close_watched(self._loop)
