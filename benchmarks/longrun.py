"""A long run: ``mlink-sim up CONFIG`` for hours on the wall clock, sampled every minute, for memory that grows,
counters or histograms that grow without bound, file handles that leak, and a report that no longer comes out
(docs/performance.md, "A long run"). ``python -m benchmarks.soak --long DURATION`` runs it.

Each sample, from outside the run: every process of it (``up`` and its slave workers, from ``/proc``) with its RSS,
its peak RSS (``VmHWM``) and its open files; the run's counters, from its control endpoint (``report``: the report as
``--report`` would write it then); the trace's size on disk. The histograms are not sampled: their memory is bounded
by construction (``mlink_sim.metrics.histogram``: pages of 1,024 counts over 1 ns .. 10 s, values beyond clamped),
so it shows in the RSS if anywhere. At the end: the report the run wrote, checked against its schema, and per process
the RSS growth per hour after the first minute and the peak RSS.

Targets: RSS growth ≤ 1 MB per process per hour after the first minute (judged on runs of 10 minutes or more),
counters that never go back, the report written and valid. Exit 0 when they held, 1 when one did not (each named on stderr), 2 on bad arguments.
"""

from __future__ import annotations

import asyncio
import json
import os
import subprocess
import sys
import tempfile
import threading
import time
from collections import deque
from pathlib import Path
from typing import Any

import jsonschema  # type: ignore[import-untyped]

from mlink_sim.aio.control.endpoint import query_control
from mlink_sim.metrics import REPORT_SCHEMA

from benchmarks.common import ROOT, write_atomically

__all__ = ["GROWTH_TARGET_KB_PER_H", "judge", "long_run", "process_sample", "processes"]

MLINK = [sys.executable, "-m", "mlink_sim"]
GROWTH_TARGET_KB_PER_H = 1024  #: RSS growth per process per hour after the first minute
_COUNTERS = ("sent", "answered", "late", "missing", "reception_failures", "wdt_errors", "dropped")


def processes(root: int) -> list[int]:
    """*root* and every process below it, from ``/proc/PID/task/*/children``."""
    found, frontier = [root], [root]
    while frontier:
        pid = frontier.pop()
        for task in Path(f"/proc/{pid}/task").glob("*/children"):
            try:
                kids = [int(k) for k in task.read_text().split()]
            except OSError:
                continue
            found += kids
            frontier += kids
    return found


def process_sample(pid: int) -> dict[str, Any] | None:
    """A process's role (``up``, ``slave …``), RSS and peak RSS in kB and open files; None once it is gone."""
    try:
        status = Path(f"/proc/{pid}/status").read_text()
        argv = Path(f"/proc/{pid}/cmdline").read_bytes().split(b"\0")
        files = len(os.listdir(f"/proc/{pid}/fd"))
    except OSError:
        return None
    fields = dict(line.split(":", 1) for line in status.splitlines() if ":" in line)
    words = [w.decode(errors="replace") for w in argv if w]
    role = next((w for w in words if w in ("up", "slave", "host")), words[-1] if words else "?")
    if role == "slave" and "--only" in words:
        role += " " + words[words.index("--only") + 1]
    return {"pid": pid, "role": role, "rss_kb": int(fields["VmRSS"].split()[0]),
            "peak_rss_kb": int(fields["VmHWM"].split()[0]), "open_files": files}


def _report_figures(control: tuple[str, int]) -> dict[str, Any] | None:
    """The run's counters now (the control endpoint's ``report``)."""
    reply = asyncio.run(query_control(*control, op="report", timeout=10.0))
    if not reply or "report" not in reply:
        return None
    return {name: reply["report"][name] for name in _COUNTERS}


def _drain(stream: Any, keep: deque[str], found: threading.Event, control: list[str]) -> None:
    for line in stream:
        keep.append(line)
        if not control and line.startswith("control: "):
            control.append(line.split()[1])
            found.set()
    found.set()


def long_run(config: str, duration_s: float, sample_s: float, extra: list[str], workdir: Path) -> dict[str, Any]:
    """Run *config* for *duration_s*, sample it every *sample_s*; the samples, the per-process summary and the
    report's check."""
    trace, report = workdir / "trace.csv", workdir / "report.json"
    argv = [*MLINK, "up", config, "--no-status", "--duration", f"{duration_s}s", "--control", "127.0.0.1:0",
            "--trace", str(trace), "--report", str(report), "--run-dir", str(workdir / "run"), *extra]
    proc = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, cwd=ROOT)
    tail: deque[str] = deque(maxlen=40)
    found, control = threading.Event(), list[str]()
    reader = threading.Thread(target=_drain, args=(proc.stderr, tail, found, control), daemon=True)
    reader.start()
    samples: list[dict[str, Any]] = []
    started = time.monotonic()
    try:
        found.wait(timeout=120)
        host, _, port = (control[0] if control else "").rpartition(":")
        due = started
        while proc.poll() is None:
            due += sample_s
            while proc.poll() is None and time.monotonic() < due:
                time.sleep(min(1.0, max(0.0, due - time.monotonic())))
            if proc.poll() is not None:
                break
            procs = [s for pid in processes(proc.pid) if (s := process_sample(pid)) is not None]
            figures = _report_figures((host, int(port))) if port else None
            samples.append({"t_s": round(time.monotonic() - started, 1), "processes": procs, "run": figures,
                            "trace_bytes": trace.stat().st_size if trace.exists() else 0})
            print(json.dumps(samples[-1]), flush=True)
        proc.wait(timeout=duration_s + 300)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    reader.join(timeout=5)
    return {"config": config, "duration_s": duration_s, "sample_s": sample_s, "exit": proc.returncode,
            "seconds": round(time.monotonic() - started, 1), "samples": samples,
            "processes": summarise(samples), "report": _check_report(report), "stderr_tail": list(tail)[-10:]}


def summarise(samples: list[dict[str, Any]]) -> dict[str, dict[str, Any]]:
    """Per process role: RSS at the first sample after the first minute and at the last, the growth per hour
    between them, the peak RSS and the open files first and last."""
    by: dict[str, list[tuple[float, dict[str, Any]]]] = {}
    for s in samples:
        for p in s["processes"]:
            by.setdefault(p["role"], []).append((s["t_s"], p))
    out = {}
    for role, rows in by.items():
        settled = [r for r in rows if r[0] >= 60.0] or rows
        (t0, first), (t1, last) = settled[0], settled[-1]
        growth = (last["rss_kb"] - first["rss_kb"]) / (t1 - t0) * 3600 if t1 > t0 else 0.0
        out[role] = {"rss_kb_first": first["rss_kb"], "rss_kb_last": last["rss_kb"], "from_s": t0, "to_s": t1,
                     "rss_growth_kb_per_h": round(growth, 1),
                     "peak_rss_kb": max(p["peak_rss_kb"] for _, p in rows),
                     "open_files_first": rows[0][1]["open_files"], "open_files_last": rows[-1][1]["open_files"]}
    return out


def _check_report(path: Path) -> dict[str, Any]:
    try:
        doc = json.loads(path.read_text())
        jsonschema.validate(doc, REPORT_SCHEMA)
    except (OSError, ValueError, jsonschema.ValidationError) as exc:
        return {"valid": False, "error": str(exc).splitlines()[0]}
    return {"valid": True, "bytes": path.stat().st_size, **{name: doc[name] for name in _COUNTERS}}


def judge(result: dict[str, Any]) -> list[str]:
    """The targets that did not hold, one line each (none: all held)."""
    failed = [] if result["report"]["valid"] else [f"the report is not valid: {result['report'].get('error')}"]
    if result["exit"] != 0:
        failed.append(f"the run exited {result['exit']}")
    for role, p in result["processes"].items():
        if p["rss_growth_kb_per_h"] > GROWTH_TARGET_KB_PER_H and p["to_s"] - p["from_s"] >= 600:
            failed.append(f"{role}: RSS grew {p['rss_growth_kb_per_h']:.0f} kB/h after the first minute")
    runs = [s["run"] for s in result["samples"] if s["run"]]
    for name in _COUNTERS:
        if any(b[name] < a[name] for a, b in zip(runs, runs[1:])):
            failed.append(f"the run's {name} went back between two samples")
    return failed


def main(config: str, duration_s: float, sample_s: float, extra: list[str], json_path: str | None) -> int:
    """``benchmarks.soak --long``: the run, a summary line per process, the targets."""
    with tempfile.TemporaryDirectory(prefix="mlink-long-") as tmp:
        result = long_run(config, duration_s, sample_s, extra, Path(tmp))
    for role, p in sorted(result["processes"].items()):
        print(f"{role}: RSS {p['rss_kb_first']} -> {p['rss_kb_last']} kB ({p['from_s']:.0f}-{p['to_s']:.0f} s, "
              f"{p['rss_growth_kb_per_h']:+.0f} kB/h), peak {p['peak_rss_kb']} kB, open files "
              f"{p['open_files_first']} -> {p['open_files_last']}")
    print(f"report: {json.dumps(result['report'])}")
    failed = judge(result)
    for line in failed:
        print(f"soak --long: {line}", file=sys.stderr)
    if json_path:
        write_atomically(json_path, json.dumps(result, indent=1))
    return 1 if failed else 0
