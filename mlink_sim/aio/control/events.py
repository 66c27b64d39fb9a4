"""What happens during a run, as numbered events in a bounded ring: the control endpoint's ``status`` hands out the
ones after the number a client saw last (docs/control.md, "Events").

Kinds: ``phase`` (a station's state changed, as the master sees it), ``alarm`` (an alarm or warning code appeared in
a station's responses, or went), ``step`` (a timeline step began), ``check`` (a timeline check's result), ``action``
(what was done: a timeline action, a control request that runs, stops, clears, writes, injects or heals). Every
event has ``seq`` (1, 2, …), ``at_s`` (seconds from the timeline's 0 s, the end of bring-up; negative before it) and
``kind``; the rest depends on the kind::

    {"seq": 7, "at_s": 0.2, "kind": "step", "describe": "0.2s run 0x21 forward 30 Hz"}
    {"seq": 8, "at_s": 1.31, "kind": "alarm", "station": "0x21", "code": "E6H", "name": "COMM_ERROR", "source": "alarm"}
    {"seq": 9, "at_s": 3.0, "kind": "check", "station": "0x21", "what": "…", "ok": true, "detail": "…"}

Touches: nothing; the masters call it (:meth:`RunLog.watch`), the status operation polls the timeline into it.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable
from typing import Any

from ...master.types import AlarmCleared, AlarmRaised, Recovered, StateChanged
from ..present.figures import station_key

__all__ = ["RunLog", "CAPACITY", "PER_REPLY"]

CAPACITY = 512  #: events kept; older ones are forgotten (a client that asks too rarely misses them)
PER_REPLY = 64  #: events in one status reply at most (it stays one datagram); the rest come with the next
#: AlarmRaised.source -> the ML-III field it came from (SI-ET3 "COMM_ALM", "CMD_ALM"); "alarm": the ML-II ALARM byte
_ALM_FIELD = {"comm": "COMM_ALM", "command": "CMD_ALM"}


class RunLog:
    """The run's events, numbered, the last :data:`CAPACITY` kept. *now_ns*: the masters' clock."""

    def __init__(self, now_ns: Callable[[], int], capacity: int = CAPACITY) -> None:
        self._now_ns = now_ns
        self._events: deque[tuple[int, int, dict[str, Any]]] = deque(maxlen=capacity)  # (seq, at_ns, fields)
        self.seq = 0  #: the number of the latest event (0: none yet)
        self.t0_ns = now_ns()  #: the masters' clock at the timeline's 0 s (until it starts: the log's creation)
        self._steps = 0  # timeline steps logged so far
        self._checks = 0  # timeline checks logged so far

    def start(self) -> None:
        """The timeline's 0 s is now: times count from here (events before it get negative times)."""
        self.t0_ns = self._now_ns()

    @property
    def elapsed_s(self) -> float:
        return (self._now_ns() - self.t0_ns) / 1e9

    def add(self, kind: str, at_ns: int | None = None, **fields: Any) -> int:
        """Log one event of *kind* at *at_ns* (the masters' clock; default now); returns its number."""
        self.seq += 1
        self._events.append((self.seq, self._now_ns() if at_ns is None else at_ns, {"kind": kind, **fields}))
        return self.seq

    def since(self, seq: int = 0, limit: int = PER_REPLY) -> tuple[list[dict[str, Any]], int]:
        """The events numbered after *seq*, oldest first, *limit* at most; and the number of the last one given
        (*seq* itself, or the latest, when there are none: nothing new)."""
        out = []
        t0 = self.t0_ns
        for n, at_ns, fields in self._events:
            if n > seq:
                out.append({"seq": n, "at_s": round((at_ns - t0) / 1e9, 6), **fields})
                if len(out) >= limit:
                    break
        return out, (out[-1]["seq"] if out else max(0, min(seq, self.seq)))

    # -- sources ------------------------------------------------------------------------------------------------

    def watch(self, master: Any) -> None:
        """Log *master*'s state changes, alarms and recoveries as they happen (:meth:`Master.watch`)."""
        master.watch(self._on_master)

    def _on_master(self, now_ns: int, ev: Any) -> None:
        t = type(ev)
        if t is StateChanged:
            self.add("phase", now_ns, station=station_key(ev.station), state=ev.new.value, phase=ev.new.phase,
                     was=ev.old.value)
        elif t is AlarmRaised:
            label = _ALM_FIELD.get(ev.source)
            code = f"{ev.code:02X}H" if label is None else f"{label} {ev.code:X}H"
            self.add("alarm", now_ns, station=station_key(ev.station), code=code, name=ev.name, source=ev.source)
        elif t is AlarmCleared:
            self.add("alarm", now_ns, station=station_key(ev.station), code=None, name=None, source=ev.source,
                     cleared=True)
        elif t is Recovered:
            self.add("phase", now_ns, station=station_key(ev.station), state="recovered", reason=ev.reason,
                     after_s=round(ev.ns / 1e9, 6))

    def poll(self, scenario: Any) -> None:
        """Log the timeline's steps begun and checks made since the last poll (at their own times)."""
        if scenario is None:
            return
        t0 = self.t0_ns
        while self._steps < scenario.started:
            step = scenario.steps[self._steps]
            self._steps += 1
            self.add("step", t0 + int(step.at), describe=step.describe)
        results = scenario.results
        while self._checks < len(results):
            c = results[self._checks]
            self._checks += 1
            self.add("check", t0 + int(c.at_s * 1e9), station=station_key(c.station), what=c.what, ok=c.ok,
                     detail=c.detail)
