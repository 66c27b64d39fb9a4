"""Durations with units (``"250us"``, ``"2ms"``, ``"0.5s"``, ``"30s"``) -> integer nanoseconds."""

from __future__ import annotations

import re

__all__ = ["parse_duration_ns", "format_ns", "parse_arrival_poll", "UNITS_NS", "AUTO_POLL_LEAD_NS", "AUTO_POLL_MAX_PERIOD_NS"]

UNITS_NS = {"ns": 1, "us": 1_000, "µs": 1_000, "ms": 1_000_000, "s": 1_000_000_000, "min": 60_000_000_000}
_RE = re.compile(r"^\s*([0-9]+(?:\.[0-9]*)?|\.[0-9]+)\s*(ns|us|µs|ms|s|min)\s*$")


def parse_duration_ns(text: str | int | float, *, default_unit: str | None = None) -> int:
    """Parse ``"2ms"`` -> 2_000_000. Bare numbers need *default_unit*; raises ValueError with a clear message."""
    if isinstance(text, bool):
        raise ValueError("expected a duration such as '2ms', got a boolean")
    if isinstance(text, (int, float)):
        if default_unit is None:
            raise ValueError(f"expected a duration with a unit (ns, us, ms, s), got the bare number {text}")
        return round(text * UNITS_NS[default_unit])
    m = _RE.match(text)
    if not m:
        if default_unit is not None:
            try:
                return round(float(text) * UNITS_NS[default_unit])
            except ValueError:
                pass
        raise ValueError(f"expected a duration such as '250us', '2ms' or '30s', got {text!r}")
    return round(float(m.group(1)) * UNITS_NS[m.group(2)])


def format_ns(ns: int | float) -> str:
    """Human-readable duration: 1500 -> '1.5us', 2_000_000 -> '2ms'."""
    ns = float(ns)
    for unit, scale in (("s", 1e9), ("ms", 1e6), ("us", 1e3)):
        if abs(ns) >= scale:
            return f"{ns / scale:.4g}{unit}"
    return f"{ns:.4g}ns"


AUTO_POLL_LEAD_NS = 80_000  #: arrival poll "auto": from this long before a burst is due (docs/timing.md)
#: arrival poll "auto": only at transmission cycles up to this: MECHATROLINK-III at 250 and 500 µs (SI-ET3 Table 14,
#: ID_CODE 16H/17H), MECHATROLINK-II with 17-byte frames at 0.5 ms (SI-T3 CONNECT). Measured to pay at 250 µs and
#: not at 1 ms, where the wake-up on arrival is on time already; 750 µs (ML-III) is not measured and is left out.
AUTO_POLL_MAX_PERIOD_NS = 500_000


def parse_arrival_poll(text: str) -> tuple[int, int | None] | None:
    """A worker's arrival poll (``mlink-sim slave --arrival-poll``, ``[network] arrival_poll``; the poll itself is
    ``mlink_sim.aio.arrival.ArrivalPoll``): ``auto``, ``off`` or a lead time (``80us``) as ``(lead_ns,
    max_period_ns)``; None for off, ``max_period_ns`` None for a poll at any cycle. ValueError for anything else,
    or a lead not between 1 µs and 1 ms."""
    word = text.strip().lower()
    if word == "off":
        return None
    if word == "auto":
        return AUTO_POLL_LEAD_NS, AUTO_POLL_MAX_PERIOD_NS
    bad = ValueError(f"expected 'auto', 'off' or a lead between 1us and 1ms such as '80us', got {text!r}")
    try:
        lead = parse_duration_ns(word, default_unit="us")
    except ValueError:
        raise bad from None
    if not 1_000 <= lead <= 1_000_000:
        raise bad
    return lead, None
