"""The stages of the impairment pipeline (docs/faults.md, "The impairment layer").

A stage takes the datagrams one datagram became so far — ``[(delay_ns, bytes), …]``, starting as
``[(0, datagram)]`` — and returns what they become: fewer (dropped), more (duplicated), altered (corrupted) or
later (delayed). It draws every random number from ``path.rng``, the seeded generator of its path (one station,
one direction), and counts what it injected with ``path.count(kind)``. Stages run in the order of their
``order`` (:data:`ORDER`), whatever the order in which they were added.

Adding a stage: subclass :class:`Stage`, give it an ``order`` (a slot of :data:`ORDER`, or a number between
two of them) and a ``counter`` (the ``injected`` key of the report it counts under), implement :meth:`Stage.apply`
and hand instances to :meth:`~mlink_sim.impair.layer.ImpairmentLayer.add`.
"""

from __future__ import annotations

import abc
import random
from collections import Counter
from typing import Any, ClassVar

from ..wire.frame import FCS_SIZE, HEADER_SIZE
from .spec import Direction

__all__ = ["ORDER", "LOSS_BLOCK", "PathState", "Stage", "Items", "Loss", "Corrupt", "Duplicate", "Delay", "Reorder"]

Items = list[tuple[int, bytes]]

#: The pipeline's slots, in the order the stages run. A datagram that a stage drops reaches no later stage.
ORDER: dict[str, int] = {
    "gate": 100,       # the datagram is not sent at all (a silent station, skipped cycles)
    "rewrite": 200,    # the master's datagram altered before it leaves, FCS recomputed (frozen WDT, bad command)
    "loss": 300,       # dropped on the way
    "corrupt": 400,    # a bit flipped after the FCS: the receiver sees a bad FCS
    "duplicate": 500,  # delivered twice
    "delay": 600,      # delivered later (delay ± jitter)
    "reorder": 700,    # held back until after the next datagram of its path
}
#: Datagrams of a path per block of stratified loss (:class:`Loss`).
LOSS_BLOCK = 1000
#: Hold of a reordered datagram when its path has no interval yet (its first datagram).
DEFAULT_HOLD_NS = 1_000_000


class PathState:
    """One path (a station, one direction): its random generator, its datagram interval, per-stage state, the
    injected counters of its station and (:attr:`tally`) those of the fault whose stage runs now."""

    __slots__ = ("station", "direction", "rng", "last_ns", "interval_ns", "scratch", "tally", "_counts")

    def __init__(self, seed: int, station: int, direction: Direction, counts: Counter[str]) -> None:
        self.station = station
        self.direction = direction
        self.rng = random.Random(f"mlink-sim/impair/{seed}/{station}/{int(direction)}")
        self.last_ns: int | None = None
        self.interval_ns = 0  #: time between the last two datagrams of this path
        self.scratch: dict[Any, Any] = {}  #: per-stage state (the Gilbert–Elliott chain's state)
        #: the counters of the fault the running stage belongs to (the layer sets it before each stage)
        self.tally: Counter[str] | None = None
        self._counts = counts

    def count(self, kind: str, n: int = 1) -> None:
        """Count *n* of *kind* injected: for the station and for the fault whose stage runs."""
        self._counts[kind] += n
        tally = self.tally
        if tally is not None:
            tally[kind] += n

    def enter(self, now: int) -> None:
        if self.last_ns is not None and now > self.last_ns:
            self.interval_ns = now - self.last_ns
        self.last_ns = now


class Stage(abc.ABC):
    """One step of the pipeline (see the module docstring): each stage implements :meth:`apply`."""

    order: ClassVar[int]
    counter: ClassVar[str]  #: the ``injected`` key it counts under
    __slots__ = ()

    @abc.abstractmethod
    def apply(self, items: Items, path: PathState) -> Items:
        """The datagrams (delay, bytes) that leave this stage for those that came in."""


class Loss(Stage):
    """Drop a datagram with probability *p*.

    Without *burst* the losses are stratified: in every block of :data:`LOSS_BLOCK` datagrams of a path exactly
    ``p × LOSS_BLOCK`` of them (the fraction carried over to the next block) are lost, at positions drawn at
    random. Each datagram is still lost with probability *p*, and the realised rate is exact over whole blocks,
    so a short run does not see 0.8 % where 1 % was asked (with independent draws, 10,000 datagrams at 1 % miss
    ±10 % one time in three).

    With *burst* (mean length of a loss burst) the drops come from a two-state Gilbert–Elliott chain: in the
    good state nothing is lost, in the bad state everything; it leaves the bad state with r = 1/burst per
    datagram and enters it with q = p·r/(1 − p), so the long-run loss rate is q/(q + r) = p and a burst lasts
    1/r datagrams on average."""

    order = ORDER["loss"]
    counter = "drops"
    __slots__ = ("p", "enter_bad", "leave_bad")

    def __init__(self, p: float, burst: float | None = None) -> None:
        self.p = p
        if burst is None:
            self.enter_bad = self.leave_bad = None
        else:
            r = 1.0 / burst
            self.leave_bad = r
            self.enter_bad = 1.0 if p >= 1.0 else min(1.0, p * r / (1.0 - p))

    def apply(self, items: Items, path: PathState) -> Items:
        out = []
        for item in items:
            if self.enter_bad is None:
                lost = self._stratified(path)
            else:
                leave_bad = self.leave_bad
                assert leave_bad is not None  # set together with enter_bad
                bad = path.scratch.get(self, False)
                random = path.rng.random()
                bad = (random >= leave_bad) if bad else (random < self.enter_bad)
                path.scratch[self] = lost = bad
            if lost:
                path.count(self.counter)
            else:
                out.append(item)
        return out

    def _stratified(self, path: PathState) -> bool:
        state = path.scratch.get(self)
        if state is None or state[0] == LOSS_BLOCK:  # a new block: draw its losses
            carry = 0.0 if state is None else state[2]
            want = self.p * LOSS_BLOCK + carry
            k = int(want)
            state = [0, frozenset(path.rng.sample(range(LOSS_BLOCK), k)), want - k]
            path.scratch[self] = state
        lost = state[0] in state[1]
        state[0] += 1
        return lost


class _Chance(Stage):
    """A stage that does something to each datagram with probability *p* (:meth:`hit`), counted once per hit."""

    __slots__ = ("p",)

    def __init__(self, p: float) -> None:
        self.p = p

    def apply(self, items: Items, path: PathState) -> Items:
        random = path.rng.random
        out: Items = []
        for item in items:
            if random() < self.p:
                out += self.hit(item, path)
                path.count(self.counter)
            else:
                out.append(item)
        return out

    @abc.abstractmethod
    def hit(self, item: tuple[int, bytes], path: PathState) -> Items:
        """What becomes of a datagram the chance fell on (each subclass: corrupt, duplicate, reorder)."""


class Corrupt(_Chance):
    """With probability *p* flip one bit of the data (between the envelope header and the FCS, so the receiver
    finds the FCS wrong rather than a wrong header; the whole datagram if it is too short to have data)."""

    order = ORDER["corrupt"]
    counter = "corruptions"
    __slots__ = ()

    def hit(self, item: tuple[int, bytes], path: PathState) -> Items:
        delay, data = item
        if not data:
            return [item]
        lo, hi = (HEADER_SIZE, len(data) - FCS_SIZE) if len(data) > HEADER_SIZE + FCS_SIZE else (0, len(data))
        bit = lo * 8 + int(path.rng.random() * (hi - lo) * 8)
        buf = bytearray(data)
        buf[bit >> 3] ^= 1 << (bit & 7)
        return [(delay, bytes(buf))]


class Duplicate(_Chance):
    """With probability *p* deliver the datagram twice (the copy right behind it)."""

    order = ORDER["duplicate"]
    counter = "duplicates"
    __slots__ = ()

    def hit(self, item: tuple[int, bytes], path: PathState) -> Items:
        return [item, item]


class Delay(Stage):
    """Add *delay_ns* ± *jitter_ns* (uniform, whole ns) to every datagram. Jitter may reorder datagrams, as on a
    real network."""

    order = ORDER["delay"]
    counter = "delays"
    __slots__ = ("delay", "span", "jitter")

    def __init__(self, delay_ns: int, jitter_ns: int = 0) -> None:
        self.delay = delay_ns
        self.jitter = jitter_ns
        self.span = 2 * jitter_ns + 1 if jitter_ns else 0

    def apply(self, items: Items, path: PathState) -> Items:
        out = []
        for delay, data in items:
            d = self.delay
            if self.span:
                d += int(path.rng.random() * self.span) - self.jitter
            if d > 0:
                path.count(self.counter)
            out.append((delay + d, data))
        return out


class Reorder(_Chance):
    """With probability *p* hold the datagram back by 1.5 times its path's interval between datagrams (one
    transmission cycle for a cyclic command), so the next datagram of the path overtakes it."""

    order = ORDER["reorder"]
    counter = "reorders"
    __slots__ = ()

    def hit(self, item: tuple[int, bytes], path: PathState) -> Items:
        hold = path.interval_ns * 3 // 2 if path.interval_ns else DEFAULT_HOLD_NS
        return [(item[0] + hold, item[1])]
