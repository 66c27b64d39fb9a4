"""``wait_until`` of the running networks (:class:`~mlink_sim.testing.RunningNetwork` on the wall clock,
:class:`~mlink_sim.testing.VirtualRunningNetwork` on simulated time): poll, and on a timeout say what was seen."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

__all__ = ["poll_until"]


def poll_until(check: Callable[[], Any], until: Callable[[Any], Any] | None, timeout: float, interval: float,
               now: Callable[[], float], advance: Callable[[float], None], clock: str = "") -> Any:
    """Call *check* every *interval* until it holds (*until* None: its result is the condition) or *until* holds of
    its result; return that result. ``TimeoutError`` after *timeout* (by *now*, in s), naming the last result:
    ``condition not met within 10 s: last value 12.31`` (*clock*, e.g. " (simulated)", follows the time)."""
    deadline = now() + timeout
    while True:
        last = check()
        if until(last) if until is not None else last:
            return last
        if now() >= deadline:
            if until is not None:
                seen = f"last value {last!r}"
            else:
                seen = (f"the condition last returned {last!r} (wait_until(read, timeout, until=test) names the "
                        "value read)")
            raise TimeoutError(f"condition not met within {timeout:g} s{clock}: {seen}")
        advance(interval)
