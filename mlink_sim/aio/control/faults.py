"""Faults on a running network (docs/faults.md): where each one is applied, how its end is timed, for both clocks,
and the name it goes by.

The control operations ``impair``, ``heal``, ``faults`` (:class:`ImpairmentOps`, a network's and the proxy's) and
``fault``, ``recovery`` (:class:`FaultOps`) are here too.

* Master-side faults (silence, skip-cycles, freeze-wdt, bad-command) go to the fault stage of the station's master
  (:meth:`mlink_sim.aio.master.runner.Master.inject_fault`), in this process.
* Drive faults (load, lock-rotor, mains-loss) are applied to the card core's drive where it runs: in a slave worker
  of ``mlink-sim up`` through its control endpoint (its ``fault`` operation: :mod:`.slave`), on the virtual clock
  directly on the fabric's card core; a fault with ``for`` is ended there after that long (simulated time on the
  virtual clock). The master's fault stage records the episode, ended as long after, so the recovery after the
  fault's end is measured the same way.
* Every impairment and fault has a name (docs/faults.md, "Names"), given or made (``loss-21H-1``,
  ``silence-all-1``) in the one namespace of the network's impairment layer (:class:`~mlink_sim.impair.Names`):
  ``faults`` lists them, ``heal NAME`` ends one, ``heal`` of a station or of all ends everything there.

Touches: the masters' fault stages in this process, and the slave workers' control endpoints (drive faults).
"""

from __future__ import annotations

import asyncio
from collections.abc import Awaitable, Callable
from dataclasses import dataclass, field
from typing import Any

from ..._log import get_logger
from ...faults import Episode, FaultSpec
from ...faults.spec import PLANT_FAULTS
from ...impair import ImpairError, Names
from ...metrics.network import station_key
from ...operations import OpError, fault_of, impairment_of
from ..slave.faults import PlantError

__all__ = ["FaultControl", "FaultOps", "ImpairmentOps", "NamedFault"]

log = get_logger("mlink_sim.faults")


@dataclass
class NamedFault:
    """A station, master or drive fault by its name: the stations it was put on, each one's episode and, for a
    drive fault, the handle its slave answered."""

    name: str
    spec: FaultSpec
    given: bool
    episodes: dict[int, Episode] = field(default_factory=dict)
    handles: dict[int, int] = field(default_factory=dict)  #: a drive fault's handle per station, until released
    until: dict[int, int | None] = field(default_factory=dict)  #: a drive fault's end per station (master's clock)


class FaultControl:
    """The faults of a :class:`~mlink_sim.aio.run.session.NetworkApi` (``net.fault(0x21, spec)``), and their
    names."""

    def __init__(self, net: Any) -> None:
        self.net = net
        self._handles: list[asyncio.TimerHandle] = []
        self.named: dict[str, NamedFault] = {}
        self._own_names = Names()

    @property
    def names(self) -> Names:
        """The network's namespace (its impairment layer's), shared by impairments and faults."""
        session = getattr(self.net, "faults", None)
        layer = getattr(session, "impairments", None)
        return layer.names if layer is not None else self._own_names

    async def inject(self, station: int, fault: FaultSpec) -> Episode:
        """Start *fault* on *station* now; returns its episode (its recovery is measured once it has ended)."""
        episode, _ = await self._inject(station, fault)
        return episode

    async def _inject(self, station: int, fault: FaultSpec) -> tuple[Episode, int | None]:
        master = self.net.master(station)
        if fault.action not in PLANT_FAULTS:
            return master.inject_fault(station, fault), None
        worker = self.net.workers.get(station)
        if worker is None:
            raise PlantError("drive faults act on the stations' own drive models: they need the slaves of "
                             "'mlink-sim up' (or the virtual clock), not 'mlink-sim master'")
        handle = await worker.drive_fault(station, fault)  # the worker ends it after its for
        episode = master.begin_fault(station, fault)
        if fault.for_ns is None:
            master.end_fault(episode)  # a step: it is over once applied
        else:
            loop = asyncio.get_running_loop()
            self._handles.append(loop.call_later(fault.for_ns / 1e9, master.end_fault, episode))
        return episode, handle

    async def start(self, stations: list[int], fault: FaultSpec, name: str | None = None,
                    every: bool = False) -> tuple[str, dict[int, Episode]]:
        """Start *fault* on each of *stations* (*every*: the request named every station) as *name* (None: a
        made one; the name of a fault in force again: that one is ended first); its name and the episodes."""
        names = self.names
        if name is not None and names.kind_of(name) == "impairment":
            raise OpError("bad_request", f"name: {name!r} is an impairment in force; heal it first, or give the "
                                         "fault another name")
        if name is not None and name in self.named:
            await self.heal(None, name)
        where = "all" if every or len(stations) != 1 else f"{stations[0]:02X}H"
        given = name is not None
        name = name if name is not None else names.new(fault.action, where)
        results = await asyncio.gather(*(self._inject(a, fault) for a in stations))
        named = NamedFault(name, fault, given)
        for a, (episode, handle) in zip(stations, results, strict=True):
            episode.name = name
            named.episodes[a] = episode
            if handle is not None:
                named.handles[a] = handle
                named.until[a] = None if fault.for_ns is None else episode.start_ns + fault.for_ns
        self.named[name] = named
        names.hold(name, "fault")
        return name, named.episodes

    def in_force(self, named: NamedFault) -> list[int]:
        """The stations *named* still acts on."""
        out = []
        for a, ep in named.episodes.items():
            now = self.net.master(a).now_ns()
            if named.spec.action in PLANT_FAULTS:
                until = named.until.get(a)
                if a in named.handles and (until is None or now < until):
                    out.append(a)
            elif ep.end_ns is None or ep.end_ns > now:
                out.append(a)
        return out

    def listing(self) -> list[dict[str, Any]]:
        """The faults in force by name (the ``faults`` reply's entries), forgetting those that are over."""
        out = []
        for name, named in list(self.named.items()):
            stations = self.in_force(named)
            if not stations:
                self._forget(name)
                continue
            injected: dict[str, int] = {}
            left: int | None = None
            for a in stations:
                ep = named.episodes[a]
                for k, n in ep.injected.items():
                    injected[k] = injected.get(k, 0) + n
                end = named.until.get(a) if named.spec.action in PLANT_FAULTS else ep.end_ns
                if end is not None:
                    left = max(left or 0, end - self.net.master(a).now_ns())
            out.append({"name": name, "kind": "fault", "given": named.given,
                        "stations": [station_key(a) for a in stations], "direction": None,
                        "describe": named.spec.describe, "left_s": None if left is None else round(left / 1e9, 3),
                        "injected": injected})
        return out

    async def heal(self, station: int | None, name: str | None = None) -> list[str]:
        """End the faults of *station* (None: every station), or the one called *name* (there); the names that
        ended. A drive fault is released on its slave; a master-side fault ends in its stage; each episode ends now,
        so its recovery is measured from here."""
        ended = []
        for n, named in list(self.named.items()):
            if name is not None and n != name:
                continue
            stations = [a for a in self.in_force(named) if station is None or a == station]
            for a in stations:
                await self._end(named, a)
            if stations:
                ended.append(n)
            if not self.in_force(named):
                self._forget(n)
        return ended

    async def _end(self, named: NamedFault, station: int) -> None:
        master = self.net.master(station)
        if named.spec.action in PLANT_FAULTS:
            handle = named.handles.pop(station)
            worker = self.net.workers.get(station)
            if worker is not None:
                await worker.release_drive_fault(station, handle)
            master.end_fault(named.episodes[station])
        elif master.faults is not None:
            master.faults.clear(station, master.now_ns(), actions=(named.spec.action,))

    def _forget(self, name: str) -> None:
        if self.named.pop(name, None) is not None:
            self.names.drop(name)

    def clear(self, station: int | None = None) -> None:
        """End every master-side fault of *station* (None: every station) now."""
        for master in self.net.masters.values():
            if master.faults is not None:
                master.faults.clear(station, master.now_ns())

    def stage(self, station: int) -> Any:
        """The master-side fault stage of *station*'s master (episodes, answers to bad commands)."""
        return self.net.master(station).fault_stage()


class ImpairmentOps:
    """``impair``, ``heal`` and ``faults`` on *target*: anything with ``impair(station, spec, name)``,
    ``heal(station, name)``, ``now_ns()`` and an ``impairments`` layer (a
    :class:`~mlink_sim.aio.run.session.NetworkSession`, the proxy). *stations*: a station argument (None: every
    station) -> the stations it names (``unknown_station`` where there is none); the proxy takes any. *faults*: the
    network's :class:`FaultControl` (the proxy has none), whose faults ``heal`` ends and ``faults`` lists too."""

    def __init__(self, target: Any, stations: Callable[[int | None], list[int]] | None = None,
                 faults: Callable[[], FaultControl] | None = None) -> None:
        self.target = target
        self.stations = stations
        self._faults = faults

    def handlers(self) -> dict[str, Callable[..., Any]]:
        return {"impair": self.impair, "heal": self.heal, "faults": self.faults}

    def _check(self, station: int | None) -> None:
        if station is not None and self.stations is not None:
            self.stations(station)

    def impair(self, station: int | None = None, name: str | None = None, **fields: Any) -> dict[str, Any]:
        spec = impairment_of(fields)
        self._check(station)
        try:
            name = self.target.impair(station, spec, name)
        except ImpairError as exc:
            raise OpError("bad_request", str(exc)) from None
        return {"name": name, "impairment": spec.as_fields(), "describe": spec.describe()}

    def heal(self, station: int | None = None, name: str | None = None) -> Any:
        """Answered at once where only impairments end; once the slaves released them where drive faults end."""
        self._check(station)
        names = self.target.impairments.names
        if name is not None and name not in names:
            raise OpError("bad_request", f"heal: no impairment or fault is called {name!r} (faults lists those in "
                                         "force)")
        ended = list(self.target.heal(station, name))
        control = self._faults() if self._faults is not None else None
        if control is None:
            return {"ended": len(ended), "names": ended}

        async def faults_too() -> dict[str, Any]:
            done = ended + [n for n in await control.heal(station, name) if n not in ended]
            return {"ended": len(done), "names": done}

        return faults_too()

    def faults(self) -> dict[str, Any]:
        layer = self.target.impairments
        now = self.target.now_ns()
        entries = [{**{k: v for k, v in f.items() if k not in ("until", "left_ns")},
                    "kind": "impairment",
                    "stations": [s if s == "all" else station_key(s) for s in f["stations"]],
                    "left_s": None if f["left_ns"] is None else round(f["left_ns"] / 1e9, 3)}
                   for f in layer.faults(now)]
        if self._faults is not None:
            entries += self._faults().listing()
        return {"faults": entries, "injected": {station_key(a): c for a, c in layer.injected().items()}}


class FaultOps:
    """``fault`` and ``recovery`` of a running network (docs/faults.md): a station, master or drive fault on one
    station or every one (``station`` None), each station's latest fault episode."""

    def __init__(self, session: Any, stations: Callable[[int | None], list[int]]) -> None:
        self.session = session
        self.stations = stations

    def handlers(self) -> dict[str, Callable[..., Any]]:
        return {"fault": self.fault, "recovery": self.recovery}

    def fault(self, station: int | None = None, name: str | None = None, **fields: Any) -> Awaitable[dict[str, Any]]:
        """Answered once the fault is in place on every station it names, with each station's episode (a drive
        fault: once the slave applied it)."""
        spec = fault_of(fields)
        control = self.session.net.fault_control
        targets = self.stations(station)

        async def start() -> dict[str, Any]:
            try:
                given, episodes = await control.start(targets, spec, name, every=station is None)
            except PlantError as exc:
                raise OpError("unavailable", str(exc)) from None
            return {"name": given, "fault": spec.as_fields(), "describe": spec.describe,
                    "episodes": {station_key(a): ep.as_dict() for a, ep in episodes.items()}}

        return start()

    def recovery(self, station: int | None = None) -> dict[str, Any]:
        control = self.session.net.fault_control
        latest = {a: control.stage(a).latest(a) for a in self.stations(station)}
        return {"episodes": {station_key(a): None if ep is None else ep.as_dict() for a, ep in latest.items()}}
