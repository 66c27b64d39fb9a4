"""Running a whole network: slave workers (``up``), one master per link, the timeline, live status, the report.

``mlink-sim up`` = :func:`run_up` (starts the slave workers, then :func:`run_network`);
``mlink-sim master`` = :func:`run_network` against endpoints elsewhere.
"""

from __future__ import annotations

import asyncio
import dataclasses
import signal
import sys
import tempfile
import time
from collections.abc import Sequence
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

import structlog

from ..config import Config, format_ns
from ..wire import Link
from .scenario import CheckResult, Scenario
from .slave import query_control
from .status import render_status
from .supervisor import Worker, WorkerError, WorkerSpec, plan_workers
from .udp import bind_address_for, resolve

__all__ = ["RunOptions", "RunOutcome", "EndpointError", "run_up", "run_network", "build_plans"]

log = structlog.get_logger("mlink_sim.network")


class EndpointError(ValueError):
    """A station endpoint that cannot be used (unresolvable host name)."""


@dataclasses.dataclass
class RunOptions:
    """How a run behaves (command-line flags of ``up`` / ``master``)."""

    config_path: Path
    duration_ns: int | None = None  #: stop after this long (from the end of bring-up); None = the timeline's end
    report_path: Path | None = None  #: write the JSON report here (atomically)
    assertions: Sequence[Any] = ()  #: parsed --assert expressions
    status: bool = True  #: live status on stdout
    bringup_timeout_s: float = 10.0
    workers: int | None = None  #: stations per worker process (up): None = one process per station
    state_dir: Path | None = None  #: EEPROM images of the slaves (up)
    run_dir: Path | None = None  #: worker logs (up); default a temporary directory
    restart_slaves: bool = True  #: restart a worker that died (up)


@dataclasses.dataclass
class RunOutcome:
    exit_code: int
    report: dict[str, Any]
    checks: list[CheckResult]
    problems: list[str]


def build_plans(config: Config) -> dict[Link, Any]:
    """One :class:`~mlink_sim.master.plan.NetworkPlan` per link present in the config."""
    from ..master.plan import NetworkPlan, StationPlan

    by_link: dict[Link, list[Any]] = {}
    for st in config.station:
        assert st.link is not None
        plan = StationPlan(
            address=st.address,
            link=st.link,
            data_size=st.frame_size or 0,
            com_tim=st.com_tim or 0,
            sync=st.sync,
            subcmd=st.subcmd,
            name=st.name or "",
            card=st.card,
            et3_syncmode_table19=bool(st.options.get("et3_syncmode_table19", False)),
        )
        by_link.setdefault(st.link, []).append(plan)
    return {
        link: NetworkPlan(link=link, tcycle_ns=config.network.transmission_cycle, stations=tuple(stations))
        for link, stations in by_link.items()
    }


class _Network:
    """The running network as the scenario and the status display see it (implements NetworkHandle).

    Routes every station to the master of its link and keeps each station's INV_CTL fields, so that a partial
    update (``set_control(0x21, ef0=True)``) leaves the other fields as they were."""

    def __init__(self, config: Config, masters: dict[Link, Any], workers: dict[int, Worker]) -> None:
        self.network_config = config
        self.masters = masters
        self.workers = workers
        self.by_station = {st.address: masters[st.link] for st in config.station}
        self._controls: dict[int, dict[str, Any]] = {st.address: {} for st in config.station}

    def master(self, station: int) -> Any:
        """The :class:`~mlink_sim.aio.master.Master` serving *station*."""
        return self.by_station[station]

    def view(self, station: int) -> Any:
        return self.by_station[station].view(station)

    def views(self) -> dict[int, Any]:
        out: dict[int, Any] = {}
        for m in self.masters.values():
            out.update(m.views())
        return out

    def control(self, station: int) -> dict[str, Any]:
        return dict(self._controls[station])

    def set_control(self, station: int, **fields: Any) -> None:
        merged = self._controls[station]
        merged.update(fields)
        self.by_station[station].set_control(station, **merged)

    async def prm_rd(self, station: int, register: int, size: int = 2) -> Any:
        return await self.by_station[station].prm_rd(station, register, size)

    async def prm_wr(self, station: int, register: int, value: int, size: int = 2) -> Any:
        return await self.by_station[station].prm_wr(station, register, value, size=size)

    async def config(self, station: int, mode: int = 0) -> Any:
        return await self.by_station[station].config(station, mode)

    async def alm_clr(self, station: int) -> Any:
        return await self.by_station[station].alm_clr(station)

    async def disconnect(self, station: int) -> Any:
        return await self.by_station[station].disconnect(station)

    async def reconnect(self, station: int) -> Any:
        self.by_station[station].connect(station)

    def kill_slave(self, station: int) -> bool:
        worker = self.workers.get(station)
        if worker is None:
            return False
        log.warning("killing_slave", station=f"{station:#04x}", pid=worker.pid)
        worker.kill()
        return True


async def _sleep_until(when: float) -> None:
    loop = asyncio.get_running_loop()
    delay = when - loop.time()
    if delay > 0:
        await asyncio.sleep(delay)


def _local_target(host: str) -> str:
    return {"0.0.0.0": "127.0.0.1", "::": "::1", "": "127.0.0.1"}.get(host, host)


async def run_up(config: Config, opts: RunOptions) -> RunOutcome:
    """Start a worker process per station (or per ``--workers`` group), then run the network against them."""
    run_dir = opts.run_dir or Path(tempfile.mkdtemp(prefix="mlink-sim-run-"))
    groups = plan_workers([st.address for st in config.station], opts.workers)
    problems: list[str] = []
    restart_tasks: set[asyncio.Task[Any]] = set()
    stopping = False

    def on_exit(worker: Worker, code: int) -> None:
        names = ",".join(f"{a:02X}H" for a in worker.spec.addresses)
        msg = f"slave worker {worker.spec.index} (station {names}) exited with code {code}"
        problems.append(msg)
        log.warning("slave_exited", worker=worker.spec.index, stations=names, code=code)
        if opts.restart_slaves and not stopping:
            async def restart() -> None:
                await asyncio.sleep(0.5)
                if stopping:
                    return
                try:
                    await worker.restart()
                    log.info("slave_restarted", worker=worker.spec.index, stations=names)
                except WorkerError as exc:
                    problems.append(str(exc))

            task = asyncio.get_running_loop().create_task(restart())
            restart_tasks.add(task)
            task.add_done_callback(restart_tasks.discard)

    workers = [
        Worker(WorkerSpec(i, opts.config_path, addrs, run_dir, opts.state_dir), on_exit=on_exit)
        for i, addrs in enumerate(groups)
    ]
    by_station = {a: w for w in workers for a in w.spec.addresses}
    try:
        results = await asyncio.gather(*(w.start() for w in workers), return_exceptions=True)
        errors = [r for r in results if isinstance(r, BaseException)]
        if errors:
            raise errors[0]
        endpoints = {
            st["address"]: (_local_target(st["host"]), st["port"]) for w in workers for st in w.ready["stations"]
        }  # type: ignore[index]
        return await run_network(config, endpoints, opts, by_station, problems)
    finally:
        stopping = True
        for task in list(restart_tasks):
            task.cancel()
        await asyncio.gather(*(w.stop() for w in workers), return_exceptions=True)


async def _collect_slave_stats(workers: dict[int, Worker]) -> dict[str, Any]:
    seen: dict[int, Worker] = {}
    for w in workers.values():
        seen[id(w)] = w  # type: ignore[index]
    stats: dict[str, Any] = {}

    async def one(w: Worker) -> None:
        if w.alive and w.control_port:
            reply = await query_control("127.0.0.1", w.control_port, "stats", timeout=1.0)
            if reply:
                stats[f"worker:{w.spec.index}"] = reply

    await asyncio.gather(*(one(w) for w in seen.values()))
    return stats


async def run_network(
    config: Config,
    endpoints: dict[int, tuple[str, int]],
    opts: RunOptions,
    workers: dict[int, Worker] | None = None,
    problems: list[str] | None = None,
) -> RunOutcome:
    """Start one master per link against *endpoints*, bring the stations up, run the timeline, report.

    *problems* collects what went wrong outside the checks (a slave worker that died, …) and may be appended to
    by the caller while the run goes on; they are printed as notes and stored in the report's meta."""
    from ..aio.master import Master
    from ..metrics import NetworkMetrics, check_all, host_info, write_report

    loop = asyncio.get_running_loop()
    workers = workers or {}
    metrics = NetworkMetrics(config.network.transmission_cycle)
    problems = problems if problems is not None else []
    stop = asyncio.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        loop.add_signal_handler(sig, stop.set)
    started_wall = datetime.now(timezone.utc)
    cpu0, wall0 = time.process_time(), time.monotonic()
    masters: dict[Link, Any] = {}
    checks: list[CheckResult] = []
    try:
        resolved: dict[int, tuple[str, int]] = {}
        for address, (host, port) in endpoints.items():
            try:
                resolved[address] = await resolve(host, port)
            except OSError as exc:
                raise EndpointError(f"station {address:#04x}: cannot resolve {host!r}: {exc.strerror or exc}") from None
        local = bind_address_for(list(resolved.values()))
        for link, plan in build_plans(config).items():
            eps = {sp.address: resolved[sp.address] for sp in plan.stations}
            masters[link] = await Master.start(plan, eps, metrics=metrics, local=local)
        net = _Network(config, masters, workers)
        # -- bring-up ------------------------------------------------------------------------------------------
        bring = asyncio.gather(*(m.bring_up(timeout=opts.bringup_timeout_s) for m in masters.values()),
                               return_exceptions=True)
        stopper = loop.create_task(stop.wait())
        done, _ = await asyncio.wait({bring, stopper}, return_when=asyncio.FIRST_COMPLETED)
        if bring in done:
            for result in bring.result():
                if isinstance(result, BaseException):
                    problems.append(f"bring-up: {result}")
        else:
            bring.cancel()
        not_up = [v for v in net.views().values() if not v.at_target]
        for v in not_up:
            problems.append(f"station {v.address:#04x} did not reach its phase (state {v.state.value})")
        if not stop.is_set():
            log.info("network_up", stations=len(config.station), not_up=len(not_up))
            # -- timeline + status ---------------------------------------------------------------------------------
            t0 = loop.time()
            scenario = Scenario(config, net)
            length = opts.duration_ns if opts.duration_ns is not None else config.run_length_ns
            tasks = [loop.create_task(scenario.run(t0, _sleep_until))]
            if opts.status:
                tasks.append(loop.create_task(_status_loop(config, net, t0, scenario.scales)))
            end = loop.create_task(_sleep_until(t0 + length / 1e9)) if length is not None else None
            waiters = {stopper} | ({end} if end else set())
            if end is None and not config.timeline:
                print("running until Ctrl-C (no timeline, no --duration)", file=sys.stderr)
            await asyncio.wait(waiters, return_when=asyncio.FIRST_COMPLETED)
            for task in tasks:
                task.cancel()
            await asyncio.gather(*tasks, return_exceptions=True)
            checks = scenario.results
            problems += scenario.action_errors
            if opts.status:
                print(render_status(config, net, loop.time() - t0, scenario.scales), flush=True)
        stopper.cancel()
        slave_stats = await _collect_slave_stats(workers)
    finally:
        for m in masters.values():
            try:
                await asyncio.wait_for(m.close(), 5.0)
            except Exception as exc:  # noqa: BLE001 - closing must not hide the run's result
                log.warning("master_close_failed", error=str(exc))
        for sig in (signal.SIGINT, signal.SIGTERM):
            loop.remove_signal_handler(sig)

    wall = time.monotonic() - wall0
    metrics.record_cpu("master", time.process_time() - cpu0, wall)
    for name, reply in slave_stats.items():
        metrics.record_cpu(name, reply.get("cpu_s", 0.0), reply.get("wall_s", wall) or wall)
        for key, snap in reply.get("stations", {}).items():
            counters = snap.get("counters") if isinstance(snap, dict) else None
            if isinstance(counters, dict):
                metrics.record_slave_counters(int(key, 16), _flatten_counters(counters))
    meta = {
        "config": str(opts.config_path),
        "network": config.network.name,
        "started": started_wall.isoformat(),
        "duration_s": round(wall, 3),
        "cycle_ns": config.network.transmission_cycle,
        "generation": ", ".join(sorted(link.label for link in masters)),
        "stations": len(config.station),
        "host": host_info(),
    }
    for c in checks:
        metrics.record_check(c.at_s, c.what, c.ok, c.detail)
    meta["problems"] = list(problems)
    report = metrics.report(meta=meta)
    results = check_all(list(opts.assertions), report) if opts.assertions else []
    report["assertions"] = [r.as_dict() for r in results]
    if opts.report_path is not None:
        write_report(opts.report_path, report)
    failed_checks = [c for c in checks if not c.ok]
    failed_asserts = [r for r in results if not getattr(r, "ok", False)]
    _print_summary(config, report, checks, failed_asserts, problems, opts)
    ok = not failed_checks and not failed_asserts and not [p for p in problems if "did not reach" in p]
    if stop.is_set() and not ok:
        return RunOutcome(1, report, checks, problems)
    return RunOutcome(0 if ok else 1, report, checks, problems)


def _flatten_counters(counters: dict[str, Any]) -> dict[str, int]:
    out: dict[str, int] = {}
    for key, value in counters.items():
        if isinstance(value, bool):
            continue
        if isinstance(value, int):
            out[key] = value
        elif isinstance(value, dict):
            out[key] = sum(v for v in value.values() if isinstance(v, int) and not isinstance(v, bool))
    return out


async def _status_loop(config: Config, net: _Network, t0: float, scales: dict[int, Any]) -> None:
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
    for c in checks:
        print(f"  {'ok  ' if c.ok else 'FAIL'} {c.what}: {c.detail}", file=out)
    for r in report.get("assertions", []):
        print(f"  {'ok  ' if r.get('ok') else 'FAIL'} assert {r.get('message') or r.get('text')}", file=out)
    for p in problems:
        print(f"  note {p}", file=out)
    failed = sum(not c.ok for c in checks) + len(failed_asserts)
    verdict = "all checks held" if not failed else f"{failed} check(s) failed"
    print(f"{verdict}" + (f"; report: {opts.report_path}" if opts.report_path else ""), file=out, flush=True)
