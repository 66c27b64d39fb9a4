"""The impairment layer: a sans-I/O pipeline between the cores and the transport (docs/faults.md).

Every driver hands each datagram to :meth:`ImpairmentLayer.process` with its direction, its station and the
time, and delivers what comes back::

    for delay_ns, data in layer.process(datagram, Direction.TO_STATION, 0x21, now):
        deliver(data, at=now + delay_ns)            # nothing: dropped; two: duplicated; altered: corrupted

The real-time master (:mod:`mlink_sim.aio.transport.impaired`), the virtual clock's fabric
(:mod:`mlink_sim.aio.virtual.fabric`) and the proxy (:mod:`mlink_sim.aio.tools.proxy`) share it. It never reads a
clock: time comes in as ``now`` (ns).

**Idle costs nothing**: while :attr:`ImpairmentLayer.active` is False (no fault on any path) the drivers do not
call it; the real-time master's socket is not even wrapped (``python -m benchmarks.micro.impair`` measures both).

**Seeded**: each path (station, direction) draws from its own ``random.Random`` seeded from the layer's seed,
the station and the direction, so the fate of the n-th datagram of a path depends only on the seed and on n,
whatever happens on the other paths and whatever the event order between them.

**Faults** are added per path (a station or every station, one direction) as a *group* of stages
(:mod:`mlink_sim.impair.stages`) with an optional end time; adding a group again on a path replaces it there
(a second ``impair`` replaces the first), other groups stay (a ``silence`` and an ``impair`` together). The
stages of every group of a path run together in the order of :data:`~mlink_sim.impair.stages.ORDER`.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from typing import Any

from .spec import Direction, Impairment
from .stages import Corrupt, Delay, Duplicate, Items, Loss, PathState, Reorder, Stage

__all__ = ["ImpairmentLayer", "Fault", "impairment_stages", "ALL"]

#: The station of a fault on every station.
ALL = None
#: Listener of fault events: ``(event, station or None, group, now)`` with event ``"start"`` or ``"end"``.
Listener = Callable[[str, "int | None", str, int], None]


def impairment_stages(spec: Impairment) -> list[Stage]:
    """The stages of one :class:`Impairment`, fresh (a path's Gilbert–Elliott state is its own)."""
    stages: list[Stage] = []
    if spec.loss:
        stages.append(Loss(spec.loss, spec.burst))
    if spec.corrupt:
        stages.append(Corrupt(spec.corrupt))
    if spec.duplicate:
        stages.append(Duplicate(spec.duplicate))
    if spec.delay:
        stages.append(Delay(spec.delay, spec.jitter))
    if spec.reorder:
        stages.append(Reorder(spec.reorder))
    return stages


@dataclass
class Fault:
    """One group of stages on one path key, until *until* (ns; None: until healed)."""

    group: str
    stages: tuple[Stage, ...]
    until: int | None
    describe: str = ""


@dataclass
class ImpairmentLayer:
    """See the module docstring. *seed* fixes every draw."""

    seed: int = 0
    #: called on every fault that starts or ends (the capture's notes, the recovery measurement)
    listener: Listener | None = None
    active: bool = field(default=False, init=False)  #: any fault on any path (drivers skip the layer otherwise)
    _faults: dict[tuple[int | None, Direction], list[Fault]] = field(default_factory=dict, init=False)
    _compiled: dict[tuple[int, Direction], tuple[Stage, ...]] = field(default_factory=dict, init=False)
    _paths: dict[tuple[int, Direction], PathState] = field(default_factory=dict, init=False)
    _counts: dict[int, Counter[str]] = field(default_factory=dict, init=False)
    _next_end: int | None = field(default=None, init=False)

    # ------------------------------------------------------------------ faults
    def impair(self, spec: Impairment, station: int | None, now: int) -> None:
        """Start *spec* on *station* (None: every station) in its direction(s), replacing the impairment there;
        it ends after ``spec.for_ns`` or at :meth:`heal`."""
        until = None if spec.for_ns is None else now + spec.for_ns
        for direction in spec.directions:
            self.add("impair", station, direction, impairment_stages(spec), now, until=until,
                     describe=spec.describe())

    def add(self, group: str, station: int | None, direction: Direction, stages: Sequence[Stage], now: int, *,
            until: int | None = None, describe: str = "") -> None:
        """Put *stages* on the path (*station* or every station, *direction*) as *group*, replacing the group
        there; it ends at *until* (ns) or at :meth:`heal`. The entry point for other kinds of fault."""
        self.expire(now)
        faults = self._faults.setdefault((station, direction), [])
        faults[:] = [f for f in faults if f.group != group]
        faults.append(Fault(group, tuple(stages), until, describe))
        self._changed()
        if self.listener is not None:
            self.listener("start", station, group, now)

    def heal(self, station: int | None, now: int, groups: Iterable[str] | None = None) -> int:
        """End the faults of *station* (None: of every station and every-station fault), of *groups* only if
        given; returns how many ended. Datagrams already delayed are still delivered."""
        wanted = None if groups is None else set(groups)
        ended = 0
        for key, faults in list(self._faults.items()):
            if station is not None and key[0] != station:
                continue
            keep = [f for f in faults if wanted is not None and f.group not in wanted]
            for f in faults:
                if f not in keep:
                    ended += 1
                    if self.listener is not None:
                        self.listener("end", key[0], f.group, now)
            if keep:
                self._faults[key] = keep
            else:
                del self._faults[key]
        self._changed()
        return ended

    def expire(self, now: int) -> None:
        """End the faults whose time is up (called by :meth:`process`; drivers may call it on each cycle)."""
        if self._next_end is None or now < self._next_end:
            return
        for key, faults in list(self._faults.items()):
            keep = []
            for f in faults:
                if f.until is not None and f.until <= now:
                    if self.listener is not None:
                        self.listener("end", key[0], f.group, now)
                else:
                    keep.append(f)
            if keep:
                self._faults[key] = keep
            else:
                del self._faults[key]
        self._changed()

    def _changed(self) -> None:
        self._compiled.clear()
        self.active = bool(self._faults)
        ends = [f.until for faults in self._faults.values() for f in faults if f.until is not None]
        self._next_end = min(ends) if ends else None

    def faults(self) -> list[dict[str, Any]]:
        """The faults in place: ``{"station", "direction", "group", "until", "describe"}`` each."""
        return [{"station": "all" if key[0] is None else key[0], "direction": key[1].name.lower().replace("_", "-"),
                 "group": f.group, "until": f.until, "describe": f.describe}
                for key, faults in sorted(self._faults.items(), key=lambda kv: (kv[0][0] or -1, kv[0][1]))
                for f in faults]

    # ------------------------------------------------------------------ datagrams
    def process(self, datagram: bytes, direction: Direction, station: int, now: int) -> Items:
        """What becomes of *datagram* (travelling in *direction*, for or from *station*, entering at *now*):
        ``[(delay_ns, data), …]``, delivered *delay_ns* after *now* each; ``[]`` if it was dropped."""
        if self._next_end is not None and now >= self._next_end:
            self.expire(now)
        key = (station, direction)
        stages = self._compiled.get(key)
        if stages is None:
            stages = self._compile(key)
        if not stages:
            return [(0, datagram)]
        path = self._paths.get(key)
        if path is None:
            path = self._paths[key] = PathState(self.seed, station, direction, self._station_counts(station))
        path.enter(now)
        items: Items = [(0, datagram)]
        for stage in stages:
            items = stage.apply(items, path)
            if not items:
                break
        return items

    def _compile(self, key: tuple[int, Direction]) -> tuple[Stage, ...]:
        faults = self._faults.get(key, []) + self._faults.get((None, key[1]), [])
        stages = tuple(sorted((s for f in faults for s in f.stages), key=lambda s: s.order))
        self._compiled[key] = stages
        return stages

    def _station_counts(self, station: int) -> Counter[str]:
        counts = self._counts.get(station)
        if counts is None:
            counts = self._counts[station] = Counter()
        return counts

    # ------------------------------------------------------------------ figures
    def injected(self) -> dict[int, dict[str, int]]:
        """What was injected so far, per station: ``{0x21: {"drops": 12, "delays": 800, …}}`` (cumulative)."""
        return {station: dict(c) for station, c in sorted(self._counts.items()) if station >= 0}
