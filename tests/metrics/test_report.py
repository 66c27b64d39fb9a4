"""mlink_sim.metrics.network + report: the report document, its schema, the atomic writer, the docs."""

from __future__ import annotations

import copy
import json
import os
import re
from pathlib import Path

import jsonschema
import pytest

from mlink_sim.metrics import (
    REPORT_SCHEMA,
    SCHEMA_ID,
    LatencyHistogram,
    NetworkMetrics,
    assertable_fields,
    check_all,
    host_info,
    parse_assertions,
    write_report,
)

US = 1_000
MS = 1_000_000
DOC = Path(__file__).resolve().parents[2] / "docs" / "report.md"
META = {"config": "configs/line1.toml", "started": "2024-05-02T10:15:00+00:00", "duration_s": 3.0}
VALIDATOR = jsonschema.Draft202012Validator(REPORT_SCHEMA, format_checker=jsonschema.FormatChecker())


def sample_metrics() -> NetworkMetrics:
    m = NetworkMetrics(cycle_ns=1 * MS)
    m.add_stations([0x21, 0x22, 0x23])
    for k in range(3000):
        m.record_cycle_lateness(20 * US + k % 50 * US, skipped=1 if k == 1000 else 0)
        for st in (0x21, 0x22):
            m.record_sent(st)
            m.record_rtt(st, 200 * US + (k % 100) * US + (st - 0x21) * 50 * US)
        m.record_sent(0x23)
    m.record_late(0x22)
    for _ in range(3000):
        m.record_missing(0x23)
    m.record_slave_counters(0x21, {"reception_failures": 1, "wdt_errors": 0, "dropped": 4})
    m.record_slave_counters(0x22, {"reception_failures": 2, "wdt_errors": 3, "dropped": 0})
    m.record_cpu("master", 0.6, 3.0)
    m.record_cpu("slave:0x21", 0.09, 3.0)
    m.record_cpu("worker:1", 0.3, 3.0)
    m.record_cpu("supervisor", 0.03, 3.0)
    m.record_check(1.5, "station 0x21 phase == 3", True)
    m.record_check(2.0, "station 0x23 answers", False, "no response")
    return m


def test_schema_is_valid_draft_2020_12():
    jsonschema.Draft202012Validator.check_schema(REPORT_SCHEMA)


def test_report_validates_and_adds_up():
    r = sample_metrics().report(meta={**META, "generation": "MECHATROLINK-II", "host": host_info()})
    VALIDATOR.validate(r)
    assert r["schema"] == SCHEMA_ID
    assert r["meta"]["cycle_ns"] == MS and r["meta"]["stations"] == 3
    assert r["cycles"] == 3001 and r["missed"] == 1 and r["missed_rate"] == pytest.approx(1 / 3001)
    assert r["lateness"]["count"] == 3000
    assert r["sent"] == 9000 and r["answered"] == 6000 and r["late"] == 1 and r["missing"] == 3000
    assert r["rtt"]["count"] == r["answered"]
    assert (r["reception_failures"], r["wdt_errors"], r["dropped"]) == (3, 3, 4)
    st = r["station"]
    assert sorted(st) == ["0x21", "0x22", "0x23"]
    assert st["0x22"]["late"] == 1 and st["0x23"]["missing"] == 3000 and st["0x23"]["rtt"]["count"] == 0
    assert abs(st["0x22"]["rtt"]["p50"] - 299 * US) <= 300     # 250..349 µs uniform: the 1500th of 3000
    assert r["cpu"] == {"master": 20.0, "slaves": 13.0,
                        "by_process": {"master": 20.0, "slave:0x21": 3.0, "supervisor": 1.0, "worker:1": 10.0}}
    assert r["checks"][1] == {"at": 2.0, "what": "station 0x23 answers", "ok": False, "detail": "no response"}
    assert r["assertions"] == []
    json.dumps(r, allow_nan=False)


def test_empty_network_report_validates():
    r = NetworkMetrics(cycle_ns=250_000).report(meta=META)
    VALIDATOR.validate(r)
    assert r["cycles"] == 0 and r["missed_rate"] == 0.0 and r["rtt"]["p99"] == 0 and r["station"] == {}


def test_report_with_hdr_blobs():
    m = sample_metrics()
    r = m.report(meta=META, hdr=True)
    VALIDATOR.validate(r)
    assert LatencyHistogram.decode(r["station"]["0x21"]["rtt"]["hdr"]) == m.stations[0x21].rtt
    assert LatencyHistogram.decode(r["rtt"]["hdr"]).count == 6000


def test_report_with_assertion_results_validates():
    r = sample_metrics().report(meta=META)
    results = check_all(parse_assertions(["rtt.p99 < 500us", "station[*].missing == 0", "missed_rate < 1%"]), r)
    r["assertions"] = [x.as_dict() for x in results]
    VALIDATOR.validate(r)
    assert [x["ok"] for x in r["assertions"]] == [True, False, True]


@pytest.mark.parametrize(
    "mutate",
    [
        lambda r: r.update(extra=1),
        lambda r: r.pop("rtt"),
        lambda r: r.update(schema="mlink-sim/report/2"),
        lambda r: r["station"].update({"0X21": r["station"]["0x21"]}),
        lambda r: r["station"].update({"33": r["station"]["0x21"]}),
        lambda r: r["rtt"].update(p99=1.5),
        lambda r: r["rtt"].update(p99=-1),
        lambda r: r.update(missed_rate=1.5),
        lambda r: r["meta"].pop("started"),
        lambda r: r["meta"].update(duration_s="30s"),
    ],
)
def test_schema_rejects_malformed_reports(mutate):
    r = sample_metrics().report(meta=META)
    mutate(r)
    assert not VALIDATOR.is_valid(r)


def test_meta_cycle_ns_and_stations_can_be_given():
    r = NetworkMetrics(cycle_ns=MS).report(meta={**META, "stations": 30, "cycle_ns": 2 * MS})
    assert r["meta"]["stations"] == 30 and r["meta"]["cycle_ns"] == 2 * MS


# ------------------------------------------------------------------------------------------ counters
def test_slave_counters_survive_slave_restart_and_ignore_junk():
    m = NetworkMetrics(cycle_ns=MS)
    assert m.record_slave_counters(0x21, {"reception_failures": 5, "wdt_errors": 1}) == []
    m.record_slave_counters(0x21, {"reception_failures": 7})
    m.record_slave_counters(0x21, {"reception_failures": 2})          # restarted: 7 before, 2 since
    rejected = m.record_slave_counters(0x21, {"dropped": -1, "wdt_errors": "3", "rx_ok": 5, "reception_failures": True})
    assert sorted(rejected) == ["dropped", "reception_failures", "wdt_errors"]
    sm = m.stations[0x21]
    assert (sm.reception_failures, sm.wdt_errors, sm.dropped) == (9, 1, 0)


def test_slave_counters_from_a_card_snapshot():
    # the shape of mlink_sim.cards StationCounters.as_dict(): drops by reason, many other counters
    snap = {"rx_ok": 1000, "tx": 1000, "dropped_by_reason": {"FCS": 2, "DUPLICATE": 1}, "other_station": 0,
            "wdt_errors": 1, "reception_failures": 4, "fcs_errors": 2, "internal_errors": 0}
    m = NetworkMetrics(cycle_ns=MS)
    assert m.record_slave_counters(0x21, snap) == []
    sm = m.stations[0x21]
    assert (sm.reception_failures, sm.wdt_errors, sm.dropped) == (4, 1, 3)
    assert m.record_slave_counters(0x21, {"dropped_by_reason": {"FCS": "x"}}) == ["dropped"]
    assert sm.dropped == 3


def test_cpu_survives_process_restart():
    m = NetworkMetrics(cycle_ns=MS)
    m.record_cpu("master", 1.0, 10.0)
    m.record_cpu("master", 2.0, 20.0)
    m.record_cpu("master", 0.5, 1.0)              # restarted
    assert m.cpu_percent() == {"master": pytest.approx(2.5 / 21 * 100, abs=1e-3)}
    m.record_cpu("slave:0x21", 0.0, 0.0)
    assert m.cpu_percent()["slave:0x21"] == 0.0
    with pytest.raises(ValueError):
        m.record_cpu("master", -1.0, 1.0)


def test_bad_cycle_ns():
    with pytest.raises(ValueError):
        NetworkMetrics(cycle_ns=0)


def test_wire_round_trip_through_json():
    m = sample_metrics()
    back = NetworkMetrics.from_wire(json.loads(json.dumps(m.to_wire())))
    assert back.report(meta=META) == m.report(meta=META)


def test_merge_adds_figures():
    a, b = sample_metrics(), sample_metrics()
    a.merge(b)
    r1, r = sample_metrics().report(meta=META), a.report(meta=META)
    assert r["cycles"] == 2 * r1["cycles"] and r["sent"] == 2 * r1["sent"]
    assert r["rtt"]["count"] == 2 * r1["rtt"]["count"] and r["rtt"]["p50"] == r1["rtt"]["p50"]
    assert r["reception_failures"] == 2 * r1["reception_failures"]
    assert r["cpu"]["master"] == pytest.approx(r1["cpu"]["master"])
    assert len(r["checks"]) == 2 * len(r1["checks"])


@pytest.mark.parametrize(
    "mutate",
    [lambda w: w.update(lateness="garbage"), lambda w: w.update(missed=-1),
     lambda w: w["stations"]["0x21"].update(sent="x"), lambda w: w["cpu"].update(master=[1, 2])],
)
def test_from_wire_rejects_malformed(mutate):
    w = copy.deepcopy(sample_metrics().to_wire())
    mutate(w)
    with pytest.raises(ValueError):
        NetworkMetrics.from_wire(w)


# ------------------------------------------------------------------------------------------ writer
def test_write_report_writes_json(tmp_path):
    r = sample_metrics().report(meta=META)
    path = tmp_path / "report.json"
    write_report(path, r)
    assert json.loads(path.read_text()) == r
    assert oct(path.stat().st_mode & 0o777) == oct(0o644)
    assert os.listdir(tmp_path) == ["report.json"]


def test_write_report_replaces_and_keeps_mode(tmp_path):
    path = tmp_path / "report.json"
    path.write_text("old")
    path.chmod(0o600)
    write_report(str(path), {"a": 1})
    assert json.loads(path.read_text()) == {"a": 1}
    assert path.stat().st_mode & 0o777 == 0o600


@pytest.mark.parametrize("bad", [{"x": float("nan")}, {"x": object()}, {"x": float("inf")}])
def test_write_report_unserialisable_leaves_old_file(tmp_path, bad):
    path = tmp_path / "report.json"
    path.write_text('{"old": true}')
    with pytest.raises((ValueError, TypeError)):
        write_report(path, bad)
    assert path.read_text() == '{"old": true}'
    assert os.listdir(tmp_path) == ["report.json"]


def test_write_report_failure_midway_leaves_old_file_and_no_temp(tmp_path, monkeypatch):
    path = tmp_path / "report.json"
    path.write_text('{"old": true}')

    def boom(src, dst):
        raise OSError("disk full")

    monkeypatch.setattr(os, "replace", boom)
    with pytest.raises(OSError, match="disk full"):
        write_report(path, {"new": True})
    assert path.read_text() == '{"old": true}'
    assert os.listdir(tmp_path) == ["report.json"]


def test_write_report_missing_directory(tmp_path):
    with pytest.raises(FileNotFoundError):
        write_report(tmp_path / "nope" / "report.json", {"a": 1})


# ------------------------------------------------------------------------------------------ docs
def doc_text() -> str:
    return DOC.read_text(encoding="utf-8")


def test_docs_example_report_validates():
    blocks = re.findall(r"```json\n(.*?)```", doc_text(), re.S)
    assert blocks, "docs/report.md has no json example"
    example = json.loads(blocks[0])
    VALIDATOR.validate(example)
    # and its assertion messages are what the code says for that report
    texts = [a["text"] for a in example["assertions"]]
    got = [r.as_dict() for r in check_all(parse_assertions(texts), example)]
    assert got == example["assertions"]


def test_docs_explain_every_field():
    text = doc_text()
    names = set()
    for path in assertable_fields():
        names.update(p for p in re.split(r"[.\[\]]", path) if p and p != "ADDR")
    names.update(REPORT_SCHEMA["properties"])
    for d in REPORT_SCHEMA["$defs"].values():
        names.update(d.get("properties", {}))
    missing = sorted(n for n in names if f"`{n}`" not in text)
    assert not missing, f"fields not documented in docs/report.md: {missing}"


def test_reset_keeps_the_commands_in_flight_so_answered_plus_missing_stays_within_sent():
    """The reset at the end of bring-up comes between a command and its answer, one per station; counting
    the answer without its command would give answered + missing = sent + about the station count."""
    m = NetworkMetrics(cycle_ns=1 * MS)
    for st in (0x21, 0x22):
        for _ in range(10):
            m.record_sent(st)
        for _ in range(8):
            m.record_rtt(st, 300 * US)
        m.record_missing(st)  # one given up, one still in flight
    m.reset()
    for st in (0x21, 0x22):
        m.record_rtt(st, 300 * US)  # the answer to the command sent before the reset
        m.record_late(st)
        for _ in range(5):
            m.record_sent(st)
            m.record_rtt(st, 300 * US)
    report = m.report(meta=META)
    for fig in [report, *report["station"].values()]:
        assert fig["answered"] + fig["missing"] <= fig["sent"]
    assert report["station"]["0x21"]["sent"] == 6 and report["station"]["0x21"]["answered"] == 6


def test_a_burst_counts_each_station_sent_once_as_record_sent_does():
    """``record_sent_burst`` (the master's one call per cycle) counts as ``record_sent`` per command, a station
    not added before included."""
    one, burst = NetworkMetrics(cycle_ns=1 * MS), NetworkMetrics(cycle_ns=1 * MS)
    for m in (one, burst):
        m.add_stations([0x21, 0x22])
    cycles = [[(0x21, b"a"), (0x22, b"b")], [(0x21, b"a")], [(0x21, b"a"), (0x22, b"b"), (0x30, b"c")]]
    for out in cycles:
        for station, _ in out:
            one.record_sent(station)
        burst.record_sent_burst(out)
    assert {a: sm.sent for a, sm in burst.stations.items()} == {a: sm.sent for a, sm in one.stations.items()} == {
        0x21: 3, 0x22: 2, 0x30: 1}
    assert burst.to_wire() == one.to_wire()
