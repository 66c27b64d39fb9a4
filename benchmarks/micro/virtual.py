"""Benchmark the virtual clock (``mlink-sim up --clock virtual``, docs/virtual-time.md) against its targets.

Cases, each the ``up`` code path (``aio.run.network.run_up`` on a ``VirtualEventLoop``) in this process:

* ``quickstart``  -- configs/quickstart.toml, its whole scenario (11 s simulated): target <= 0.5 s wall
* ``ml3-62``      -- configs/ml3-62-max.toml (62 SI-ET3 at 1 ms) for ``--duration`` (60 s) simulated: target
                     <= 60 s wall
* ``determinism`` -- the quickstart twice with the same seed: identical reports once ``meta.started``,
                     ``meta.host`` and ``meta.wall`` are left out

"wall" is the run itself (session open to final report, ``meta.wall.elapsed_s``), not the interpreter's start-up
and imports (printed apart). ``--floor`` also times the cores alone on the same traffic (master core, card core
and drive called in a plain loop, no clock, no network model; for ml3-62 over 20 s): what bounds the run. The
last line is JSON.

Run from the repository's root on a quiet machine: ``python -m benchmarks.micro.virtual --floor``.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import sys
import time
from pathlib import Path
from typing import Any

import mlink_sim.cards  # noqa: F401  # imported lazily by the run: an import, not counted in its wall
from mlink_sim.aio.run.network import RunOptions, run_up
from mlink_sim.aio.virtual.vclock import VirtualEventLoop
from mlink_sim.aio.run.virtual_session import without_wall_clock
from mlink_sim.cli.logs import configure_logging
from mlink_sim.config import load_config, parse_duration_ns

from benchmarks.common import ROOT

__all__ = ["ML3_62", "QUICKSTART", "floor", "main", "run"]

#: the CPU time this process took before the runs: the interpreter's start-up and the imports (printed apart)
IMPORT_S = time.process_time()
QUICKSTART = ROOT / "configs" / "quickstart.toml"
ML3_62 = ROOT / "configs" / "ml3-62-max.toml"


def run(path: Path, *, seed: int = 0, duration_ns: int | None = None) -> dict[str, Any]:
    """One ``up --clock virtual`` run; its report (the summary it prints is swallowed)."""
    config = load_config(path)
    opts = RunOptions(config_path=path, duration_ns=duration_ns, status=False, clock="virtual", seed=seed)
    loop = VirtualEventLoop()
    try:
        with contextlib.redirect_stdout(io.StringIO()):
            outcome = loop.run_until_complete(run_up(config, opts))
    finally:
        loop.close()
    if outcome.exit_code != 0:
        raise SystemExit(f"{path.name}: the run failed (exit {outcome.exit_code}): {outcome.problems}")
    return outcome.report


def floor(path: Path, seconds: float) -> tuple[float, float]:
    """CPU seconds of the cores alone for *seconds* of the config's cyclic traffic after bring-up, every drive
    running at 30 Hz (its ramp included): master core -> card core -> master core in a plain loop. Returns
    (total, the card cores' share with their drives: ``receive`` and ``poll``, timed with ``process_time``)."""
    from mlink_sim.scenario import speed_scales
    from mlink_sim.aio.run.session import build_plans
    from mlink_sim.aio.slave.stations import build_station, spec_for
    from mlink_sim.master import MasterCore

    config = load_config(path)
    period = config.network.transmission_cycle
    scales = speed_scales(config)
    cores = [MasterCore(plan) for plan in build_plans(config).values()]
    stations = {st.address: build_station(spec_for(st), None, 0) for st in config.station}
    now = 0
    card_s = 0.0
    clock = time.process_time

    def cycle(k: int) -> None:
        nonlocal card_s
        for core in cores:
            for address, datagram in core.on_cycle(k, now):
                station = stations[address]
                t0 = clock()
                response = station.receive(datagram, "master", now + 50_000)
                due = station.next_deadline()
                if due is not None and due <= now:
                    station.poll(now)
                card_s += clock() - t0
                if response is not None:
                    core.on_response(response, now + 100_000)
            core.drain_events()

    k = 0
    while not all(core.all_at_target() for core in cores):
        now += period
        cycle(k)
        k += 1
    for core in cores:
        for address in core.addresses:
            core.set_control(address, True, False, scales[address].to_raw(30.0))
    card_s = 0.0
    cpu0 = time.process_time()
    for _ in range(round(seconds * 1e9 / period)):
        now += period
        cycle(k)
        k += 1
    return time.process_time() - cpu0, card_s


def main() -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.micro.virtual", description=__doc__.splitlines()[0])
    parser.add_argument("--only", choices=["quickstart", "ml3-62", "determinism"], action="append")
    parser.add_argument("--duration", default="60s", help="ml3-62: simulated run length (default 60s)")
    parser.add_argument("--floor", action="store_true", help="also time the cores alone on the same traffic")
    args = parser.parse_args()
    configure_logging(level="warning")
    cases = args.only or ["quickstart", "ml3-62", "determinism"]
    out: dict[str, Any] = {"import_s": round(IMPORT_S, 3)}
    print(f"interpreter start-up and imports: {IMPORT_S:.2f} s of CPU (not counted below)")
    if "quickstart" in cases:
        wall = run(QUICKSTART)["meta"]["wall"]
        out["quickstart"] = {**wall, "target_s": 0.5, "met": wall["elapsed_s"] <= 0.5}
        print(f"quickstart: {wall['simulated_s']:.1f} s simulated in {wall['elapsed_s']:.3f} s wall "
              f"({wall['speedup']}x); target <= 0.5 s: {'met' if out['quickstart']['met'] else 'NOT met'}")
        if args.floor:
            cpu, cards = floor(QUICKSTART, 11.0)
            out["quickstart"].update(cores_cpu_s=round(cpu, 3), cards_s=round(cards, 3))
            print(f"  the cores alone, 11 s of cyclic traffic: {cpu:.3f} s CPU, of which the cards and drives "
                  f"{cards:.3f} s")
    if "ml3-62" in cases:
        duration_ns = parse_duration_ns(args.duration, default_unit="s")
        wall = run(ML3_62, duration_ns=duration_ns)["meta"]["wall"]
        out["ml3-62"] = {**wall, "target_s": 60.0, "met": wall["elapsed_s"] <= duration_ns / 1e9}
        verdict = "met" if out["ml3-62"]["met"] else "NOT met"
        print(f"ml3-62: {wall['simulated_s']:.1f} s simulated in {wall['elapsed_s']:.1f} s wall "
              f"({wall['speedup']}x); target <= {duration_ns / 1e9:g} s: {verdict}")
        if args.floor:
            span = min(20.0, duration_ns / 1e9)  # the 5 s ramp to 30 Hz and 15 s at speed: a minute costs too long
            cpu, cards = floor(ML3_62, span)
            out["ml3-62"].update(floor_span_s=span, cores_cpu_s=round(cpu, 3), cards_s=round(cards, 3))
            print(f"  the cores alone, {span:g} s of cyclic traffic: {cpu:.1f} s CPU ({cpu / span:.2f} s per "
                  f"simulated s), of which the cards and drives {cards:.1f} s")
    if "determinism" in cases:
        a, b = (without_wall_clock(run(QUICKSTART, seed=3)) for _ in range(2))
        same = json.dumps(a, sort_keys=True) == json.dumps(b, sort_keys=True)
        out["determinism"] = {"identical": same}
        print(f"determinism: two quickstart runs, seed 3: reports {'identical' if same else 'DIFFER'}")
    print(json.dumps(out))
    return 0 if out.get("determinism", {}).get("identical", True) else 1


if __name__ == "__main__":
    sys.exit(main())
