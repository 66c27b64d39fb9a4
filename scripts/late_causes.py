#!/usr/bin/env python3
"""What held the CPUs when answers came late: each late cycle of a network (and, with ``--floor``, of its batched
floor) put beside a ``perf`` record of both CPUs, and named by what ran instead (docs/performance.md, "What holds
the CPU when answers come late (session 18)").

The network is brought up as ``scripts/bench.py`` brings up a cell (the same configuration, one worker per CPU but
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
batched floor of ``scripts/bench_floor.py``, one process serving all the stations on one socket), one after the
other, so the two can be compared. Both run with ordinary scheduling: with ``mlink-sim up``'s real-time requests
(SCHED_FIFO, the master's CPU apart) the record itself raised the network's late answers from 0.13–0.29 %
(``bench.py --realtime``, no perf) to 1.8–6.0 %, so this script does not offer them. Root only (``perf`` over
every CPU), with ``perf`` installed (Debian: ``linux-perf``); otherwise exit 2. Late cycles of the moments perf
was not yet or no longer recording are counted apart ("outside the perf record").

    scripts/late_causes.py --stations 62 --links ML3 --cycles 1ms --duration 15s --floor
    scripts/late_causes.py --stations 30 --links ML2 --json late.json
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

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import bench_floor
from bench import write_config

from mlink_sim._files import write_atomically
from mlink_sim.aio.session import NetworkSession
from mlink_sim.aio.udp import new_event_loop
from mlink_sim.cli.logs import configure_logging
from mlink_sim.config import load_config, parse_duration_ns
from mlink_sim.metrics import LatencyHistogram

__all__ = ["Sample", "LateCycle", "LateLog", "attribute", "parse_samples", "summarise"]

SAMPLE_NS = 100_000  #: perf's cpu-clock period: one sample per CPU each 100 µs of its time, ≥ 10 in a late window
PERF_LEAD_S = 1.0  #: perf records this long before the window opens: its start-up is not measured
SAME_CYCLE_NS = 300_000  #: late answers whose commands went out closer than this are one late cycle
MIN_SHARE = 0.3  #: the share of a late cycle's window a cause must hold on one CPU to be named
GC_SYMBOLS = ("gc_collect", "visit_decref", "visit_reachable", "subtract_refs", "move_unreachable", "update_refs",
              "deduce_unreachable", "list_traverse", "dict_traverse", "tupletraverse", "subtype_traverse")
_LINE = re.compile(r"\s*(\d+)\s+\[(\d+)\]\s+([\d.]+):\s+cpu-clock:\s*(?:\S+\s*(\S*))?")


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


def summarise(cycles: list[LateCycle], answers_total: int) -> dict[str, Any]:
    """Late answers and cycles per cause, and their share of all answers read (the missed rate they make)."""
    by: dict[str, dict[str, Any]] = {}
    for c in cycles:
        row = by.setdefault(c.cause, {"cycles": 0, "answers": 0})
        row["cycles"] += 1
        row["answers"] += c.answers
    for row in by.values():
        row["pct_of_answers"] = round(100 * row["answers"] / answers_total, 3) if answers_total else 0.0
    return dict(sorted(by.items(), key=lambda kv: -kv[1]["answers"]))


# ----------------------------------------------------------------------------------------------- measuring
class _Perf:
    """``perf record`` of every CPU for *seconds*, from now; :meth:`samples` once it has ended."""

    def __init__(self, path: Path, seconds: float) -> None:
        self.path = path
        self.proc = subprocess.Popen(["perf", "record", "-q", "-e", "cpu-clock", "-c", str(SAMPLE_NS), "-a", "-k",
                                      "CLOCK_MONOTONIC", "-o", str(path), "--", "sleep", f"{seconds:.3f}"],
                                     stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)

    def samples(self) -> tuple[list[Sample], dict[int, str]]:
        _, err = self.proc.communicate(timeout=120)
        if self.proc.returncode != 0:
            raise RuntimeError(f"perf record failed: {err.decode(errors='replace').strip()[-300:]}")
        out = subprocess.run(["perf", "script", "-i", str(self.path), "-F", "comm,pid,cpu,time,event,ip,sym"],
                             capture_output=True, text=True, timeout=600)
        names: dict[int, str] = {}
        lines = []
        for line in out.stdout.splitlines():  # "comm pid [cpu] time: event: addr sym": the comm may hold blanks
            m = re.match(r"\s*(.*?)\s+(\d+)\s+(\[\d+\].*)", line)
            if m:
                names.setdefault(int(m.group(2)), m.group(1))
                lines.append(f"{m.group(2)} {m.group(3)}")
        return parse_samples(lines), names


async def _network(config_path: Path, duration_s: float, tmp: Path) -> dict[str, Any]:
    config = load_config(config_path)
    cycle = config.network.transmission_cycle
    session = await NetworkSession.open(config, config_path, workers=max(1, (os.cpu_count() or 1) - 1),
                                        restart_slaves=False)
    log, count = LateLog(), [0]
    try:
        not_up = await session.bring_up(timeout=20.0)
        if not_up:
            raise RuntimeError(f"{len(not_up)} station(s) not up")
        perf = _Perf(tmp / "network.data", duration_s + PERF_LEAD_S + 0.5)
        await asyncio.sleep(PERF_LEAD_S)  # perf's own start-up (symbols, buffers) kept out of the window
        hooked = [(master, master.core.on_rtt) for master in session.masters.values()]
        for master, record in hooked:

            def on_rtt(station: int, ns: int, record: Any = record) -> None:
                record(station, ns)
                count[0] += 1
                if ns > cycle:
                    log.add(time.monotonic_ns(), ns)

            master.core.on_rtt = on_rtt
        await asyncio.sleep(duration_s)
        for master, record in hooked:
            master.core.on_rtt = record
        ours = {os.getpid()} | {w.pid for w in session.worker_list if w.pid}
    finally:
        await session.close()
    samples, names = perf.samples()
    return _judge("network", log, count[0], samples, names, ours)


async def _floor(stations: int, size: int, cycle_ns: int, duration_s: float, tmp: Path) -> dict[str, Any]:
    log, count, pids = LateLog(), [0], {os.getpid()}
    perf: list[_Perf] = []

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

    popen = subprocess.Popen

    def spawn(*args: Any, **kwargs: Any) -> Any:
        proc = popen(*args, **kwargs)
        pids.add(proc.pid)
        return proc

    made: list[Any] = []

    def histogram() -> Any:  # floor_window makes its RTT histogram first, then its clock's lateness histogram
        made.append(Recording() if not made else LatencyHistogram())
        return made[-1]

    saved = bench_floor.LatencyHistogram, bench_floor.subprocess.Popen
    bench_floor.LatencyHistogram, bench_floor.subprocess.Popen = histogram, spawn  # type: ignore[misc,assignment]
    perf.append(_Perf(tmp / "floor.data", duration_s + PERF_LEAD_S + 0.5))
    await asyncio.sleep(max(0.0, PERF_LEAD_S - bench_floor._WARM_UP_S))  # the rest of the lead is the warm-up
    try:
        await bench_floor.floor_window(stations, size, cycle_ns, duration_s, True, shared=True)
    finally:
        bench_floor.LatencyHistogram, bench_floor.subprocess.Popen = saved  # type: ignore[misc]
    samples, names = perf[0].samples()
    return _judge("floor", log, count[0], samples, names, pids)


def _judge(side: str, log: LateLog, answers: int, samples: list[Sample], names: dict[int, str],
           ours: set[int]) -> dict[str, Any]:
    cycles = log.cycles()
    attribute(cycles, samples, ours, os.cpu_count() or 1, names)
    first, last = (samples[0].t, samples[-1].t) if samples else (0, -1)
    for c in cycles:
        if c.sent < first or c.end > last:  # perf starts and stops a moment apart from the window
            c.cause, c.shares = "outside the perf record", {}
    late = sum(c.answers for c in cycles)
    return {"side": side, "answers": answers, "late_answers": late, "late_pct": round(100 * late / answers, 3)
            if answers else 0.0, "dropped": log.dropped, "causes": summarise(cycles, answers),
            "cycles": [asdict(c) for c in cycles]}


def _print(result: dict[str, Any]) -> None:
    print(f"{result['side']}: {result['answers']} answers read, {result['late_answers']} later than a cycle "
          f"({result['late_pct']:.3f} %)")
    for cause, row in result["causes"].items():
        print(f"  {cause:<34} {int(row['cycles']):>5} late cycles {int(row['answers']):>7} answers "
              f"{row['pct_of_answers']:>7.3f} % of all")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--stations", type=int, default=62)
    ap.add_argument("--links", default="ML3", choices=("ML2", "ML3"))
    ap.add_argument("--cycles", default="1ms", help="the transmission cycle")
    ap.add_argument("--duration", default="15s")
    ap.add_argument("--floor", action="store_true", help="the batched floor as well, after the network")
    ap.add_argument("--json", type=Path, default=None, help="write every late cycle here")
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
            results.append(loop.run_until_complete(_network(path, duration, Path(tmp))))
            _print(results[-1])
            if args.floor:
                results.append(loop.run_until_complete(_floor(args.stations, size, cycle, duration, Path(tmp))))
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
