"""Recovery from host stalls: the simulator against its floor, both stopped by the same injected stalls.

On a small shared machine the 1 ms cells of the capacity targets miss more than their floor mostly in bursts: a host stall of
a few ms (a kernel thread, the hypervisor) makes every answer of the cycles it covers late, and the simulator then
takes longer than the floor to get back to answering within a cycle (docs/performance.md, "What bounds each figure"). This tool measures that recovery on purpose instead of waiting for the host to stall.

For one cell (``--link``, ``--stations``, ``--cycle``) it measures, in turns of ``--duration`` each:

* the simulator (a network as :mod:`benchmarks.bench` brings it up: the master in this process, the slave workers),
  once undisturbed and once with stalls injected;
* its floor (:mod:`benchmarks.floor`: one server process for all the stations, a client on the same
  ``CycleTimer``, the simulator's system calls), the same two ways.

A stall is ``SIGSTOP`` of the chosen processes for ``--stall``, then ``SIGCONT``, every ``--every``, made by a helper
process, :mod:`benchmarks.lab.stall_inject` (standard library only, so that starting it costs next to no CPU; SCHED_FIFO
where granted, so that its timing does not depend on what it stops). ``--who`` chooses what stops: ``master`` (the
master, or the floor's client), ``workers`` (the slave workers, or the floor's server) or ``both``. With ``--who
both``, ``--lag`` continues the master (the client) that long after the workers (the server): a host stall that
gives the workers' CPU back first, so that their 1 ms tick runs before the master's catch-up comes (under the
default host-stall policy the cards' silence tolerance is its bound, 100 ms, so their predictions stay:
docs/cards.md, "A backlog"). The helper continues whatever it stopped on every way out (its end, a SIGTERM, its
parent's death) and reports the stalls it made, measured.

The figure per side, from the missed exchanges of the two windows (:mod:`benchmarks.figures`: due but not answered within
a cycle): **cycles missed per stall** = (missed with stalls − missed without, scaled to the same number of
exchanges due) ÷ stations ÷ stalls made. Both sides stamp a command when it is sent, so what a stall costs by
itself depends on what it stops: stopping the server alone makes late the answers of the cycles it covers (about
stall ÷ cycle cycles); stopping the client as well delays the commands too, and a floor then loses next to nothing.
Whatever the simulator loses beyond its floor is its recovery: the last line gives the difference and the ratio.

Run from the repository's root:

    python -m benchmarks.lab.recovery                           # 62 ML-III @ 1 ms, 3 ms stalls of both, 10 s turns
    python -m benchmarks.lab.recovery --who workers --stall 5ms --every 250ms
    python -m benchmarks.lab.recovery --who both --lag 500us      # the workers continued first
    python -m benchmarks.lab.recovery --stations 30 --link ML2 --rounds 3 --json recovery.json

Loops are bounded by ``--duration`` × ``--rounds``; traffic stays on loopback. Exit status: 0 with the figures
(a benchmark reports, it does not gate), 2 for bad options or a window that could not be measured (the message
says why), 1 when ``--json`` could not be written (the table is printed first), 130/143 on Ctrl-C/SIGTERM
(nothing written; every stopped process continued).
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import platform
import signal
import statistics
import sys
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from mlink_sim.aio.transport import mmsg
from mlink_sim.config import format_ns, load_config, parse_duration_ns

from benchmarks import bench
from benchmarks.common import child_env, module_command, write_atomically
from benchmarks.figures import During, Window, add_window
from benchmarks.floor import floor_window
from benchmarks.lab.stall_inject import signal_all

__all__ = ["Recovery", "recovery", "stalled_pids"]

WHO = ("both", "master", "workers")
INJECTOR = "benchmarks.lab.stall_inject"  #: the helper that makes the stalls, run as ``python -m``


# ----------------------------------------------------------------------------------------------- the injector
def stalled_pids(who: str, pids: list[int]) -> list[int]:
    """The processes of a side that *who* stops; *pids*: the master (or the floor's client) first, then the workers
    (or the floor's server)."""
    return {"both": pids, "master": pids[:1], "workers": pids[1:]}[who]


def injector_args(who: str, pids: list[int], lag_ns: int = 0) -> list[str]:
    """The PID arguments of :mod:`benchmarks.lab.stall_inject` for *who* (:func:`stalled_pids`); with *lag_ns* (``both``
    only), the workers (the floor's server) first and the master (its client) ``--later``."""
    if lag_ns and who == "both":
        return [*map(str, pids[1:]), "--later", str(lag_ns), str(pids[0])]
    return [str(pid) for pid in stalled_pids(who, pids)]


def injecting(who: str, stall_ns: int, every_ns: int, reports: list[dict[str, Any]], lag_ns: int = 0) -> During:
    """A window's ``during``: :mod:`benchmarks.lab.stall_inject` stops the side's processes as *who* says (the master
    continued *lag_ns* after the workers), from now until the window's end; its report goes to *reports*.
    Cancelled, it terminates the helper, which continues them."""
    async def during(pids: list[int], duration_s: float) -> None:
        chosen = stalled_pids(who, pids)
        start = time.monotonic_ns()
        proc = await asyncio.create_subprocess_exec(
            *module_command(INJECTOR, str(stall_ns), str(every_ns), str(start), str(start + round(duration_s * 1e9)),
                            *injector_args(who, pids, lag_ns)), stdout=asyncio.subprocess.PIPE, env=child_env())
        try:
            out, _ = await proc.communicate()
        finally:
            if proc.returncode is None:
                proc.terminate()
                await proc.wait()
            signal_all(chosen, signal.SIGCONT)  # the helper continues them itself; this covers one killed outright
        if proc.returncode != 0:
            raise RuntimeError(f"{INJECTOR} exited {proc.returncode}")
        reports.append(json.loads(out))
    return during


# ----------------------------------------------------------------------------------------------- the figures
@dataclass
class Recovery:
    """One side's windows, undisturbed (``False``) and stalled (``True``), each its turns added up, and the stalls
    made in the stalled ones."""

    side: str                       #: simulator / floor
    stations: int
    windows: dict[bool, Window] = field(default_factory=dict)
    stalls_ns: list[int] = field(default_factory=list)  #: the stalls made, measured

    def figures(self) -> dict[str, Any]:
        return recovery(self.windows[False], self.windows[True], self.stalls_ns, self.stations)


def recovery(calm: Window, stalled: Window, stalls_ns: list[int], stations: int) -> dict[str, Any]:
    """The figures of one side (module docstring): the missed rates of *calm* and *stalled*, and the cycles missed
    per stall beyond the calm rate."""
    fc, fs = calm.figures(), stalled.figures()
    n = len(stalls_ns)
    per_stall = (fs.missed_rate - fc.missed_rate) * fs.due / stations / n if n and stations else 0.0
    return {"stalls": n, "stall_median_ns": int(statistics.median(stalls_ns)) if n else 0,
            "stall_max_ns": max(stalls_ns, default=0), "missed_rate_calm": fc.missed_rate,
            "missed_rate_stalled": fs.missed_rate, "cycles_per_stall": round(per_stall, 2)}


def table(sides: list[Recovery]) -> str:
    rows = [f"{'side':<10} {'stalls':>6} {'stall p50/max':>15} {'missed calm':>12} {'missed stalled':>15} "
            f"{'cycles missed per stall':>24}"]
    figs = {}
    for r in sides:
        f = figs[r.side] = r.figures()
        rows.append(f"{r.side:<10} {f['stalls']:>6} "
                    f"{format_ns(f['stall_median_ns']) + ' / ' + format_ns(f['stall_max_ns']):>15} "
                    f"{f['missed_rate_calm'] * 100:>11.2f}% {f['missed_rate_stalled'] * 100:>14.2f}% "
                    f"{f['cycles_per_stall']:>24.2f}")
    for side, f in figs.items():
        if f["missed_rate_calm"] > f["missed_rate_stalled"]:
            rows.append(f"! {side}: it missed more undisturbed ({f['missed_rate_calm'] * 100:.2f} %) than with the stalls: "
                        "something else disturbed its calm turns; more --rounds tell it apart")
    sim, floor = figs.get("simulator"), figs.get("floor")
    if sim and floor:
        extra = sim["cycles_per_stall"] - floor["cycles_per_stall"]
        ratio = f" ({sim['cycles_per_stall'] / floor['cycles_per_stall']:.1f}×)" if floor["cycles_per_stall"] > 0 else ""
        rows.append(f"the simulator's recovery: {extra:+.2f} cycles missed per stall beyond its floor's{ratio}")
    return "\n".join(rows)


# ----------------------------------------------------------------------------------------------- the run
@dataclass(frozen=True)
class Plan:
    link: str
    stations: int
    cycle_ns: int
    stall_ns: int
    every_ns: int
    duration_s: float
    rounds: int
    who: str
    workers: int
    lag_ns: int = 0


def _duration(option: str, text: str, unit: str) -> int:
    try:
        return parse_duration_ns(text, default_unit=unit)
    except ValueError as exc:
        raise ValueError(f"{option}: {exc}") from None


def _plan(args: argparse.Namespace) -> Plan:
    """The run *args* ask for; ValueError with the reason for a bad option."""
    link = args.link.strip().upper()
    if link not in bench.LINKS:
        raise ValueError("--link takes ML2 or ML3")
    cycle, stall = _duration("--cycle", args.cycle, "us"), _duration("--stall", args.stall, "ms")
    every, duration = _duration("--every", args.every, "ms"), _duration("--duration", args.duration, "s")
    if args.stations < 1 or args.rounds < 1 or args.workers < 1:
        raise ValueError("--stations, --rounds and --workers are at least 1")
    lag = _duration("--lag", args.lag, "us")
    if not 0 < stall < every:
        raise ValueError("--stall must be > 0 and shorter than --every")
    if lag and args.who != "both":
        raise ValueError("--lag needs --who both: it continues the master that long after the workers")
    if lag < 0 or stall + lag >= every:
        raise ValueError("--lag must be ≥ 0, and --stall + --lag shorter than --every")
    if duration < 2 * every:
        raise ValueError("--duration must hold at least two --every periods")
    reason = bench.applicable(link, args.stations, cycle)
    if reason:
        raise ValueError(reason)
    return Plan(link, args.stations, cycle, stall, every, duration / 1e9, args.rounds, args.who, args.workers, lag)


_TURNS = [("simulator", False), ("simulator", True), ("floor", False), ("floor", True)]


def _order(round_: int) -> list[tuple[str, bool]]:
    """Each round's turns; every other round the other way round, so that neither way always goes first."""
    return _TURNS if round_ % 2 == 0 else _TURNS[::-1]


def run(loop: asyncio.AbstractEventLoop, tmp: Path, plan: Plan) -> list[Recovery]:
    path = tmp / "network.toml"
    size = bench.write_config(path, plan.link, plan.stations, plan.cycle_ns)
    absorb_ns = load_config(path).network.absorb_ns
    workers = min(plan.workers, plan.stations)
    io = "batched" if mmsg.supported() else "plain"
    sides = {s: Recovery(s, plan.stations) for s in ("simulator", "floor")}
    for round_ in range(plan.rounds):
        for side, stalled in _order(round_):
            reports: list[dict[str, Any]] = []
            during = injecting(plan.who, plan.stall_ns, plan.every_ns, reports, plan.lag_ns) if stalled else None
            if side == "simulator":
                cell = bench.Cell(plan.link, plan.stations, plan.cycle_ns, workers, plan.duration_s, io,
                                  layout="shared" if workers < plan.stations else "station")
                w = loop.run_until_complete(bench.measure_network(path, workers, plan.duration_s, cell,
                                                                  during=during))
                if cell.notes:
                    raise RuntimeError("the network: " + "; ".join(cell.notes))
            else:
                w = loop.run_until_complete(floor_window(plan.stations, size, plan.cycle_ns, plan.duration_s,
                                                         io == "batched", absorb_ns, shared=workers < plan.stations,
                                                         during=during))
            add_window(sides[side].windows, stalled, w)
            for report in reports:
                sides[side].stalls_ns += report["stalls_ns"]
            fig = w.figures()
            print(f"round {round_ + 1} {side:<9} {'stalled' if stalled else 'calm':<7} missed "
                  f"{fig.missed_rate * 100:.2f}%" + (f", {len(reports[0]['stalls_ns'])} stalls "
                                                     f"({reports[0]['scheduling']})" if reports else ""),
                  file=sys.stderr, flush=True)
    return list(sides.values())


def main() -> int:
    ap = argparse.ArgumentParser(prog="python -m benchmarks.lab.recovery", description=__doc__.split("\n\n")[0])
    ap.add_argument("--link", default="ML3", help="ML2 or ML3 (default ML3)")
    ap.add_argument("--stations", type=int, default=62, help="stations on the line (default 62)")
    ap.add_argument("--cycle", default="1ms", help="transmission cycle (default 1ms)")
    ap.add_argument("--stall", default="3ms", help="how long each stall stops the processes (default 3ms)")
    ap.add_argument("--every", default="500ms", help="one stall per this period (default 500ms)")
    ap.add_argument("--who", choices=WHO, default="both",
                    help="what the stalls stop: the master (the floor's client), the workers (its server) or both")
    ap.add_argument("--lag", default="0",
                    help="with --who both: continue the master (the floor's client) this long after the workers "
                         "(its server), e.g. 500us (default 0: together)")
    ap.add_argument("--duration", default="10s", help="each turn's measuring time (default 10s)")
    ap.add_argument("--rounds", type=int, default=1, help="rounds of the four turns (default 1)")
    ap.add_argument("--workers", type=int, default=max(1, (os.cpu_count() or 1) - 1),
                    help="slave worker processes (default: one per CPU but one, as the capacity sweep)")
    ap.add_argument("--json", type=Path, default=None, help="also write the figures here")
    args = ap.parse_args()
    try:
        plan = _plan(args)
        if args.json is not None and not args.json.resolve().parent.is_dir():
            raise ValueError(f"--json: no directory {args.json.resolve().parent}")
    except ValueError as exc:
        print(f"recovery: {exc}", file=sys.stderr)
        return 2
    try:
        sides = bench.measuring("recovery", lambda loop, tmp: run(loop, tmp, plan))
    except bench.Interrupted as exc:
        return exc.code
    except (RuntimeError, OSError, ValueError) as exc:
        print(f"recovery: a window could not be measured: {exc}", file=sys.stderr)
        return 2
    print(f"{plan.link} {plan.stations} stations @ {format_ns(plan.cycle_ns)}, stalls of {format_ns(plan.stall_ns)} "
          f"every {format_ns(plan.every_ns)} stopping {plan.who}"
          + (f", the master continued {format_ns(plan.lag_ns)} after the workers" if plan.lag_ns else "")
          + f", {plan.rounds} × {plan.duration_s:g} s turns")
    print(table(sides))
    if args.json is not None:
        doc = {"host": {"node": platform.node(), "cpus": os.cpu_count(), "kernel": platform.release(),
                        "load_avg": os.getloadavg()},
               "plan": asdict(plan),
               "sides": {r.side: {**r.figures(), "stalls_ns": r.stalls_ns, "calm": r.windows[False].summary(),
                                  "stalled": r.windows[True].summary()} for r in sides}}
        try:
            write_atomically(args.json, json.dumps(doc, indent=1))
        except OSError as exc:
            print(f"recovery: could not write {args.json}: {exc} (the table above is the run's)",
                  file=sys.stderr)
            return 1
        print(f"wrote {args.json}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
