"""The slave workers' arrival poll as a setting (``[network] arrival_poll``, ``mlink-sim slave --arrival-poll``):
``auto``, ``off`` or a lead time with a unit. Durations with units in general are :mod:`mlink_sim.units`.
"""

from __future__ import annotations

from ..units import parse_duration_ns

__all__ = ["parse_arrival_poll", "AUTO_POLL_LEAD_NS", "AUTO_POLL_MAX_PERIOD_NS"]


AUTO_POLL_LEAD_NS = 80_000  #: arrival poll "auto": from this long before a burst is due (docs/timing.md)
#: arrival poll "auto": only at transmission cycles up to this: MECHATROLINK-III at 250 and 500 µs (SI-ET3 Table 14,
#: ID_CODE 16H/17H), MECHATROLINK-II with 17-byte frames at 0.5 ms (SI-T3 CONNECT). Measured to pay at 250 µs and
#: not at 1 ms, where the wake-up on arrival is on time already; 750 µs (ML-III) is not measured and is left out.
AUTO_POLL_MAX_PERIOD_NS = 500_000


def parse_arrival_poll(text: str) -> tuple[int, int | None] | None:
    """A worker's arrival poll (``mlink-sim slave --arrival-poll``, ``[network] arrival_poll``; the poll itself is
    ``mlink_sim.aio.timing.arrival.ArrivalPoll``): ``auto``, ``off`` or a lead time (``80us``) as ``(lead_ns,
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
