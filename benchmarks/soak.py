"""Soak: run ``mlink-sim up CONFIG`` many times in a row and count how many pass, with the host stalls of the
same runs (docs/timing.md, "Host stalls"). Its targets, on a quiet machine and with a CPU hog on one core beside
it: docs/performance.md, "Soak: the quickstart, many runs in a row".

Before the runs it measures the machine itself, as a baseline in the same sitting: a bare Python loop that only
wakes every 2 ms for ``--baseline`` seconds and counts the wake-ups 4 ms or more late (the stalls no simulator
could avoid). Then each run's report gives its stalls, missed cycles and failed checks.

Run from the repository's root:

    python -m benchmarks.soak                             # 100 runs of configs/quickstart.toml
    python -m benchmarks.soak --runs 20 --hog             # with a CPU hog pinned to the last CPU
    python -m benchmarks.soak configs/quickstart.toml --json soak.json -- --host-stalls strict
    python -m benchmarks.soak --runs 10 --stop 400ms@1s   # a stall beyond the bound in every run
    python -m benchmarks.soak --long 60min --json long.json  # one hour of configs/ml3-62-max.toml, sampled each minute

``--stop D@T`` stops each run's whole process group (``up`` and its slave workers) with SIGSTOP for D, T into the
timeline (after bring-up: the run's ``network_up`` log line), then SIGCONT: a host stall of a chosen length, e.g.
one beyond the 100 ms bound the policy absorbs, after which the stations must recover by themselves
(docs/timing.md, "Host stalls").

Exit 0 when at least ``--target`` percent of the runs passed, 1 otherwise, 2 on bad arguments.
Everything it starts (runs, the hog) stops by itself: each run has a timeout and the hog a time limit.
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from mlink_sim.config import parse_duration_ns

from benchmarks import longrun
from benchmarks.common import ROOT, write_atomically

__all__ = ["baseline", "main", "one_run", "parse_stop", "summarise"]

MLINK = [sys.executable, "-m", "mlink_sim"]
_HOG = "import time\nend = time.monotonic() + {limit}\nwhile time.monotonic() < end:\n    pass\n"


def baseline(seconds: float, period_s: float = 0.002, stall_s: float = 0.004) -> dict[str, Any]:
    """A bare loop that sleeps to absolute 2 ms deadlines: its wake-ups 4 ms or more late."""
    stalls: list[float] = []
    start = time.monotonic()
    deadline = start
    while deadline - start < seconds:
        deadline += period_s
        delay = deadline - time.monotonic()
        if delay > 0:
            time.sleep(delay)
        late = time.monotonic() - deadline
        if late >= stall_s:
            stalls.append(late)
            deadline = time.monotonic()
    return {"seconds": seconds, "stalls": len(stalls), "max_ms": round(max(stalls, default=0.0) * 1e3, 2),
            "total_ms": round(sum(stalls) * 1e3, 2)}


def parse_stop(text: str) -> tuple[float, float]:
    """``D@T`` -> (D, T) in seconds: stop for D, T into the timeline (``400ms@1s``)."""
    duration, sep, at = text.partition("@")
    if not sep:
        raise argparse.ArgumentTypeError(f"expected DURATION@TIME, e.g. 400ms@1s, got {text!r}")
    try:
        return parse_duration_ns(duration) / 1e9, parse_duration_ns(at) / 1e9
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def _until_up(proc: subprocess.Popen[str], head: list[str]) -> bool:
    """Read the run's output into *head* until its ``network_up`` line; False if it ended first."""
    assert proc.stdout is not None
    for line in proc.stdout:
        head.append(line)
        if "network_up" in line:
            return True
    return False


def one_run(config: str, extra: list[str], workdir: Path, index: int, timeout: float,
            stop: tuple[float, float] | None = None) -> dict[str, Any]:
    report_path = workdir / f"run-{index}.json"
    started = time.monotonic()
    logs = ["--log-level", "info"] if stop is not None else []  # its network_up line starts the stop's clock
    proc = subprocess.Popen([*MLINK, "up", config, "--no-status", "--report", str(report_path), *logs, *extra],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, cwd=ROOT,
                            start_new_session=stop is not None)  # its own group: up and its workers stop together
    head: list[str] = []
    try:
        if stop is not None and _until_up(proc, head):
            time.sleep(stop[1])
            try:
                os.killpg(proc.pid, signal.SIGSTOP)
                time.sleep(stop[0])
            finally:
                os.killpg(proc.pid, signal.SIGCONT)
        out = "".join(head) + proc.communicate(timeout=max(1.0, timeout - (time.monotonic() - started)))[0]
        code = proc.returncode
    except subprocess.TimeoutExpired:
        proc.kill()
        code, out = -1, f"timeout after {timeout} s: " + "".join(head) + proc.communicate()[0]
    except ProcessLookupError:  # the run ended before the stop
        code, out = proc.wait(), "".join(head)
    row: dict[str, Any] = {"run": index, "exit": code, "seconds": round(time.monotonic() - started, 2)}
    if stop is not None:
        row["stopped_ms"] = round(stop[0] * 1e3, 1)
    try:
        report = json.loads(report_path.read_text())
    except (OSError, ValueError):
        row["error"] = out.strip().splitlines()[-1:] or ["no report"]
        return row
    host = report.get("host", {}).get("stall", {})
    row.update({
        "missed": report["missed"], "missing": report["missing"], "reception_failures": report["reception_failures"],
        "stalls": host.get("count", 0), "stall_max_ms": round(host.get("max", 0) / 1e6, 2),
        "stall_total_ms": round(host.get("total", 0) / 1e6, 2), "cycles_run_late": host.get("absorbed", 0),
        "cycles_lost": host.get("lost", 0), "bound_ms": report.get("host", {}).get("bound", 0) / 1e6,
        "failed": [f"{c['what']}: {c.get('detail', '')}" for c in report["checks"] if not c["ok"]],
    })
    return row


def _pct(values: list[float], q: float) -> float:
    if not values:
        return 0.0
    values = sorted(values)
    return values[min(len(values) - 1, int(q * len(values)))]


def summarise(rows: list[dict[str, Any]], base: dict[str, Any]) -> dict[str, Any]:
    passed = sum(r["exit"] == 0 for r in rows)
    maxes = [r.get("stall_max_ms", 0.0) for r in rows]
    within = [r for r in rows if "bound_ms" in r and r["stall_max_ms"] < r["bound_ms"]]
    return {
        "runs": len(rows), "passed": passed, "baseline": base,
        "stall_max_ms": {"p50": round(statistics.median(maxes), 2) if maxes else 0.0, "p90": _pct(maxes, 0.9),
                         "max": max(maxes, default=0.0)},
        "stalls_per_run_p50": statistics.median([r.get("stalls", 0) for r in rows]) if rows else 0,
        "cycles_run_late": sum(r.get("cycles_run_late", 0) for r in rows),
        "cycles_lost": sum(r.get("cycles_lost", 0) for r in rows),
        "runs_within_bound": len(within),
        "runs_within_bound_with_missed": sum(r["missed"] > 0 for r in within),
        "failures": [r for r in rows if r["exit"] != 0],
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m benchmarks.soak", description=__doc__.split("\n\n")[0])
    ap.add_argument("config", nargs="?", help="default: configs/quickstart.toml, with --long configs/ml3-62-max.toml")
    ap.add_argument("--runs", type=int, default=100)
    ap.add_argument("--hog", action="store_true", help="a busy loop pinned to the last CPU for the whole soak")
    ap.add_argument("--baseline", type=float, default=10.0, metavar="S", help="seconds of bare-loop baseline")
    ap.add_argument("--timeout", type=float, default=60.0, help="seconds one run may take")
    ap.add_argument("--target", type=float, default=99.0, help="percent of runs that must pass")
    ap.add_argument("--json", help="write the rows and the summary here")
    ap.add_argument("--stop", type=parse_stop, metavar="D@T",
                    help="stop each run (up and its workers) for D, T after it started, e.g. 400ms@1s")
    ap.add_argument("--long", metavar="DURATION", help="one run of DURATION (e.g. 60min) sampled every --sample instead "
                    "of many short ones (benchmarks.longrun); the config defaults to configs/ml3-62-max.toml")
    ap.add_argument("--sample", default="60s", metavar="DURATION", help="with --long: how often to sample the run")
    ap.epilog = "Arguments after '--' go to mlink-sim up, e.g. -- --no-realtime."
    argv = list(sys.argv[1:] if argv is None else argv)
    cut = argv.index("--") if "--" in argv else len(argv)
    args = ap.parse_args(argv[:cut])
    args.extra = argv[cut + 1:]
    if args.runs < 1 or args.timeout <= 0:
        ap.error("--runs must be at least 1 and --timeout positive")
    if args.long is not None:
        try:
            duration, sample = parse_duration_ns(args.long) / 1e9, parse_duration_ns(args.sample) / 1e9
        except ValueError as exc:
            ap.error(f"--long/--sample: {exc}")
        if duration <= 0 or sample <= 0:
            ap.error("--long and --sample must be positive")
        return longrun.main(args.config or "configs/ml3-62-max.toml", duration, sample, args.extra, args.json)
    hog = None
    if args.hog:
        limit = args.baseline + args.runs * args.timeout + 60
        cpu = max(os.sched_getaffinity(0))
        hog = subprocess.Popen([sys.executable, "-c", _HOG.format(limit=limit)],
                               preexec_fn=lambda: os.sched_setaffinity(0, {cpu}))
    rows: list[dict[str, Any]] = []
    try:
        base = baseline(args.baseline) if args.baseline > 0 else {}
        print(f"baseline: bare 2 ms loop, {base.get('seconds', 0)} s: {base.get('stalls', 0)} stalls >= 4 ms, "
              f"longest {base.get('max_ms', 0)} ms", flush=True)
        with tempfile.TemporaryDirectory(prefix="mlink-soak-") as tmp:
            for i in range(args.runs):
                row = one_run(args.config or "configs/quickstart.toml", args.extra, Path(tmp), i, args.timeout, args.stop)
                rows.append(row)
                print(json.dumps(row), flush=True)
    finally:
        if hog is not None:
            hog.kill()
            hog.wait()
    summary = summarise(rows, base)
    print(f"\n{summary['passed']} of {summary['runs']} runs passed{' (CPU hog on one core)' if args.hog else ''}; "
          f"per-run longest stall p50 {summary['stall_max_ms']['p50']} ms, p90 {summary['stall_max_ms']['p90']} ms, "
          f"max {summary['stall_max_ms']['max']} ms; cycles run late {summary['cycles_run_late']}, lost "
          f"{summary['cycles_lost']}; runs within the bound with missed cycles: "
          f"{summary['runs_within_bound_with_missed']} of {summary['runs_within_bound']}")
    if args.json:
        write_atomically(args.json, json.dumps({"rows": rows, "summary": summary}, indent=1))
    return 0 if summary["passed"] * 100 >= args.target * summary["runs"] else 1


if __name__ == "__main__":
    sys.exit(main())
