"""A running network as one object: slave workers (optional), one master per link, live metrics, the report.

``mlink-sim up`` / ``mlink-sim master`` (:mod:`mlink_sim.aio.run.network`) and the pytest plugin
(:mod:`mlink_sim.testing`) are both thin drivers of :class:`NetworkSession`::

    session = await NetworkSession.open(config, config_path=path)   # workers + masters, cycling
    await session.bring_up(timeout=10)                               # every station at its phase
    await session.net.prm_rd(0x21, 0x0180)                           # the master API, routed per station
                                                                     # (:class:`~.netapi.NetworkApi`)
    report = await session.report()                                  # live figures (docs/report.md)
    await session.close()                                            # DISCONNECT, stop masters and workers

Touches: the worker processes (through the supervisor), one master per link, the slave workers' stats endpoints, the
run directory; real-time scheduling where asked.
"""

from __future__ import annotations

import asyncio
import socket
import tempfile
import time
from collections.abc import Callable, Sequence
from datetime import UTC, datetime
from pathlib import Path
from typing import Any, Self


from ..._log import get_logger
from ...config import Config
from ...metrics.stalls import StallLog
from ...wire import Link
from ..master.runner import Master
from ..timing.heap import settle_heap
from ..timing.realtime import MASTER_PRIORITY, apply, pin
from ..timing.realtime import cpu_plan as rt_cpu_plan
from ..timing.realtime import format_cpus as rt_format_cpus
from ..timing.ticker import CycleTimer
from ..transport.udp import bind_address_for, resolve
from ..control.endpoint import query_control
from .netapi import NetworkApi, build_plans
from .supervisor import Worker, WorkerError, WorkerSpec, plan_workers

__all__ = ["NetworkSession", "EndpointError", "flatten_counters"]

log = get_logger("mlink_sim.session")


class EndpointError(ValueError):
    """A station endpoint that cannot be used (unresolvable host name)."""


def _local_target(host: str) -> str:
    return {"0.0.0.0": "127.0.0.1", "::": "::1", "": "127.0.0.1"}.get(host, host)


class NetworkSession:
    """One running network. Build with :meth:`open`; always :meth:`close` (also after an exception).

    With ``endpoints=None`` the session starts the slaves itself (``mlink-sim up``: one worker process per
    station, or ``workers`` groups); otherwise it runs only the masters against *endpoints*
    (``mlink-sim master``)."""

    def __init__(self, config: Config, config_path: Path, *, workers: int | None = None,
                 state_dir: Path | None = None, run_dir: Path | None = None, restart_slaves: bool = True,
                 problems: list[str] | None = None, realtime: bool = False, capture: Any = None,
                 seed: int = 0, cpus: set[int] | None = None) -> None:
        from ...impair import ImpairmentLayer
        from ...metrics import NetworkMetrics

        self.capture = capture  #: a CaptureWriter recording every master socket (``--capture``), or None
        self.slave_snapshots: dict[int, dict[str, Any]] = {}  #: each station's slave stats entry, by address
        self.snapshots_at = float("-inf")  #: when :meth:`refresh_slave_stats` last took them (time.monotonic)
        self.config = config
        self.config_path = Path(config_path)
        self.metrics = NetworkMetrics(config.network.transmission_cycle)
        self.metrics.stalls = StallLog(config.network.host_stalls, config.network.absorb_ns)
        self.metrics.stalls.reset(time.monotonic_ns())
        self.problems: list[str] = problems if problems is not None else []
        #: the in-memory network whose card cores are in this process (the virtual clock's), else None
        self.fabric: Any = None
        #: the stations found not at their target phase after bring-up (address -> the master's state then)
        self.unreached: dict[int, str] = {}
        self.masters: dict[Link, Any] = {}
        self.worker_list: list[Worker] = []
        self.workers: dict[int, Worker] = {}
        self.net: NetworkApi | None = None
        self._clock: CycleTimer | None = None
        self._cycle_callbacks: list[Any] = []
        self.started_wall = datetime.now(UTC)
        self._cpu0 = time.process_time()
        self._wall0 = time.monotonic()
        self._span0, self._span_wall, self._measured_from = self._clock_s(), self.started_wall, "start"
        self._n_workers = workers
        self._state_dir = state_dir
        self.run_dir = run_dir
        self._restart = restart_slaves
        self.realtime = realtime  #: SCHED_FIFO / mlockall / CPUs where permitted (aio/timing/realtime.py)
        #: (master CPUs, worker CPUs), planned once, before the master takes its CPU, of the CPUs the user chose
        #: (``--cpus``, placed with or without real time) or, with *realtime*, of those this process may use
        self.cpus = rt_cpu_plan(cpus) if realtime or cpus else None
        self._placed = cpus or None  #: the CPUs the user chose: all of them the master's when it runs alone
        self.realtime_granted: dict[str, str] = {}  #: process -> what it was granted
        self._restart_tasks: set[asyncio.Task[Any]] = set()
        #: each link's master socket address, held from before the workers start until its master binds it
        self._held: dict[Link, socket.socket] = {}
        self._stopping = False
        self._closed = False
        self.seed = seed
        #: called with (event "start"/"end", station or None, group, description) as an impairment begins or ends
        self.fault_hooks: list[Callable[[str, int | None, str, str], None]] = []
        #: network impairments between the masters and the stations (docs/faults.md); seeded by *seed*
        self.impairments = ImpairmentLayer(seed=seed, listener=self._on_fault)

    # ------------------------------------------------------------------ faults
    def _now_ns(self) -> int:
        """Now on the session's clock (real: ``time.monotonic_ns``)."""
        return time.monotonic_ns()

    def impair(self, station: int | None, spec: Any, name: str | None = None) -> str:
        """Start *spec* (an :class:`~mlink_sim.impair.Impairment`) on *station* (None: every station, each on its
        own, so that a later ``impair`` or ``heal`` of one station replaces or ends it there), as *name* (None: a
        made name, replacing the unnamed impairment there); returns its name."""
        stations = [st.address for st in self.config.station] if station is None else [station]
        name = self.impairments.impair(spec, stations, self._now_ns(), name=name)
        self._route_impairments()
        return name

    def heal(self, station: int | None = None, name: str | None = None) -> list[str]:
        """End the network impairments of *station* (None: all), or only the one called *name*; the names that
        ended."""
        return self.impairments.heal(station, self._now_ns(), name=name)

    def now_ns(self) -> int:
        """Now on the session's clock, as the impairment layer reads it."""
        return self._now_ns()

    def _route_impairments(self) -> None:
        """Put the masters' sockets behind the layer while it has a fault (the virtual fabric reads it itself)."""
        for master in self.masters.values():
            master.impair_with(self.impairments)

    def _on_fault(self, event: str, station: int | None, group: str, now: int) -> None:
        who = "every station" if station is None else f"station {station:02X}H"
        log.info("fault_" + event, station=who, fault=group)
        if self.capture is not None:
            self.capture.note(now, f"{group} {'started' if event == 'start' else 'ended'}: {who}")
        if self.fault_hooks:
            describe = next((f["describe"] for f in self.impairments.faults() if f["name"] == group),
                            "") if event == "start" else ""
            for hook in self.fault_hooks:
                hook(event, station, group, describe)

    # ------------------------------------------------------------------ life cycle
    @classmethod
    async def open(cls, config: Config, config_path: Path | str, *,
                   endpoints: dict[int, tuple[str, int]] | None = None, **kwargs: Any) -> Self:
        """Start the slaves (unless *endpoints* is given) and one cycling master per link.

        Raises :class:`~mlink_sim.aio.run.supervisor.WorkerError` (a slave did not start) or :class:`EndpointError`
        (an endpoint name does not resolve); nothing is left running then."""
        self = cls(config, Path(config_path), **kwargs)
        try:
            if endpoints is None:
                endpoints = await self._start_workers()
            await self._start_masters(endpoints)
        except BaseException:
            await self.close()
            raise
        return self

    async def _start_workers(self) -> dict[int, tuple[str, int]]:
        run_dir = self.run_dir = self.run_dir or Path(tempfile.mkdtemp(prefix="mlink-sim-run-"))
        groups = plan_workers([st.address for st in self.config.station], self._n_workers)
        self._hold_master_addresses()
        self.worker_list = [
            Worker(WorkerSpec(i, self.config_path, addrs, run_dir, self._state_dir,
                              extra_args=self.config.network.slave_flags() + self._realtime_flags()
                              + self._allow_flags(addrs) + (["--shared-port"] if len(addrs) > 1 else [])),
                   on_exit=self._on_worker_exit)
            for i, addrs in enumerate(groups)
        ]
        self.workers = {a: w for w in self.worker_list for a in w.spec.addresses}
        results = await asyncio.gather(*(w.start() for w in self.worker_list), return_exceptions=True)
        errors = [r for r in results if isinstance(r, BaseException)]
        if errors:
            raise errors[0]
        for w in self.worker_list:
            if w.ready and ("realtime" in w.ready or "cpus" in w.ready):
                self.realtime_granted[f"worker:{w.spec.index}"] = w.ready.get("realtime") or w.ready["cpus"]
        return {
            st["address"]: (_local_target(st["host"]), st["port"])
            for w in self.worker_list for st in (w.ready or {}).get("stations", [])
        }

    def _station_host(self, address: int) -> str:
        """The address station *address* listens on as the master reaches it (a wildcard: loopback)."""
        return _local_target(self.config.station_by_address(address).host_port(self.config.network.host)[0])

    def _hold_master_addresses(self) -> None:
        """Bind each link's master socket address before the workers start, so that each worker is told where its
        master sends from (:meth:`_allow_flags`); the master takes it over when it starts (:meth:`_start_masters`)."""
        local = bind_address_for([(self._station_host(st.address), 0) for st in self.config.station])
        for st in self.config.station:
            if st.link is not None and st.link not in self._held:
                sock = self._held[st.link] = socket.socket(socket.AF_INET6 if ":" in local[0] else socket.AF_INET,
                                                           socket.SOCK_DGRAM)
                sock.bind(local)

    def _allow_flags(self, addresses: list[int]) -> list[str]:
        """``--allow-master HOST:PORT`` for a worker hosting *addresses*: each station takes commands only from its
        link's master (docs/cards.md, "Who may change a station"). A datagram to an address of this host comes
        from that same address."""
        out: list[str] = []
        for address in addresses:
            st = self.config.station_by_address(address)
            held = self._held.get(st.link) if st.link is not None else None
            if held is None:
                continue
            host, port = self._station_host(address), held.getsockname()[1]
            rule = f"[{host}]:{port}" if ":" in host else f"{host}:{port}"
            if rule not in out:
                out += ["--allow-master", rule]
        return out

    def _realtime_flags(self) -> list[str]:
        """``mlink-sim slave``'s flags for this session's real-time requests and CPUs: ``--realtime`` (a worker
        then plans its CPUs as this session did, from the CPUs it is started with: :func:`unplace_child`), and
        ``--cpus LIST`` (the workers' CPUs of :attr:`cpus`) when the user chose the CPUs."""
        return ((["--realtime"] if self.realtime else [])
                + (["--cpus", rt_format_cpus(self.cpus[1])] if self._placed and self.cpus else []))

    def _on_worker_exit(self, worker: Worker, code: int) -> None:
        names = ",".join(f"{a:02X}H" for a in worker.spec.addresses)
        self.problems.append(f"slave worker {worker.spec.index} (station {names}) exited with code {code}")
        log.warning("slave_exited", worker=worker.spec.index, stations=names, code=code)
        if self.capture is not None:
            self.capture.note(time.monotonic_ns(), f"slave worker {worker.spec.index} (station {names}) exited "
                                                   f"with code {code}")
        if not self._restart or self._stopping:
            return

        async def restart() -> None:
            await asyncio.sleep(0.5)
            if self._stopping:
                return
            try:
                await worker.restart()
                log.info("slave_restarted", worker=worker.spec.index, stations=names)
            except WorkerError as exc:
                self.problems.append(str(exc))

        task = asyncio.get_running_loop().create_task(restart())
        self._restart_tasks.add(task)
        task.add_done_callback(self._restart_tasks.discard)

    async def _start_masters(self, endpoints: dict[int, tuple[str, int]]) -> None:
        resolved: dict[int, tuple[str, int]] = {}
        for address, (host, port) in endpoints.items():
            try:
                resolved[address] = await resolve(host, port)
            except OSError as exc:
                raise EndpointError(f"station {address:02X}H: cannot resolve {host!r}: {exc.strerror or exc}") from None
        local = bind_address_for(list(resolved.values()))
        plans = build_plans(self.config)
        from ...metrics import host_info

        host_info()  # its first call reads the interpreter binary (many cycles' time): not in the middle of a run
        if self.cpus is not None:
            mine = self._placed if self._placed and not self.worker_list else self.cpus[0]
            self.realtime_granted["master"] = (apply(MASTER_PRIORITY, mine, placed=bool(self._placed))
                                               if self.realtime else pin(mine))
        settle_heap()  # before the clock starts: no full collection of the start-up heap mid-cycle
        clock = None
        catch_up = self.config.network.absorb_ns
        if len(plans) > 1:  # one clock for every link: two spinning timers in one loop would delay each other
            clock = self._clock = CycleTimer(self.config.network.transmission_cycle, self._on_cycle,
                                             loop=asyncio.get_running_loop(), catch_up_ns=catch_up,
                                             on_stall=self.metrics.stall_recorder("master"))
        for link, plan in plans.items():
            eps = {sp.address: resolved[sp.address] for sp in plan.stations}
            held = self._held.pop(link, None)
            where = local if held is None else (local[0], held.getsockname()[1])  # what the workers were told
            if held is not None:
                held.close()
            master = await Master.start(plan, eps, metrics=self.metrics, local=where, clock=clock,
                                        catch_up_ns=catch_up, capture=self.capture)
            master.record_lateness = not self.masters
            self.masters[link] = master
        self._cycle_callbacks = [m.on_cycle for m in self.masters.values()]
        self._route_impairments()
        if clock is not None:
            readers = [m.read_one for m in self.masters.values()]

            def idle() -> None:
                for read in readers:
                    read()

            clock.idle = idle
            clock.start()
        self.net = NetworkApi(self.config, self.masters, self.workers)
        self.net.faults = self

    def _on_cycle(self, cycle: int, deadline_ns: int, now_ns: int, skipped: int) -> None:
        for on_cycle in self._cycle_callbacks:
            on_cycle(cycle, deadline_ns, now_ns, skipped)

    async def bring_up(self, timeout: float) -> list[str]:
        """Wait until every station is at its target phase or *timeout* s passed; returns (and records in
        ``problems``) one message per station that did not get there."""
        results = await asyncio.gather(*(m.bring_up(timeout=timeout) for m in self.masters.values()),
                                       return_exceptions=True)
        for result in results:
            if isinstance(result, BaseException):
                self.problems.append(f"bring-up: {result}")
        return self.not_up()

    def not_up(self) -> list[str]:
        """One message per station not at its target phase now; each such station is counted in
        :attr:`unreached` (the run's verdict reads it) and named in :attr:`problems`."""
        assert self.net is not None
        late = {v.address: v.state.value for v in self.net.views().values() if not v.at_target}
        self.unreached.update(late)
        out = [f"station {a:02X}H did not reach its phase (state {state})" for a, state in late.items()]
        self.problems.extend(m for m in out if m not in self.problems)
        return out

    async def close_masters(self) -> None:
        """DISCONNECT every station and stop the masters (the slaves keep running). Idempotent."""
        results = await asyncio.gather(*(asyncio.wait_for(m.close(), 5.0) for m in self.masters.values()),
                                       return_exceptions=True)
        for result in results:
            if isinstance(result, Exception):  # closing must not hide the run's result
                log.warning("master_close_failed", error=str(result))
        if self._clock is not None:
            self._clock.stop()

    async def close(self) -> None:
        """DISCONNECT every station, stop the masters, then the slave workers. Idempotent."""
        if self._closed:
            return
        self._closed = True
        self._stopping = True
        for held in self._held.values():
            held.close()
        self._held.clear()
        await self.close_masters()
        for task in list(self._restart_tasks):
            task.cancel()
        await asyncio.gather(*(w.stop() for w in self.worker_list), return_exceptions=True)

    async def __aenter__(self) -> NetworkSession:
        return self

    async def __aexit__(self, *exc: object) -> None:
        await self.close()

    # ------------------------------------------------------------------ time (the virtual session reads its own)
    def _clock_s(self) -> float:
        """The clock the run is measured on, in seconds (real: ``time.monotonic``)."""
        return time.monotonic()

    def _clock_meta(self) -> dict[str, Any]:
        """What the report's ``meta`` says about the clock (docs/report.md)."""
        return {"clock": "real"}

    def _record_cpu(self) -> None:
        self.metrics.record_cpu("master", time.process_time() - self._cpu0, time.monotonic() - self._wall0)

    # ------------------------------------------------------------------ figures
    async def refresh_slave_stats(self) -> None:
        """The slaves' counters and CPU time into :attr:`metrics`, their stations' snapshots into :attr:`slave_snapshots`."""
        stats: dict[str, Any] = {}
        async def one(w: Worker) -> None:
            if w.alive and w.control_port:
                reply = await query_control("127.0.0.1", w.control_port, "stats", timeout=1.0,
                                            since=self.metrics.stalls.origin_ns)
                if reply:
                    stats[f"worker:{w.spec.index}"] = reply
                    self.metrics.stalls.add(f"worker:{w.spec.index}", reply.get("stalls", []))
                    self.metrics.stalls.set_totals(f"worker:{w.spec.index}", reply.get("stall_totals", {}))

        await asyncio.gather(*(one(w) for w in self.worker_list))
        self.snapshots_at = time.monotonic()
        wall = self.snapshots_at - self._wall0
        for name, reply in stats.items():
            self.metrics.record_cpu(name, reply.get("cpu_s", 0.0), reply.get("wall_s", wall) or wall)
            regulation = reply.get("regulation")
            for key, snap in reply.get("stations", {}).items():
                if not isinstance(snap, dict):
                    continue
                if isinstance(regulation, dict):  # the drive's regulation states, beside the snapshots
                    snap["regulation"] = regulation.get(key, 0)
                self.slave_snapshots[int(key, 16)] = snap
                if isinstance(counters := snap.get("counters"), dict):
                    self.metrics.record_slave_counters(int(key, 16), flatten_counters(counters))

    def reset_metrics(self) -> None:
        """Start the master-side figures afresh (e.g. after bring-up, to measure the steady state only). The
        report's ``meta.started``/``duration_s`` then cover the span from here, ``meta.measured_from`` says
        ``"bring-up done"``; ``cpu`` keeps covering the whole run (docs/report.md)."""
        self.metrics.reset()
        self.metrics.stalls.reset(time.monotonic_ns())
        self._span0 = self._clock_s()
        self._span_wall = datetime.now(UTC)
        self._measured_from = "bring-up done"

    async def snapshot(self, *, extra_meta: dict[str, Any] | None = None,
                       slave_stats: bool = True) -> tuple[Any, dict[str, Any]]:
        """A copy of the figures and the report's ``meta`` as of now; build the report from them with
        ``metrics.report(meta=meta)`` anywhere (outside the loop, so the cycle is not held up)."""
        from ...metrics import host_info

        if slave_stats:
            await self.refresh_slave_stats()
        self._record_cpu()
        for station, counts in self.impairments.injected().items():
            self.metrics.record_injected(station, counts)
        for master in self.masters.values():  # what the fault stages did (docs/faults.md)
            if master.faults is not None:
                for station, totals in master.faults.injected().items():
                    self.metrics.record_injected(station, totals)
        meta = {
            "config": str(self.config_path),
            "network": self.config.network.name,
            "started": self._span_wall.isoformat(),
            "duration_s": round(self._clock_s() - self._span0, 3),
            "measured_from": self._measured_from,
            "cycle_ns": self.config.network.transmission_cycle,
            "generation": ", ".join(sorted(link.label for link in self.masters)),
            "stations": len(self.config.station),
            "host": host_info(),
            **self._clock_meta(),
            **(extra_meta or {}),
            "problems": list(self.problems),
        }
        return self.metrics.copy(), meta

    async def report(self, *, assertions: Sequence[Any] = (), extra_meta: dict[str, Any] | None = None,
                     slave_stats: bool = True) -> dict[str, Any]:
        """The report document as of now (schema: docs/report.md), with *assertions* evaluated into it."""
        metrics, meta = await self.snapshot(extra_meta=extra_meta, slave_stats=slave_stats)
        from ...metrics import build_report

        return build_report(metrics, meta, assertions)


def flatten_counters(counters: dict[str, Any]) -> dict[str, int]:
    out: dict[str, int] = {}
    for key, value in counters.items():
        if isinstance(value, bool):
            continue
        if isinstance(value, int):
            out[key] = value
        elif isinstance(value, dict):
            out[key] = sum(v for v in value.values() if isinstance(v, int) and not isinstance(v, bool))
    return out
