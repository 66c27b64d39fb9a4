"""Host stalls: how late each process's own loop and clock ran (docs/report.md "host", docs/timing.md).

A *stall* is a wake-up that came a whole period or more after it was due: for the master, a transmission cycle
that started one period or more late (``CycleTimer``'s ``on_stall``); for a slave worker, its 1 ms housekeeping
tick running :data:`WORKER_STALL_NS` or more late. Each stall is kept as an event ``(at, duration, cycles,
absorbed)`` per process, on the host's monotonic clock (the same for every process of one host, also across
containers). The report counts from ``origin_ns`` (the start of the measured span) and says, per process and in
total, how many stalls there were, how long they lasted together and at most, how many cycles they delayed, and
how many of those cycles the host-stall policy absorbed (run late) or lost (skipped).

Events arrive more than once from a worker (its control endpoint repeats its recent events); they are kept by
their time, so a repeat changes nothing.
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Mapping
from typing import Any

__all__ = ["StallLog", "Stall", "WORKER_STALL_NS", "POLICIES", "longest_named_ms"]

#: One stall as :meth:`StallLog.describe_near` names it: "<ms> ms at <s> s (<process>…)".
_NAMED = re.compile(r"(\d+(?:\.\d+)?) ms at -?\d+(?:\.\d+)? s \(")


def longest_named_ms(text: str) -> float:
    """The longest host stall, in ms, that the :meth:`StallLog.describe_near` sentences in *text* name (a failed
    check's detail, or ``mlink-sim up``'s output); 0.0 when they name none. With the bound (``host.bound`` of the
    report) it tells a check that failed after a stall beyond what the policy absorbs (docs/ci.md)."""
    return max((float(ms) for ms in _NAMED.findall(text)), default=0.0)

#: A worker's 1 ms tick that runs this late is a stall (twice the tick: uvloop's timers are whole milliseconds).
WORKER_STALL_NS = 2_000_000
#: The host-stall policies (docs/timing.md, "Host stalls").
POLICIES = ("absorb", "strict")

_MAX_EVENTS = 10_000  # per process; older ones are forgotten (counted in ``forgotten``)
_REPORTED = 100       # events listed in the report, longest first

Stall = tuple[int, int, int, bool]  #: (at_ns, duration_ns, cycles, absorbed)


class StallLog:
    """Stalls of every process of a network, keyed by process name (``"master"``, ``"worker:0"`` …)."""

    def __init__(self, policy: str = "strict", bound_ns: int = 0) -> None:
        if policy not in POLICIES:
            raise ValueError(f"host-stall policy must be one of {POLICIES}, got {policy!r}")
        self.policy = policy
        self.bound_ns = int(bound_ns)
        self.origin_ns = 0  #: monotonic ns the report's times count from (the measured span's start)
        self.forgotten = 0
        self._events: dict[str, dict[int, tuple[int, int, bool]]] = {}
        self._totals: dict[str, dict[str, int]] = {}

    # ------------------------------------------------------------------ recording
    def record(self, process: str, at_ns: int, duration_ns: int, cycles: int = 0, absorbed: bool = False) -> None:
        """One stall of *process* that began at *at_ns* (when the late wake-up was due) and lasted *duration_ns*."""
        events = self._events.setdefault(process, {})
        events[int(at_ns)] = (int(duration_ns), int(cycles), bool(absorbed))
        if len(events) > _MAX_EVENTS:
            del events[min(events)]
            self.forgotten += 1

    def add(self, process: str, events: Iterable[Iterable[Any]]) -> None:
        """Events as :meth:`events` gives them (e.g. from a worker's control endpoint); repeats change nothing."""
        for at, duration, cycles, absorbed in events:
            self.record(process, at, duration, cycles, absorbed)

    def set_totals(self, process: str, totals: Mapping[str, Any]) -> None:
        """*process*'s own ``count``/``total``/``max`` since the origin (a worker sends its recent events only):
        the report takes whichever says more, these or the events kept here."""
        self._totals[process] = {k: int(totals.get(k, 0)) for k in ("count", "total", "max")}

    def totals(self, process: str, since: int | None = None) -> dict[str, int]:
        """``count``/``total``/``max`` of *process*'s stalls since *since* (default: the origin), for
        :meth:`set_totals`."""
        summary = self._summary(self._since(process, since))
        return {k: v for k, v in summary.items() if k in ("count", "total", "max")}

    def events(self, process: str, last: int | None = None, since: int = 0) -> list[list[Any]]:
        """*process*'s events, oldest first (the *last* ones only), JSON-safe."""
        items = [(at, e) for at, e in sorted(self._events.get(process, {}).items()) if at >= since]
        if last is not None:
            items = items[-last:]
        return [[at, d, c, a] for at, (d, c, a) in items]

    def reset(self, origin_ns: int) -> None:
        """Count from *origin_ns* on (events before it stay, but no longer count)."""
        self.origin_ns = int(origin_ns)

    # ------------------------------------------------------------------ figures
    def _since(self, process: str, since: int | None = None) -> list[Stall]:
        origin = self.origin_ns if since is None else since
        return [(at, d, c, a) for at, (d, c, a) in sorted(self._events.get(process, {}).items()) if at >= origin]

    @staticmethod
    def _summary(events: list[Stall]) -> dict[str, int]:
        cycles = sum(c for _, _, c, _ in events)
        absorbed = sum(c for _, _, c, a in events if a)
        return {"count": len(events), "total": sum(d for _, d, _, _ in events),
                "max": max((d for _, d, _, _ in events), default=0), "cycles": cycles, "absorbed": absorbed,
                "lost": cycles - absorbed}

    def report(self) -> dict[str, Any]:
        """The report's ``host`` section (docs/report.md)."""
        by_process = {p: self._since(p) for p in sorted(self._events)}
        every = [(p, e) for p, evs in by_process.items() for e in evs]
        listed = sorted(every, key=lambda pe: (-pe[1][1], pe[1][0]))[:_REPORTED]
        summaries = {p: self._with_totals(p, self._summary(evs)) for p, evs in by_process.items()}
        overall = self._summary([e for _, e in every])
        overall["count"] = sum(v["count"] for v in summaries.values())
        overall["total"] = sum(v["total"] for v in summaries.values())
        overall["max"] = max((v["max"] for v in summaries.values()), default=0)
        return {
            "policy": self.policy,
            "bound": self.bound_ns,
            "stall": overall,
            "by_process": summaries,
            "stalls": [{"process": p, "at": max(0, at - self.origin_ns), "duration": d, "cycles": c,
                        "absorbed": a} for p, (at, d, c, a) in sorted(listed, key=lambda pe: pe[1][0])],
        }

    def overview(self) -> dict[str, int]:
        """Every process's stalls since the origin in a few numbers: ``count``, ``max`` and ``total`` (ns) (the
        control endpoint's ``status``; cheap: no sorting, no report)."""
        origin = self.origin_ns
        durations = [d for evs in self._events.values() for at, (d, _, _) in evs.items() if at >= origin]
        return {"count": len(durations), "max": max(durations, default=0), "total": sum(durations)}

    def brief(self) -> str:
        """For the live status: ``"0"``, or the count and the longest since the origin, ``"3 (max 23.9ms)"``."""
        origin = self.origin_ns
        durations = [d for evs in self._events.values() for at, (d, _, _) in evs.items() if at >= origin]
        return f"{len(durations)} (max {durations and max(durations) / 1e6:.1f}ms)" if durations else "0"

    def _with_totals(self, process: str, summary: dict[str, int]) -> dict[str, int]:
        totals = self._totals.get(process)
        if totals is not None:
            for key in ("count", "total", "max"):
                summary[key] = max(summary[key], totals[key])
        return summary

    def near(self, at_ns: int, before_ns: int, after_ns: int = 0) -> list[tuple[str, Stall]]:
        """Stalls that overlap ``[at_ns - before_ns, at_ns + after_ns]`` (absolute monotonic ns), oldest first."""
        lo, hi = at_ns - before_ns, at_ns + after_ns
        out = [(p, (at, d, c, a)) for p, evs in self._events.items() for at, (d, c, a) in evs.items()
               if at <= hi and at + d >= lo]
        return sorted(out, key=lambda pe: pe[1][0])

    def describe_near(self, at_ns: int, zero_ns: int | None = None, before_ns: int = 3_000_000_000) -> str:
        """A sentence on the stalls in the *before_ns* before a failed check at *at_ns*: how many, and the three
        longest in time order, e.g. ``"the host stalled 2 times in the 3 s before: 23.0 ms at 4.20 s (master,
        11 cycles lost); …"``. Times count from *zero_ns* (default: the origin); empty when there were none."""
        near = self.near(at_ns, before_ns)
        if not near:
            return ""
        zero = self.origin_ns if zero_ns is None else zero_ns
        parts = []
        for process, (at, d, c, a) in sorted(sorted(near, key=lambda pe: -pe[1][1])[:3], key=lambda pe: pe[1][0]):
            cycles = f", {c} cycles {'run late' if a else 'lost'}" if c else ""
            parts.append(f"{d / 1e6:.1f} ms at {(at - zero) / 1e9:.2f} s ({process}{cycles})")
        times = "once" if len(near) == 1 else f"{len(near)} times"
        return f"the host stalled {times} in the {before_ns / 1e9:g} s before, longest: " + "; ".join(parts)

    # ------------------------------------------------------------------ transport and combination
    def copy(self) -> StallLog:
        out = StallLog(self.policy, self.bound_ns)
        out.origin_ns, out.forgotten = self.origin_ns, self.forgotten
        out._events = {p: dict(evs) for p, evs in self._events.items()}
        out._totals = {p: dict(t) for p, t in self._totals.items()}
        return out

    def to_wire(self) -> dict[str, Any]:
        return {"policy": self.policy, "bound": self.bound_ns, "origin": self.origin_ns,
                "events": {p: self.events(p) for p in self._events}, "totals": self._totals}

    @classmethod
    def from_wire(cls, data: Mapping[str, Any]) -> StallLog:
        out = cls(str(data.get("policy", "strict")), int(data.get("bound", 0)))
        out.origin_ns = int(data.get("origin", 0))
        for process, events in dict(data.get("events", {})).items():
            out.add(str(process), events)
        for process, totals in dict(data.get("totals", {})).items():
            out.set_totals(str(process), totals)
        return out

    def merge(self, other: StallLog) -> None:
        for process in other._events:
            self.add(process, other.events(process))
        for process, totals in other._totals.items():
            self.set_totals(process, totals)
