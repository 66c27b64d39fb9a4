"""The quickstart on the single-node swarm beside the compose testbed, or beside the two-node swarm across a delayed
link: pass counts and RTT p50 and p99 of each, measured one run after the other on the same machine
(docs/testbeds.md, "More than one machine").

Each round runs ``scripts/swarm-testbed CONFIG --no-build`` and then ``scripts/docker-testbed CONFIG --no-build``
(``--nodes 2``: ``scripts/swarm-testbed CONFIG --no-build --nodes 2 --link-delay D``), so that both see the same
load on a machine whose load drifts; the image is built once first (``scripts/docker-build``) unless
``--no-build``. A run passes when its script exits 0 (every check held); its RTT figures are the report's
``rtt.p50`` and ``rtt.p99``. Needs a Docker engine (every script), docker-compose (the compose testbed) or root
(the two-node swarm).

Run from the repository's root, as root or a member of the ``docker`` group, on a quiet machine:

    python -m benchmarks.lab.testbeds --runs 20
    python -m benchmarks.lab.testbeds --runs 20 --nodes 2 --link-delay 200us --json testbeds-2nodes.json
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
TWO_NODES = "swarm-2"  #: the name of the two-node arm (scripts/swarm-testbed --nodes 2)

__all__ = ["Run", "Side", "main", "run_once", "summarize"]


@dataclass
class Run:
    code: int  #: the script's exit code
    seconds: float
    rtt_p99_ns: int | None  #: the report's rtt.p99; None without a report
    missed: int | None
    rtt_p50_ns: int | None = None  #: the report's rtt.p50
    note: str = ""  #: the script's last line on stderr, for a run that failed or left no report


@dataclass
class Side:
    testbed: str
    runs: list[Run] = field(default_factory=list)

    @property
    def passed(self) -> int:
        return sum(1 for r in self.runs if r.code == 0)


def arms(nodes: int, link_delay: str) -> dict[str, tuple[str, list[str]]]:
    """The arms of a measurement: name -> (testbed, its extra options)."""
    if nodes == 2:
        return {"swarm": ("swarm", []), TWO_NODES: ("swarm", ["--nodes", "2", "--link-delay", link_delay])}
    return {name: (name, []) for name in TESTBEDS}


def run_once(testbed: str, config: str, report: Path, timeout_s: float, extra: list[str] | None = None) -> Run:
    """One run of *testbed*'s script on *config* (with *extra* options); its exit code and its report's figures."""
    t0 = time.monotonic()
    try:
        proc = subprocess.run([str(ROOT / TESTBEDS[testbed]), config, "--no-build", "--report", str(report),
                               *(extra or [])],
                              cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                              timeout=timeout_s)  # fmt: skip
        code, err = proc.returncode, proc.stderr
    except subprocess.TimeoutExpired:
        code, err = 124, f"{testbed}: no end after {timeout_s:.0f} s"
    seconds = time.monotonic() - t0
    if code == 2:
        raise SystemExit(f"testbeds: {TESTBEDS[testbed]} {' '.join(extra or [])} could not run: "
                         f"{err.strip().splitlines()[-1] if err else ''}")
    lines = err.strip().splitlines()
    note = lines[-1] if lines else ""
    try:
        doc: dict[str, Any] = json.loads(report.read_text(encoding="utf-8"))
        p50 = doc["rtt"].get("p50")
        return Run(code, seconds, int(doc["rtt"]["p99"]), int(doc["missed"]), None if p50 is None else int(p50),
                   note if code else "")  # fmt: skip
    except (OSError, ValueError, KeyError, TypeError):
        return Run(code, seconds, None, None, None, note)


def _median(values: list[int]) -> str:
    return f"{statistics.median(values) / 1e6:.2f} ms ({min(values) / 1e6:.2f}–{max(values) / 1e6:.2f})"


def summarize(side: Side) -> str:
    """One line per side: its name, how many of its runs passed, the median RTT p50 and p99 over them with their
    ranges, and the cycles missed in all."""
    p50 = [r.rtt_p50_ns for r in side.runs if r.rtt_p50_ns is not None]
    p99 = [r.rtt_p99_ns for r in side.runs if r.rtt_p99_ns is not None]
    missed = sum(r.missed or 0 for r in side.runs)
    figure = (f"RTT p50 median {_median(p50)}  p99 median {_median(p99)}" if p50 and p99
              else f"RTT p99 median {_median(p99)}" if p99 else "no report")
    return f"{side.testbed:<8} {side.passed} of {len(side.runs)} passed  {figure}  missed {missed}"


def _commit() -> str:
    out = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True, text=True)
    return out.stdout.strip() or "unknown"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.lab.testbeds", description=__doc__.split("\n\n")[0])
    parser.add_argument("--runs", type=int, default=20, help="runs of each testbed (default 20)")
    parser.add_argument("--config", default="configs/quickstart.toml", help="the config (default: the quickstart)")
    parser.add_argument("--no-build", action="store_true", help="use the image as it is")
    parser.add_argument("--timeout", type=float, default=600.0, help="seconds one run may take (default 600)")
    parser.add_argument("--json", type=Path, help="write every run's figures here")
    parser.add_argument("--nodes", type=int, choices=(1, 2), default=1,
                        help="1: the one-node swarm beside the compose testbed (default); 2: beside the two-node swarm")
    parser.add_argument("--link-delay", default="200us", help="with --nodes 2: the link's delay each way (default 200us)")
    parser.add_argument("--machine", default="", help="a description of the machine, for the --json file")
    args = parser.parse_args(argv)
    if args.runs < 1:
        parser.error("--runs: at least 1")
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(143))
    if not args.no_build:
        built = subprocess.run([str(ROOT / "scripts" / "docker-build")], cwd=ROOT, stdout=subprocess.DEVNULL)
        if built.returncode != 0:
            print("testbeds: scripts/docker-build failed", file=sys.stderr)
            return 2
    commit = _commit()  # the code that runs: the tree may move on while it does
    plan = arms(args.nodes, args.link_delay)
    sides = {name: Side(name) for name in plan}
    try:
        with tempfile.TemporaryDirectory(prefix="mlink-testbeds-") as tmp:
            for i in range(1, args.runs + 1):
                for name, side in sides.items():
                    testbed, extra = plan[name]
                    run = run_once(testbed, args.config, Path(tmp) / f"{name}-{i}.json", args.timeout, extra)
                    side.runs.append(run)
                    p50, p99 = (f"{v / 1e6:.2f} ms" if v is not None else "-" for v in (run.rtt_p50_ns, run.rtt_p99_ns))
                    print(f"run {i:>2} {name:<8} exit {run.code}  RTT p50 {p50} p99 {p99}  {run.seconds:.0f} s",
                          flush=True)
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
            meta = {"date": time.strftime("%Y-%m-%d"), "commit": commit, "machine": args.machine,
                    "command": "python -m benchmarks.lab.testbeds " + " ".join(argv if argv is not None else sys.argv[1:]),
                    "config": args.config}  # fmt: skip
            doc = {**meta, **{n: [asdict(r) for r in s.runs] for n, s in sides.items()}}
            args.json.write_text(json.dumps(doc, indent=1), encoding="utf-8")
        except OSError as exc:
            print(f"testbeds: cannot write {args.json}: {exc.strerror or exc}", file=sys.stderr)
            return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
