"""MetricsView: report fields in seconds for tests (mlink_sim.testing.metrics)."""

from __future__ import annotations

import pytest

from mlink_sim.metrics import NetworkMetrics
from mlink_sim.testing import MetricsView

META = {"config": "net.toml", "started": "2026-01-01T00:00:00+00:00", "duration_s": 1.0}


@pytest.fixture
def view() -> MetricsView:
    m = NetworkMetrics(1_000_000)
    for ns in (100_000, 200_000, 300_000):
        m.record_sent(0x21)
        m.record_rtt(0x21, ns)
    m.record_sent(0x22)
    m.record_missing(0x22)
    m.record_cycle_lateness(5_000, skipped=2)
    return MetricsView(m.report(meta=META))


def test_latencies_are_seconds_and_ns(view):
    assert view.rtt.count == 3
    assert view.rtt.p50 == pytest.approx(200e-6, rel=1e-3)
    assert view.rtt.p50_ns == pytest.approx(200_000, rel=1e-3)
    assert view.rtt.max == pytest.approx(300e-6, rel=1e-3)


def test_counters_and_stations(view):
    assert (view.missed, view.missing, view.sent, view.answered) == (2, 1, 4, 3)
    assert view.station[0x22].missing == 1
    assert view.station["22H"].missing == 1
    assert view.station["0x21"].rtt.count == 3
    assert sorted(view.station) == [0x21, 0x22]


def test_unknown_fields_say_what_exists(view):
    with pytest.raises(AttributeError, match="p99_9"):
        view.rtt.p95
    with pytest.raises(AttributeError, match="missed"):
        view.mised
    with pytest.raises(KeyError, match="0x21"):
        view.station[0x30]


def test_host_stalls_in_seconds():
    from mlink_sim.metrics.stalls import StallLog

    m = NetworkMetrics(2_000_000)
    m.stalls = StallLog("absorb", 50_000_000)
    m.stall_recorder("master")(0, 24_000_000, 12, True)
    view = MetricsView(m.report(meta={"config": "c.toml", "started": "2026-01-01T00:00:00+00:00",
                                      "duration_s": 1.0}))
    assert view.host.policy == "absorb" and view.host.bound == pytest.approx(0.05)
    assert view.host.stall.max == pytest.approx(0.024) and view.host.stall.max_ns == 24_000_000
    assert (view.host.stall.count, view.host.stall.absorbed, view.host.stall.lost) == (1, 12, 0)
    assert view.host.by_process["master"].cycles == 12
    with pytest.raises(AttributeError, match="lost"):
        view.host.stall.longest
