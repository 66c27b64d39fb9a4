"""Benchmark the drive model: ns per model step per station at a 1 ms step.

Cases (each a fresh drive, A1000 family, 3.7 kW motor, ``LoadSpec`` as named):

* ``steady``      -- running at 40 Hz, settled: ``advance(t + 1 ms)`` (closed form, no sub-step)
* ``steady+card`` -- as a card does per cycle: ``command`` (unchanged INV_CTL), ``advance``,
                     ``status``, output frequency/current and two SEL_MON reads
* ``ramping``     -- accelerating with S-curve under a fan load: one integrated 1 ms sub-step
* ``ramping+card`` -- both: the worst per-cycle cost of a station
* ``decel+stall`` -- decelerating a big inertia, stall prevention (L3-04 = 2) holding the bus
* ``coasting``    -- output off, friction load slowing the shaft

Each figure is the median over ``--repeat`` runs of ``timeit`` (``--number`` steps per run),
divided by the number of steps.  The last line is one JSON object with the same figures.
Run from the repository's root: ``python -m benchmarks.micro.drive``.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import timeit

from mlink_sim.drive import Drive, DriveCommand, DriveSettings, Family, LoadSpec

__all__ = ["Case", "cases", "main", "measure"]

MS = 1_000_000
VALUES: dict[str, int] = {
    "A1-02": 0, "b1-01": 3, "b1-02": 3, "b1-03": 0,
    "C1-01": 100, "C1-02": 100, "C1-03": 100, "C1-04": 100, "C1-09": 100,
    "C2-01": 20, "C2-02": 20, "C2-03": 20, "C2-04": 0,
    **{f"d1-{i:02d}": 0 for i in range(1, 17)}, "d1-17": 600, "d5-01": 0,
    "E1-01": 200, "E1-04": 600, "E1-05": 2000, "E1-06": 600, "E1-07": 30, "E1-08": 150,
    "E1-09": 15, "E1-10": 90,
    "E2-01": 1400, "E2-02": 273, "E2-03": 450, "E2-04": 4, "E2-05": 771, "E2-11": 370,
    "F6-01": 1, "F6-02": 0, "F6-03": 1, "F6-06": 0, "F6-07": 0, "F6-25": 1,
    "H1-03": 0x24, "H1-04": 0x14, "H1-05": 3, "H1-06": 4, "H1-07": 6, "H1-08": 8,
    "L1-01": 1, "L1-02": 10, "L3-01": 1, "L3-02": 150, "L3-04": 1, "L4-01": 0, "L4-02": 20,
    "o1-03": 0,
}


class Case:
    def __init__(self, name: str, load: LoadSpec, cmd: DriveCommand, warmup_ms: int,
                 card: bool = False, after: DriveCommand | None = None,
                 overrides: dict[str, int] | None = None) -> None:
        self.name, self.card = name, card
        s = DriveSettings.from_params(Family.A1000, {**VALUES, **(overrides or {})})
        self.d = Drive(Family.A1000, s, load)
        self.cmd = cmd
        self.d.command(cmd, 0)
        self.t = 0
        for _ in range(warmup_ms):
            self.t += MS
            self.d.advance(self.t)
        if after is not None:
            self.cmd = after
            self.d.command(after, self.t)

    def step(self) -> None:
        self.t += MS
        self.d.advance(self.t)

    def card_step(self) -> None:
        d = self.d
        self.t += MS
        d.command(self.cmd, self.t)
        st = d.status
        _ = (st.running, st.faulted, d.output_frequency_hz, d.output_current_a,
             d.sel_mon("SI-T3", 1), d.sel_mon("SI-T3", 6))


def cases() -> list[Case]:
    run40 = DriveCommand(forward=True, freq_ref_raw=4000)
    return [
        Case("steady", LoadSpec("constant", 0.05, 10.0), run40, 8000),
        Case("steady+card", LoadSpec("constant", 0.05, 10.0), run40, 8000, card=True),
        Case("ramping", LoadSpec("fan", 0.05, 15.0), DriveCommand(forward=True, freq_ref_raw=6000), 500,
             overrides={"C1-01": 60000}),  # 6000 s ramp: still accelerating after the timing runs
        Case("ramping+card", LoadSpec("fan", 0.05, 15.0), DriveCommand(forward=True, freq_ref_raw=6000),
             500, card=True, overrides={"C1-01": 60000}),
        Case("decel+stall", LoadSpec("inertia", 0.5), DriveCommand(forward=True, freq_ref_raw=6000),
             60_000, after=DriveCommand(), overrides={"L3-04": 2}),
        Case("coasting", LoadSpec("friction", 0.5, 0.0, 0.001),
             DriveCommand(forward=True, freq_ref_raw=6000), 60_000,
             after=DriveCommand(external_baseblock=True)),
    ]


def measure(case: Case, number: int, repeat: int) -> tuple[float, float]:
    """(median, min) ns per step over ``repeat`` timing runs of ``number`` steps."""
    fn = case.card_step if case.card else case.step
    runs = timeit.repeat(fn, number=number, repeat=repeat)
    return statistics.median(runs) / number * 1e9, min(runs) / number * 1e9


def main() -> None:
    ap = argparse.ArgumentParser(prog="python -m benchmarks.micro.drive", description=__doc__.splitlines()[0])
    ap.add_argument("--number", type=int, default=5000, help="steps per timing run")
    ap.add_argument("--repeat", type=int, default=7, help="timing runs (median taken)")
    ap.add_argument("--stations", type=int, default=62, help="stations per process")
    args = ap.parse_args()
    results: dict[str, float] = {}
    best: dict[str, float] = {}
    steady_flags: dict[str, bool] = {}
    for case in cases():
        results[case.name], best[case.name] = measure(case, args.number, args.repeat)
        steady_flags[case.name] = case.d.is_steady
        if case.d.status.faulted:
            raise SystemExit(f"bench case {case.name} faulted: {case.d.status.fault}")
    print(f"drive model step cost, 1 ms step, median of {args.repeat} x {args.number} steps")
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"python {platform.python_version()} on {platform.machine()}, {os.cpu_count()} CPUs, "
          f"load average {load:.2f} (other processes inflate the figures)")
    hdr = "x" + str(args.stations) + " us/cycle"
    print(f"{'case':<14}{'median ns':>10}{'min ns':>9}{hdr:>16}   mode")
    for name, ns in results.items():
        mode = "closed form" if steady_flags[name] else "integrated"
        print(f"{name:<14}{ns:>10.0f}{best[name]:>9.0f}{ns * args.stations / 1000:>16.1f}   {mode}")
    print(json.dumps({"bench": "drive_step", "step_ms": 1, "stations": args.stations,
                      "ns_per_step": {k: round(v) for k, v in results.items()},
                      "ns_per_step_min": {k: round(v) for k, v in best.items()},
                      "steady": steady_flags, "loadavg": round(load, 2),
                      "python": platform.python_version()}))


if __name__ == "__main__":
    main()
