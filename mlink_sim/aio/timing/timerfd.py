"""ctypes bindings for Linux timerfd (private helper of the cycle timer and the arrival poll).

Python 3.11 has no ``os.timerfd_create`` (added in 3.13), so this calls libc directly:
``timerfd_create(CLOCK_MONOTONIC, TFD_NONBLOCK | TFD_CLOEXEC)`` and
``timerfd_settime(fd, TFD_TIMER_ABSTIME, ...)``. ``CLOCK_MONOTONIC`` is the clock behind
``time.monotonic_ns()`` (``time.get_clock_info("monotonic")``), so deadlines are passed through unchanged.

Constants are the Linux UAPI values (``<sys/timerfd.h>``, ``<linux/time.h>``);
they are the same on every Linux architecture CPython supports except ``TFD_NONBLOCK``/``TFD_CLOEXEC``,
which equal ``O_NONBLOCK``/``O_CLOEXEC`` and are therefore taken from :mod:`os`.

Touches: the timerfds it creates (libc through ctypes).
"""

from __future__ import annotations

import ctypes
import ctypes.util
import os
import sys
from collections.abc import Callable
from typing import Any

__all__ = ["TimerFD", "timerfd_supported"]

CLOCK_MONOTONIC = 1
TFD_TIMER_ABSTIME = 1
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


def timerfd_supported() -> bool:
    """True if a timerfd can actually be created here (Linux, libc exports it, not blocked by seccomp)."""
    if _libc is None:
        return False
    try:
        TimerFD().close()
    except OSError:
        return False
    return True
