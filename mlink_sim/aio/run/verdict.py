"""The verdict of a run (:class:`Verdict`: the checks, the assertions, the stations that never came up, the steps
that never ran, a signal) and its summary on stdout: one place, so that the summary line and the exit status can
never disagree.

Touches: stdout (the summary).
"""

from __future__ import annotations

import signal
import sys
from dataclasses import dataclass
from typing import Any

from ...config import Config, format_ns
from ..present.status import SummaryWriter

__all__ = ["Verdict", "SIGNAL_EXIT", "print_summary"]

#: Exit status of a run ended by a signal: 128 + the signal number, as a shell reports a process it killed.
SIGNAL_EXIT = {signal.SIGINT: 130, signal.SIGTERM: 143}

_Signal = signal.Signals  # for the annotations inside Verdict, whose field `signal` hides the module there


@dataclass(frozen=True)
class Verdict:
    """The run's outcome in one place, so the summary line and the exit status can never disagree."""

    failed_checks: int
    failed_asserts: int
    unreached: int  #: stations that never reached their phase
    not_run: int  #: timeline steps that never began
    checks_not_run: int
    held: int  #: checks and assertions that held
    signal: signal.Signals | None

    @classmethod
    def of(cls, timeline: Any, report: dict[str, Any], unreached: int, sig: _Signal | None) -> Verdict:
        """The verdict of a run whose *timeline* (a :class:`~mlink_sim.scenario.Timeline`) ran, whose *report* was
        made, with *unreached* stations that never reached their phase, ended by *sig* (None: by itself)."""
        asserts = report.get("assertions", [])
        not_run = timeline.not_run()
        return cls(
            failed_checks=sum(not c.ok for c in timeline.results),
            failed_asserts=sum(not a.get("ok") for a in asserts),
            unreached=unreached,
            not_run=len(not_run),
            checks_not_run=sum(s.expect is not None for s in not_run),
            held=sum(c.ok for c in timeline.results) + sum(bool(a.get("ok")) for a in asserts),
            signal=sig,
        )

    @property
    def exit_code(self) -> int:
        if self.signal is not None:
            return SIGNAL_EXIT[self.signal]
        return 1 if self.failed_checks or self.failed_asserts or self.unreached else 0

    def line(self, duration_ns: int | None) -> str:
        parts = []
        if self.signal is not None:
            parts.append(f"interrupted by {self.signal.name}")
        failed = self.failed_checks + self.failed_asserts
        if failed:
            parts.append(f"{failed} check(s) failed")
        if self.unreached:
            parts.append(f"{self.unreached} station(s) did not come up")
        if self.not_run:
            why = "" if self.signal is not None else f" (--duration {format_ns(duration_ns or 0)} ended the run)"
            parts.append(f"{self.not_run} timeline step(s) not run{why}")
        if not parts and self.held:
            return "all checks held"
        if not parts:
            return "run complete (no checks in the timeline, no --assert)"
        return "; ".join(parts) + (f"; {self.held} check(s) held" if self.held else "")


def print_summary(config: Config, report: dict[str, Any], timeline: Any, verdict: Verdict, problems: list[str],
                  duration_ns: int | None, files: list[str]) -> None:
    """The run's summary on stdout: its figures, each check, the steps not run, the assertions, the problems and the
    verdict's line with the files written (*files*: ``"report: PATH"`` …)."""
    out = SummaryWriter.for_terminal(sys.stdout)
    rtt = report.get("rtt", {})
    print(f"\n== {config.network.name}: {len(config.station)} stations, "
          f"{format_ns(config.network.transmission_cycle)} cycle, {report['meta']['duration_s']:.1f} s ==", file=out)
    if rtt.get("count"):
        print(f"rtt p50 {format_ns(rtt['p50'])}  p99 {format_ns(rtt['p99'])}  max {format_ns(rtt['max'])}  "
              f"({rtt['count']} responses); missed cycles {report.get('missed', 0)}, "
              f"missing responses {report.get('missing', 0)}, late {report.get('late', 0)}", file=out)
    injected = [f"{int(key, 16):02X}H " + ", ".join(f"{n} {kind}" for kind, n in st["injected"].items() if n)
                for key, st in report.get("station", {}).items() if any(st.get("injected", {}).values())]
    if injected:  # docs/faults.md: what was done on purpose, next to what the stations reported
        print("injected: " + "; ".join(injected), file=out)
    host = report.get("host")
    if host:
        st = host["stall"]
        bound = f"absorbs up to {format_ns(host['bound'])}" if host["policy"] == "absorb" else "strict"
        print(f"host stalls {st['count']}, longest {format_ns(st['max'])}, {st['cycles']} cycles delayed: "
              f"{st['absorbed']} run late, {st['lost']} lost (policy {bound})", file=out)
    for c in timeline.results:
        why = f" — {c.cause}" if c.cause else ""
        print(f"  {'ok  ' if c.ok else 'FAIL'} {c.what}: {c.detail}{why}", file=out)
    for step in timeline.not_run():
        print(f"  --   {step.describe}: not run", file=out)
    for r in report.get("assertions", []):
        print(f"  {'ok  ' if r.get('ok') else 'FAIL'} assert {r.get('message') or r.get('text')}", file=out)
    for p in problems:
        print(f"  note {p}", file=out)
    meta = report["meta"]
    wall = meta.get("wall")
    if meta.get("clock") == "virtual" and isinstance(wall, dict):
        print(f"virtual clock (seed {meta.get('seed')}): {wall['simulated_s']:.1f} s simulated in "
              f"{wall['elapsed_s']:.2f} s wall, {wall['speedup'] or 0:g}x real time", file=out)
    print("; ".join([verdict.line(duration_ns), *files]), file=out, flush=True)
