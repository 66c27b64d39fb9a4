"""ctypes bindings for Linux timerfd and per-thread timer slack (private helper of :mod:`.ticker`).

Python 3.11 has no ``os.timerfd_create`` (added in 3.13), so this calls libc directly:
``timerfd_create(CLOCK_MONOTONIC, TFD_NONBLOCK | TFD_CLOEXEC)`` and
``timerfd_settime(fd, TFD_TIMER_ABSTIME, ...)``. ``CLOCK_MONOTONIC`` is the clock behind
``time.monotonic_ns()`` (``time.get_clock_info("monotonic")``), so deadlines are passed through unchanged.

Constants are the Linux UAPI values (``<sys/timerfd.h>``, ``<linux/time.h>``, ``<linux/prctl.h>``);
they are the same on every Linux architecture CPython supports except ``TFD_NONBLOCK``/``TFD_CLOEXEC``,
which equal ``O_NONBLOCK``/``O_CLOEXEC`` and are therefore taken from :mod:`os`.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import errno
import os
import sys
import time
from collections.abc import Callable
from typing import Any

__all__ = ["TimerFD", "LookaheadTimer", "timerfd_supported", "set_thread_timer_slack", "make_abs_sleeper"]

CLOCK_MONOTONIC = 1
TFD_TIMER_ABSTIME = 1
TIMER_ABSTIME = 1
_EINTR = errno.EINTR
PR_SET_TIMERSLACK = 29
_NS = 1_000_000_000


class _Timespec(ctypes.Structure):
    _fields_ = [("tv_sec", ctypes.c_long), ("tv_nsec", ctypes.c_long)]


class _Itimerspec(ctypes.Structure):
    _fields_ = [("it_interval", _Timespec), ("it_value", _Timespec)]


def _load_libc() -> ctypes.CDLL | None:
    if not sys.platform.startswith("linux"):
        return None
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6", use_errno=True)
        libc.timerfd_create.argtypes = [ctypes.c_int, ctypes.c_int]
        libc.timerfd_create.restype = ctypes.c_int
        libc.timerfd_settime.argtypes = [
            ctypes.c_int, ctypes.c_int, ctypes.POINTER(_Itimerspec), ctypes.POINTER(_Itimerspec)]
        libc.timerfd_settime.restype = ctypes.c_int
        libc.prctl.argtypes = [ctypes.c_int, ctypes.c_ulong, ctypes.c_ulong, ctypes.c_ulong, ctypes.c_ulong]
        libc.prctl.restype = ctypes.c_int
    except (OSError, AttributeError):
        return None
    return libc


_libc = _load_libc()


class TimerFD:
    """A one-shot absolute CLOCK_MONOTONIC timerfd. Not thread-safe; owned by the event-loop thread."""

    __slots__ = ("_fd", "_spec", "_ref", "_settime", "_value")

    def __init__(self) -> None:
        if _libc is None:
            raise OSError("timerfd is not available on this platform")
        fd = _libc.timerfd_create(CLOCK_MONOTONIC, os.O_NONBLOCK | os.O_CLOEXEC)
        if fd < 0:
            err = ctypes.get_errno()
            raise OSError(err, os.strerror(err))
        self._fd = fd
        self._spec = _Itimerspec()  # it_interval stays 0: one-shot
        self._ref = ctypes.byref(self._spec)
        self._value = self._spec.it_value
        self._settime = _libc.timerfd_settime

    def fileno(self) -> int:
        return self._fd

    def set_abs(self, deadline_ns: int) -> None:
        """Arm to expire at ``deadline_ns`` (monotonic). A deadline in the past expires at once."""
        if deadline_ns <= 0:
            deadline_ns = 1  # all-zero it_value would disarm instead
        v = self._value
        v.tv_sec, v.tv_nsec = divmod(deadline_ns, _NS)
        if self._settime(self._fd, TFD_TIMER_ABSTIME, self._ref, None) < 0:
            err = ctypes.get_errno()
            raise OSError(err, os.strerror(err))

    def disarm(self) -> None:
        v = self._value
        v.tv_sec = v.tv_nsec = 0
        self._settime(self._fd, TFD_TIMER_ABSTIME, self._ref, None)

    def drain(self) -> int:
        """Consume the expiration counter; 0 if the wake-up was spurious."""
        try:
            return int.from_bytes(os.read(self._fd, 8), sys.byteorder)
        except BlockingIOError:
            return 0

    @property
    def closed(self) -> bool:
        return self._fd < 0

    def watch(self, loop: Any, on_expiry: Callable[[], None]) -> None:
        """Have *loop* call *on_expiry* each time this timerfd expires (``loop.add_reader``; a wake-up that finds
        no expiration calls nothing); :meth:`close_watched` ends it."""
        drain = self.drain

        def on_readable() -> None:
            if drain():
                on_expiry()

        loop.add_reader(self._fd, on_readable)

    def close_watched(self, loop: Any) -> None:
        """Stop *loop* watching this timerfd (``loop.add_reader``) and close it; a loop already closed is fine."""
        try:
            loop.remove_reader(self._fd)
        except (RuntimeError, ValueError, OSError):
            pass  # loop already closed: its selector no longer holds the fd
        self.close()

    def close(self) -> None:
        fd, self._fd = self._fd, -1
        if fd >= 0:
            os.close(fd)


class LookaheadTimer:
    """Two timerfds (:class:`TimerFD`) in turn for a periodic wake-up: each :meth:`set_abs` for the next wake-up
    also arms the one after it, a period later, on the other timerfd (docs/timing.md, "The clock's timer, armed a
    cycle ahead").

    Why: arming a timer that becomes the CPU's earliest makes the kernel reprogram the CPU's timer device, and on
    a virtual machine that is the hypervisor's work. On the 2-vCPU bench machine a ``timerfd_settime`` 200 µs
    ahead took 7.0 µs (median) against 1.8 µs for one behind an earlier timer and 0.35 µs for a plain system
    call (``scripts/bench_timers.py --arm``). Here the next wake-up was armed a period ago, so it is usually
    already set; the call arms the one after it, which lies behind it, and the device is reprogrammed only by the
    expiry itself, as it is anyway.

    :meth:`set_abs` keeps the timer already set for the next wake-up when it is at most *early_ns* before the
    target or *late_ns* after it (an adaptive spin moves the target by nanoseconds a cycle); otherwise it re-arms
    it (and pays as a single timerfd does). :attr:`rearmed` counts those, :attr:`kept` the others. A timerfd that
    expired for a target already served (after a stall) is re-armed too, which clears it, so it wakes nobody.
    """

    __slots__ = ("_fds", "_armed", "period_ns", "early_ns", "_late", "_fired", "kept", "rearmed")

    def __init__(self, period_ns: int, *, early_ns: int = 5_000, late_ns: int = 1_000) -> None:
        self._fds = (TimerFD(), TimerFD())
        self._armed = [0, 0]  # the target each is set for (0: not set)
        self.period_ns = int(period_ns)  #: how far after a target the one after it is armed (the owner may change it)
        self.early_ns = int(early_ns)  #: how far before its target a kept wake-up may come (the owner spins it out)
        self._late = int(late_ns)
        self._fired = 0  # the one that woke us last: free to be armed a period ahead
        self.kept = 0  #: set_abs calls whose target was already set a period ago
        self.rearmed = 0  #: set_abs calls that had to move the next wake-up

    def set_abs(self, target_ns: int) -> None:
        """Wake at *target_ns* (within the tolerances of the class docstring) and, a period later, once more
        unless moved before then."""
        i = self._fired
        j = 1 - i
        armed = self._armed
        g = armed[j]
        if g and target_ns - self.early_ns <= g <= target_ns + self._late:
            self.kept += 1
        else:
            self.rearmed += 1
            self._fds[j].set_abs(target_ns)
            armed[j] = target_ns
        ahead = target_ns + self.period_ns  # from the target asked for, not the one kept: no drift
        self._fds[i].set_abs(ahead)
        armed[i] = ahead
        self._fired = j  # the next wake-up is j's: then i holds the one after

    def watch(self, loop: Any, on_expiry: Callable[[], None]) -> None:
        """Have *loop* call *on_expiry* when either timerfd expires (see :meth:`TimerFD.watch`)."""
        for k, fd in enumerate(self._fds):
            drain = fd.drain

            def on_readable(k: int = k, drain: Callable[[], int] = drain) -> None:
                if drain():
                    self._fired = k
                    on_expiry()

            loop.add_reader(fd.fileno(), on_readable)

    def close_watched(self, loop: Any) -> None:
        for fd in self._fds:
            fd.close_watched(loop)

    @property
    def closed(self) -> bool:
        return self._fds[0].closed


def timerfd_supported() -> bool:
    """True if a timerfd can actually be created here (Linux, libc exports it, not blocked by seccomp)."""
    if _libc is None:
        return False
    try:
        TimerFD().close()
    except OSError:
        return False
    return True


def set_thread_timer_slack(slack_ns: int) -> bool:
    """``prctl(PR_SET_TIMERSLACK)`` for the *calling* thread (default slack is 50 µs for SCHED_OTHER).

    Affects sleeps with a timeout (``clock_nanosleep``, ``epoll_wait``), not timerfd expirations.
    Returns False where unsupported."""
    if _libc is None:
        return False
    return _libc.prctl(PR_SET_TIMERSLACK, max(1, int(slack_ns)), 0, 0, 0) == 0



def _bind_clock_nanosleep() -> Callable[..., int] | None:
    if _libc is None:
        return None
    try:
        fn = _libc.clock_nanosleep
    except AttributeError:
        return None
    fn.argtypes = [ctypes.c_int, ctypes.c_int, ctypes.POINTER(_Timespec), ctypes.POINTER(_Timespec)]
    fn.restype = ctypes.c_int
    return fn


_clock_nanosleep = _bind_clock_nanosleep()


def make_abs_sleeper() -> Callable[[int], None]:
    """Return ``sleep_until(deadline_ns)`` for the calling thread: ``clock_nanosleep(CLOCK_MONOTONIC,
    TIMER_ABSTIME)`` via ctypes (releases the GIL, restarts on EINTR), or a ``time.sleep`` fallback.
    Each thread should make its own (the timespec buffer is per sleeper)."""
    if _clock_nanosleep is None:
        mono = time.monotonic_ns
        sleep = time.sleep

        def sleep_until_portable(deadline_ns: int) -> None:
            dt = deadline_ns - mono()
            if dt > 0:
                sleep(dt / 1e9)
        return sleep_until_portable

    ts = _Timespec()
    ref = ctypes.byref(ts)
    fn = _clock_nanosleep

    def sleep_until(deadline_ns: int) -> None:
        ts.tv_sec, ts.tv_nsec = divmod(max(deadline_ns, 1), _NS)
        while fn(CLOCK_MONOTONIC, TIMER_ABSTIME, ref, None) == _EINTR:
            pass
    return sleep_until
