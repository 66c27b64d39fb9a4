"""What held the CPUs when answers came late: each late cycle of a network (and, with ``--floor``, of its batched
floor) put beside a ``perf`` record of both CPUs, and named by what ran instead (docs/performance.md, "What bounds each figure").

The network is brought up as :mod:`benchmarks.bench` brings up a cell (the same configuration, one worker per CPU but
one), then measured for ``--duration`` while ``perf record -e cpu-clock -c 100000 -a -k CLOCK_MONOTONIC`` samples
every CPU each 100 µs of its time. The master keeps each answer later than one transmission cycle (its time and
round trip, in a preallocated array: no allocation per answer, no garbage collection caused by the record).
Answers whose commands went out within :data:`SAME_CYCLE_NS` of each other are one **late cycle**; its window runs
from the commands' send to the last late answer. Each late cycle is named by the largest of (:func:`attribute`):

* **a task of the host** (``held by kdamond.0``): a process or kernel thread other than the simulator's ran on a
  CPU for that share of the window;
* **vCPU not running**: a CPU took no sample for that share of the window (its virtual CPU was not run by the
  hypervisor: steal);
* **garbage collection**: the simulator's processes were in CPython's collector (``gc_collect_main`` …);
* **own work** otherwise, if the measured processes (the simulator's, or the floor's) ran for most of the
  window on one CPU; else **unexplained**.

A share below :data:`MIN_SHARE` names nothing (unexplained). The same is done for the floor (``--floor``: the
batched floor of :mod:`benchmarks.floor`, one process serving all the stations on one socket), one after the
other, so the two can be compared. Both run with ordinary scheduling: with ``mlink-sim up``'s real-time requests
(SCHED_FIFO, the master's CPU apart) the record itself raised the network's late answers from 0.13–0.29 %
(the capacity sweep with real time, no perf) to 1.8–6.0 %, so this tool does not offer them. Root only (``perf`` over
every CPU), with ``perf`` installed (Debian: ``linux-perf``); otherwise exit 2. Late cycles of the moments perf
was not yet or no longer recording are counted apart ("outside the perf record").

``--sched`` records the scheduler's switches and wake-ups in the same ``perf`` record, and says for each late cycle
where **the process that answers** (the worker; the floor's server) was when the commands went out
(:func:`answerer_states`): **running** (its arrival poll, or still at work), **waiting for a CPU** (preempted, or
woken and not yet run), or **asleep**, and then how long after the send the kernel woke it (within 40 µs,
40–100 µs, over 100 µs: a halted vCPU that the hypervisor ran late). A second table counts the late cycles and
answers so. The record adds perf's own cost of every switch and wake-up, not measured apart (docs/performance.md,
"What bounds each figure").

Run from the repository's root, as root:

    python -m benchmarks.lab.late_causes --stations 62 --links ML3 --cycles 1ms --duration 15s --floor
    python -m benchmarks.lab.late_causes --stations 30 --links ML2 --json late.json
    python -m benchmarks.lab.late_causes --stations 8 --cycles 250us --floor --sched   # where the answerer was
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from array import array
from bisect import bisect_left, bisect_right
from collections import Counter
from collections.abc import Iterable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from mlink_sim.aio.run.session import NetworkSession
from mlink_sim.aio.transport.udp import new_event_loop
from mlink_sim.cli.logs import configure_logging
from mlink_sim.config import load_config, parse_duration_ns
from mlink_sim.metrics import LatencyHistogram

from benchmarks import floor
from benchmarks.bench import watching_rtt, write_config
from benchmarks.common import write_atomically

__all__ = ["Sample", "LateCycle", "LateLog", "Switch", "Wakeup", "answerer_states", "attribute", "parse_sched",
           "parse_samples", "summarise"]

SAMPLE_NS = 100_000  #: perf's cpu-clock period: one sample per CPU each 100 µs of its time, ≥ 10 in a late window
PERF_LEAD_S = 1.0  #: perf records this long before the window opens: its start-up is not measured
SAME_CYCLE_NS = 300_000  #: late answers whose commands went out closer than this are one late cycle
MIN_SHARE = 0.3  #: the share of a late cycle's window a cause must hold on one CPU to be named
GC_SYMBOLS = ("gc_collect", "visit_decref", "visit_reachable", "subtract_refs", "move_unreachable", "update_refs",
              "deduce_unreachable", "list_traverse", "dict_traverse", "tupletraverse", "subtype_traverse")
_LINE = re.compile(r"\s*(\d+)\s+\[(\d+)\]\s+([\d.]+):\s+cpu-clock:\s*(?:\S+\s*(\S*))?")
_SWITCH = re.compile(r"\s*\d+\s+\[(\d+)\]\s+([\d.]+):\s+sched:sched_switch:\s+prev_comm=.*? prev_pid=(\d+) "
                     r"prev_prio=\S+ prev_state=(\S+) ==> next_comm=.*? next_pid=(\d+)")
_WAKEUP = re.compile(r"\s*\d+\s+\[(\d+)\]\s+([\d.]+):\s+sched:sched_wakeup:\s+comm=.*? pid=(\d+) prio=\S+ "
                     r"target_cpu=(\d+)")
#: how soon after the commands' send an asleep answering process was woken: the bounds of the --sched table's rows
WAKE_BOUNDS_NS = (40_000, 100_000)


@dataclass(frozen=True)
class Sample:
    """One cpu-clock sample: when (monotonic ns), where, which task (0: idle), in which function."""

    t: int
    cpu: int
    pid: int
    sym: str


@dataclass
class LateCycle:
    """One late cycle: its commands' send time, the number of late answers, the window it held, what was named."""

    sent: int
    answers: int
    end: int
    cause: str = "unexplained"
    shares: dict[str, float] = field(default_factory=dict)
    answerer: str = ""  #: --sched: where the answering process was at the send (answerer_states)
    woken_us: float | None = None  #: --sched: its wake-up after the send (asleep at the send), µs
    running_us: float | None = None  #: --sched: when it ran after the send (not running at the send), µs


@dataclass(frozen=True)
class Switch:
    """One ``sched_switch``: when (monotonic ns), on which CPU, the task switched out (its state: ``S``/``D``
    asleep, ``R``/``R+`` preempted) and the task switched in (0: idle)."""

    t: int
    cpu: int
    prev: int
    prev_state: str
    next: int


@dataclass(frozen=True)
class Wakeup:
    """One ``sched_wakeup``: when, which task, onto which CPU."""

    t: int
    pid: int
    cpu: int


class LateLog:
    """The late answers, kept without an allocation each: (read time, round trip) in two preallocated arrays."""

    def __init__(self, capacity: int = 1 << 20) -> None:
        self.read = array("q", bytes(8 * capacity))
        self.rtt = array("q", bytes(8 * capacity))
        self.n = 0
        self.dropped = 0

    def add(self, now: int, rtt: int) -> None:
        n = self.n
        if n < len(self.read):
            self.read[n] = now
            self.rtt[n] = rtt
            self.n = n + 1
        else:
            self.dropped += 1

    def cycles(self) -> list[LateCycle]:
        """The late answers grouped by cycle (commands sent within :data:`SAME_CYCLE_NS`), by send time."""
        answers = sorted((self.read[i] - self.rtt[i], self.read[i]) for i in range(self.n))
        out: list[LateCycle] = []
        for sent, read in answers:
            if out and sent - out[-1].sent < SAME_CYCLE_NS:
                out[-1].answers += 1
                out[-1].end = max(out[-1].end, read)
            else:
                out.append(LateCycle(sent, 1, read))
        return out


def parse_samples(lines: Iterable[str]) -> list[Sample]:
    """``perf script -F pid,cpu,time,event,ip,sym`` output (``  1234 [001] 12.345678: cpu-clock: ffff… sym``) →
    samples by time (a sample without a symbol has ``sym`` ""); lines of any other form are skipped."""
    out = []
    for line in lines:
        m = _LINE.match(line)
        if m:
            out.append(Sample(round(float(m.group(3)) * 1e9), int(m.group(2)), int(m.group(1)), m.group(4) or ""))
    out.sort(key=lambda s: s.t)
    return out


def parse_sched(lines: Iterable[str]) -> tuple[list[Switch], list[Wakeup]]:
    """``perf script`` lines of ``sched:sched_switch`` and ``sched:sched_wakeup`` (``pid [cpu] time: event:
    fields``, the comm taken off as :func:`parse_samples` has it) → switches and wake-ups, each by time; lines of
    any other form are skipped."""
    switches, wakeups = [], []
    for line in lines:
        m = _SWITCH.match(line)
        if m:
            switches.append(Switch(round(float(m.group(2)) * 1e9), int(m.group(1)), int(m.group(3)), m.group(4),
                                   int(m.group(5))))
            continue
        m = _WAKEUP.match(line)
        if m:
            wakeups.append(Wakeup(round(float(m.group(2)) * 1e9), int(m.group(3)), int(m.group(4))))
    switches.sort(key=lambda e: e.t)
    wakeups.sort(key=lambda e: e.t)
    return switches, wakeups


def answerer_states(cycles: list[LateCycle], switches: list[Switch], wakeups: list[Wakeup],
                    answerers: set[int]) -> None:
    """Where the answering processes (*answerers*: the workers, or the floor's server) were when each of *cycles*'
    commands went out (``LateCycle.sent``), from the scheduler's events by time (module docstring, ``--sched``):
    "running at the send" if one of them was on a CPU; else "waiting for a CPU at the send" if the last one
    switched out was left runnable (preempted) or was woken since, or "asleep, woken …" by how long after the send
    the first of them was woken; "not seen" where the events say nothing (outside the record). Sets ``answerer``,
    ``woken_us`` and ``running_us``; *cycles* need not be in order."""
    mine = [e for e in switches if e.prev in answerers or e.next in answerers]
    times = [e.t for e in mine]
    woken = [e for e in wakeups if e.pid in answerers]
    wake_times = [e.t for e in woken]
    low, high = (b // 1000 for b in WAKE_BOUNDS_NS)
    running: set[int] = set()  # who of them is on a CPU: the events up to the send, replayed once in order
    last_out: Switch | None = None
    k = 0
    for c in sorted(cycles, key=lambda c: c.sent):
        i = bisect_right(times, c.sent)
        for e in mine[k:i]:
            if e.prev in answerers:
                running.discard(e.prev)
                last_out = e
            if e.next in answerers:
                running.add(e.next)
        k = i
        after = next((e for e in mine[i:] if e.next in answerers), None)
        c.running_us = None if after is None or running else round((after.t - c.sent) / 1000, 1)
        if running:
            c.answerer = "running at the send"
        elif last_out is None and after is None:
            c.answerer = "not seen"
        else:
            j = bisect_left(wake_times, c.sent)
            if last_out is not None and (last_out.prev_state.startswith("R")  # preempted, or woken but not yet run
                                         or (j and woken[j - 1].t > last_out.t)):
                c.answerer = "waiting for a CPU at the send"
                continue
            wake = woken[j] if j < len(woken) else None
            if wake is None:
                c.answerer = "not seen"
                continue
            us = c.woken_us = round((wake.t - c.sent) / 1000, 1)
            c.answerer = (f"asleep, woken within {low} µs" if us <= low else
                          f"asleep, woken {low}–{high} µs after" if us <= high else
                          f"asleep, woken over {high} µs after")


def attribute(cycles: list[LateCycle], samples: list[Sample], ours: set[int], cpus: int,
              names: dict[int, str]) -> None:
    """Name each of *cycles* by what the *samples* (by time) show in its window (module docstring); *ours*: the
    simulator's (or floor's) process ids; *names*: pid → command name of the host's tasks."""
    times = [s.t for s in samples]
    for c in cycles:
        span = max(c.end - c.sent, SAMPLE_NS)
        expect = span / SAMPLE_NS
        per_cpu: dict[int, Counter[str]] = {cpu: Counter() for cpu in range(cpus)}
        for s in samples[bisect_left(times, c.sent):bisect_right(times, c.end)]:
            kind = ("idle" if s.pid == 0 else
                    ("garbage collection" if s.sym.startswith(GC_SYMBOLS) else "ours") if s.pid in ours else
                    f"held by {names.get(s.pid, str(s.pid))}")
            per_cpu.setdefault(s.cpu, Counter())[kind] += 1
        shares: dict[str, float] = {"ours": 0.0}
        for counts in per_cpu.values():
            missing = max(0.0, expect - sum(counts.values()))
            for kind, n in [*counts.items(), ("vCPU not running", missing)]:
                shares[kind] = max(shares.get(kind, 0.0), n / expect)
        c.shares = {k: round(v, 2) for k, v in shares.items() if v}
        named = {k: v for k, v in shares.items() if k not in ("ours", "idle")}
        kind, share = max(named.items(), key=lambda kv: kv[1], default=("", 0.0))
        if share >= MIN_SHARE:
            c.cause = kind
        elif shares["ours"] >= 0.5:
            c.cause = "own work"


def summarise(cycles: list[LateCycle], answers_total: int, key: str = "cause") -> dict[str, Any]:
    """Late answers and cycles per cause (*key* ``"answerer"``: per answerer's state), and their share of all
    answers read (the missed rate they make)."""
    by: dict[str, dict[str, Any]] = {}
    for c in cycles:
        row = by.setdefault(getattr(c, key), {"cycles": 0, "answers": 0})
        row["cycles"] += 1
        row["answers"] += c.answers
    for row in by.values():
        row["pct_of_answers"] = round(100 * row["answers"] / answers_total, 3) if answers_total else 0.0
    return dict(sorted(by.items(), key=lambda kv: -kv[1]["answers"]))


# ----------------------------------------------------------------------------------------------- measuring
class _Perf:
    """``perf record`` of every CPU for *seconds*, from now; :meth:`samples` once it has ended."""

    def __init__(self, path: Path, seconds: float, sched: bool = False) -> None:
        self.path = path
        self.sched = sched
        events = ["-e", "cpu-clock", "-c", str(SAMPLE_NS)]
        if sched:  # the tracepoints take every event (no -c of theirs)
            events += ["-e", "sched:sched_switch", "-e", "sched:sched_wakeup"]
        self.proc = subprocess.Popen(["perf", "record", "-q", *events, "-a", "-k", "CLOCK_MONOTONIC", "-o", str(path),
                                      "--", "sleep", f"{seconds:.3f}"],
                                     stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)

    def samples(self) -> tuple[list[Sample], dict[int, str], tuple[list[Switch], list[Wakeup]]]:
        """The cpu-clock samples, the tasks' names, and (``sched``) the scheduler's switches and wake-ups."""
        _, err = self.proc.communicate(timeout=120)
        if self.proc.returncode != 0:
            raise RuntimeError(f"perf record failed: {err.decode(errors='replace').strip()[-300:]}")
        fields = ["-F", "sw:comm,pid,cpu,time,event,ip,sym"] + (["-F", "trace:comm,pid,cpu,time,event,trace"]
                                                               if self.sched else [])
        out = subprocess.run(["perf", "script", "-i", str(self.path), *fields],
                             capture_output=True, text=True, timeout=600)
        names: dict[int, str] = {}
        lines = []
        for line in out.stdout.splitlines():  # "comm pid [cpu] time: event: addr sym": the comm may hold blanks
            m = re.match(r"\s*(.*?)\s+(\d+)\s+(\[\d+\].*)", line)
            if m:
                names.setdefault(int(m.group(2)), m.group(1))
                lines.append(f"{m.group(2)} {m.group(3)}")
        return parse_samples(lines), names, parse_sched(lines) if self.sched else ([], [])


async def _network(config_path: Path, duration_s: float, tmp: Path, sched: bool = False) -> dict[str, Any]:
    config = load_config(config_path)
    cycle = config.network.transmission_cycle
    session = await NetworkSession.open(config, config_path, workers=max(1, (os.cpu_count() or 1) - 1),
                                        restart_slaves=False)
    log, count = LateLog(), [0]
    try:
        not_up = await session.bring_up(timeout=20.0)
        if not_up:
            raise RuntimeError(f"{len(not_up)} station(s) not up")
        perf = _Perf(tmp / "network.data", duration_s + PERF_LEAD_S + 0.5, sched)
        await asyncio.sleep(PERF_LEAD_S)  # perf's own start-up (symbols, buffers) kept out of the window

        def on_rtt(ns: int) -> None:
            count[0] += 1
            if ns > cycle:
                log.add(time.monotonic_ns(), ns)

        with watching_rtt(session, on_rtt):
            await asyncio.sleep(duration_s)
        workers = {w.pid for w in session.worker_list if w.pid}
    finally:
        await session.close()
    samples, names, events = perf.samples()
    return _judge("network", log, count[0], samples, names, {os.getpid()} | workers, events, workers)


async def _floor(stations: int, size: int, cycle_ns: int, duration_s: float, tmp: Path,
                 sched: bool = False) -> dict[str, Any]:
    log, count, pids = LateLog(), [0], {os.getpid()}

    class Recording:  # the floor client's RTT histogram, which also keeps the late answers (compiled: wrapped)
        def __init__(self) -> None:
            self.histogram = LatencyHistogram()

        def record(self, ns: int) -> None:
            self.histogram.record(ns)
            count[0] += 1
            if ns > cycle_ns:
                log.add(time.monotonic_ns(), ns)

        def reset(self) -> None:  # the end of the floor's warm-up: the window starts
            self.histogram.reset()
            count[0] = log.n = 0

        def __getattr__(self, name: str) -> Any:
            return getattr(self.histogram, name)

    async def during(procs: list[int], seconds: float) -> None:  # the floor's client and server
        pids.update(procs)
        await asyncio.sleep(seconds)

    made: list[Any] = []

    def histogram() -> Any:  # floor_window makes its RTT histogram first, then its clock's lateness histogram
        made.append(Recording() if not made else LatencyHistogram())
        return made[-1]

    perf = _Perf(tmp / "floor.data", duration_s + PERF_LEAD_S + 0.5, sched)
    saved = floor.LatencyHistogram
    floor.LatencyHistogram = histogram  # type: ignore[misc,assignment]
    await asyncio.sleep(max(0.0, PERF_LEAD_S - floor.WARM_UP_S))  # the rest of the lead is the warm-up
    try:
        await floor.floor_window(stations, size, cycle_ns, duration_s, True, shared=True, during=during)
    finally:
        floor.LatencyHistogram = saved  # type: ignore[misc]
    samples, names, events = perf.samples()
    return _judge("floor", log, count[0], samples, names, pids, events, pids - {os.getpid()})


def _judge(side: str, log: LateLog, answers: int, samples: list[Sample], names: dict[int, str],
           ours: set[int], events: tuple[list[Switch], list[Wakeup]] = ([], []),
           answerers: set[int] | None = None) -> dict[str, Any]:
    """The late cycles named (and, with scheduler *events*, where the *answerers* were), summed up per cause."""
    cycles = log.cycles()
    attribute(cycles, samples, ours, os.cpu_count() or 1, names)
    switches, wakeups = events
    if switches:
        answerer_states(cycles, switches, wakeups, answerers or set())
    first, last = (samples[0].t, samples[-1].t) if samples else (0, -1)
    for c in cycles:
        if c.sent < first or c.end > last:  # perf starts and stops a moment apart from the window
            c.cause, c.shares = "outside the perf record", {}
            if switches:
                c.answerer = "outside the perf record"
    late = sum(c.answers for c in cycles)
    result = {"side": side, "answers": answers, "late_answers": late, "late_pct": round(100 * late / answers, 3)
              if answers else 0.0, "dropped": log.dropped, "causes": summarise(cycles, answers)}
    if switches:
        result["answerer"] = summarise(cycles, answers, "answerer")
    result["cycles"] = [asdict(c) for c in cycles]
    return result


def _print(result: dict[str, Any]) -> None:
    print(f"{result['side']}: {result['answers']} answers read, {result['late_answers']} later than a cycle "
          f"({result['late_pct']:.3f} %)")
    for cause, row in result["causes"].items():
        print(f"  {cause:<34} {int(row['cycles']):>5} late cycles {int(row['answers']):>7} answers "
              f"{row['pct_of_answers']:>7.3f} % of all")
    if "answerer" in result:
        print(f"  the answering process ({'worker' if result['side'] == 'network' else 'server'}) when the commands "
              "went out:")
        for state, row in result["answerer"].items():
            print(f"    {state:<32} {int(row['cycles']):>5} late cycles {int(row['answers']):>7} answers "
                  f"{row['pct_of_answers']:>7.3f} % of all")


def main() -> int:
    ap = argparse.ArgumentParser(prog="python -m benchmarks.lab.late_causes", description=__doc__.split("\n\n")[0])
    ap.add_argument("--stations", type=int, default=62)
    ap.add_argument("--links", default="ML3", choices=("ML2", "ML3"))
    ap.add_argument("--cycles", default="1ms", help="the transmission cycle")
    ap.add_argument("--duration", default="15s")
    ap.add_argument("--floor", action="store_true", help="the batched floor as well, after the network")
    ap.add_argument("--json", type=Path, default=None, help="write every late cycle here")
    ap.add_argument("--sched", action="store_true",
                    help="record the scheduler's switches and wake-ups too: where the answering process was")
    args = ap.parse_args()
    try:
        cycle = parse_duration_ns(args.cycles, default_unit="us")
        duration = parse_duration_ns(args.duration, default_unit="s") / 1e9
        if not 1 <= args.stations <= 62 or duration <= 0:
            raise ValueError("--stations 1–62, --duration > 0")
    except ValueError as exc:
        print(f"late_causes.py: {exc}", file=sys.stderr)
        return 2
    if shutil.which("perf") is None:
        print("late_causes.py: perf is not installed (Debian: apt-get install linux-perf)", file=sys.stderr)
        return 2
    if os.geteuid() != 0:
        print("late_causes.py: perf over every CPU needs root", file=sys.stderr)
        return 2
    configure_logging(level="error")
    loop = new_event_loop()
    results = []
    try:
        with tempfile.TemporaryDirectory(prefix="mlink-late-") as tmp:
            path = Path(tmp) / "net.toml"
            size = write_config(path, args.links, args.stations, cycle)
            results.append(loop.run_until_complete(_network(path, duration, Path(tmp), args.sched)))
            _print(results[-1])
            if args.floor:
                results.append(loop.run_until_complete(_floor(args.stations, size, cycle, duration, Path(tmp),
                                                              args.sched)))
                _print(results[-1])
    except (RuntimeError, OSError, subprocess.SubprocessError) as exc:
        print(f"late_causes.py: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:  # perf, in the same process group, stopped with it
        print("late_causes.py: interrupted, nothing written", file=sys.stderr)
        return 130
    finally:
        loop.close()
    if args.json is not None:
        write_atomically(args.json, json.dumps({"stations": args.stations, "link": args.links, "cycle_ns": cycle,
                                                "duration_s": duration, "results": results}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
