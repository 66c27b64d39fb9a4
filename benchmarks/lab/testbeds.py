"""The quickstart on the single-node swarm beside the compose testbed: pass counts and RTT p99 of each, measured
one run after the other on the same machine (docs/testbeds.md, "More than one machine").

Each round runs ``scripts/swarm-testbed CONFIG --no-build`` and then ``scripts/docker-testbed CONFIG --no-build``,
so that both see the same load on a machine whose load drifts; the image is built once first
(``scripts/docker-build``) unless ``--no-build``. A run passes when its script exits 0 (every timeline check
held); its RTT p99 is the report's ``rtt.p99``. Needs a Docker engine (both scripts) and docker-compose.

Run from the repository's root, as root or a member of the ``docker`` group, on a quiet machine:

    python -m benchmarks.lab.testbeds --runs 20
    python -m benchmarks.lab.testbeds --runs 2 --no-build --json testbeds.json

Exit status: 0 with the table (a benchmark reports, it does not gate), 2 for bad options or when a script could
not run at all (exit 2: no engine, a usage error; the message says which), 1 when ``--json`` could not be written,
130/143 on Ctrl-C/SIGTERM (each script tears its testbed down).
"""

from __future__ import annotations

import argparse
import json
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[2]
TESTBEDS = {"swarm": "scripts/swarm-testbed", "compose": "scripts/docker-testbed"}

__all__ = ["Run", "Side", "main", "run_once", "summarize"]


@dataclass
class Run:
    code: int  #: the script's exit code
    seconds: float
    rtt_p99_ns: int | None  #: the report's rtt.p99; None without a report
    missed: int | None


@dataclass
class Side:
    testbed: str
    runs: list[Run] = field(default_factory=list)

    @property
    def passed(self) -> int:
        return sum(1 for r in self.runs if r.code == 0)


def run_once(testbed: str, config: str, report: Path, timeout_s: float) -> Run:
    """One run of *testbed*'s script on *config*; its exit code and the figures of its report."""
    t0 = time.monotonic()
    try:
        proc = subprocess.run([str(ROOT / TESTBEDS[testbed]), config, "--no-build", "--report", str(report)],
                              cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                              timeout=timeout_s)  # fmt: skip
        code, err = proc.returncode, proc.stderr
    except subprocess.TimeoutExpired:
        code, err = 124, f"{testbed}: no end after {timeout_s:.0f} s"
    seconds = time.monotonic() - t0
    if code == 2:
        raise SystemExit(f"testbeds: {TESTBEDS[testbed]} could not run: {err.strip().splitlines()[-1] if err else ''}")
    try:
        doc: dict[str, Any] = json.loads(report.read_text(encoding="utf-8"))
        return Run(code, seconds, int(doc["rtt"]["p99"]), int(doc["missed"]))
    except (OSError, ValueError, KeyError, TypeError):
        return Run(code, seconds, None, None)


def summarize(side: Side) -> str:
    """One line per side: its name, how many of its runs passed, the median RTT p99 over them with its range, and
    the cycles missed in all."""
    p99 = [r.rtt_p99_ns for r in side.runs if r.rtt_p99_ns is not None]
    missed = sum(r.missed or 0 for r in side.runs)
    figure = (f"RTT p99 median {statistics.median(p99) / 1e6:.2f} ms ({min(p99) / 1e6:.2f}–{max(p99) / 1e6:.2f})"
              if p99 else "no report")
    return f"{side.testbed:<8} {side.passed} of {len(side.runs)} passed  {figure}  missed {missed}"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.lab.testbeds", description=__doc__.split("\n\n")[0])
    parser.add_argument("--runs", type=int, default=20, help="runs of each testbed (default 20)")
    parser.add_argument("--config", default="configs/quickstart.toml", help="the config (default: the quickstart)")
    parser.add_argument("--no-build", action="store_true", help="use the image as it is")
    parser.add_argument("--timeout", type=float, default=600.0, help="seconds one run may take (default 600)")
    parser.add_argument("--json", type=Path, help="write every run's figures here")
    args = parser.parse_args(argv)
    if args.runs < 1:
        parser.error("--runs: at least 1")
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(143))
    if not args.no_build:
        built = subprocess.run([str(ROOT / "scripts" / "docker-build")], cwd=ROOT, stdout=subprocess.DEVNULL)
        if built.returncode != 0:
            print("testbeds: scripts/docker-build failed", file=sys.stderr)
            return 2
    sides = {name: Side(name) for name in TESTBEDS}
    try:
        with tempfile.TemporaryDirectory(prefix="mlink-testbeds-") as tmp:
            for i in range(1, args.runs + 1):
                for name, side in sides.items():
                    run = run_once(name, args.config, Path(tmp) / f"{name}-{i}.json", args.timeout)
                    side.runs.append(run)
                    p99 = f"{run.rtt_p99_ns / 1e6:.2f} ms" if run.rtt_p99_ns is not None else "-"
                    print(f"run {i:>2} {name:<8} exit {run.code}  RTT p99 {p99}  {run.seconds:.0f} s", flush=True)
    except KeyboardInterrupt:
        return 130
    except SystemExit as exc:
        if isinstance(exc.code, str):
            print(exc.code, file=sys.stderr)
            return 2
        raise
    for side in sides.values():
        print(summarize(side))
    if args.json is not None:
        try:
            args.json.write_text(json.dumps({n: [asdict(r) for r in s.runs] for n, s in sides.items()}, indent=2),
                                 encoding="utf-8")
        except OSError as exc:
            print(f"testbeds: cannot write {args.json}: {exc.strerror or exc}", file=sys.stderr)
            return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
