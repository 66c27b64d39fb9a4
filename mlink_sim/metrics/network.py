"""Accumulators for one network's run: per-station counters and histograms, cycle timing, slave counters, CPU.

No clock is read here: every time is passed in (ns for latencies, seconds for CPU). The master runner calls
the ``record_*`` methods from its cycle callback and response handler; the supervisor feeds in what the slave
processes report (:meth:`NetworkMetrics.record_slave_counters`, :meth:`NetworkMetrics.record_cpu`) and asks
for :meth:`NetworkMetrics.report` at the end.

Counting rules (the report's invariants, see docs/report.md):

* every command sent to a station is ``record_sent`` once;
* a response matched to its command is ``record_rtt(station, ns)`` (→ ``answered`` and the RTT histogram);
  if it arrived after its cycle's deadline, ``record_late(station)`` as well (``late ⊆ answered``);
* a command that will never be answered (the master gave up: next command to the station sent, run over)
  is ``record_missing(station)`` once — not a command whose response is merely late;
* so ``answered + missing <= sent``; the difference is what was in flight when the figures were taken;
* :meth:`NetworkMetrics.reset` (the end of bring-up) keeps the commands in flight in ``sent``, so their
  answers, counted after the reset, keep the invariant.

Hot path: ``record_sent``/``record_rtt`` are a dict lookup and a few additions; a runner that wants less can
keep the :class:`StationMetrics` from :meth:`NetworkMetrics.station` and touch its fields directly. The
network-wide RTT histogram is the merge of the stations' histograms, computed when asked for.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping
from typing import Any

from .faults import FaultFigures
from .histogram import LatencyHistogram
from .report import INJECTED_KINDS, SCHEMA_ID
from .stalls import StallLog

__all__ = ["StationMetrics", "NetworkMetrics", "SLAVE_COUNTERS", "INJECTED_KINDS", "station_key"]

#: Counters a slave keeps and reports in its snapshot, cumulative since the slave process started.
SLAVE_COUNTERS: tuple[str, ...] = ("reception_failures", "wdt_errors", "dropped", "foreign_source")
_MASTER_COUNTERS: tuple[str, ...] = ("sent", "answered", "late", "missing")


def station_key(station: int) -> str:
    """Report key of a station address: ``0x21`` → ``"0x21"`` (lower case, at least two hex digits)."""
    return f"0x{station:02x}"


class _Cumulative:
    """A counter fed with a remote process's cumulative value; survives the process restarting (value drops)."""

    __slots__ = ("base", "last", "zero")

    def __init__(self) -> None:
        self.base = 0
        self.last = 0
        self.zero = 0  # the total at the last reset()

    def feed(self, value: int) -> None:
        if value < self.last:          # the remote counter restarted from 0
            self.base += self.last
        self.last = value

    def reset(self) -> None:
        """Count from now on: the total drops to 0, later values count from the current one."""
        self.zero = self.base + self.last

    @property
    def total(self) -> int:
        return self.base + self.last - self.zero


class StationMetrics:
    """Figures of one slave station. Master-side counters are plain attributes; slave-side ones are set."""

    __slots__ = ("address", "rtt", "sent", "answered", "late", "missing", "alarms", "_slave", "_injected", "faults")

    def __init__(self, address: int) -> None:
        self.address = address
        self.rtt = LatencyHistogram()
        self.sent = 0
        self.answered = 0
        self.late = 0
        self.missing = 0
        self.alarms = 0  #: alarms the station raised, as the master saw them (AlarmRaised)
        self._slave = {name: _Cumulative() for name in SLAVE_COUNTERS}
        self._injected = {name: _Cumulative() for name in INJECTED_KINDS}
        self.faults = FaultFigures()  #: faults injected, recovery times (metrics/faults.py)

    def copy(self) -> StationMetrics:
        out = StationMetrics(self.address)
        out.rtt = self.rtt.copy()
        for name in (*_MASTER_COUNTERS, "alarms"):
            setattr(out, name, getattr(self, name))
        for mine, theirs in ((self._slave, out._slave), (self._injected, out._injected)):
            for name, c in mine.items():
                o = theirs[name]
                o.base, o.last, o.zero = c.base, c.last, c.zero
        out.faults = self.faults.copy()
        return out

    def set_injected(self, counts: Mapping[str, int]) -> None:
        """The fault injection's cumulative counts for this station (``ImpairmentLayer.injected()``)."""
        for name, value in counts.items():
            slot = self._injected.get(name)
            if slot is not None:
                slot.feed(value)

    def reset(self) -> None:
        """Forget what was counted so far (RTT, master counters; slave counters count from their current value).

        Commands still in flight (sent, neither answered nor given up) stay counted in ``sent``: their answer or
        their ``missing`` comes after the reset, and counting it without its command would break
        ``answered + missing <= sent`` by about one command per station after bring-up."""
        self.rtt.reset()
        self.sent = max(0, self.sent - self.answered - self.missing)
        self.answered = self.late = self.missing = self.alarms = 0
        for c in (*self._slave.values(), *self._injected.values()):
            c.reset()
        self.faults.reset()

    @property
    def reception_failures(self) -> int:
        return self._slave["reception_failures"].total

    @property
    def wdt_errors(self) -> int:
        return self._slave["wdt_errors"].total

    @property
    def dropped(self) -> int:
        return self._slave["dropped"].total

    def set_slave_counters(self, counters: Mapping[str, Any]) -> list[str]:
        """Take the slave's cumulative counters from its snapshot (``StationSnapshot.counters`` as is).

        Reads ``reception_failures``, ``wdt_errors`` and ``dropped``; without ``dropped``, the sum of
        ``dropped_by_reason`` (the cards' ``StationCounters``; a number there is that sum already). Other keys are the card's own and are skipped.
        Values are the slave's totals since it started; a value lower than the previous one means the slave
        restarted, and the run total keeps what was counted before. Returns the names of the counters above
        whose value was unusable (not a non-negative integer), so the caller can log them.
        """
        values = dict(counters)
        by_reason = values.get("dropped_by_reason")
        if "dropped" not in values and isinstance(by_reason, Mapping):
            good = [v for v in by_reason.values() if isinstance(v, int) and not isinstance(v, bool) and v >= 0]
            values["dropped"] = sum(good) if len(good) == len(by_reason) else by_reason
        elif "dropped" not in values and by_reason is not None:  # already summed (the session's flattened counters)
            values["dropped"] = by_reason
        rejected = []
        for name, slot in self._slave.items():
            if name not in values:
                continue
            value = values[name]
            if isinstance(value, bool) or not isinstance(value, int) or value < 0:
                rejected.append(name)
                continue
            slot.feed(value)
        return rejected

    def summary(self, *, hdr: bool = False) -> dict[str, Any]:
        """This station's entry of the report's ``station`` object."""
        rtt: dict[str, Any] = self.rtt.summary()
        if hdr:
            rtt["hdr"] = self.rtt.encode()
        out: dict[str, Any] = {"rtt": rtt}
        out.update({name: getattr(self, name) for name in _MASTER_COUNTERS})
        out["alarms"] = self.alarms
        out.update({name: self._slave[name].total for name in SLAVE_COUNTERS})
        out["injected"] = {name: c.total for name, c in self._injected.items()}
        out.update(self.faults.summary(hdr=hdr))
        return out

    def to_wire(self, *, hdr: bool = True) -> dict[str, Any]:
        """JSON-safe state for shipping to another process (histogram HDR-encoded, or as bucket pairs with
        ``hdr=False``: ~100× cheaper); see ``from_wire``."""
        return {
            "rtt": self.rtt.encode() if hdr else self.rtt.to_pairs(),
            **{name: getattr(self, name) for name in _MASTER_COUNTERS},
            "alarms": self.alarms,
            "slave": {name: [c.base, c.last, c.zero] for name, c in self._slave.items()},
            "injected": {name: [c.base, c.last, c.zero] for name, c in self._injected.items()},
            "faults": self.faults.to_wire(hdr=hdr),
        }

    @classmethod
    def from_wire(cls, address: int, data: Mapping[str, Any]) -> StationMetrics:
        out = cls(address)
        out.rtt = _histogram(data["rtt"])
        for name in _MASTER_COUNTERS:
            setattr(out, name, _non_negative(data[name], name))
        out.alarms = _non_negative(data.get("alarms", 0), "alarms")
        for key, slots in (("slave", out._slave), ("injected", out._injected)):
            for name, pair in data.get(key, {}).items():
                if name in slots:
                    base, last, *zero = pair
                    slots[name].base = _non_negative(base, name)
                    slots[name].last = _non_negative(last, name)
                    slots[name].zero = _non_negative(zero[0], name) if zero else 0
        if "faults" in data:
            out.faults = FaultFigures.from_wire(data["faults"])
        return out

    def merge(self, other: StationMetrics) -> None:
        """Add ``other``'s figures (same station measured by another process or in another period)."""
        self.rtt.merge(other.rtt)
        for name in (*_MASTER_COUNTERS, "alarms"):
            setattr(self, name, getattr(self, name) + getattr(other, name))
        for name, c in self._slave.items():
            c.base += other._slave[name].total
        for name, c in self._injected.items():
            c.base += other._injected[name].total
        self.faults.merge(other.faults)


class NetworkMetrics:
    """All figures of one network. ``cycle_ns`` is the transmission cycle (goes to ``meta.cycle_ns``)."""

    def __init__(self, cycle_ns: int) -> None:
        if cycle_ns <= 0:
            raise ValueError(f"cycle_ns must be positive, got {cycle_ns}")
        self.cycle_ns = cycle_ns
        self.lateness = LatencyHistogram()
        self.started = 0                  # cycles whose callback ran
        self.missed = 0                   # cycles skipped by the timer
        self.stations: dict[int, StationMetrics] = {}
        self.checks: list[dict[str, Any]] = []
        self._cpu: dict[str, list[float]] = {}   # role -> [seconds base, wall base, last seconds, last wall]
        self.stalls = StallLog()          # host stalls per process (metrics/stalls.py)

    # ------------------------------------------------------------------ recording (master side)
    def station(self, station: int) -> StationMetrics:
        """The station's accumulator, created on first use (call it at bring-up so silent stations appear)."""
        sm = self.stations.get(station)
        if sm is None:
            sm = self.stations[station] = StationMetrics(station)
        return sm

    def add_stations(self, stations: Iterable[int]) -> None:
        for s in stations:
            self.station(s)

    def copy(self) -> NetworkMetrics:
        """An independent copy (sparse histograms: well under a millisecond), e.g. to build a live report
        outside the event loop that records into this one."""
        out = NetworkMetrics(self.cycle_ns)
        out.lateness = self.lateness.copy()
        out.started, out.missed = self.started, self.missed
        out.stations = {a: sm.copy() for a, sm in self.stations.items()}
        out.checks = [dict(c) for c in self.checks]
        out._cpu = {role: list(v) for role, v in self._cpu.items()}
        out.stalls = self.stalls.copy()
        return out

    def reset(self) -> None:
        """Forget the master-side figures (lateness, cycles, RTT, counters, checks) but keep the stations and the
        CPU accounting, e.g. to measure only the steady state after bring-up."""
        self.lateness.reset()
        self.started = 0
        self.missed = 0
        self.checks.clear()
        for sm in self.stations.values():
            sm.reset()

    def record_cycle_lateness(self, ns: int, skipped: int = 0) -> None:
        """One cycle started ``ns`` after its ideal start; ``skipped`` earlier cycles were not started at all.

        Maps directly onto ``CycleTimer``'s ``on_cycle(cycle, deadline_ns, now_ns, skipped)``:
        ``record_cycle_lateness(now_ns - deadline_ns, skipped)``. Skipped cycles are counted in ``missed``,
        not in the lateness histogram.
        """
        self.lateness.record(ns)
        self.started += 1
        if skipped:
            self.missed += skipped

    def record_stall(self, process: str, at_ns: int, duration_ns: int, cycles: int = 0,
                     absorbed: bool = False) -> None:
        """A host stall of *process* (see :mod:`.stalls`); ``CycleTimer.on_stall`` maps onto it for the master."""
        self.stalls.record(process, at_ns, duration_ns, cycles, absorbed)

    def stall_recorder(self, process: str) -> Callable[[int, int, int, bool], None]:
        """``CycleTimer``'s ``on_stall(deadline_ns, now_ns, cycles, absorbed)`` recording into :attr:`stalls`."""

        def on_stall(deadline_ns: int, now_ns: int, cycles: int, absorbed: bool) -> None:
            self.stalls.record(process, deadline_ns, now_ns - deadline_ns, cycles, absorbed)

        return on_stall

    def record_sent(self, station: int) -> None:
        sm = self.stations.get(station)  # self.station(station), one call fewer on the per-datagram path
        if sm is None:
            sm = self.station(station)
        sm.sent += 1

    def record_sent_burst(self, burst: list[tuple[int, bytes]]) -> None:
        """:meth:`record_sent` of each station of a cycle's burst (the master core's ``(station, datagram)``
        pairs) in one call: the loop compiled here, not run by the interpreter once per command right after the
        burst went out, while the worker it woke may be waiting for this CPU."""
        for station, _ in burst:
            self.record_sent(station)

    def record_rtt(self, station: int, ns: int) -> None:
        """A response matched to its command, ``ns`` after the command was sent (counts as answered)."""
        sm = self.stations.get(station)
        if sm is None:
            sm = self.station(station)
        sm.rtt.record(ns)
        sm.answered += 1

    def record_late(self, station: int) -> None:
        """The response just given to ``record_rtt`` arrived after its cycle's deadline."""
        self.station(station).late += 1

    def record_missing(self, station: int) -> None:
        """A command to ``station`` will never be answered."""
        self.station(station).missing += 1

    def record_alarm(self, station: int) -> None:
        """``station`` raised an alarm (the master's ``AlarmRaised``)."""
        self.station(station).alarms += 1

    def record_injected(self, station: int, counts: Mapping[str, int]) -> None:
        """What the fault injection did to ``station`` so far (cumulative, as ``set_slave_counters``)."""
        self.station(station).set_injected(counts)
    # ------------------------------------------------------------------ faults (mlink_sim.faults, docs/faults.md)
    def record_recovery(self, station: int, ns: int) -> None:
        """*station* was healthy again *ns* after a fault ended."""
        self.station(station).faults.recovery.record(ns)

    def record_unrecovered(self, station: int) -> None:
        """A fault of *station* ended and the station did not recover (given up after a minute)."""
        self.station(station).faults.unrecovered += 1

    # ------------------------------------------------------------------ recording (from other processes)
    def record_slave_counters(self, station: int, counters: Mapping[str, Any]) -> list[str]:
        """Cumulative counters from the slave's snapshot; returns rejected names (see ``set_slave_counters``)."""
        return self.station(station).set_slave_counters(counters)

    def record_cpu(self, role: str, seconds: float, wall: float) -> None:
        """A process used ``seconds`` of CPU in ``wall`` seconds, both cumulative since it started.

        ``role`` is ``"master"``, ``"slave:0x21"``, ``"worker:1"`` (a process serving several slaves) or any
        other name (``"supervisor"``): only the first counts towards ``cpu.master``, ``slave:``/``worker:``
        towards ``cpu.slaves``. Feed the latest totals as often as convenient; a process restart (totals
        drop) is carried over.
        """
        if seconds < 0 or wall < 0:
            raise ValueError(f"cpu figures must be non-negative, got seconds={seconds} wall={wall}")
        st = self._cpu.get(role)
        if st is None:
            st = self._cpu[role] = [0.0, 0.0, 0.0, 0.0]
        if seconds < st[2] or wall < st[3]:
            st[0] += st[2]
            st[1] += st[3]
        st[2], st[3] = seconds, wall

    def record_check(self, at: float, what: str, ok: bool, detail: str | None = None, cause: str | None = None,
                     station: int | None = None) -> None:
        """A timeline check's outcome, ``at`` seconds into the run; *cause*: what the drive was doing when a check
        of it failed (docs/report.md, ``checks[].cause``); *station*: the station it judged (``"0x21"`` in the
        report, so the HTML report finds the station's figures at that moment in the trace)."""
        entry: dict[str, Any] = {"at": round(float(at), 6), "what": what, "ok": bool(ok)}
        if station is not None:
            entry["station"] = station_key(station)
        if detail:
            entry["detail"] = detail
        if cause:
            entry["cause"] = cause
        self.checks.append(entry)

    # ------------------------------------------------------------------ figures
    @property
    def cycles(self) -> int:
        """Cycles due: started + missed."""
        return self.started + self.missed

    @property
    def rtt(self) -> LatencyHistogram:
        """Network-wide RTT histogram (a new merge of all stations' histograms on each access)."""
        return LatencyHistogram.merged(sm.rtt for sm in self.stations.values())

    def cpu_percent(self) -> dict[str, float]:
        """CPU % of one core per role (seconds / wall × 100)."""
        out = {}
        for role, (sb, wb, s, w) in sorted(self._cpu.items()):
            wall = wb + w
            out[role] = round((sb + s) / wall * 100.0, 3) if wall > 0 else 0.0
        return out

    def report(self, *, meta: Mapping[str, Any], hdr: bool = False) -> dict[str, Any]:
        """The report document (schema: ``REPORT_SCHEMA``, fields: docs/report.md).

        ``meta`` must give ``config``, ``started`` (ISO 8601) and ``duration_s``; ``cycle_ns`` and ``stations``
        default to this network's. ``hdr=True`` adds each histogram's HDR blob (``"hdr"``) for offline
        analysis. ``assertions`` is left empty: the caller fills it from ``check_all``.
        """
        stations = {station_key(a): sm.summary(hdr=hdr) for a, sm in sorted(self.stations.items())}
        # Any, not float: compiled (mypyc), sum() of no floats would be 0.0 where Python's is 0 (the virtual
        # clock's reports, which have no CPU figures, are compared byte for byte with the pure build's)
        by_process: dict[str, Any] = self.cpu_percent()

        def total(name: str) -> int:
            return sum(s[name] for s in stations.values())

        def hist(h: LatencyHistogram) -> dict[str, Any]:
            out: dict[str, Any] = h.summary()
            if hdr:
                out["hdr"] = h.encode()
            return out

        cycles = self.cycles
        rtt = self.rtt
        meta_out = dict(meta)
        meta_out.setdefault("cycle_ns", self.cycle_ns)
        meta_out.setdefault("stations", len(self.stations))
        return {
            "schema": SCHEMA_ID,
            "meta": meta_out,
            "cycles": cycles,
            "missed": self.missed,
            "missed_rate": self.missed / cycles if cycles else 0.0,
            "rtt": {**hist(rtt), "bins": rtt.bins()},
            "lateness": hist(self.lateness),
            **{name: total(name) for name in _MASTER_COUNTERS},
            **{name: total(name) for name in SLAVE_COUNTERS},
            "cpu": {
                "master": round(sum(v for r, v in by_process.items() if r == "master"), 3),
                "slaves": round(sum(v for r, v in by_process.items() if r.startswith(("slave:", "worker:"))), 3),
                "by_process": by_process,
            },
            "host": self.stalls.report(),
            "station": stations,
            "checks": list(self.checks),
            "assertions": [],
        }

    # ------------------------------------------------------------------ transport between processes
    def to_wire(self, *, hdr: bool = True) -> dict[str, Any]:
        """JSON-safe state of everything recorded (histograms HDR-encoded, or bucket pairs with ``hdr=False``),
        for :meth:`from_wire`."""
        return {
            "cycle_ns": self.cycle_ns,
            "started": self.started,
            "missed": self.missed,
            "lateness": self.lateness.encode() if hdr else self.lateness.to_pairs(),
            "stations": {station_key(a): sm.to_wire(hdr=hdr) for a, sm in self.stations.items()},
            "cpu": {role: list(v) for role, v in self._cpu.items()},
            "checks": list(self.checks),
            "stalls": self.stalls.to_wire(),
        }

    @classmethod
    def from_wire(cls, data: Mapping[str, Any]) -> NetworkMetrics:
        """Rebuild from :meth:`to_wire`. Malformed input raises ValueError (or KeyError/TypeError)."""
        out = cls(int(data["cycle_ns"]))
        out.started = _non_negative(data["started"], "started")
        out.missed = _non_negative(data["missed"], "missed")
        out.lateness = _histogram(data["lateness"])
        for key, sd in data["stations"].items():
            address = int(key, 16)
            out.stations[address] = StationMetrics.from_wire(address, sd)
        for role, v in data.get("cpu", {}).items():
            if len(v) != 4 or any(x < 0 for x in v):
                raise ValueError(f"bad cpu entry for {role!r}: {v!r}")
            out._cpu[str(role)] = [float(x) for x in v]
        out.checks = [dict(c) for c in data.get("checks", [])]
        if "stalls" in data:
            out.stalls = StallLog.from_wire(data["stalls"])
        return out

    def merge(self, other: NetworkMetrics) -> None:
        """Add another process's (or period's) figures for the same network."""
        self.lateness.merge(other.lateness)
        self.started += other.started
        self.missed += other.missed
        for address, sm in other.stations.items():
            self.station(address).merge(sm)
        for role, (sb, wb, s, w) in other._cpu.items():
            st = self._cpu.setdefault(role, [0.0, 0.0, 0.0, 0.0])
            st[0] += sb + s
            st[1] += wb + w
        self.checks.extend(other.checks)
        self.stalls.merge(other.stalls)


def _histogram(data: Any) -> LatencyHistogram:
    """A histogram from its wire form: an HDR blob (str) or bucket pairs (list)."""
    if isinstance(data, list):
        return LatencyHistogram.from_pairs(data)
    return LatencyHistogram.decode(data)


def _non_negative(value: Any, name: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < 0:
        raise ValueError(f"{name} must be a non-negative integer, got {value!r}")
    return value
