"""station[…].injected and alarms in the report (docs/faults.md, docs/report.md): what the fault injection did,
next to what was observed, assertable, carried between processes and reset after bring-up."""

from __future__ import annotations

import jsonschema

from mlink_sim.metrics import REPORT_SCHEMA, NetworkMetrics, check_all, parse_assertion

META = {"config": "faults.toml", "started": "2026-12-01T20:00:00+00:00", "duration_s": 1.0}
MS = 1_000_000


def test_injected_counts_sit_next_to_the_observed_ones_and_validate() -> None:
    m = NetworkMetrics(2 * MS)
    m.add_stations([0x21, 0x22])
    m.record_injected(0x21, {"drops": 12, "corruptions": 3})
    m.record_alarm(0x21)
    report = m.report(meta=META)
    jsonschema.validate(report, REPORT_SCHEMA)
    st = report["station"]["0x21"]
    assert st["injected"] == {"drops": 12, "delays": 0, "corruptions": 3, "duplicates": 0, "reorders": 0,
                              "silences": 0, "skips": 0, "wdt_freezes": 0, "bad_commands": 0, "drive_faults": 0}
    assert st["alarms"] == 1
    assert report["station"]["0x22"]["injected"]["drops"] == 0


def test_injected_is_assertable() -> None:
    m = NetworkMetrics(2 * MS)
    m.record_injected(0x21, {"drops": 5})
    report = m.report(meta=META)
    ok, bad = check_all([parse_assertion("station[0x21].injected.drops > 0"),
                         parse_assertion("station[*].injected.corruptions > 0")], report)
    assert ok.ok and not bad.ok


def test_injected_counts_from_the_reset_survive_the_wire_and_merge() -> None:
    m = NetworkMetrics(2 * MS)
    m.record_injected(0x21, {"drops": 4})
    m.reset()  # the end of bring-up: what was injected before does not count
    m.record_injected(0x21, {"drops": 10})  # cumulative from the layer
    assert m.report(meta=META)["station"]["0x21"]["injected"]["drops"] == 6
    back = NetworkMetrics.from_wire(m.to_wire(hdr=False))
    assert back.report(meta=META) == m.report(meta=META)
    back.merge(m)
    assert back.report(meta=META)["station"]["0x21"]["injected"]["drops"] == 12


def test_dropped_is_taken_from_a_summed_dropped_by_reason() -> None:
    m = NetworkMetrics(2 * MS)
    m.record_slave_counters(0x21, {"reception_failures": 2, "dropped_by_reason": 7})
    assert m.report(meta=META)["station"]["0x21"]["dropped"] == 7
