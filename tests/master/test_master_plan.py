"""StationPlan / NetworkPlan validation and derived CONNECT fields."""

from __future__ import annotations

import pytest

from mlink_sim.master import NetworkPlan, StationPlan
from mlink_sim.wire import Link, M2ComMod, M3ComMod

MS = 1_000_000


def test_defaults_follow_the_cards_factory_frame_size():
    assert StationPlan(0x21, Link.ML1).data_size == 17
    assert StationPlan(0x21, Link.ML2).data_size == 32  # SI-T3 F6-21 = 0
    assert StationPlan(0x03, Link.ML3).data_size == 64  # SI-ET3 Table 7 F6-21 = 0
    assert StationPlan(0x21, Link.ML1).com_tim == 2
    assert StationPlan(0x21, Link.ML2).com_tim == 1


def test_connect_fields_per_generation():
    assert [StationPlan(0x21, link).ver for link in (Link.ML1, Link.ML2, Link.ML3)] == [0x10, 0x21, 0x30]
    assert StationPlan(0x21, Link.ML3).profile_type == 0x20
    p = StationPlan(0x21, Link.ML2, subcmd=True)
    assert p.com_mod == M2ComMod.SYNCMOD | M2ComMod.SUBCMD
    assert StationPlan(0x21, Link.ML2, sync=False).com_mod == 0
    assert StationPlan(0x21, Link.ML3, subcmd=True).com_mod == M3ComMod.SUBCMD | M3ComMod.SYNCMODE  # ML-II reading
    assert StationPlan(0x21, Link.ML3, subcmd=True, et3_syncmode_table19=True).com_mod == M3ComMod.SUBCMD  # Table 19
    assert StationPlan(0x21, Link.ML3, sync=False).com_mod == 0


def test_communication_cycle():
    assert StationPlan(0x21, Link.ML1, com_tim=4).comm_cycles(2 * MS) == 2  # ML-I: COM_TIM in ms
    assert StationPlan(0x21, Link.ML2, com_tim=3).comm_cycles(MS) == 3
    assert StationPlan(0x21, Link.ML3, com_tim=4).comm_cycle_ns(250_000) == MS


@pytest.mark.parametrize(("kwargs", "match"), [
    ({"link": Link.ML2, "data_size": 64}, "64-byte frames do not exist"),
    ({"link": Link.ML1, "data_size": 32}, "32-byte frames do not exist"),
    ({"link": Link.ML2, "data_size": 17, "subcmd": True}, "sub-commands need"),
    ({"link": Link.ML3, "data_size": 32, "subcmd": True}, "sub-commands need"),
    ({"link": Link.ML1, "com_tim": 3}, "must be even"),
    ({"link": Link.ML2, "com_tim": 33}, "outside 1–32"),
    ({"link": Link.ML3, "com_tim": 256}, "outside 1–255"),
])
def test_station_plan_rejects(kwargs, match):
    with pytest.raises(ValueError, match=match):
        StationPlan(0x21, **kwargs)


@pytest.mark.parametrize(("link", "tcycle", "match"), [
    (Link.ML1, MS, "outside"),
    (Link.ML2, 250_000, "outside"),
    (Link.ML2, 750_000, "multiples of 0.5 ms"),
    (Link.ML3, 100_000, "outside"),
    (Link.ML3, 9 * MS, "outside"),
])
def test_network_plan_transmission_cycle_per_generation(link, tcycle, match):
    with pytest.raises(ValueError, match=match):
        NetworkPlan(link, tcycle)


def test_network_plan_checks_stations():
    with pytest.raises(ValueError, match="appears twice"):
        NetworkPlan(Link.ML2, MS, (StationPlan(0x21, Link.ML2), StationPlan(0x21, Link.ML2)))
    with pytest.raises(ValueError, match="on a MECHATROLINK-II network"):
        NetworkPlan(Link.ML2, MS, (StationPlan(0x21, Link.ML3),))
    plan = NetworkPlan(Link.ML3, 250_000, (StationPlan(0x03, Link.ML3),))
    assert plan.station(0x03).address == 0x03
    with pytest.raises(KeyError):
        plan.station(0x04)
