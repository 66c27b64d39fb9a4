"""Recovery figures of one station (docs/report.md, docs/faults.md "Recovery"): the recovery times
after each fault as an HDR histogram (:class:`LatencyHistogram`), and the faults after which the station did not
recover. What was injected is the station's ``injected`` counts (the impairment layer's and the fault stage's)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from .histogram import LatencyHistogram

__all__ = ["FaultFigures"]


class FaultFigures:
    """Recovery histogram and unrecovered episodes of one station."""

    __slots__ = ("recovery", "unrecovered")

    def __init__(self) -> None:
        self.recovery = LatencyHistogram()
        self.unrecovered = 0

    def copy(self) -> FaultFigures:
        out = FaultFigures()
        out.recovery = self.recovery.copy()
        out.unrecovered = self.unrecovered
        return out

    def reset(self) -> None:
        self.recovery.reset()
        self.unrecovered = 0

    def merge(self, other: FaultFigures) -> None:
        self.recovery.merge(other.recovery)
        self.unrecovered += other.unrecovered

    def summary(self, *, hdr: bool = False) -> dict[str, Any]:
        """The station entry's fields: ``recovery`` (a histogram) and ``unrecovered``."""
        recovery: dict[str, Any] = self.recovery.summary()
        if hdr:
            recovery["hdr"] = self.recovery.encode()
        return {"recovery": recovery, "unrecovered": self.unrecovered}

    def to_wire(self, *, hdr: bool = True) -> dict[str, Any]:
        return {"recovery": self.recovery.encode() if hdr else self.recovery.to_pairs(),
                "unrecovered": self.unrecovered}

    @classmethod
    def from_wire(cls, data: Mapping[str, Any]) -> FaultFigures:
        out = cls()
        rec = data.get("recovery")
        if rec is not None:
            out.recovery = LatencyHistogram.from_pairs(rec) if isinstance(rec, list) else LatencyHistogram.decode(rec)
        value = data.get("unrecovered", 0)
        if isinstance(value, bool) or not isinstance(value, int) or value < 0:
            raise ValueError(f"unrecovered must be a non-negative integer, got {value!r}")
        out.unrecovered = value
        return out
