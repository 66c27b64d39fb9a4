"""Embedding the virtual network: :class:`VirtualNetwork`, a whole network on simulated time that your own
program steps (co-simulation, long scenarios, protocol tests). No thread, no socket, no wall clock: time moves
only inside :meth:`~VirtualNetwork.advance` / :meth:`~VirtualNetwork.run_until` and the blocking master calls.

    from mlink_sim.aio.run.embed import VirtualNetwork

    with VirtualNetwork("configs/quickstart.toml", seed=1) as net:   # stations powered up, bring-up done
        net.set_param(0x21, "C1-01", 1.0)                            # PRM_WR and CONFIG: a 1 s ramp from now on
        net.run(0x21, hz=30)                                         # forward at 30 Hz (o1-03 units handled)
        while net.output_hz(0x21) < 29.9:
            net.step()                                               # one transmission cycle
        assert net.get_param(0x21, "C1-01") == 1.0                   # PRM_RD by name: 1.0 s (a ParamValue)
        net.advance(60.0)                                            # a simulated minute, in a few seconds
        print(net.now, net.report()["rtt"]["p99"])

The network's operations (``run``, ``stop``, ``set_param``, ``get_param``, ``alarm_clear``, ``impair``, ``fault``,
``status`` …: :class:`~mlink_sim.operations.NetworkOperations`, one method per operation of the table) do what a
control request, the command line and the HTTP API do, and refuse what they refuse, with the same message
(:class:`~mlink_sim.operations.OpError`). The bare master API stays beside them under the protocol's names, for tests
of a master's own handling (``prm_rd``, ``prm_wr`` — written, not entered: CONFIG is ``send_config`` — ``id_rd``,
``alm_rd``, ``alm_clr``, ``set_control``, ``view``), routed per station (:class:`~mlink_sim.aio.run.netapi.NetworkApi`).
A request blocks until answered, advancing simulated time meanwhile. ``view()`` decodes what it carries:
``output_hz``, ``status_bits``, ``bit("RUNX")``, ``alarm_text``.
:meth:`~VirtualNetwork.station` is the card core itself (``snapshot()``: phase, LEDs, alarms, drive, counters).

Touches: no socket, thread or wall clock; a virtual session on a virtual event loop of its own.
"""

from __future__ import annotations

import asyncio
import threading
from collections.abc import Awaitable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TypeVar

from ...config import Config, load_config
from ...metrics import build_report
from ...operations import NetworkOperations, request_of
from ...scenario import CheckResult, StationViews, Timeline, speed_scales
from ..control.endpoint import perform
from ..control.events import RunLog
from ..control.network import NetworkOps
from ..control.timeline import TimelineRunner
from ..virtual.vclock import VirtualEventLoop
from .netapi import NetworkApi
from .virtual_session import VirtualSession

__all__ = ["VirtualNetwork", "NetworkSnapshot", "BringUpFailed"]

T = TypeVar("T")


@dataclass(frozen=True)
class NetworkSnapshot:
    """The whole network at one instant of simulated time: what the masters see and what the stations are."""

    t_s: float  #: simulated time, seconds
    cycle: int  #: number of the last transmission cycle
    views: dict[int, Any]  #: address -> the master's :class:`~mlink_sim.master.StationView`
    stations: dict[int, Any]  #: address -> the card's :class:`~mlink_sim.cards.StationSnapshot` (absent while killed)


class BringUpFailed(RuntimeError):
    """A station did not reach its phase within the bring-up timeout (simulated): ``problems`` says which."""

    def __init__(self, problems: list[str]) -> None:
        super().__init__("network did not come up: " + "; ".join(problems))
        self.problems = problems


class VirtualNetwork(NetworkOperations, StationViews):
    """The network of *config* (a :class:`~mlink_sim.config.Config` or a TOML path) on simulated time.

    *seed*: the jitter draws of the network model (``[network] latency`` / ``jitter``). *bring_up*: bring every
    station to its phase before returning (:class:`BringUpFailed` if one does not get there within
    *bringup_timeout* simulated seconds); *reset_after_bringup*: the figures then count from there, as
    ``mlink-sim up`` does. *state_dir*: the cards' EEPROM images, as ``up --state-dir``."""

    def __init__(self, config: Config | str | Path, *, seed: int = 0, bring_up: bool = True,
                 bringup_timeout: float = 10.0, reset_after_bringup: bool = True,
                 state_dir: str | Path | None = None) -> None:
        if isinstance(config, Config):
            self.config, path = config, Path(config.network.name + ".toml")
        else:
            path = Path(config)
            self.config = load_config(path)
        self._scales = speed_scales(self.config)
        self._links = {st.address: st.link for st in self.config.station}
        self.loop = VirtualEventLoop()
        self._lock = threading.Lock()  # one caller at a time (``net.aio`` calls come from worker threads)
        self.session: VirtualSession = self.call(VirtualSession.open(
            self.config, path, seed=seed, state_dir=Path(state_dir) if state_dir else None))
        net = self.session.net
        assert net is not None  # open() builds it
        self.net: NetworkApi = net
        events = RunLog(self.session.masters[next(iter(self.session.masters))].now_ns)
        for master in self.session.masters.values():
            events.watch(master)
        #: the network's operations, which the methods of the table perform (and the timeline)
        self.ops = NetworkOps(self.session, events, in_thread=False, scales=self._scales)
        self._handlers = self.ops.handlers()
        self._scenario: tuple[Timeline, asyncio.Task[None]] | None = None
        self._closed = False
        self.final_report: dict[str, Any] | None = None
        if bring_up:
            problems = self.call(self.session.bring_up(bringup_timeout))
            if problems:
                self.close()
                raise BringUpFailed(problems)
            if reset_after_bringup:
                self.session.reset_metrics()

    # ------------------------------------------------------------------ time
    @property
    def now(self) -> float:
        """Simulated time in seconds (0 at power-up, before bring-up)."""
        return self.loop.clock.now / 1e9

    @property
    def now_ns(self) -> int:
        return self.loop.clock.now

    @property
    def cycle_s(self) -> float:
        """The transmission cycle in seconds."""
        return self.config.network.transmission_cycle / 1e9

    def call(self, coro: Awaitable[T]) -> T:
        """Run *coro* (anything of the async API) to completion on simulated time and return its result. Should
        the loop stop on an error of its own before *coro* is done, *coro*'s own outcome is collected when it
        comes (no "Task exception was never retrieved" at the end)."""
        with self._lock:
            task = asyncio.ensure_future(coro, loop=self.loop)
            try:
                return self.loop.run_until_complete(task)
            except BaseException:
                if not task.done():
                    task.add_done_callback(_collect)
                raise

    def run_until(self, t: float) -> None:
        """Let the network run until simulated time *t* (seconds; nothing happens if it is past)."""
        self.run_until_ns(round(t * 1e9))

    def run_until_ns(self, t_ns: int) -> None:
        clock = self.loop.clock
        if t_ns <= clock.now:
            return
        fut = self.loop.create_future()
        clock.at(t_ns, _resolve, fut)
        self.call(fut)

    def advance(self, seconds: float) -> None:
        """Let the network run for *seconds* of simulated time."""
        self.run_until_ns(self.loop.clock.now + round(seconds * 1e9))

    def step(self, cycles: int = 1) -> None:
        """Let the network run for *cycles* transmission cycles."""
        self.run_until_ns(self.loop.clock.now + cycles * self.config.network.transmission_cycle)

    # ------------------------------------------------------------------ the operations
    def _perform(self, op: str, **args: Any) -> dict[str, Any]:
        return self.call(perform(self._handlers, request_of(op, **args)))

    # ------------------------------------------------------------------ the bare master API
    def set_control(self, station: int, **fields: Any) -> None:
        """Cyclic INV_CTL fields (forward, reverse, speed_ref [raw], fault_reset, ef0, …); others stay as set."""
        self.net.set_control(station, **fields)

    def view(self, station: int) -> Any:
        """The master's :class:`~mlink_sim.master.StationView` of *station*."""
        return self.net.view(station)

    def views(self) -> dict[int, Any]:
        return self.net.views()

    def prm_rd(self, station: int, register: int | str, size: int = 2) -> Any:
        """PRM_RD by name (``"C1-01"`` -> a :class:`~mlink_sim.master.ParamValue`, 2.0 with its unit "s") or by
        register number (the raw unsigned word; *size* bytes when not 2): :meth:`Master.prm_rd
        <mlink_sim.aio.master.Master.prm_rd>`."""
        return self.call(self.net.prm_rd(station, register, size))

    def prm_wr(self, station: int, register: int | str, value: Any, size: int = 2) -> None:
        """PRM_WR by name in engineering units (``prm_wr(0x21, "C1-01", 5.0)``, range-checked) or by register
        number with the raw int: written, not entered (the drive keeps its value until :meth:`send_config`;
        :meth:`set_param` does both)."""
        self.call(self.net.prm_wr(station, register, value, size))

    def send_config(self, station: int, mode: int = 0) -> None:
        """CONFIG (enter the parameters written by PRM_WR; mode 1 also stores them in EEPROM)."""
        self.call(self.net.config(station, mode))

    def id_rd(self, station: int, code: int, offset: int = 0, size: int = 8) -> bytes:
        return self.call(self.net.id_rd(station, code, offset, size))

    def alm_rd(self, station: int, mode: int = 0, index: int = 0) -> Any:
        return self.call(self.net.alm_rd(station, mode, index))

    def alm_clr(self, station: int) -> None:
        self.call(self.net.alm_clr(station))

    # ------------------------------------------------------------------ the stations
    def station(self, address: int) -> Any:
        """The card core of *address* (``snapshot()``, ``counters`` …); None while killed."""
        return self.session.fabric.station(address)

    def snapshots(self) -> dict[int, Any]:
        """Every station's :class:`~mlink_sim.cards.StationSnapshot` (the slave side), by address."""
        return {a: node.station.snapshot() for a, node in self.session.fabric.nodes.items()
                if node.station is not None}

    def snapshot(self) -> NetworkSnapshot:
        """The master's view and every station's snapshot, now (for a co-simulation step, or a log of states)."""
        cycle = self.session.cycle
        return NetworkSnapshot(self.now, cycle.cycle if cycle is not None else -1, self.views(), self.snapshots())

    # ------------------------------------------------------------------ timeline and figures
    def start_timeline(self) -> None:
        """Start the config's timeline now ("0 s" of its steps); its actions run as time advances."""
        timeline = self.ops.timeline = Timeline(self.config)
        task = self.loop.create_task(TimelineRunner(timeline, self.ops).run(self.loop.time()))
        self._scenario = (timeline, task)

    def run_timeline(self) -> list[CheckResult]:
        """Run the timeline to its end (started now unless :meth:`start_timeline` was called); its checks."""
        if self._scenario is None:
            self.start_timeline()
        assert self._scenario is not None
        timeline, task = self._scenario
        self.call(asyncio.shield(task))
        return list(timeline.results)

    def reset_metrics(self) -> None:
        """Start the figures afresh from now."""
        self.session.reset_metrics()

    def report(self) -> dict[str, Any]:
        """The report as of now (docs/report.md; ``meta.clock`` = ``"virtual"``, the timeline's checks so far); after
        :meth:`close`, the final one."""
        if self._closed and self.final_report is not None:
            return self.final_report
        return super().report()

    def close(self) -> dict[str, Any] | None:
        """DISCONNECT every station, stop; returns the final report (with the timeline's checks). Idempotent."""
        if self._closed:
            return self.final_report
        self._closed = True
        session = self.session
        try:
            if self._scenario is not None:
                self._scenario[1].cancel()
            self.call(session.close_masters())
            for c in self._scenario[0].results if self._scenario else []:
                session.metrics.record_check(c.at_s, c.what, c.ok, c.detail, station=c.station)
            self.final_report = build_report(*self.call(session.snapshot()))
            self.call(session.close())
        finally:
            self.loop.close()
        return self.final_report

    def __enter__(self) -> VirtualNetwork:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __repr__(self) -> str:
        return (f"VirtualNetwork({self.config.network.name!r}, {len(self.config.station)} stations, "
                f"t={self.now:.6f} s{', closed' if self._closed else ''})")


def _collect(task: asyncio.Future[Any]) -> None:
    if not task.cancelled():
        task.exception()


def _resolve(fut: asyncio.Future[None]) -> None:
    if not fut.done():
        fut.set_result(None)
