#!/usr/bin/env python
"""Measure the CycleTimer wake-up strategies (mlink_sim.aio.ticker) — the numbers behind docs/timing.md.

For every cell (load x event loop x period x strategy) a fresh event loop runs a CycleTimer for
``--warmup`` seconds (discarded: lets the adaptive spin settle) and then ``--seconds`` seconds. Reported:

* lateness = ``time.monotonic_ns()`` read inside on_cycle minus the ideal absolute deadline, µs:
  p50 / p90 / p99 / p99.9 / max over the cycles that ran,
* missed  = cycles skipped because whole periods went by (``skipped`` summed),
* cpu %   = ``time.process_time()`` delta / wall time (whole process: loop thread, helper thread, echoes),
* spin    = spin budget at the end of the cell (adaptive unless --spin-ns),
* bg %    = CPU used meanwhile by *other* processes (not this one, not the load), % of one core, from
  /proc/stat. The bench machine is shared: a cell with bg above ``--max-bg`` is run again (``--retries``
  times) after waiting up to 10 s for a quiet machine, within ``--busy-budget`` seconds in all; the last
  attempt is kept either way, so check the column.

Loads (bounded in time, loopback only; each load process ends itself even if this script dies):

* ``none`` – nothing else running,
* ``cpu``  – a second process busy-looping, pinned to the last CPU ("the other core" on 2 cores),
* ``udp``  – a process on the last CPU sends ``--udp-rate`` 64-byte datagrams/s (1 ms bursts) to a UDP echo
  endpoint served by the *timer's own* event loop, which echoes each one back: the loop contention a master
  with slaves answering every cycle would see.

Example (the sweep in docs/timing.md, ≈ 3 min on 2 cores):

    .venv/bin/python scripts/bench_timers.py --seconds 1 --json /tmp/timers.json

``--arm`` measures instead what arming the clock's timer costs (docs/timing.md, "The clock's timer, armed a cycle
ahead"): ``timerfd_settime`` for a target ``--arm-ahead`` away (default 200 µs) that becomes the CPU's earliest
timer, the same call behind an earlier timer (as ``mlink_sim.aio._timerfd.LookaheadTimer`` arms the one after
the next), and a plain system call (``getppid``) for scale; µs per call, p50 / p90 / p99 of ``--arm-calls`` calls
each (≈ 1 s):

    .venv/bin/python scripts/bench_timers.py --arm
"""

from __future__ import annotations

import argparse
import asyncio
import datetime as _dt
import gc
import json
import logging
import os
import platform
import subprocess
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import structlog

from mlink_sim._files import write_atomically
from mlink_sim.aio import CycleTimer, available_strategies
from mlink_sim.aio._timerfd import TimerFD, timerfd_supported

try:
    import uvloop
except ImportError:  # pragma: no cover - uvloop is a runtime dependency on Linux
    uvloop = None

_CPU_HOG = """
import os, sys, time
try:
    os.sched_setaffinity(0, {int(sys.argv[1])})
except (AttributeError, OSError):
    pass
end = time.monotonic() + float(sys.argv[2])
while time.monotonic() < end:
    pass
"""

_UDP_FLOOD = """
import os, socket, sys, time
try:
    os.sched_setaffinity(0, {int(sys.argv[1])})
except (AttributeError, OSError):
    pass
port, rate, dur = int(sys.argv[2]), int(sys.argv[3]), float(sys.argv[4])
s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
s.setblocking(False)
dst = ("127.0.0.1", port)
payload = bytes(64)
burst = max(1, rate // 1000)
t = time.monotonic()
end = t + dur
while t < end:
    for _ in range(burst):
        try:
            s.sendto(payload, dst)
        except OSError:
            pass
    while True:
        try:
            s.recv(2048)
        except OSError:
            break
    t += 0.001
    d = t - time.monotonic()
    if d > 0:
        time.sleep(d)
"""


class _Echo(asyncio.DatagramProtocol):
    def connection_made(self, transport):  # type: ignore[override]
        self.transport = transport
        self.count = 0

    def datagram_received(self, data, addr):  # type: ignore[override]
        self.count += 1
        self.transport.sendto(data, addr)


_HZ = os.sysconf("SC_CLK_TCK") if hasattr(os, "sysconf") else 100


def _machine_busy_s() -> float:
    """Busy CPU seconds of the whole machine so far (all CPUs), or nan where /proc/stat is missing."""
    try:
        with open("/proc/stat") as f:
            v = [int(x) for x in f.readline().split()[1:]]
    except OSError:
        return float("nan")
    return (sum(v[:8]) - v[3] - v[4]) / _HZ  # user nice system [idle iowait] irq softirq steal


def _proc_cpu_s(pid: int | None) -> float:
    if pid is None:
        return 0.0
    try:
        with open(f"/proc/{pid}/stat") as f:
            fields = f.read().rpartition(")")[2].split()
    except OSError:
        return 0.0
    return (int(fields[11]) + int(fields[12])) / _HZ  # utime stime


def _parse_period(text: str) -> int:
    t = text.strip().lower()
    for suffix, mult in (("us", 1_000), ("µs", 1_000), ("ms", 1_000_000), ("ns", 1)):
        if t.endswith(suffix):
            return int(float(t[: -len(suffix)]) * mult)
    return int(float(t) * 1_000)  # bare number: µs


def _new_loop(name: str) -> asyncio.AbstractEventLoop:
    if name == "uvloop":
        if uvloop is None:
            raise SystemExit("uvloop is not installed")
        return uvloop.new_event_loop()
    return asyncio.new_event_loop()


def _pct(sorted_vals: list[int], p: float) -> float:
    if not sorted_vals:
        return float("nan")
    return sorted_vals[min(len(sorted_vals) - 1, int(p * len(sorted_vals)))] / 1000.0


async def _cell(period_ns: int, strategy: str, load: str, args: argparse.Namespace, hog_pid: int | None) -> dict:
    loop = asyncio.get_running_loop()
    lat: list[int] = []
    mono = time.monotonic_ns

    def on_cycle(cycle: int, deadline_ns: int, now_ns: int, skipped: int) -> None:
        lat.append(mono() - deadline_ns)

    flood = echo = transport = None
    if load == "udp":
        transport, echo = await loop.create_datagram_endpoint(_Echo, local_addr=("127.0.0.1", 0))
        port = transport.get_extra_info("sockname")[1]
        flood = subprocess.Popen([sys.executable, "-S", "-c", _UDP_FLOOD, str(args.load_cpu), str(port),
                                  str(args.udp_rate), str(args.warmup + args.seconds + 0.5)])
    spin = {"spin_ns": args.spin_ns} if args.spin_ns is not None and strategy.endswith("+spin") else {}
    timer = CycleTimer(period_ns, on_cycle, loop=loop, strategy=strategy, **spin)
    try:
        timer.start()
        await asyncio.sleep(args.warmup)
        first, skipped0 = len(lat), timer.skipped_total
        load_pid = flood.pid if flood is not None else hog_pid
        m0, l0 = _machine_busy_s(), _proc_cpu_s(load_pid)
        c0, w0 = time.process_time(), time.monotonic()
        await asyncio.sleep(args.seconds)
        c1, w1 = time.process_time(), time.monotonic()
        m1, l1 = _machine_busy_s(), _proc_cpu_s(load_pid)
        last, skipped1 = len(lat), timer.skipped_total
        final_spin = timer.spin_ns
    finally:
        timer.stop()
        if flood is not None:
            flood.kill()
            flood.wait()
        if transport is not None:
            transport.close()
    vals = sorted(lat[first:last])
    return {
        "load": load, "period_us": period_ns / 1000, "strategy": strategy, "n": len(vals),
        "p50_us": _pct(vals, 0.50), "p90_us": _pct(vals, 0.90), "p99_us": _pct(vals, 0.99),
        "p999_us": _pct(vals, 0.999), "max_us": vals[-1] / 1000.0 if vals else float("nan"),
        "missed": skipped1 - skipped0, "cpu_pct": 100.0 * (c1 - c0) / (w1 - w0), "spin_us": final_spin / 1000,
        "bg_pct": max(0.0, 100.0 * ((m1 - m0) - (c1 - c0) - (l1 - l0)) / (w1 - w0)),
        "echoed": echo.count if echo is not None else 0,
    }


def _wait_quiet(max_bg: float, timeout: float, hog_pid: int | None) -> float:
    """Wait (at most ``timeout`` s) until other processes use less than ``max_bg`` % of a core; time waited."""
    t0 = time.monotonic()
    while time.monotonic() - t0 < timeout:
        m0, l0, c0, w0 = _machine_busy_s(), _proc_cpu_s(hog_pid), time.process_time(), time.monotonic()
        time.sleep(0.25)
        m1, l1, c1, w1 = _machine_busy_s(), _proc_cpu_s(hog_pid), time.process_time(), time.monotonic()
        if not 100.0 * ((m1 - m0) - (l1 - l0) - (c1 - c0)) / (w1 - w0) > max_bg:
            break
    return time.monotonic() - t0


def _run_cell(loop_name: str, period_ns: int, strategy: str, load: str, args: argparse.Namespace,
              hog_pid: int | None = None) -> dict:
    attempt = 0
    while True:
        loop = _new_loop(loop_name)
        try:
            row = loop.run_until_complete(_cell(period_ns, strategy, load, args, hog_pid))
        finally:
            loop.close()
        gc.collect()
        attempt += 1
        if not row["bg_pct"] > args.max_bg or attempt > args.retries or args.busy_budget <= 0:
            break
        print(f"# busy machine (bg {row['bg_pct']:.0f}%): {load} {loop_name} {period_ns // 1000}us {strategy}, "
              f"waiting to re-run ({args.busy_budget:.0f} s of --busy-budget left)", flush=True)
        args.busy_budget -= _wait_quiet(args.max_bg, min(10.0, args.busy_budget), hog_pid) + args.seconds
    return {"loop": loop_name, **row, "attempts": attempt}


_HEADER = (f"{'load':5} {'loop':8} {'period':>7} {'strategy':13} {'n':>6} {'p50':>7} {'p90':>7} {'p99':>7} "
           f"{'p99.9':>7} {'max':>7} {'missed':>6} {'cpu%':>6} {'spin':>5} {'bg%':>4}")


def _fmt(r: dict) -> str:
    return (f"{r['load']:5} {r['loop']:8} {r['period_us']:>5.0f}us {r['strategy']:13} {r['n']:>6} "
            f"{r['p50_us']:>7.1f} {r['p90_us']:>7.1f} {r['p99_us']:>7.1f} {r['p999_us']:>7.1f} "
            f"{r['max_us']:>7.1f} {r['missed']:>6} {r['cpu_pct']:>6.1f} {r['spin_us']:>5.0f} {r['bg_pct']:>4.0f}")


def arm_costs(calls: int, ahead_ns: int) -> dict[str, dict[str, float]]:
    """µs per call (p50 / p90 / p99) of arming a timerfd that becomes the earliest timer, of arming one behind an
    earlier timer, and of ``getppid`` (see the module docstring, ``--arm``)."""
    first, second = TimerFD(), TimerFD()
    pc, mono = time.perf_counter_ns, time.monotonic_ns
    earliest: list[int] = []
    behind: list[int] = []
    syscall: list[int] = []
    try:
        for _ in range(calls):
            now = mono()
            t0 = pc()
            first.set_abs(now + ahead_ns)  # nothing earlier is armed by us: the CPU's next timer event
            t1 = pc()
            second.set_abs(now + 2 * ahead_ns)  # behind *first*: the timer device is left as it is
            t2 = pc()
            os.getppid()
            t3 = pc()
            earliest.append(t1 - t0)
            behind.append(t2 - t1)
            syscall.append(t3 - t2)
            first.disarm()
            second.disarm()
    finally:
        first.close()
        second.close()
    out = {}
    for name, xs in (("earliest", earliest), ("behind an earlier one", behind), ("getppid", syscall)):
        xs.sort()
        out[name] = {f"p{p}": round(_pct(xs, p / 100), 2) for p in (50, 90, 99)}
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seconds", type=float, default=1.0, help="measured seconds per cell (default 1.0)")
    ap.add_argument("--warmup", type=float, default=0.25, help="discarded seconds per cell (default 0.25)")
    ap.add_argument("--periods", default="250us,500us,1ms,2ms", help="comma list; bare numbers are µs")
    ap.add_argument("--strategies", default=",".join(available_strategies()))
    ap.add_argument("--loops", default="uvloop,asyncio")
    ap.add_argument("--loads", default="none,cpu,udp")
    ap.add_argument("--udp-rate", type=int, default=20_000, help="datagrams/s for the udp load (default 20000)")
    ap.add_argument("--spin-ns", type=int, default=None, help="fixed spin for '+spin' strategies (default adaptive)")
    ap.add_argument("--load-cpu", type=int, default=(os.cpu_count() or 1) - 1, help="CPU the load is pinned to")
    ap.add_argument("--max-bg", type=float, default=25.0,
                    help="re-run a cell if other processes used more than this %% of a core (default 25)")
    ap.add_argument("--retries", type=int, default=1, help="re-runs of a busy cell (default 1)")
    ap.add_argument("--busy-budget", type=float, default=60.0,
                    help="total seconds spent waiting for a quiet machine and re-running (default 60)")
    ap.add_argument("--json", type=Path, default=None, help="write rows and metadata here")
    ap.add_argument("--arm", action="store_true", help="measure what arming a timerfd costs instead (see above)")
    ap.add_argument("--arm-calls", type=int, default=20_000, help="calls per figure of --arm (default 20000)")
    ap.add_argument("--arm-ahead", type=_parse_period, default=200_000,
                    help="how far ahead --arm arms the earliest timer (default 200us)")
    args = ap.parse_args(argv)
    if args.arm:
        if not timerfd_supported():
            print("bench_timers.py --arm: no timerfd on this machine", file=sys.stderr)
            return 2
        if args.arm_calls < 1:
            ap.error("--arm-calls must be at least 1")
        costs = arm_costs(args.arm_calls, args.arm_ahead)
        print(f"# timerfd_settime, µs per call, {args.arm_calls} calls, {platform.platform()}")
        for name, q in costs.items():
            print(f"{name:<22} " + "  ".join(f"{k} {v:6.2f}" for k, v in q.items()))
        if args.json is not None:
            write_atomically(args.json, json.dumps({"arm": costs, "calls": args.arm_calls,
                                                    "ahead_ns": args.arm_ahead}, indent=1))
        return 0

    structlog.configure(wrapper_class=structlog.make_filtering_bound_logger(logging.INFO))
    periods = [_parse_period(p) for p in args.periods.split(",") if p.strip()]
    strategies = [s.strip() for s in args.strategies.split(",") if s.strip()]
    loops = [s.strip() for s in args.loops.split(",") if s.strip()]
    loads = [s.strip() for s in args.loads.split(",") if s.strip()]
    for load in loads:
        if load not in ("none", "cpu", "udp"):
            ap.error(f"unknown load {load!r}")
    per_load = len(loops) * len(periods) * len(strategies) * (args.seconds + args.warmup + 0.1)
    print(f"# {len(loads) * len(loops) * len(periods) * len(strategies)} cells, ~{len(loads) * per_load:.0f} s; "
          f"{os.cpu_count()} CPUs, {platform.platform()}, Python {platform.python_version()}, "
          f"uvloop {getattr(uvloop, '__version__', '-')}; lateness in µs", flush=True)
    print(_HEADER, flush=True)
    rows: list[dict] = []
    t0 = time.monotonic()
    for load in loads:
        hog = None
        if load == "cpu":
            hog = subprocess.Popen([sys.executable, "-S", "-c", _CPU_HOG, str(args.load_cpu), str(per_load + 10)])
            time.sleep(0.1)
        try:
            for loop_name in loops:
                for period in periods:
                    for strategy in strategies:
                        row = _run_cell(loop_name, period, strategy, load, args,
                                        hog.pid if hog is not None else None)
                        rows.append(row)
                        print(_fmt(row), flush=True)
        finally:
            if hog is not None:
                hog.kill()
                hog.wait()
    elapsed = time.monotonic() - t0
    print(f"# done in {elapsed:.0f} s", flush=True)
    if args.json is not None:
        meta = {"date": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
                "command": " ".join([Path(sys.executable).name, *sys.argv]), "cpus": os.cpu_count(),
                "platform": platform.platform(), "python": platform.python_version(),
                "uvloop": getattr(uvloop, "__version__", None), "elapsed_s": round(elapsed, 1), "args": {
                    k: (str(v) if isinstance(v, Path) else v) for k, v in vars(args).items()}}
        write_atomically(args.json, json.dumps({"meta": meta, "rows": rows}, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
