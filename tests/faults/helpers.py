"""A master core, its fault stage and real card cores on explicit time (shared by tests/faults)."""

from __future__ import annotations

from typing import Any

from mlink_sim.cards import CardOptions, create_card, settings_for
from mlink_sim.faults import FaultStage, StationTraits
from mlink_sim.faults.stage import is_healthy
from mlink_sim.master import MasterCore, NetworkPlan, StationPlan
from mlink_sim.wire import Link

MS = 1_000_000
LATENCY = 20_000
CARD_LINK = {"si-t3": Link.ML2, "si-t-v7": Link.ML2, "si-et3": Link.ML3}
FAMILY = {"si-t3": "a1000", "si-et3": "a1000", "si-t-v7": "v7"}


class Bench:
    """One station of *card* behind a :class:`MasterCore` and a :class:`FaultStage`, cycled on explicit time."""

    def __init__(self, card: str = "si-t3", *, address: int = 0x21, frame_size: int | None = None,
                 subcmd: bool = False, params: tuple[str, ...] = (), tcycle_ns: int = MS, **plan: Any) -> None:
        link = CARD_LINK[card]
        size = frame_size or (64 if link is Link.ML3 else 32)
        settings = settings_for(card, address, size, list(params), options=CardOptions())
        self.card = create_card(card, settings=settings, now=0)
        self.address = address
        self.tcycle = tcycle_ns
        self.core = MasterCore(NetworkPlan(link, tcycle_ns, (StationPlan(address, link, data_size=size,
                                                                          subcmd=subcmd, card=card, **plan),)))
        self.stage = FaultStage([StationTraits(address, FAMILY[card], subcmd)],
                                healthy=lambda a, since: is_healthy(self.core.view(a), since))
        self.layer: Any = None  #: an impairment layer to put the datagrams through instead (mlink_sim.impair)
        self.cycle = 0
        self.events: list[Any] = []
        self.sent: list[bytes] = []  # what reached the card

    @property
    def now(self) -> int:
        return self.cycle * self.tcycle

    def step(self) -> None:
        self.cycle += 1
        now = self.now
        for station, datagram in self.core.on_cycle(self.cycle, now):
            out = self.stage.to_station(station, datagram, now)
            if out is None:
                continue
            self.sent.append(out)
            response = self.card.receive(out, "master", now + LATENCY)
            if response is None:
                continue
            response = self.stage.to_master(station, response, now + 2 * LATENCY)
            if response is not None:
                self.core.on_response(response, now + 2 * LATENCY)
        self.card.poll(now + self.tcycle // 2)
        self.events.extend(self.core.drain_events())
        if self.stage.watching:
            self.stage.after_cycle(now + 2 * LATENCY + 1)

    def run(self, cycles: int) -> None:
        for _ in range(cycles):
            self.step()

    def run_until(self, predicate: Any, limit: int) -> int:
        for n in range(limit):
            if predicate():
                return n
            self.step()
        raise AssertionError(f"not reached within {limit} cycles")

    def up(self) -> Bench:
        self.run_until(self.core.all_at_target, 50)
        self.run(5)
        self.events.clear()
        return self
