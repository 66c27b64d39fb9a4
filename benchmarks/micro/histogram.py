"""The metrics' recording path and report path: ns per call, and ms per report step over a full line's histograms.

    python -m benchmarks.micro.histogram [--stations 62] [--values 600000] [--repeat 7] [--calls 200000]

Recording (ns per call, best of *repeat* loops of *calls* calls, the empty loop's cost taken off):
``LatencyHistogram.record`` of one value; the same over *stations* histograms with RTT-like values (lognormal,
median e^12.2 ns, 199 µs, so that the counts are spread as in a running master); ``NetworkMetrics.record_rtt``,
``record_sent`` and ``record_cycle_lateness``.

Report path (ms, best of 5), over *stations* histograms holding *values* RTT-like values in all: ``copy`` (what a
snapshot of the metrics does per station), ``summary``, ``LatencyHistogram.merged`` and ``to_pairs``.

Prints one line per figure, whether the cores are compiled, and one JSON line. docs/report.md ("Cost on the
recording path") quotes it. Run it from the repository's root on a quiet machine, and compare builds in the same
sitting (e.g. a checkout of the previous commit with its own ``.venv``, alternated).
"""

from __future__ import annotations

import argparse
import json
import random
import sys
import time
from collections.abc import Callable

from mlink_sim.metrics import LatencyHistogram, NetworkMetrics

from benchmarks.common import cores

__all__ = ["main", "recording", "report_path", "rtt_like"]


def rtt_like(n: int, seed: int = 1) -> list[int]:
    """*n* values in ns, lognormal with median e^12.2 ns (199 µs): the spread of a 62-station line's RTTs."""
    rnd = random.Random(seed)
    return [int(rnd.lognormvariate(12.2, 0.3)) for _ in range(n)]


def _best_ns(run: Callable[[], None], empty: Callable[[], None], calls: int, repeat: int) -> float:
    """ns per call of *run* (a loop of *calls* calls) less *empty* (the same loop without the call), best of *repeat*."""
    best = float("inf")
    for _ in range(repeat):
        t = time.perf_counter_ns()
        run()
        a = time.perf_counter_ns() - t
        t = time.perf_counter_ns()
        empty()
        b = time.perf_counter_ns() - t
        best = min(best, (a - b) / calls)
    return max(best, 0.0)


def recording(stations: int, repeat: int, calls: int) -> dict[str, float]:
    """ns per call of the recording path (see the module docstring)."""
    one = LatencyHistogram()
    hs = [LatencyHistogram() for _ in range(stations)]
    values = rtt_like(calls)
    m = NetworkMetrics(cycle_ns=1_000_000)
    m.add_stations([0x21])
    rng = range(calls)

    def single() -> None:
        for _ in rng:
            one.record(123_456)

    def spread() -> None:
        for i in rng:
            hs[i % stations].record(values[i])

    def spread_empty() -> None:
        for i in rng:
            hs[i % stations]  # the loop's own indexing, taken off
            values[i]

    def rtt() -> None:
        for _ in rng:
            m.record_rtt(0x21, 123_456)

    def sent() -> None:
        for _ in rng:
            m.record_sent(0x21)

    def lateness() -> None:
        for _ in rng:
            m.record_cycle_lateness(20_000)

    def empty() -> None:
        for _ in rng:
            pass

    spread()  # the pages (or buckets) the values fall in exist before the timing
    return {"record": _best_ns(single, empty, calls, repeat),
            f"record_over_{stations}": _best_ns(spread, spread_empty, calls, repeat),
            "record_rtt": _best_ns(rtt, empty, calls, repeat),
            "record_sent": _best_ns(sent, empty, calls, repeat),
            "record_cycle_lateness": _best_ns(lateness, empty, calls, repeat)}


def report_path(stations: int, values: int) -> dict[str, float]:
    """ms per step of the report path over *stations* histograms (see the module docstring), best of 5."""
    hs = [LatencyHistogram() for _ in range(stations)]
    for i, v in enumerate(rtt_like(values, seed=2)):
        hs[i % stations].record(v)

    def best(step: Callable[[], object]) -> float:
        out = []
        for _ in range(5):
            t = time.perf_counter_ns()
            step()
            out.append((time.perf_counter_ns() - t) / 1e6)
        return min(out)

    return {"copy": best(lambda: [h.copy() for h in hs]), "summary": best(lambda: [h.summary() for h in hs]),
            "merged": best(lambda: LatencyHistogram.merged(hs)), "to_pairs": best(lambda: [h.to_pairs() for h in hs])}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m benchmarks.micro.histogram", description=__doc__.split("\n\n")[0])
    ap.add_argument("--stations", type=int, default=62, help="histograms (one per station)")
    ap.add_argument("--values", type=int, default=600_000, help="values in the report path's histograms, in all")
    ap.add_argument("--repeat", type=int, default=7, help="loops per recording figure (the best is kept)")
    ap.add_argument("--calls", type=int, default=200_000, help="calls per loop")
    args = ap.parse_args(argv)
    if min(args.stations, args.values, args.repeat, args.calls) < 1:
        print("histogram: --stations, --values, --repeat and --calls must be ≥ 1", file=sys.stderr)
        return 2
    rec = recording(args.stations, args.repeat, args.calls)
    rep = report_path(args.stations, args.values)
    print(f"cores: {cores(LatencyHistogram)}")
    for name, ns in rec.items():
        print(f"{name}: {ns:.0f} ns per call")
    for name, ms in rep.items():
        print(f"{name} of {args.stations} histograms: {ms:.2f} ms")
    print(json.dumps({"cores": cores(LatencyHistogram), "stations": args.stations, "values": args.values,
                      "recording_ns": {k: round(v, 1) for k, v in rec.items()},
                      "report_ms": {k: round(v, 2) for k, v in rep.items()}}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
