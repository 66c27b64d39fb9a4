"""The slack of a cycle: the time between the cycle's last answer and the clock's next wake-up, where the work that is
not the cycle's runs (docs/timing.md, "Work beside the cycle").

A running network does more than its cycles: it builds the status a page or ``mlink-sim status`` asks for, samples
its trace, reads the slave workers' snapshots. Each of those is cut into steps of a fraction of a millisecond; run at
any moment, a step delays the answers that arrive while it runs (the master reads them only after it), which is
the RTT tail an open page would cost. Run in the slack, a step delays nothing: every answer of the cycle is in, and
the clock's next wake-up is further off than the step takes.

    slack = Slack()
    slack.open(until_ns)          # the masters: this cycle's answers are in; free until the clock's next wake-up
                                  # (each master's AnswersIn says when its own are)
    step = Step()                 # one kind of step: how long it takes
    await slack.wait(step.need_ns)
    with step:                    # a step of beside-the-cycle work, inside a slack it fits in
        ...

:meth:`Slack.wait` returns at once while the slack lasts at least *need_ns* more, else when the next one opens; a
waiter no slack opened for within :data:`MAX_WAIT_S` runs all the same (a network whose answers never all come: a
station gone, a master stopped), so that nothing waits for ever. ``Slack(always=True)`` is open all the time: the
virtual clock, whose cycles take no wall time.

Touches: nothing; the time (``time.monotonic_ns``) and the event loop's futures.
"""

from __future__ import annotations

import asyncio
import time
from collections.abc import Callable
from typing import Final

__all__ = ["Slack", "Step", "AnswersIn", "MAX_WAIT_S", "MARGIN_NS"]

#: A step waits for a slack at most this long, then runs (a cycle whose answers never all come)
MAX_WAIT_S: Final = 0.05
#: What a slack leaves before the clock's next wake-up: the clock's own timer and the loop's turn
MARGIN_NS: Final = 30_000
#: What a kind of step is taken to need before it first ran, and the most it is taken to need (a step a host stall
#: made long would otherwise wait for a slack no cycle has)
FIRST_NEED_NS: Final = 50_000
MOST_NEED_NS: Final = 300_000


class Slack:
    """See the module docstring. *always*: the slack is always open (no cycle to keep free)."""

    def __init__(self, *, always: bool = False, max_wait_s: float = MAX_WAIT_S) -> None:
        self.always = always
        self.max_wait_s = max_wait_s  #: a step runs after this long without a slack
        self.until_ns = 0  #: the slack lasts until then (monotonic ns); past it, it is closed
        self.opened = 0  #: slacks opened
        self.waited_out = 0  #: steps that ran because no slack opened in time (max_wait_s)
        self._waiters: list[asyncio.Future[bool]] = []

    def open(self, until_ns: int) -> None:
        """The cycle's answers are in: work may run until *until_ns* (the clock's next wake-up, less a margin)."""
        self.until_ns = until_ns
        self.opened += 1
        waiters = self._waiters
        if waiters:
            self._waiters = []
            for fut in waiters:
                if not fut.done():
                    fut.set_result(True)

    def left_ns(self) -> int:
        """How much of the slack is left now (0: none, or it is closed)."""
        left = self.until_ns - time.monotonic_ns()
        return left if left > 0 else 0

    async def wait(self, need_ns: int = 0) -> None:
        """Return inside a slack with at least *need_ns* left (what the step to follow takes), at once where this
        one has it; at the latest after :attr:`max_wait_s`. The loop turns once either way."""
        if self.always:
            await asyncio.sleep(0)
            return
        loop = asyncio.get_running_loop()
        deadline = loop.time() + self.max_wait_s
        while True:
            if self.left_ns() > need_ns:
                await asyncio.sleep(0)
                if self.left_ns() > need_ns:  # the turn took little: the slack still holds the step
                    return
            remaining = deadline - loop.time()
            if remaining <= 0:
                self.waited_out += 1
                return
            # A future and a timer, not ``asyncio.wait_for``: on Python 3.11 wait_for returns the result instead of
            # raising when the task is cancelled in the turn its future is done, and a slack opens every cycle, so
            # a sampler told to stop would go on sampling.
            fut: asyncio.Future[bool] = loop.create_future()
            self._waiters.append(fut)
            timer = loop.call_later(remaining, _expire, fut)
            try:
                opened = await fut
            finally:
                timer.cancel()
            if not opened:
                self.waited_out += 1
                return


def _expire(fut: asyncio.Future[bool]) -> None:
    """No slack opened in time: the waiter runs all the same."""
    if not fut.done():
        fut.set_result(False)


class Step:
    """How long one kind of step takes (:attr:`need_ns`, what it asks :meth:`Slack.wait` for): the longest of the
    recent ones, each step timed as a ``with`` block; it decays by a sixteenth a step, so that one long step (a
    host stall in it) does not count for ever, and it is bounded by :data:`MOST_NEED_NS`."""

    __slots__ = ("need_ns", "_t0")

    def __init__(self, need_ns: int = FIRST_NEED_NS) -> None:
        self.need_ns = need_ns
        self._t0 = 0

    def __enter__(self) -> Step:
        self._t0 = time.monotonic_ns()
        return self

    def __exit__(self, *exc: object) -> None:
        took = time.monotonic_ns() - self._t0
        decayed = self.need_ns - (self.need_ns >> 4)
        self.need_ns = min(MOST_NEED_NS, took if took > decayed else decayed)


class AnswersIn:
    """When a master's cycle has its answers: :meth:`expect` after the cycle's commands went, :meth:`answered` for
    each read; :attr:`hook` is called once a cycle, when they are in. The answers of the stations that did not
    answer the cycle before are not waited for (a station gone or held up); one that comes back answers early once,
    and is waited for again from then on."""

    __slots__ = ("hook", "_awaiting", "_silent", "_told")

    def __init__(self) -> None:
        self.hook: Callable[[], None] | None = None  #: None: nobody asks
        self._awaiting = 0  # answers of this cycle still to come
        self._silent = 0  # stations that did not answer in the cycles before: not waited for
        self._told = True  # the hook was called for this cycle

    def expect(self, sent: int) -> None:
        """This cycle's *sent* commands were sent: their answers are awaited (but the silent stations')."""
        left = self._awaiting
        if not self._told:
            self._silent += left  # the last cycle's answers that did not come
        elif left < 0:
            self._silent = max(0, self._silent + left)  # more came than were awaited: stations back
        self._awaiting = sent - self._silent
        self._told = False
        if self._awaiting <= 0:
            self.answered(0)

    def answered(self, n: int) -> None:
        """*n* answers were read: once this cycle's are in, :attr:`hook` hears of it (once a cycle)."""
        self._awaiting -= n
        if self._awaiting <= 0 and not self._told:
            self._told = True
            hook = self.hook
            if hook is not None:
                hook()
