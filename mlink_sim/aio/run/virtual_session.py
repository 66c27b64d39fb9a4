"""The virtual-clock driver: the whole network in one process on simulated time (``mlink-sim up --clock virtual``).

What differs from the real-time run is only time and transport. :class:`VirtualSession` is a
:class:`~mlink_sim.aio.run.session.NetworkSession` whose stations are card cores on a
:class:`~mlink_sim.aio.virtual.fabric.Fabric` instead of slave processes, and whose masters are
:class:`~mlink_sim.aio.master.runner.Master` objects on a :class:`~mlink_sim.aio.virtual.fabric.FabricPort` instead of a
UDP socket, cycled by a :class:`~mlink_sim.aio.virtual.fabric.VirtualCycle`. It must run on a
:class:`~mlink_sim.aio.virtual.vclock.VirtualEventLoop`. Bring-up, the master API, the timeline, the checks, the report
and the summary are the real-time run's own code (``aio/run/network.py``, ``scenario/timeline.py``, ``metrics``).

The report says ``meta.clock = "virtual"`` and carries the seed and the network model; everything that depends on
the wall clock is in ``meta.started``, ``meta.host`` and ``meta.wall`` (:data:`WALL_META`), so two runs with the
same config and seed give the same report once those are left out (:func:`without_wall_clock`).

Touches: no socket and no process: the in-memory fabric, the card cores of this process, the state directory's
EEPROM images.
"""

from __future__ import annotations

import asyncio
import time
from pathlib import Path
from typing import Any

from ...config import Config
from ...jsonable import to_jsonable
from ...master import MasterCore, NetworkPlan
from ...faults import FaultStage
from ...faults.plant import PlantFaults
from ...operations import OpError
from ..virtual.fabric import Fabric, FabricPort, VirtualCycle
from ..slave.faults import apply_drive_fault, release_drive_fault
from ..timing.heap import settle_heap
from ..master.runner import Master, MetricsSink, NullMetrics
from ..present.figures import REGULATION_WINDOW_NS
from .netapi import NetworkApi, build_plans
from .session import NetworkSession, flatten_counters
from ..slave.stations import build_station, spec_for
from ..virtual.vclock import VirtualEventLoop

__all__ = ["VirtualMaster", "VirtualSession", "WALL_META", "without_wall_clock"]

#: The report's ``meta`` keys that depend on the wall clock or the machine, not on config and seed.
WALL_META: tuple[str, ...] = ("started", "host", "wall")
#: A killed station powers up again after this long, as ``mlink-sim up`` restarts a dead slave worker.
RESTART_AFTER_NS = 500_000_000
#: The capture (``--capture``) is written in place, in the loop, this often in simulated time (``CaptureWriter.flush``).
CAPTURE_FLUSH_NS = 250_000_000


def without_wall_clock(report: dict[str, Any]) -> dict[str, Any]:
    """*report* without :data:`WALL_META`: what two virtual runs with the same config and seed agree on."""
    return {**report, "meta": {k: v for k, v in report["meta"].items() if k not in WALL_META}}


class VirtualMaster(Master):
    """A :class:`Master` whose socket is a :class:`FabricPort` and whose clock is the fabric's: its cycle, fast
    path and request API are the real master's."""

    _fabric: Fabric

    @classmethod
    def attach(cls, plan: NetworkPlan, fabric: Fabric, cycle: VirtualCycle, *, metrics: MetricsSink | None = None,
               loop: asyncio.AbstractEventLoop | None = None) -> VirtualMaster:
        """A master for *plan* on *fabric*, cycled by *cycle* (which calls :meth:`on_cycle`; shared by the links)."""
        # the fabric's ends are the station addresses, where a UDP master has (host, port)
        self = cls(MasterCore(plan), {sp.address: sp.address for sp in plan.stations},  # type: ignore[misc]
                   metrics if metrics is not None else NullMetrics(), loop or asyncio.get_running_loop())
        add_stations = getattr(self.metrics, "add_stations", None)
        if callable(add_stations):
            add_stations(self.core.addresses)
        self._fabric = fabric
        # responses go straight to the core until a fault stage exists (:meth:`fault_stage`), then through
        # :meth:`deliver`, which does the same without one (one call fewer per response)
        self._sock = FabricPort(fabric, f"master:{plan.link.name}", self.core.on_response)
        self._timer, self._owns_timer = cycle, False  # type: ignore[assignment]
        return self

    def fault_stage(self) -> FaultStage:
        stage = super().fault_stage()
        if isinstance(self._sock, FabricPort):
            self._sock.on_datagram = self.deliver  # the stage sees every response from now on
        return stage

    def _now(self) -> int:  # type: ignore[override]
        return self._fabric.clock.now

    def read_responses(self, limit: int = 0) -> None:
        """Nothing waits to be read: the fabric hands every response to the core at its arrival time."""

    read_one = read_responses


class _VirtualWorker:
    """What ``NetworkApi.kill_slave`` needs of a worker, for a station on the fabric."""

    pid = None

    def __init__(self, session: VirtualSession, address: int) -> None:
        self.session = session
        self.address = address

    def kill(self) -> None:
        self.session.kill_station(self.address)

    async def drive_fault(self, station: int, fault: Any) -> int:
        """A drive fault on the card core itself (what a slave worker's ``fault`` operation does), ended by itself
        after its ``for`` in simulated time."""
        fabric = self.session.fabric
        core = fabric.station(station)
        cores = {} if core is None else {station: core}
        handle = apply_drive_fault(cores, self.session.plants, station, fault, fabric.clock.now)
        fabric.rearm(station)  # the drive is moving again: poll it
        if fault.for_ns is not None:
            asyncio.get_running_loop().call_later(fault.for_ns / 1e9, self._release, station, handle)
        return handle

    async def release_drive_fault(self, station: int, handle: int) -> None:
        """End the drive fault *handle* of *station* now (``heal``)."""
        self._release(station, handle)

    def _release(self, station: int, handle: int) -> None:
        fabric = self.session.fabric
        core = fabric.station(station)
        if core is not None:
            try:
                release_drive_fault({station: core}, self.session.plants, station, handle, fabric.clock.now)
            except OpError:  # released already (healed before its for ran out)
                return
            fabric.rearm(station)

    async def drive_activity(self, station: int) -> Any:
        """The station's ``Drive.activity()`` (None while it is down), read on the card core itself."""
        core = self.session.fabric.station(station)
        return None if core is None else core.drive_activity()


class VirtualSession(NetworkSession):
    """A :class:`NetworkSession` on simulated time (see the module docstring). Open it with
    ``await VirtualSession.open(config, path, seed=…)`` inside a :class:`VirtualEventLoop`."""

    def __init__(self, config: Config, config_path: Path, *, seed: int = 0, state_dir: Path | None = None,
                 restart_slaves: bool = True, problems: list[str] | None = None, capture: Any = None,
                 **_ignored: Any) -> None:
        loop = asyncio.get_running_loop()
        if not isinstance(loop, VirtualEventLoop):
            raise RuntimeError("a VirtualSession runs on a VirtualEventLoop")
        self.clock = loop.clock
        self.seed = seed
        self.plants = PlantFaults()  #: drive faults in force on the fabric's card cores
        self._wall_start = time.perf_counter()
        self._sim_start = self.clock.now
        super().__init__(config, config_path, state_dir=state_dir, restart_slaves=restart_slaves,
                         problems=problems, capture=capture, seed=seed)
        if capture is not None:  # simulated time, shown from the wall-clock second the run starts (a whole
            # second, so that the file's microseconds round the same in every run with the same seed)
            capture.epoch_offset_ns = time.time_ns() // 1_000_000_000 * 1_000_000_000 - self.clock.now
        net = config.network
        self.fabric = Fabric(self.clock, latency_ns=net.latency, jitter_ns=net.jitter, seed=seed,
                             state_dir=state_dir, capture=capture)
        self.fabric.impair = self.impairments
        self.cycle: VirtualCycle | None = None

    # ------------------------------------------------------------------ life cycle
    async def _start_workers(self) -> dict[int, tuple[str, int]]:
        """Power up every station on the fabric (``ValueError`` for settings a card refuses)."""
        state_dir = self._state_dir
        for st in self.config.station:
            spec = spec_for(st)

            def factory(now: int, eeprom: bytes | None, spec: Any = spec) -> Any:
                return build_station(spec, state_dir, now, eeprom=eeprom)

            self.fabric.add_station(st.address, factory)
        return {}

    async def _start_masters(self, endpoints: dict[int, tuple[str, int]]) -> None:
        loop = asyncio.get_running_loop()
        cycle = self.cycle = VirtualCycle(self.clock, self.config.network.transmission_cycle, self._on_cycle)
        self._clock = cycle  # type: ignore[assignment]  # stopped by close_masters
        for link, plan in build_plans(self.config).items():
            master = VirtualMaster.attach(plan, self.fabric, cycle, metrics=self.metrics, loop=loop)
            if self.capture is not None:
                master._note = self.capture.note
                master.note_cards()  # decode --pcap names the parameters by them
            master.record_lateness = not self.masters
            self.masters[link] = master
        self._cycle_callbacks = [m.on_cycle for m in self.masters.values()]
        if self.capture is not None:
            self._cycle_callbacks.append(self._capture_flusher(cycle.period_ns))
        workers = {st.address: _VirtualWorker(self, st.address) for st in self.config.station}
        self.net = NetworkApi(self.config, self.masters, workers)
        self.net.faults = self
        settle_heap(collect=False)  # as the real-time session, without the collection (docs/performance.md)
        cycle.start()

    def _capture_flusher(self, period_ns: int) -> Any:
        """The cycle callback that writes the capture in place every :data:`CAPTURE_FLUSH_NS` of simulated time
        (a writer thread would fight this loop, which never sleeps, for the GIL). Where the flushes fall does not
        change the file: runs with the same seed still give the same capture."""
        every = max(1, CAPTURE_FLUSH_NS // period_ns)
        flush = self.capture.flush

        def on_cycle(cycle: int, deadline_ns: int, now_ns: int, skipped: int) -> None:
            if cycle % every == 0:
                flush()

        return on_cycle

    def _now_ns(self) -> int:
        return self.clock.now

    def _route_impairments(self) -> None:
        """Nothing to route: the fabric puts every datagram through the layer while it is active."""

    def kill_station(self, address: int) -> None:
        """As a killed slave worker: the station stops answering; powered up again 0.5 s later (its EEPROM image
        kept) unless the session was opened with ``restart_slaves=False``."""
        if self.fabric.kill(address, RESTART_AFTER_NS if self._restart else None):
            self.plants.forget(address)
            self.problems.append(f"station {address:02X}H was killed (kill-slave)"
                                 + ("; powered up again after 0.5 s" if self._restart else ""))
            if self.capture is not None:
                self.capture.note(self.clock.now, f"station {address:02X}H killed (kill-slave)")

    # ------------------------------------------------------------------ figures
    async def refresh_slave_stats(self) -> None:
        """The stations' counters and snapshots, read from the card cores in this process, with each drive's
        regulation over the :data:`~mlink_sim.aio.present.figures.REGULATION_WINDOW_NS` before now."""
        for address, node in self.fabric.nodes.items():
            if node.station is not None:
                self.metrics.record_slave_counters(address, flatten_counters(node.station.counters.as_dict()))
                snap = self.slave_snapshots[address] = to_jsonable(node.station.snapshot())
                snap["regulation"] = node.station.drive.drive.regulation(self.clock.now - REGULATION_WINDOW_NS)

    def _clock_s(self) -> float:
        return self.clock.now / 1e9

    def _record_cpu(self) -> None:
        """Not in the figures: CPU time depends on the machine (it is in ``meta.wall.cpu_s``)."""

    def _clock_meta(self) -> dict[str, Any]:
        elapsed = time.perf_counter() - self._wall_start
        simulated = (self.clock.now - self._sim_start) / 1e9
        return {
            "clock": "virtual",
            "seed": self.seed,
            "network_model": {"latency_ns": self.fabric.latency_ns, "jitter_ns": self.fabric.jitter_ns},
            "wall": {"elapsed_s": round(elapsed, 3), "simulated_s": round(simulated, 6),
                     "speedup": round(simulated / elapsed, 1) if elapsed > 0 else None,
                     "cpu_s": round(time.process_time() - self._cpu0, 3)},
        }
