"""Running a whole network: slave workers (``up``), one master per link, the timeline, live status, the report.

``mlink-sim up`` = :func:`run_up` (starts the slave workers, then :func:`run_network`);
``mlink-sim master`` = :func:`run_network` against endpoints elsewhere.
"""

from __future__ import annotations

import asyncio
import dataclasses
import os
import signal
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import structlog

from ..config import Config, format_ns
from ..metrics import write_report
from .scenario import CheckResult, Scenario, speed_scales
from .session import EndpointError, NetworkApi, NetworkSession, build_plans
from .status import render_status
from .supervisor import resolve_workers

__all__ = ["RunOptions", "RunOutcome", "EndpointError", "run_up", "run_network", "build_plans"]

log = structlog.get_logger("mlink_sim.network")


@dataclasses.dataclass
class RunOptions:
    """How a run behaves (command-line flags of ``up`` / ``master``)."""

    config_path: Path
    duration_ns: int | None = None  #: stop after this long (from the end of bring-up); None = the timeline's end
    report_path: Path | None = None  #: write the JSON report here (atomically)
    assertions: Sequence[Any] = ()  #: parsed --assert expressions
    status: bool = True  #: live status on stdout
    bringup_timeout_s: float = 10.0
    include_bringup: bool = False  #: False: the report's figures count from the end of bring-up
    #: worker processes of the slaves (up): a number, "auto" (one per station up to max(2, CPUs − 1) stations, else
    #: CPUs − 1 processes) or "station" (one process per station); see ``supervisor.resolve_workers``
    workers: int | str = "auto"
    state_dir: Path | None = None  #: EEPROM images of the slaves (up)
    run_dir: Path | None = None  #: worker logs (up); default a temporary directory
    restart_slaves: bool = True  #: restart a worker that died (up)
    #: "real" (slave processes, UDP, the wall clock) or "virtual" (one process, in-memory network, simulated time;
    #: the loop must be a ``vclock.VirtualEventLoop``), docs/virtual-time.md
    clock: str = "real"
    seed: int = 0  #: virtual clock: seed of the network model's jitter
    realtime: bool = False  #: SCHED_FIFO, locked memory, the clock on a CPU of its own, where permitted (CLI: on)


@dataclasses.dataclass
class RunOutcome:
    exit_code: int
    report: dict[str, Any]
    checks: list[CheckResult]
    problems: list[str]


async def _sleep_until(when: float) -> None:
    loop = asyncio.get_running_loop()
    delay = when - loop.time()
    if delay > 0:
        await asyncio.sleep(delay)


async def run_up(config: Config, opts: RunOptions) -> RunOutcome:
    """Start the slave worker processes (``--workers``: one per station, or packed), then run the network against
    them."""
    return await _run(config, opts, None)


async def run_network(config: Config, endpoints: dict[int, tuple[str, int]], opts: RunOptions) -> RunOutcome:
    """Start one master per link against *endpoints* (slaves started elsewhere) and run the network."""
    return await _run(config, opts, endpoints)


async def _run(config: Config, opts: RunOptions, endpoints: dict[int, tuple[str, int]] | None) -> RunOutcome:
    """Bring the stations up, run the timeline with the live status until its end / --duration / a signal, then
    write the report, evaluate the assertions and print the summary."""
    loop = asyncio.get_running_loop()
    stop = asyncio.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        loop.add_signal_handler(sig, stop.set)
    checks: list[CheckResult] = []
    t0 = loop.time()
    session: NetworkSession | None = None
    workers = None
    session_cls: type[NetworkSession] = NetworkSession
    extra: dict[str, Any] = {}
    if opts.clock == "virtual":
        from .virtual import VirtualSession

        session_cls, extra = VirtualSession, {"seed": opts.seed}
    elif endpoints is None:
        workers = resolve_workers(opts.workers, len(config.station))
        if opts.workers == "auto" and workers is not None:
            print(f"note: {len(config.station)} stations on {os.cpu_count() or 1} CPUs: hosted in {workers} slave "
                  f"process(es), so the master's clock keeps a CPU (--workers station: one process per station; "
                  "docs/performance.md)", file=sys.stderr)
    scales = speed_scales(config)  # now, not in the event loop once it keeps time
    try:
        session = await session_cls.open(
            config, opts.config_path, endpoints=endpoints, workers=workers, state_dir=opts.state_dir,
            run_dir=opts.run_dir, restart_slaves=opts.restart_slaves, realtime=opts.realtime, **extra)
        if session.realtime_granted:
            print("realtime: " + "; ".join(f"{p} {g}" for p, g in session.realtime_granted.items()),
                  file=sys.stderr, flush=True)
        net = session.net
        assert net is not None
        # -- bring-up ----------------------------------------------------------------------------------------------
        bring = loop.create_task(session.bring_up(opts.bringup_timeout_s))
        stopper = loop.create_task(stop.wait())
        done, _ = await asyncio.wait({bring, stopper}, return_when=asyncio.FIRST_COMPLETED)
        if bring not in done:
            bring.cancel()
            await asyncio.gather(bring, return_exceptions=True)
        not_up = session.not_up()
        if not stop.is_set():
            log.info("network_up", stations=len(config.station), not_up=len(not_up))
            if not opts.include_bringup:
                session.reset_metrics()  # the report is about the running network, not five processes starting
            # -- timeline + status -----------------------------------------------------------------------------
            t0 = loop.time()
            scenario = Scenario(config, net, scales)
            length = opts.duration_ns if opts.duration_ns is not None else config.run_length_ns
            tasks = [loop.create_task(scenario.run(t0, _sleep_until))]
            if opts.status:
                tasks.append(loop.create_task(_status_loop(config, net, t0, scenario.scales)))
            end = loop.create_task(_sleep_until(t0 + length / 1e9)) if length is not None else None
            waiters = {stopper} | ({end} if end else set())
            if end is None and not config.timeline:
                print("running until Ctrl-C (no timeline, no --duration)", file=sys.stderr)
            await asyncio.wait(waiters, return_when=asyncio.FIRST_COMPLETED)
            for task in [*tasks, *waiters]:
                task.cancel()
            await asyncio.gather(*tasks, return_exceptions=True)
            checks = scenario.results
            session.problems.extend(scenario.action_errors)
            if opts.status:
                print(render_status(config, net, loop.time() - t0, scenario.scales), flush=True)
        stopper.cancel()
        await session.refresh_slave_stats()
        await session.close_masters()  # DISCONNECT while the slaves still run
        checks = [_with_stalls(c, session.metrics.stalls, t0) for c in checks]
        for c in checks:
            session.metrics.record_check(c.at_s, c.what, c.ok, c.detail)
        report = await session.report(assertions=opts.assertions, slave_stats=False)
    finally:
        if session is not None:
            await session.close()
        for sig in (signal.SIGINT, signal.SIGTERM):
            loop.remove_signal_handler(sig)
    if opts.report_path is not None:
        write_report(opts.report_path, report)
    problems = session.problems
    failed_checks = [c for c in checks if not c.ok]
    failed_asserts = [r for r in report["assertions"] if not r.get("ok")]
    _print_summary(config, report, checks, failed_asserts, problems, opts)
    ok = not failed_checks and not failed_asserts and not [p for p in problems if "did not reach" in p]
    return RunOutcome(0 if ok else 1, report, checks, problems)


def _with_stalls(check: CheckResult, stalls: Any, t0: float) -> CheckResult:
    """A failed check names the host stalls of the three seconds before it (loop time is the monotonic clock)."""
    near = "" if check.ok else stalls.describe_near(int((t0 + check.at_s) * 1e9), zero_ns=int(t0 * 1e9))
    return dataclasses.replace(check, detail=f"{check.detail}; {near}") if near else check


async def _status_loop(config: Config, net: NetworkApi, t0: float, scales: dict[int, Any]) -> None:
    loop = asyncio.get_running_loop()
    tty = sys.stdout.isatty()
    interval = 0.5 if tty else 5.0
    lines_drawn = 0
    while True:
        await asyncio.sleep(interval)
        text = render_status(config, net, loop.time() - t0, scales)
        if tty and lines_drawn:
            sys.stdout.write(f"\x1b[{lines_drawn}F\x1b[J")
        sys.stdout.write(text + "\n")
        sys.stdout.flush()
        lines_drawn = text.count("\n") + 1 if tty else 0


def _print_summary(config: Config, report: dict[str, Any], checks: list[CheckResult], failed_asserts: list[Any],
                   problems: list[str], opts: RunOptions) -> None:
    out = sys.stdout
    rtt = report.get("rtt", {})
    print(f"\n== {config.network.name}: {len(config.station)} stations, "
          f"{format_ns(config.network.transmission_cycle)} cycle, {report['meta']['duration_s']:.1f} s ==", file=out)
    if rtt.get("count"):
        print(f"rtt p50 {format_ns(rtt['p50'])}  p99 {format_ns(rtt['p99'])}  max {format_ns(rtt['max'])}  "
              f"({rtt['count']} responses); missed cycles {report.get('missed', 0)}, "
              f"missing responses {report.get('missing', 0)}, late {report.get('late', 0)}", file=out)
    host = report.get("host")
    if host:
        st = host["stall"]
        bound = f"absorbs up to {format_ns(host['bound'])}" if host["policy"] == "absorb" else "strict"
        print(f"host stalls {st['count']}, longest {format_ns(st['max'])}, {st['cycles']} cycles delayed: "
              f"{st['absorbed']} run late, {st['lost']} lost (policy {bound})", file=out)
    for c in checks:
        print(f"  {'ok  ' if c.ok else 'FAIL'} {c.what}: {c.detail}", file=out)
    for r in report.get("assertions", []):
        print(f"  {'ok  ' if r.get('ok') else 'FAIL'} assert {r.get('message') or r.get('text')}", file=out)
    for p in problems:
        print(f"  note {p}", file=out)
    meta = report["meta"]
    wall = meta.get("wall")
    if meta.get("clock") == "virtual" and isinstance(wall, dict):
        print(f"virtual clock (seed {meta.get('seed')}): {wall['simulated_s']:.1f} s simulated in "
              f"{wall['elapsed_s']:.2f} s wall, {wall['speedup'] or 0:g}x real time", file=out)
    failed = sum(not c.ok for c in checks) + len(failed_asserts)
    verdict = "all checks held" if not failed else f"{failed} check(s) failed"
    print(f"{verdict}" + (f"; report: {opts.report_path}" if opts.report_path else ""), file=out, flush=True)
