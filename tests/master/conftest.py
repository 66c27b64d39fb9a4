"""Fixtures of the master-core tests: a network of slaves on explicit time (``net_of``).

pytest runs with ``--import-mode=importlib`` (no test directory on ``sys.path``), so the helper module
``master_fakes`` is loaded here once, by path, under its own unique name (as tests/wire/conftest.py does).
"""

from __future__ import annotations

import importlib.util
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

if "master_fakes" not in sys.modules:
    _spec = importlib.util.spec_from_file_location("master_fakes", Path(__file__).with_name("master_fakes.py"))
    assert _spec is not None and _spec.loader is not None
    _module = importlib.util.module_from_spec(_spec)
    sys.modules["master_fakes"] = _module
    _spec.loader.exec_module(_module)

from master_fakes import Net, card_factory, fake_factory

from mlink_sim.master import MasterCore, NetworkPlan, StationPlan
from mlink_sim.wire import Link


@pytest.fixture(params=["card", "fake"])
def slave_factory(request: pytest.FixtureRequest) -> Callable[[int], Any]:
    """``slave_factory(tcycle_ns)(link, address, data_size, **options)`` -> a station object with
    ``receive(datagram, source, now)`` and ``poll(now)``: the real card cores (``mlink_sim.cards``: SI-T3 for
    ML-I/II, SI-ET3 for ML-III) and the in-test fake, so the master is checked against two independent slaves."""
    return card_factory if request.param == "card" else fake_factory


@pytest.fixture
def net_of(slave_factory: Callable[[int], Any]) -> Callable[..., Net]:
    """``net_of(link, tcycle_ns, *station_plans, **network_options)`` -> a :class:`Net` with one slave each."""

    def build(link: Link, tcycle_ns: int, *stations: StationPlan, **options: Any) -> Net:
        plan = NetworkPlan(link, tcycle_ns, stations or (StationPlan(0x21, link),), **options)
        make = slave_factory(tcycle_ns)
        slaves = {sp.address: make(link, sp.address, sp.data_size) for sp in plan.stations}
        net = Net(MasterCore(plan), slaves)
        # a new slave for *address* (a power-cycled card: phase 1)
        net.make_slave = lambda address: make(link, address, plan.station(address).data_size)  # type: ignore
        return net

    return build

