"""Faults on a running network (docs/faults.md): where each one is applied and how its end is timed, for both
clocks.

The control operations ``impair``, ``heal``, ``faults`` (:class:`ImpairmentOps`, a network's and the proxy's) and
``fault``, ``recovery`` (:class:`FaultOps`) are here too.

* Master-side faults (silence, skip-cycles, freeze-wdt, bad-command) go to the fault stage of the station's master
  (:meth:`mlink_sim.aio.master.runner.Master.inject_fault`), in this process.
* Drive faults (load, lock-rotor, mains-loss) are applied to the card core's drive where it runs: in a slave worker
  of ``mlink-sim up`` through its control endpoint (its ``fault`` operation: :mod:`.slave`), on the virtual clock
  directly on the fabric's card core; a fault with ``for`` is ended there after that long (simulated time on the
  virtual clock). The master's fault stage records the episode, ended as long after, so the recovery after the
  fault's end is measured the same way.

Touches: the masters' fault stages in this process, and the slave workers' control endpoints (drive faults).
"""

from __future__ import annotations

import asyncio
from collections.abc import Awaitable, Callable
from typing import Any

from ..._log import get_logger
from ...faults import Episode, FaultSpec
from ...faults.spec import PLANT_FAULTS
from ...metrics.network import station_key
from ...operations import OpError, fault_of, impairment_of
from ..slave.faults import PlantError

__all__ = ["FaultControl", "FaultOps", "ImpairmentOps"]

log = get_logger("mlink_sim.faults")


class FaultControl:
    """The faults of a :class:`~mlink_sim.aio.run.session.NetworkApi` (``net.fault(0x21, spec)``)."""

    def __init__(self, net: Any) -> None:
        self.net = net
        self._handles: list[asyncio.TimerHandle] = []

    async def inject(self, station: int, fault: FaultSpec) -> Episode:
        """Start *fault* on *station* now; returns its episode (its recovery is measured once it has ended)."""
        master = self.net.master(station)
        if fault.action not in PLANT_FAULTS:
            return master.inject_fault(station, fault)
        worker = self.net.workers.get(station)
        if worker is None:
            raise PlantError("drive faults act on the stations' own drive models: they need the slaves of "
                             "'mlink-sim up' (or the virtual clock), not 'mlink-sim master'")
        await worker.drive_fault(station, fault)  # the worker ends it after its for
        episode = master.begin_fault(station, fault)
        if fault.for_ns is None:
            master.end_fault(episode)  # a step: it is over once applied
        else:
            loop = asyncio.get_running_loop()
            self._handles.append(loop.call_later(fault.for_ns / 1e9, master.end_fault, episode))
        return episode

    def clear(self, station: int | None = None) -> None:
        """End every master-side fault of *station* (None: every station) now."""
        for master in self.net.masters.values():
            if master.faults is not None:
                master.faults.clear(station, master.now_ns())

    def stage(self, station: int) -> Any:
        """The master-side fault stage of *station*'s master (episodes, answers to bad commands)."""
        return self.net.master(station).fault_stage()


class ImpairmentOps:
    """``impair``, ``heal`` and ``faults`` on *target*: anything with ``impair(station, spec)``, ``heal(station)`` and
    an ``impairments`` layer (a :class:`~mlink_sim.aio.run.session.NetworkSession`, the proxy). *stations*: a
    station argument (None: every station) -> the stations it names (``unknown_station`` where there is none);
    the proxy takes any."""

    def __init__(self, target: Any, stations: Callable[[int | None], list[int]] | None = None) -> None:
        self.target = target
        self.stations = stations

    def handlers(self) -> dict[str, Callable[..., Any]]:
        return {"impair": self.impair, "heal": self.heal, "faults": self.faults}

    def _check(self, station: int | None) -> None:
        if station is not None and self.stations is not None:
            self.stations(station)

    def impair(self, station: int | None = None, **fields: Any) -> dict[str, Any]:
        spec = impairment_of(fields)
        self._check(station)
        self.target.impair(station, spec)
        return {"impairment": spec.as_fields(), "describe": spec.describe()}

    def heal(self, station: int | None = None) -> dict[str, Any]:
        self._check(station)
        return {"ended": self.target.heal(station)}

    def faults(self) -> dict[str, Any]:
        layer = self.target.impairments
        return {"faults": [{**f, "station": f["station"] if f["station"] == "all" else station_key(f["station"])}
                           for f in layer.faults()],
                "injected": {station_key(a): c for a, c in layer.injected().items()}}


class FaultOps:
    """``fault`` and ``recovery`` of a running network (docs/faults.md): a station, master or drive fault on one
    station or every one (``station`` None), each station's latest fault episode."""

    def __init__(self, session: Any, stations: Callable[[int | None], list[int]]) -> None:
        self.session = session
        self.stations = stations

    def handlers(self) -> dict[str, Callable[..., Any]]:
        return {"fault": self.fault, "recovery": self.recovery}

    def fault(self, station: int | None = None, **fields: Any) -> Awaitable[dict[str, Any]]:
        """Answered once the fault is in place on every station it names, with each station's episode (a drive
        fault: once the slave applied it)."""
        spec = fault_of(fields)
        net = self.session.net
        targets = self.stations(station)

        async def start() -> dict[str, Any]:
            try:
                episodes = await asyncio.gather(*(net.fault(a, spec) for a in targets))
            except PlantError as exc:
                raise OpError("unavailable", str(exc)) from None
            return {"fault": spec.as_fields(), "describe": spec.describe,
                    "episodes": {station_key(a): ep.as_dict() for a, ep in zip(targets, episodes)}}

        return start()

    def recovery(self, station: int | None = None) -> dict[str, Any]:
        control = self.session.net.fault_control
        latest = {a: control.stage(a).latest(a) for a in self.stations(station)}
        return {"episodes": {station_key(a): None if ep is None else ep.as_dict() for a, ep in latest.items()}}
