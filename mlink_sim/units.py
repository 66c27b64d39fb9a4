"""Values a user writes as text, read and written the same way everywhere: durations with units (``"250us"``,
``"2ms"``, ``"0.5s"``, ``"30s"``) as integer nanoseconds and back, and station addresses (``0x21``, ``"21H"``).

A leaf: it imports only the standard library, so that every package that reads such a value (the config, the
network impairments, the faults, the metrics' assertions and reports, the command line) takes it from here and
none of them has to import another for it. CPU lists (``"0,2"``: ``--cpus``, a station's ``cpus``) too.
"""

from __future__ import annotations

import re
from typing import Any

__all__ = ["UNITS_NS", "parse_duration_ns", "format_ns", "parse_address", "parse_cpus", "format_cpus"]

UNITS_NS = {"ns": 1, "us": 1_000, "µs": 1_000, "ms": 1_000_000, "s": 1_000_000_000, "min": 60_000_000_000}
_DURATION = re.compile(r"^\s*([0-9]+(?:\.[0-9]*)?|\.[0-9]+)\s*(ns|us|µs|ms|s|min)\s*$")
_ADDRESS = re.compile(r"0[xX]([0-9A-Fa-f]+)|([0-9A-Fa-f]+)[hH]|([0-9]+)")


def parse_duration_ns(text: str | int | float, *, default_unit: str | None = None) -> int:
    """Parse ``"2ms"`` -> 2_000_000. Bare numbers need *default_unit*; raises ValueError with a clear message."""
    if isinstance(text, bool):
        raise ValueError("expected a duration such as '2ms', got a boolean")
    if isinstance(text, (int, float)):
        if default_unit is None:
            raise ValueError(f"expected a duration with a unit (ns, us, ms, s), got the bare number {text}")
        return round(text * UNITS_NS[default_unit])
    m = _DURATION.match(text)
    if not m:
        if default_unit is not None:
            try:
                return round(float(text) * UNITS_NS[default_unit])
            except ValueError:
                pass
        raise ValueError(f"expected a duration such as '250us', '2ms' or '30s', got {text!r}")
    return round(float(m.group(1)) * UNITS_NS[m.group(2)])


def format_ns(ns: int | float) -> str:
    """A duration in ns in the largest unit it reaches, 4 significant digits: ``850ns``, ``731.2us``, ``1.25ms``,
    ``2s``. :func:`parse_duration_ns` reads it back (to those 4 digits)."""
    magnitude = abs(ns)
    for unit, scale in (("s", 1e9), ("ms", 1e6), ("us", 1e3)):
        if magnitude >= scale:
            return f"{ns / scale:.4g}{unit}"
    return f"{ns:.4g}ns"


def parse_address(value: Any) -> int:
    """A station address: an integer, ``"0x21"``, ``"21H"`` or ``"33"``."""
    if isinstance(value, bool):
        raise ValueError("expected a station address such as 0x21")
    if isinstance(value, int):
        address = value
    elif isinstance(value, str):
        m = _ADDRESS.fullmatch(value.strip())
        if not m:
            raise ValueError(f"expected a station address such as 0x21 or 21H, got {value!r}")
        address = int(m.group(1) or m.group(2), 16) if (m.group(1) or m.group(2)) else int(m.group(3))
    else:
        raise ValueError(f"expected a station address such as 0x21, got {value!r}")
    if not 0 <= address <= 0xFF:
        raise ValueError(f"station address {address:#x} does not fit in one byte")
    return address


def parse_cpus(text: str) -> set[int]:
    """``"0,2"`` → ``{0, 2}``; ``ValueError`` for anything else (an empty list, a negative or non-numeric CPU)."""
    try:
        cpus = {int(part) for part in text.split(",")}
    except ValueError:
        raise ValueError(f"expected CPU numbers separated by commas (e.g. 0,2), got {text!r}") from None
    if any(c < 0 for c in cpus):
        raise ValueError(f"CPU numbers are 0 or above, got {text!r}")
    return cpus


def format_cpus(cpus: set[int]) -> str:
    """``{0, 2}`` → ``"0,2"``: the form :func:`parse_cpus` reads."""
    return ",".join(map(str, sorted(cpus)))
