"""mlink_sim.metrics.stalls: host stalls per process, in the report's ``host`` section (docs/report.md)."""

from __future__ import annotations

import pytest

from mlink_sim.metrics import NetworkMetrics, check_all, parse_assertion
from mlink_sim.metrics.stalls import StallLog, longest_named_ms

MS = 1_000_000


def test_summary_counts_since_the_origin_and_splits_absorbed_from_lost():
    log = StallLog("absorb", 50 * MS)
    log.record("master", 100 * MS, 30 * MS, 15, True)   # before the origin: not counted
    log.reset(1_000 * MS)
    log.record("master", 1_200 * MS, 24 * MS, 12, True)
    log.record("master", 2_000 * MS, 60 * MS, 30, False)
    log.record("worker:0", 1_500 * MS, 5 * MS)
    host = log.report()
    assert host["policy"] == "absorb" and host["bound"] == 50 * MS
    assert host["stall"] == {"count": 3, "total": 89 * MS, "max": 60 * MS, "cycles": 42, "absorbed": 12, "lost": 30}
    assert host["by_process"]["worker:0"]["count"] == 1
    assert [s["at"] for s in host["stalls"]] == [200 * MS, 500 * MS, 1_000 * MS]


def test_repeated_events_from_a_worker_count_once_and_totals_cover_what_was_not_sent():
    log = StallLog()
    events = [[10 * MS, 4 * MS, 0, False], [20 * MS, 6 * MS, 0, False]]
    log.add("worker:1", events)
    log.add("worker:1", events)  # the next stats reply repeats them
    assert log.report()["by_process"]["worker:1"]["count"] == 2
    log.set_totals("worker:1", {"count": 300, "total": 900 * MS, "max": 6 * MS})
    assert log.report()["stall"]["count"] == 300


def test_describe_near_names_the_stall_before_a_failed_check():
    log = StallLog("absorb", 50 * MS)
    log.reset(0)
    log.record("master", 4_200 * MS, 23 * MS, 11, False)
    assert log.describe_near(5_000 * MS) == ("the host stalled once in the 3 s before, longest: 23.0 ms at 4.20 s "
                                             "(master, 11 cycles lost)")
    assert log.describe_near(9_000 * MS) == ""
    for at in range(1, 6):
        log.record("worker:0", 4_000 * MS + at * MS, at * MS)
    text = log.describe_near(5_000 * MS, zero_ns=1_000 * MS)
    assert text.startswith("the host stalled 6 times in the 3 s before, longest: 4.0 ms at 3.00 s (worker:0); ")
    assert text.endswith("23.0 ms at 3.20 s (master, 11 cycles lost)")


@pytest.mark.parametrize("zero_ms", [0, 4_500])  # a stall before the timeline's "0 s" is at a negative time
def test_longest_named_reads_back_what_describe_near_writes(zero_ms):
    log = StallLog("absorb", 100 * MS)
    log.reset(0)
    for at_ms, ms in ((4_100, 12.6), (4_200, 130.5), (4_300, 5.2), (4_400, 0.4)):
        log.record("master", at_ms * MS, int(ms * MS), 3, False)
    detail = "output 0.00 Hz, expected 20 ± 0.5 Hz; " + log.describe_near(5_000 * MS, zero_ns=zero_ms * MS)
    assert longest_named_ms(detail) == 130.5
    assert longest_named_ms("output 0.00 Hz, expected 20 ± 0.5 Hz") == 0.0
    assert longest_named_ms("rtt p50 86.78us; host stalls 3, longest 130.5ms") == 0.0  # the summary is not a check


def test_wire_round_trip_and_merge():
    log = StallLog("absorb", 40 * MS)
    log.record("master", 5 * MS, 3 * MS, 1, True)
    back = StallLog.from_wire(log.to_wire())
    assert back.report() == log.report()
    back.merge(log)
    assert back.report()["stall"]["count"] == 1


def test_unknown_policy_is_rejected():
    with pytest.raises(ValueError, match="absorb"):
        StallLog("lenient")


def test_network_report_carries_host_and_the_assertion_reads_it():
    m = NetworkMetrics(2 * MS)
    m.stalls = StallLog("absorb", 50 * MS)
    m.stall_recorder("master")(10 * MS, 34 * MS, 12, True)
    report = m.report(meta={"config": "x.toml", "started": "2026-01-01T00:00:00+00:00", "duration_s": 1.0})
    assert report["host"]["stall"]["max"] == 24 * MS
    [result] = check_all([parse_assertion("host.stall.max < 5ms")], report)
    assert not result.ok and result.measured == 24 * MS
    m2 = NetworkMetrics.from_wire(m.to_wire())
    assert m2.report(meta=report["meta"])["host"] == report["host"]


def test_brief_for_the_live_status():
    log = StallLog("absorb", 50 * MS)
    assert log.brief() == "0"
    log.record("master", 10 * MS, 23_900_000, 11, True)
    log.record("worker:0", 20 * MS, 4 * MS)
    assert log.brief() == "2 (max 23.9ms)"


def test_totals_since_a_time_leave_the_origin_alone():
    log = StallLog()
    log.record("self", 10 * MS, 4 * MS)
    log.record("self", 30 * MS, 6 * MS)
    assert log.totals("self", since=20 * MS) == {"count": 1, "total": 6 * MS, "max": 6 * MS}
    assert log.origin_ns == 0 and log.totals("self")["count"] == 2
