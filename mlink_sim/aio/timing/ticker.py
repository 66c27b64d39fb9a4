"""Cycle wake-up source for the master's transmission cycle (250 µs … 8 ms).

:class:`CycleTimer` calls ``on_cycle(cycle, deadline_ns, now_ns, skipped)`` in the event-loop thread once per
period against absolute deadlines ``deadline_k = start_ns + k * period_ns`` on the ``time.monotonic_ns()``
clock. Deadlines are computed by integer addition from ``start_ns``, never from "now", so error never
accumulates: whatever the wake-up jitter, cycle ``k`` is always due at exactly ``start_ns + k * period_ns``.

Wake-up sources (``strategy``), measured in ``docs/timing.md``:

* ``"call_at"``  – ``loop.call_later``; on uvloop timers are whole milliseconds (libuv), on asyncio the
  selector timeout is rounded up to 1 ms by ``epoll_wait``.
* ``"timerfd"``  – a Linux ``timerfd`` (``CLOCK_MONOTONIC``, ``TFD_TIMER_ABSTIME``) watched with
  ``loop.add_reader``; hrtimer precision, no timer slack.
* ``"<source>+spin"`` – the source is armed ``spin_ns`` before the deadline and the last stretch is a busy
  spin on ``time.monotonic_ns()``. With ``spin_ns=None`` the spin adapts: it tracks the 99th percentile of the
  source's wake-up error (streaming quantile estimate) plus a margin, clamped to ``spin_max_ns``.
* ``"auto"``     – ``"timerfd+spin"`` where a timerfd can be created, else ``"call_at+spin"``.

Invariant at every on-time call: ``deadline_ns <= now_ns < deadline_ns + period_ns``. If whole periods went by
(a host stall: blocked loop, long callback, a descheduled process), either

* the calls for them are made at once, in order, each with its own (past) deadline, ``skipped = 0`` and the time
  its own call begins as ``now_ns`` (its commands' round trips count from when they go out), when
  the stall is no longer than ``catch_up_ns`` (the host-stall policy ``absorb``, docs/timing.md); or
* they are not made (``catch_up_ns = 0``, the policy ``strict``, or a longer stall): the next call is for the
  most recent deadline, ``skipped`` says how many were dropped, and the one after is on the next future deadline.

Either way ``on_stall(deadline_ns, now_ns, cycles_behind, absorbed)`` is told once per such wake-up. Between two
cycles run back to back the clock yields its CPU once (``os.sched_yield``,
:func:`~mlink_sim.aio.timing.realtime.yield_after_send`): a cycle's send woke its slaves on this CPU, and without the
yield they wait behind the whole catch-up (docs/timing.md, "The catch-up yields").

Touches: a timerfd (or the loop's own timers) and the CPU it spins on; calls back into its owner only.
"""

from __future__ import annotations

import asyncio
import time
from collections.abc import Callable

from ..._log import get_logger
from .timerfd import TimerFD, timerfd_supported
from .realtime import yield_after_send

__all__ = ["CycleTimer", "available_strategies", "STRATEGIES"]

STRATEGIES: tuple[str, ...] = ("call_at", "call_at+spin", "timerfd", "timerfd+spin")

OnCycle = Callable[[int, int, int, int], None]
#: ``on_stall(deadline_ns, now_ns, cycles_behind, absorbed)``: a wake-up came whole periods after its deadline
OnStall = Callable[[int, int, int, bool], None]

_mono = time.monotonic_ns

# Adaptive spin (strategy "...+spin", spin_ns=None). Starting points are the sources' measured wake-up error
# on the 2-core bench machine (docs/timing.md); the estimator then follows the machine it runs on.
_SPIN_INIT_NS = {"call_at": 1_100_000, "timerfd": 60_000}
_SPIN_MARGIN_NS = 10_000          # added to the p99 estimate of the wake-up error
_SPIN_MIN_NS = 10_000
_Q_UP_NS = 2_000                  # quantile estimator step when a wake-up error exceeds the estimate ...
_Q_DOWN_NS = _Q_UP_NS // 99       # ... and when it does not: equilibrium at P(err > q) = 1 %
_ERRORS_LOGGED_IN_FULL = 10       # then only when the error count is a power of two


_timerfd_ok: bool | None = None


def learn_wake_error(q: int, error_ns: int, cap_ns: int) -> int:
    """The adaptive spin's estimate of the wake-up source's 99th-percentile error, *q*, after one wake-up *error_ns*
    late (from the armed target): up by ``_Q_UP_NS`` when above it, down by ``_Q_DOWN_NS`` when not (equilibrium at
    1 % above); it stops rising at *cap_ns* (an overload leaves no huge estimate behind; the spin itself is clamped
    to the cap). Called once per wake-up, on the clock's hot path: a few compares. An error beyond *cap_ns* leaves
    it as it is: that is a stall of the host or of this loop, not the source's error, and no spin up to the cap
    could have covered it; counted, a host that stalls twice a second drives the spin to its cap (docs/timing.md,
    "What the spin learns from")."""
    if error_ns <= q:
        return q - _Q_DOWN_NS if q > _Q_DOWN_NS else q
    if error_ns <= cap_ns and q < cap_ns:
        return q + _Q_UP_NS
    return q


def available_strategies() -> list[str]:
    """Strategies the running kernel and loop offer (``"auto"`` is always accepted as well)."""
    global _timerfd_ok
    if _timerfd_ok is None:
        _timerfd_ok = timerfd_supported()
    return [s for s in STRATEGIES if _timerfd_ok or not s.startswith("timerfd")]


def _resolve(strategy: str) -> str:
    if strategy == "auto":
        return "timerfd+spin" if "timerfd" in available_strategies() else "call_at+spin"
    if strategy not in STRATEGIES:
        raise ValueError(f"unknown strategy {strategy!r}; expected 'auto' or one of {STRATEGIES}")
    if strategy not in available_strategies():
        raise ValueError(f"strategy {strategy!r} is not available on this machine")
    return strategy


def _is_uvloop(loop: asyncio.AbstractEventLoop) -> bool:
    return type(loop).__module__.partition(".")[0] == "uvloop"


class CycleTimer:
    """Calls ``on_cycle(cycle, deadline_ns, now_ns, skipped)`` once per period against absolute deadlines.

    ``deadline_k = start_ns + k * period_ns`` (``time.monotonic_ns`` clock; ``start_ns`` defaults to one period
    after :meth:`start`). If the loop was so late that whole periods passed, those cycles are run at once, late
    and in order, when the stall is at most ``catch_up_ns``; otherwise they are skipped and ``skipped`` says how
    many, and the next call is on the next future deadline. ``on_stall`` hears of every such stall. ``on_cycle`` runs
    in the event-loop thread; an exception from it is logged (structlog, ``on_cycle_failed``) and counted in
    :attr:`errors`, and the timer continues.

    ``strategy``: one of :data:`STRATEGIES` or ``"auto"`` (see the module docstring). ``spin_ns``: fixed busy-spin
    budget for a ``"+spin"`` strategy (``None`` = adaptive, ``0`` = none). ``spin_max_ns``: cap of the adaptive
    spin (default: one period for ``call_at+spin``, half a period otherwise).
    ``loop``: defaults to the running loop at :meth:`start`. ``idle``: called over and over while spinning, so the
    spin does useful work (the master reads the responses that arrive meanwhile); it must be short and must not
    raise.
    """

    def __init__(self, period_ns: int, on_cycle: OnCycle, *, loop: asyncio.AbstractEventLoop | None = None,
                 strategy: str = "auto", spin_ns: int | None = None, start_ns: int | None = None,
                 spin_max_ns: int | None = None, idle: Callable[[], None] | None = None,
                 catch_up_ns: int = 0, on_stall: OnStall | None = None) -> None:
        period_ns = int(period_ns)
        if period_ns <= 0:
            raise ValueError("period_ns must be positive")
        if catch_up_ns < 0:
            raise ValueError("catch_up_ns must be >= 0")
        self._catch_up = int(catch_up_ns)
        self.on_stall = on_stall  #: called once per wake-up that comes whole periods late (see the class docstring)
        self._strategy = _resolve(strategy)
        self._source, _, spin = self._strategy.partition("+")
        if spin_ns is not None and spin_ns < 0:
            raise ValueError("spin_ns must be >= 0")
        if not spin and spin_ns:
            raise ValueError(f"spin_ns needs a '+spin' strategy, got {self._strategy!r}")
        self._period = period_ns
        self._on_cycle = on_cycle
        self.idle = idle  #: called repeatedly during the spin (see the class docstring)
        self._loop = loop
        self._start_ns = start_ns
        # call_at's error is about a millisecond, so let its spin cover a whole period if need be.
        default_max = period_ns if self._source == "call_at" else period_ns // 2
        self._spin_max = min(period_ns, default_max if spin_max_ns is None else int(spin_max_ns))
        self._adaptive = bool(spin) and spin_ns is None
        if not spin:
            self._q = 0
        elif spin_ns is None:
            self._q = _SPIN_INIT_NS[self._source]
        else:
            self._q = int(spin_ns)
        if self._adaptive:
            self._spin = self._clamp_spin(self._q + _SPIN_MARGIN_NS)
        else:
            self._spin = min(self._spin_max, self._q)

        self._running = False
        self._started = False
        self._next_k = 0
        self._cycle = -1
        self._deadline = 0
        self._target = 0
        self._skipped_total = 0
        self._caught_up_total = 0
        self._errors = 0
        self._spun_ns = 0
        #: called between two cycles of a catch-up (os.sched_yield; None where it does not exist)
        self._between = yield_after_send()
        # lazy proxy with bound context: resolved per call, so it follows later structlog.configure()
        self._log = get_logger(__name__, strategy=self._strategy, period_ns=period_ns)
        # per-source resources
        self._handle: asyncio.TimerHandle | asyncio.Handle | None = None
        self._tfd: TimerFD | None = None
        self._coarse = False
        self._arm: Callable[[int], None] = self._arm_call_at

    # ------------------------------------------------------------------ public
    @property
    def period_ns(self) -> int:
        return self._period

    @property
    def cycle(self) -> int:
        """Number of the last cycle passed to ``on_cycle`` (-1 before the first)."""
        return self._cycle

    @property
    def strategy(self) -> str:
        """The resolved strategy (never ``"auto"``)."""
        return self._strategy

    @property
    def start_ns(self) -> int | None:
        return self._start_ns

    @property
    def next_deadline_ns(self) -> int:
        return self._deadline

    @property
    def skipped_total(self) -> int:
        return self._skipped_total

    @property
    def caught_up_total(self) -> int:
        """Cycles run late, after a stall within ``catch_up_ns``, instead of being skipped."""
        return self._caught_up_total

    @property
    def spun_ns(self) -> int:
        """Time spent in the spin before the deadlines so far (ns, the ``idle`` calls included): busy CPU that
        keeps the clock's precision, for a benchmark to tell apart from the work per exchange."""
        return self._spun_ns

    @property
    def errors(self) -> int:
        return self._errors

    @property
    def spin_ns(self) -> int:
        """Current busy-spin budget before each deadline (0 without '+spin')."""
        return self._spin

    @property
    def running(self) -> bool:
        return self._running

    def start(self) -> None:
        """Arm the first deadline. Must be called from the loop's thread; a timer runs once (no restart)."""
        if self._started:
            raise RuntimeError("CycleTimer.start() called twice (a stopped timer is not restartable)")
        loop = self._loop if self._loop is not None else asyncio.get_running_loop()
        self._loop = loop
        src = self._source
        if src == "timerfd":  # one timerfd, armed after each wake-up for the next
            self._tfd = TimerFD()
            self._tfd.watch(loop, self._on_wake)
            self._arm = self._tfd.set_abs
        else:
            self._coarse = _is_uvloop(loop)
            self._arm = self._arm_call_at
        self._started = self._running = True
        if self._start_ns is None:
            self._start_ns = _mono() + self._period
        self._deadline = self._start_ns
        self._target = self._deadline - self._spin
        self._arm(self._target)
        self._log.debug("cycle_timer_started", start_ns=self._start_ns, spin_ns=self._spin)

    def stop(self) -> None:
        """Stop calling ``on_cycle`` and release the timerfd. Idempotent; safe from inside ``on_cycle``."""
        if not self._running:
            return
        self._running = False
        if self._handle is not None:
            self._handle.cancel()
            self._handle = None
        tfd, self._tfd = self._tfd, None
        if tfd is not None:
            tfd.close_watched(self._loop)
        self._log.debug("cycle_timer_stopped", cycle=self._cycle, skipped_total=self._skipped_total,
                        errors=self._errors)

    # ------------------------------------------------------------------ sources
    def _arm_call_at(self, target_ns: int) -> None:
        self._handle = self._loop.call_later((target_ns - _mono()) / 1e9, self._on_wake)  # type: ignore[union-attr]

    def _rearm_early(self, target_ns: int, now_ns: int) -> None:
        # Only call_at wakes early (uvloop: ms rounding against libuv's ms clock). Re-arm, rounding the
        # delay *up* to uvloop's 1 ms granularity so that it does not degenerate into spinning through the loop.
        if self._source != "call_at":
            self._arm(target_ns)
            return
        delay = target_ns - now_ns
        if self._coarse:
            delay = -(-delay // 1_000_000) * 1_000_000
        self._handle = self._loop.call_later(delay / 1e9, self._on_wake)  # type: ignore[union-attr]

    # ------------------------------------------------------------------ hot path
    def _clamp_spin(self, spin: int) -> int:
        return min(self._spin_max, max(_SPIN_MIN_NS, spin))

    def _on_wake(self) -> None:
        if not self._running:
            return
        self._handle = None
        mono = _mono
        now = mono()
        d = self._deadline
        if now < d and d - now > self._spin:
            self._rearm_early(d - self._spin, now)
            return
        if self._adaptive:
            self._q = q = learn_wake_error(self._q, now - self._target, self._spin_max)
            self._spin = self._clamp_spin(q + _SPIN_MARGIN_NS)
        idle = self.idle
        spin_from = now
        if idle is None:
            while now < d:
                now = mono()
        else:
            while now < d:
                idle()
                now = mono()
        self._spun_ns += now - spin_from
        period = self._period
        k = self._next_k
        skipped = 0
        if now - d >= period:
            behind = (now - d) // period
            absorbed = now - d <= self._catch_up
            on_stall = self.on_stall
            if on_stall is not None:
                on_stall(d, now, behind, absorbed)
            if absorbed:  # host-stall policy "absorb": the missed cycles run now, late but in order
                self._caught_up_total += behind
                between = self._between
                for _ in range(behind):
                    self._run(k, d, now, 0)
                    if not self._running:
                        return
                    k += 1
                    d += period
                    if between is not None:  # the slaves this cycle's send woke run now, not after the catch-up
                        between()
                    now = mono()  # each cycle starts when it runs: its commands' round trips count from there
            else:
                skipped = behind
                k += skipped
                d += skipped * period
                self._skipped_total += skipped
        self._run(k, d, now, skipped)
        if not self._running:
            return
        self._next_k = k + 1
        d += period
        self._deadline = d
        self._target = t = d - self._spin
        self._arm(t)

    def _run(self, k: int, d: int, now: int, skipped: int) -> None:
        self._cycle = k
        try:
            self._on_cycle(k, d, now, skipped)
        except Exception:  # noqa: BLE001 - the cycle must go on; logged and counted
            self._on_error(k)

    def _on_error(self, cycle: int) -> None:
        self._errors += 1
        n = self._errors
        if n <= _ERRORS_LOGGED_IN_FULL or not n & (n - 1):
            self._log.exception("on_cycle_failed", cycle=cycle, errors_total=n)
