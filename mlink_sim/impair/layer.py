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

**Named**: every fault is a *name* (:mod:`.names`: given, or made as ``loss-21H-1``) with a group of stages
(:mod:`mlink_sim.impair.stages`) on each of its paths (a station or every station, one direction) and an optional
end time. An :meth:`~ImpairmentLayer.impair` without a name replaces the unnamed impairment of its paths (a second
``impair`` of a station replaces the first); one with a name stacks beside the others, and the same name again
replaces that one wherever it was. :meth:`~ImpairmentLayer.heal` ends them by station, by name or all;
:meth:`~ImpairmentLayer.faults` lists them with what each has injected. The stages of every fault of a path run
together in the order of :data:`~mlink_sim.impair.stages.ORDER`.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from typing import Any

from .names import Names
from .spec import Direction, ImpairError, Impairment
from .stages import Corrupt, Delay, Duplicate, Items, Loss, PathState, Reorder, Stage

__all__ = ["ImpairmentLayer", "Fault", "impairment_stages", "impairment_kind", "ALL", "IMPAIR"]

#: The station of a fault on every station.
ALL = None
#: The kind of the faults :meth:`ImpairmentLayer.impair` adds (another kind of fault gives its own to ``add``).
IMPAIR = "impair"
#: Listener of fault events: ``(event, station or None, name, now)`` with event ``"start"`` or ``"end"``.
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


def impairment_kind(spec: Impairment) -> str:
    """What a made name of *spec* starts with: its first field of loss, delay, duplicate, reorder, corrupt."""
    return next(n for n in ("loss", "delay", "duplicate", "reorder", "corrupt") if getattr(spec, n))


@dataclass
class Fault:
    """One named group of stages on one path key, until *until* (ns; None: until healed)."""

    name: str
    stages: tuple[Stage, ...]
    until: int | None
    describe: str = ""
    kind: str = IMPAIR
    given: bool = True  #: the name was given (False: made by the layer, replaced by the next unnamed ``impair``)


@dataclass
class _Named:
    """What the layer keeps of one name: its kind, description, end, and what its stages injected."""

    kind: str
    describe: str
    until: int | None
    given: bool
    counts: Counter[str] = field(default_factory=Counter)


@dataclass
class ImpairmentLayer:
    """See the module docstring. *seed* fixes every draw; *names* is the namespace it shares with the faults of
    the same network (its own by default)."""

    seed: int = 0
    #: called on every fault that starts or ends (the capture's notes, the recovery measurement)
    listener: Listener | None = None
    names: Names = field(default_factory=Names)
    active: bool = field(default=False, init=False)  #: any fault on any path (drivers skip the layer otherwise)
    _faults: dict[tuple[int | None, Direction], list[Fault]] = field(default_factory=dict, init=False)
    _named: dict[str, _Named] = field(default_factory=dict, init=False)
    _compiled: dict[tuple[int, Direction], tuple[tuple[Stage, Counter[str]], ...]] = field(default_factory=dict,
                                                                                            init=False)
    _paths: dict[tuple[int, Direction], PathState] = field(default_factory=dict, init=False)
    _counts: dict[int, Counter[str]] = field(default_factory=dict, init=False)
    _next_end: int | None = field(default=None, init=False)

    # ------------------------------------------------------------------ faults
    def impair(self, spec: Impairment, station: int | None | Sequence[int | None], now: int, *,
               name: str | None = None) -> str:
        """Start *spec* on *station* (None: every station; a list: each of them, one name) in its direction(s);
        it ends after ``spec.for_ns`` or at :meth:`heal`. Without *name* it replaces the unnamed impairment of those
        paths and gets a made name; with one it stacks beside the others (the same name again replaces that one;
        the name of a fault in force: ImpairError). Returns its name."""
        targets = [station] if station is None or isinstance(station, int) else list(station)
        self.expire(now)
        if name is None:
            for st in targets:
                for direction in spec.directions:
                    self._remove((st, direction), now, lambda f: f.kind == IMPAIR and not f.given)
            where = f"{targets[0]:02X}H" if len(targets) == 1 and targets[0] is not None else "all"
            name, given = self.names.new(impairment_kind(spec), where), False
        else:
            if self.names.kind_of(name) not in (None, "impairment"):
                raise ImpairError(f"name: {name!r} is a fault in force; heal it first, or give the impairment "
                                  "another name")
            self.heal(None, now, name=name)
            given = True
        until = None if spec.for_ns is None else now + spec.for_ns
        for st in targets:
            for direction in spec.directions:
                self.add(name, st, direction, impairment_stages(spec), now, until=until, describe=spec.describe(),
                         given=given)
        return name

    def add(self, name: str, station: int | None, direction: Direction, stages: Sequence[Stage], now: int, *,
            until: int | None = None, describe: str = "", kind: str = IMPAIR, given: bool = True) -> None:
        """Put *stages* on the path (*station* or every station, *direction*) as *name*, replacing what that name
        had there; it ends at *until* (ns) or at :meth:`heal`. The entry point for other kinds of fault (*kind*)."""
        self.expire(now)
        named = self._named.get(name)
        if named is None:
            named = self._named[name] = _Named(kind, describe, until, given)
            self.names.hold(name, "impairment")
        faults = self._faults.setdefault((station, direction), [])
        faults[:] = [f for f in faults if f.name != name]
        faults.append(Fault(name, tuple(stages), until, describe, kind, given))
        self._changed()
        if self.listener is not None:
            self.listener("start", station, name, now)

    def heal(self, station: int | None, now: int, groups: Iterable[str] | None = None, *,
             name: str | None = None) -> list[str]:
        """End the faults of *station* (None: of every station and every-station fault), of the kinds *groups*
        only if given, the one called *name* only if given; returns the names that ended there (each once).
        Datagrams already delayed are still delivered."""
        wanted = None if groups is None else set(groups)
        ended = self._remove_where(station, now, lambda f: (wanted is None or f.kind in wanted)
                                   and (name is None or f.name == name))
        return ended

    def expire(self, now: int) -> None:
        """End the faults whose time is up (called by :meth:`process`; drivers may call it on each cycle)."""
        if self._next_end is None or now < self._next_end:
            return
        self._remove_where(None, now, lambda f: f.until is not None and f.until <= now)

    def _remove(self, key: tuple[int | None, Direction], now: int, which: Callable[[Fault], bool]) -> list[str]:
        faults = self._faults.get(key)
        if not faults:
            return []
        keep = [f for f in faults if not which(f)]
        gone = [f.name for f in faults if which(f)]
        if keep:
            self._faults[key] = keep
        else:
            del self._faults[key]
        if self.listener is not None:
            for n in gone:
                self.listener("end", key[0], n, now)
        self._forget_unused(gone)
        self._changed()
        return gone

    def _remove_where(self, station: int | None, now: int, which: Callable[[Fault], bool]) -> list[str]:
        ended: list[str] = []
        for key in list(self._faults):
            if station is not None and key[0] != station:
                continue
            ended += [n for n in self._remove(key, now, which) if n not in ended]
        return ended

    def _forget_unused(self, names: Iterable[str]) -> None:
        left = {f.name for faults in self._faults.values() for f in faults}
        for n in names:
            if n not in left and self._named.pop(n, None) is not None:
                self.names.drop(n)

    def _changed(self) -> None:
        self._compiled.clear()
        self.active = bool(self._faults)
        ends = [f.until for faults in self._faults.values() for f in faults if f.until is not None]
        self._next_end = min(ends) if ends else None

    def faults(self, now: int | None = None) -> list[dict[str, Any]]:
        """The faults in place, one per name in the order they began: ``{"name", "kind", "given", "stations"
        (addresses, or ``["all"]``), "direction", "describe", "until", "left_ns", "injected"}`` (*left_ns*: the time
        left at *now*, None without an end or a *now*)."""
        where: dict[str, tuple[set[int | None], set[Direction]]] = {n: (set(), set()) for n in self._named}
        for (st, direction), faults in self._faults.items():
            for f in faults:
                stations, directions = where[f.name]
                stations.add(st)
                directions.add(direction)
        out = []
        for n, named in self._named.items():
            stations, directions = where[n]
            way = "both" if len(directions) > 1 else next(iter(directions)).name.lower().replace("_", "-")
            left = None if named.until is None or now is None else max(0, named.until - now)
            out.append({"name": n, "kind": named.kind, "given": named.given,
                        "stations": ["all"] if None in stations else sorted(s for s in stations if s is not None),
                        "direction": way, "describe": named.describe, "until": named.until, "left_ns": left,
                        "injected": dict(named.counts)})
        return out

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
        for stage, tally in stages:
            path.tally = tally
            items = stage.apply(items, path)
            if not items:
                break
        return items

    def _compile(self, key: tuple[int, Direction]) -> tuple[tuple[Stage, Counter[str]], ...]:
        faults = self._faults.get(key, []) + self._faults.get((None, key[1]), [])
        stages = tuple(sorted(((s, self._named[f.name].counts) for f in faults for s in f.stages),
                              key=lambda pair: pair[0].order))
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
