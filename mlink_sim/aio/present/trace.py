"""The trace of a running network (``--trace FILE.csv``, ``--trace-interval``): a sampler in the master's process.

Every *interval* of the run's clock (the wall clock, or simulated time with ``--clock virtual``) it writes one
``sample`` row per station: the station figures (:mod:`mlink_sim.aio.present.figures`, the one definition the status
and the web page share), flattened into the trace's columns (:data:`mlink_sim.metrics.trace.TRACE_COLUMNS`). Beside
them it writes an ``action`` row for each thing done or seen: a timeline step, a control request that acts, an
impairment's start and end, a fault's start and end and the station's recovery (from the masters' fault stages),
each check as it is judged. ``t_s`` counts from the timeline's 0 s (the end of bring-up), as the checks' ``at``.

Per sample and station: the figures' dict (the views, the monitors, the slave's last snapshot), a tuple of its
values and one list append; everything that can be is done once (the column getters, each station's constants in
``StationFigures``). Costlier parts run less often: the RTT percentiles are refreshed for a few stations once a
second (``RttPercentiles``), the slaves' snapshots (DC bus, motor speed where the monitors do not carry them, the
LEDs) every :data:`SNAPSHOT_EVERY_S` from the slave workers of ``mlink-sim up`` (read from the card cores at each
sample on the virtual clock, where that is a read in this process). The stations are sampled :data:`SLICE` at a
time, the loop free between two slices. Rows go through the writer's bounded buffer,
flushed about once a second and at the end (:class:`~mlink_sim.metrics.trace.TraceWriter`): memory stays bounded
however long the run.

Touches: the trace file (through the writer); reads the session's views, metrics, snapshots and fault stages.
"""

from __future__ import annotations

import asyncio
import inspect
import json
import math
import time
from collections.abc import Callable
from operator import itemgetter
from typing import Any

from ..._log import get_logger
from ...metrics.trace import TraceWriter
from ...operations import OPERATIONS, leds_text
from .figures import REGULATION_OF, NetworkFigures, station_key

__all__ = ["TraceSampler", "DEFAULT_INTERVAL_NS", "SNAPSHOT_EVERY_S", "ACTING_OPS"]

log = get_logger("mlink_sim.trace")

#: ``--trace-interval``'s default.
DEFAULT_INTERVAL_NS = 10_000_000
#: How often the slave workers' snapshots are asked for on the wall clock (``{"op": "stats"}``, paced by the worker).
SNAPSHOT_EVERY_S = 0.5
#: The rows are flushed, the RTT figures and the fault episodes looked at, about this often (the run's clock).
FLUSH_EVERY_S = 1.0
#: Stations sampled in one go before the loop is let go (about 0.2 ms of figures).
SLICE = 8
#: Control operations that change the run (:data:`mlink_sim.operations.OPERATIONS` that act): each request is an
#: ``action`` row (``control``); the others only read.
ACTING_OPS = frozenset(op.name for op in OPERATIONS.values() if op.acts)

_HEAD = itemgetter("address", "name", "card", "link", "phase", "connected")
_DRIVE = itemgetter("running", "direction", "reference_hz", "output_hz", "output_current_a", "dc_bus_v",
                    "motor_speed_rpm")
_TAIL = itemgetter("rtt_us", "rtt_p50_us", "rtt_p99_us", "missed", "late")
#: The ``regulation`` column of each figure's value (``("stall-decel",)`` -> ``stall-decel``; null: empty), made once.
_REGULATION_TEXT: dict[tuple[str, ...] | None, str] = {None: "", **{names: "|".join(names) for names in REGULATION_OF}}


def _row(t: float, fig: dict[str, Any]) -> tuple[Any, ...]:
    """One ``sample`` row of the station figures *fig* at *t* (the columns of ``metrics.trace.FIGURE_COLUMNS``)."""
    alarm = fig["alarm"]
    leds = fig["leds"]
    return (t, "sample", *_HEAD(fig), "" if alarm is None else alarm["code"] or "",
            "" if alarm is None else alarm["name"], "|".join(fig["warnings"]),
            leds_text(leds), *_DRIVE(fig), _REGULATION_TEXT[fig["regulation"]], *_TAIL(fig), "", "")


class TraceSampler:
    """Samples *session*'s stations into *writer* every *interval_ns* from :meth:`start` until :meth:`close`."""

    def __init__(self, session: Any, writer: TraceWriter, interval_ns: int = DEFAULT_INTERVAL_NS) -> None:
        self.session = session
        self.writer = writer
        self.interval_s = interval_ns / 1e9
        self._interval_ns = interval_ns
        self.figures = NetworkFigures(session.config)  # once: each station's constants (too slow to make per sample)
        self._addresses = list(self.figures.by_address)
        self._t0: float | None = None  # the loop time of the timeline's 0 s, once it is known (start)
        self._early: list[tuple[float, str, str, str]] = []  # actions before it: (loop time, event, detail, address)
        self._tasks: list[asyncio.Task[Any]] = []
        self._settled: set[tuple[int, str]] = set()  # (id(episode), event) already written
        self._snapshots: dict[int, dict[str, Any]] = {}  # the card cores' figures (virtual clock)
        self._impairments: dict[tuple[int | None, str], str] = {}  # (station, name) -> "NAME: what"
        self._last_impairment: tuple[Any, ...] = ()
        #: the card cores are in this process (virtual clock): their snapshots are read at each sample
        workers = session.net.workers
        self._local = bool(workers) and session.fabric is not None
        self._remote = bool(workers) and not self._local  #: slave workers of ``mlink-sim up``
        session.fault_hooks.append(self._on_impairment)

    # ------------------------------------------------------------------ life cycle
    def start(self, t0: float) -> None:
        """Sample from now on; *t0* is the loop time of the timeline's 0 s. The actions taken before it (control
        requests, faults during bring-up) are written now, at negative times."""
        self._t0 = t0
        for at, event, detail, address in self._early:
            self.writer.action(at - t0, event, detail, address)
        self._early.clear()
        loop = asyncio.get_running_loop()
        self._tasks.append(loop.create_task(self._sample_loop(t0)))
        if self._remote:
            self._tasks.append(loop.create_task(self._snapshot_loop()))

    async def close(self) -> None:
        """Stop sampling, write the fault episodes settled so far and close the file."""
        for task in self._tasks:
            task.cancel()
        await asyncio.gather(*self._tasks, return_exceptions=True)
        self._tasks.clear()
        if self._on_impairment in self.session.fault_hooks:
            self.session.fault_hooks.remove(self._on_impairment)
        if self._t0 is not None:
            self._episodes(self._t0)
        self.writer.close()
        if self.writer.error:
            self.session.problems.append(f"trace: {self.writer.error}")

    # ------------------------------------------------------------------ actions
    def action(self, event: str, detail: str = "", station: int | None = None) -> None:
        """An ``action`` row now (*station* None: the whole network); before :meth:`start`, kept until then."""
        address = "" if station is None else station_key(station)
        now = asyncio.get_running_loop().time()
        if self._t0 is None:
            self._early.append((now, event, detail, address))
        else:
            self.writer.action(now - self._t0, event, detail, address)

    def on_step(self, step: Any) -> None:
        """A timeline action began (``Scenario.on_action``)."""
        self.action("step", step.describe, None if step.station == "all" else step.station)

    def on_check(self, result: Any) -> None:
        """A check was judged (``Scenario.on_check``): at its own time, which may lie before now (a waiting check)."""
        self.writer.action(result.at_s, "check", f"{'ok' if result.ok else 'FAIL'} {result.what}: {result.detail}",
                           station_key(result.station))

    def recording(self, handlers: dict[str, Callable[..., Any]]) -> dict[str, Callable[..., Any]]:
        """The control endpoint's *handlers*, those of :data:`ACTING_OPS` writing a ``control`` row when they
        succeed; an operation answered later writes it once it is answered."""
        def wrap(name: str, op: Callable[..., Any]) -> Callable[..., Any]:
            def note(args: dict[str, Any]) -> None:
                fields = {k: v for k, v in args.items() if v is not None and k != "station"}
                self.action("control", f"{name} {json.dumps(fields, separators=(',', ':'))}", args.get("station"))

            def recorded(**args: Any) -> Any:
                reply = op(**args)
                if not inspect.isawaitable(reply):
                    note(args)
                    return reply

                async def answered() -> Any:  # an operation answered later (through the master): once it has
                    out = await reply
                    note(args)
                    return out

                return answered()
            return recorded

        return {name: wrap(name, op) if name in ACTING_OPS else op for name, op in handlers.items()}

    def _on_impairment(self, event: str, station: int | None, name: str, describe: str) -> None:
        """An impairment began or ended on *station*'s path: one row (``NAME: what``), though the layer calls once
        per direction."""
        key = (station, name)
        if event == "start":
            self._impairments[key] = f"{name}: {describe}" if describe else name
        seen = (event, station, name, asyncio.get_running_loop().time())
        if seen == self._last_impairment:
            return
        self._last_impairment = seen
        self.action(f"impair-{event}", self._impairments.get(key, name), station)

    def _episodes(self, t0: float) -> None:
        """``fault`` / ``fault-end`` / ``recovered`` / ``unrecovered`` rows of the masters' fault episodes, each
        once, at its own time (*t0*: the loop time of the timeline's 0 s)."""
        for master in self.session.masters.values():
            stage = master.faults
            if stage is None:
                continue
            for ep in stage.log.episodes:
                key = station_key(ep.station)
                what = f"{ep.name}: {ep.what}" if ep.name else ep.what
                for event, ns, detail in (
                        ("fault", ep.start_ns, what), ("fault-end", ep.end_ns, what),
                        ("recovered", ep.recovered_ns,
                         f"{what}: healthy {(ep.recovery_ns or 0) / 1e6:.1f} ms after its end"),
                        ("unrecovered", 0 if ep.gave_up else None, f"{what}: not healthy again")):
                    mark = (id(ep), event)
                    if ns is None or mark in self._settled:
                        continue
                    self._settled.add(mark)
                    at = (ep.end_ns or ep.start_ns) / 1e9 - t0 if event == "unrecovered" else ns / 1e9 - t0
                    self.writer.action(at, event, detail, key)

    # ------------------------------------------------------------------ sampling
    async def _sample_loop(self, t0: float) -> None:
        """Sample every station each interval, :data:`SLICE` stations at a time with the loop free between two
        slices (each row carries its slice's own time), so that a large network never holds the cycle for the
        whole time its figures take (docs/performance.md, "Live status and traces")."""
        loop = asyncio.get_running_loop()
        session, figures, writer = self.session, self.figures, self.writer
        net, metrics, station = session.net, session.metrics, figures.station
        slices = [self._addresses[i:i + SLICE] for i in range(0, len(self._addresses), SLICE)]
        interval = self.interval_s
        fabric = session.fabric if self._local else None
        snapshots = self._snapshots if fabric is not None else session.slave_snapshots
        per_flush = max(1, round(FLUSH_EVERY_S / interval))
        k = 0
        figures.rtt.step(metrics)
        while True:
            try:
                for i, part in enumerate(slices):
                    if i:
                        await asyncio.sleep(0)
                    if fabric is not None:
                        self._read_cores(fabric, part)
                    t = round(loop.time() - t0, 6)
                    writer.add_many([_row(t, station(a, net, snapshots)) for a in part])
            except Exception as exc:  # noqa: BLE001 - a figure that cannot be read ends the trace, not the run
                session.problems.append(f"trace: sampling stopped at {loop.time() - t0:g} s: {exc}")
                log.warning("trace_stopped", error=str(exc))
                return
            k += 1
            if k % per_flush == 0:
                figures.rtt.step(metrics)
                self._episodes(t0)
                writer.flush()
            # the next instant on the schedule t0 + k·interval; instants the loop was too late for are skipped
            due = t0 + k * interval
            now = loop.time()
            if now > due + interval:
                k = math.floor((now - t0) / interval) + 1
                due = t0 + k * interval
            await asyncio.sleep(max(due - loop.time(), 0.0))

    def _read_cores(self, fabric: Any, addresses: list[int]) -> None:
        """The virtual clock's card cores, read in this process: what the figures take from a slave's snapshot
        (the drive's reference, DC bus, motor speed and fault, the LEDs, the warnings), without turning the whole
        snapshot into JSON as a worker's ``stats`` does."""
        out = self._snapshots
        since = fabric.clock.now - self._interval_ns  # the regulation since the last sample
        for address in addresses:
            core = fabric.station(address)
            if core is None:  # a killed station, until it powers up again
                out.pop(address, None)
                continue
            snap = core.snapshot()
            d = snap.drive
            out[address] = {"drive": {"reference_hz": d.reference_hz, "dc_bus_v": d.dc_bus_v,
                                      "motor_rpm": d.motor_rpm, "fault": d.fault},
                            "leds": snap.leds, "led_colors": snap.led_colors, "warnings": list(snap.warnings),
                            "regulation": core.drive.drive.regulation(since)}

    async def _snapshot_loop(self) -> None:
        """The slave workers' snapshots, refreshed every :data:`SNAPSHOT_EVERY_S` (one query at a time)."""
        while True:
            try:
                if time.monotonic() - self.session.snapshots_at >= SNAPSHOT_EVERY_S:  # not taken for a page meanwhile
                    await self.session.refresh_slave_stats()
            except OSError as exc:
                log.info("trace_snapshot_failed", error=str(exc))
            await asyncio.sleep(SNAPSHOT_EVERY_S)
