"""What one network impairment is: :class:`Impairment`, validated once, from the timeline, the command line
(``--impair 'loss=5%,delay=200us'``), a control request or the pytest plugin (docs/faults.md).

Every field is checked here with a message that names the field and what was expected, so the config loader,
the CLI (exit 2) and the control endpoint all refuse bad values the same way.
"""

from __future__ import annotations

import enum
import re
from collections.abc import Mapping
from dataclasses import dataclass, fields
from typing import Any

from ..units import format_ns, parse_address, parse_duration_ns

__all__ = ["Direction", "Impairment", "ImpairError", "parse_probability", "parse_impair_text", "as_impairment",
           "target_station", "DIRECTIONS"]


class ImpairError(ValueError):
    """A bad impairment value; ``str()`` names the field and what was expected."""


class Direction(enum.IntEnum):
    """Which way a datagram travels."""

    TO_STATION = 1  #: a command, master -> slave
    TO_MASTER = 2  #: a response, slave -> master


#: The ``direction`` values of ``do = "impair"`` and the paths each one impairs.
DIRECTIONS: dict[str, tuple[Direction, ...]] = {
    "to-station": (Direction.TO_STATION,),
    "to-master": (Direction.TO_MASTER,),
    "both": (Direction.TO_STATION, Direction.TO_MASTER),
}
_PROBABILITIES = ("loss", "duplicate", "reorder", "corrupt")
_DURATIONS = ("delay", "jitter", "for")


def parse_probability(value: Any, name: str) -> float:
    """A probability per datagram: a number 0…1 or a percentage string (``"5%"``); ImpairError otherwise."""
    if isinstance(value, bool):
        raise ImpairError(f"{name}: expected a probability 0…1 or a percentage such as '5%', got {value!r}")
    if isinstance(value, str):
        text = value.strip()
        try:
            p = float(text[:-1]) / 100.0 if text.endswith("%") else float(text)
        except ValueError:
            raise ImpairError(f"{name}: expected a probability 0…1 or a percentage such as '5%', "
                              f"got {value!r}") from None
    elif isinstance(value, (int, float)):
        p = float(value)
    else:
        raise ImpairError(f"{name}: expected a probability 0…1 or a percentage such as '5%', got {value!r}")
    if not 0.0 <= p <= 1.0:
        raise ImpairError(f"{name}: a probability is between 0 and 1 (0 % and 100 %), got {value!r}")
    return p


def _duration(value: Any, name: str) -> int:
    """A duration in ns from ``"300us"`` or a bare number of seconds (``for_=2.0``)."""
    try:
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            ns = parse_duration_ns(value, default_unit="s")
        else:
            ns = parse_duration_ns(value)
    except (ValueError, TypeError) as exc:
        raise ImpairError(f"{name}: {exc}") from None
    if ns < 0:
        raise ImpairError(f"{name}: expected a duration of 0 or more, got {value!r}")
    return ns


@dataclass(frozen=True)
class Impairment:
    """One impairment of a path (a station, one or both directions). Probabilities are per datagram.

    * ``loss`` — drop; with ``burst`` (mean loss-burst length, ≥ 1) drawn from a two-state Gilbert–Elliott chain
      whose long-run loss rate is ``loss``, else stratified (exactly ``loss`` × 1000 in every 1000 datagrams of
      a path, at random positions: :class:`~mlink_sim.impair.stages.Loss`).
    * ``delay`` ± ``jitter`` — added one-way delay, uniform in ``[delay − jitter, delay + jitter]`` (ns).
    * ``duplicate`` — the datagram is delivered twice.
    * ``reorder`` — the datagram is held back until after the next one on its path.
    * ``corrupt`` — one bit of the data is flipped after the FCS was computed: the receiver sees a bad FCS.
    * ``for_ns`` — it ends by itself after this long (None: until healed).
    """

    direction: str = "both"
    loss: float = 0.0
    burst: float | None = None
    delay: int = 0
    jitter: int = 0
    duplicate: float = 0.0
    reorder: float = 0.0
    corrupt: float = 0.0
    for_ns: int | None = None

    def __post_init__(self) -> None:
        if self.direction not in DIRECTIONS:
            raise ImpairError(f"direction: expected 'to-station', 'to-master' or 'both', got {self.direction!r}")
        if self.burst is not None:
            if isinstance(self.burst, bool) or not isinstance(self.burst, (int, float)) or self.burst < 1:
                raise ImpairError(f"burst: the mean length of a loss burst is a number of datagrams ≥ 1, "
                                  f"got {self.burst!r}")
            if not self.loss:
                raise ImpairError("burst: needs loss (the long-run loss rate of the bursts)")
            if self.loss < 1 and self.loss / (1 - self.loss) > self.burst:
                raise ImpairError(f"burst: a loss rate of {self.loss:g} needs bursts of at least "
                                  f"{self.loss / (1 - self.loss):.3g} datagrams on average (the gaps between bursts "
                                  f"cannot be shorter than one datagram), got {self.burst:g}")
        if self.jitter > self.delay:
            raise ImpairError(f"jitter: at most the delay ({format_ns(self.delay)}): the delay varies uniformly "
                              f"by ± jitter and cannot go below 0, got {format_ns(self.jitter)}")
        if self.for_ns is not None and self.for_ns <= 0:
            raise ImpairError(f"for: expected a duration above 0, got {self.for_ns} ns")
        if not (self.loss or self.delay or self.duplicate or self.reorder or self.corrupt):
            raise ImpairError("impair: nothing to do; give at least one of loss, delay, duplicate, reorder or "
                              "corrupt")

    @property
    def directions(self) -> tuple[Direction, ...]:
        return DIRECTIONS[self.direction]

    @classmethod
    def from_fields(cls, values: Mapping[str, Any]) -> Impairment:
        """From user fields as the timeline spells them (``for``, probabilities as numbers or ``"5%"``,
        durations as ``"300us"``); unknown names are an ImpairError naming the known ones."""
        known = {"direction", "loss", "burst", "delay", "jitter", "duplicate", "reorder", "corrupt", "for"}
        unknown = [k for k in values if k not in known and k != "for_"]
        if unknown:
            raise ImpairError(f"{unknown[0]}: unknown impairment field (known: {', '.join(sorted(known))})")
        kw: dict[str, Any] = {}
        for name, value in values.items():
            if value is None:
                continue
            if name in _PROBABILITIES:
                kw[name] = parse_probability(value, name)
            elif name in ("for", "for_"):
                kw["for_ns"] = _duration(value, "for")
            elif name in _DURATIONS:
                kw[name] = _duration(value, name)
            elif name == "burst":
                if isinstance(value, str):
                    try:
                        value = float(value)
                    except ValueError:
                        raise ImpairError(f"burst: expected a number ≥ 1, got {value!r}") from None
                kw["burst"] = value
            else:
                kw[name] = value
        return cls(**kw)

    def as_fields(self) -> dict[str, Any]:
        """The non-default fields, as :meth:`from_fields` takes them (JSON-safe; durations as ``"300000ns"``)."""
        out: dict[str, Any] = {}
        for f in fields(self):
            value = getattr(self, f.name)
            if value != f.default:
                name = "for" if f.name == "for_ns" else f.name
                out[name] = f"{value}ns" if name in _DURATIONS else value
        return out

    def describe(self) -> str:
        """``loss 5% (bursts of 3), delay 300us ± 200us, to-station, for 2s``."""
        parts = []
        if self.loss:
            parts.append(f"loss {self.loss * 100:.4g}%" + (f" (bursts of {self.burst:g})" if self.burst else ""))
        if self.delay:
            parts.append(f"delay {format_ns(self.delay)}" + (f" ± {format_ns(self.jitter)}" if self.jitter else ""))
        for name in ("duplicate", "reorder", "corrupt"):
            p = getattr(self, name)
            if p:
                parts.append(f"{name} {p * 100:.4g}%")
        if self.direction != "both":
            parts.append(self.direction)
        if self.for_ns is not None:
            parts.append(f"for {format_ns(self.for_ns)}")
        return ", ".join(parts)


_ITEM = re.compile(r"\s*([A-Za-z_-]+)\s*=\s*([^,]+?)\s*(?:,|$)")


def parse_impair_text(text: str) -> Impairment:
    """``'loss=5%,delay=200us,jitter=50us,for=2s,direction=to-station'`` -> :class:`Impairment`."""
    values: dict[str, Any] = {}
    pos = 0
    text = text.strip()
    while pos < len(text):
        m = _ITEM.match(text, pos)
        if not m:
            raise ImpairError(f"expected NAME=VALUE pairs separated by commas, such as 'loss=5%,delay=200us', "
                              f"got {text!r}")
        name, value = m.group(1).lower(), m.group(2)
        if name in values:
            raise ImpairError(f"{name}: given twice in {text!r}")
        values[name] = value
        pos = m.end()
    if not values:
        raise ImpairError("expected NAME=VALUE pairs such as 'loss=5%,delay=200us', got nothing")
    return Impairment.from_fields(values)


def as_impairment(spec: Impairment | str | None = None, fields: Mapping[str, Any] | None = None) -> Impairment:
    """An :class:`Impairment` from what an API caller gives: one already made, its text form
    (``"loss=5%,delay=200us"``) or keyword fields (``loss=0.1, for_=2.0``: numbers of seconds for durations)."""
    if spec is not None and fields:
        raise ImpairError("give an impairment or its fields, not both")
    if isinstance(spec, Impairment):
        return spec
    if isinstance(spec, str):
        return parse_impair_text(spec)
    if spec is not None:
        raise ImpairError(f"expected an Impairment, its text form or its fields, got {spec!r}")
    return Impairment.from_fields(dict(fields or {}))


def target_station(station: Any) -> int | None:
    """A station argument (``0x21``, ``"0x21"``, ``"21H"``, ``"all"``/None) -> its address, or None for all."""
    if station is None or (isinstance(station, str) and station.strip().lower() == "all"):
        return None
    try:
        return parse_address(station)
    except ValueError as exc:
        raise ImpairError(f"station: {exc} (or 'all')") from None
