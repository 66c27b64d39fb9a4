"""benchmarks.lab.testbeds: each round runs the swarm testbed then the compose testbed (or the two-node swarm), a
pass is exit 0, the figures are the report's rtt.p50 and rtt.p99 (fake testbed scripts stand in for Docker)."""

from __future__ import annotations

import json

import pytest

from benchmarks.lab import testbeds as tb

FAKE = """#!/bin/sh
# usage: fake CONFIG --no-build --report FILE [OPTIONS]
echo "$(basename "$0") $5 $6" >> "{log}"
printf '{{"rtt": {{"p50": {p50}, "p99": {p99}}}, "missed": {missed}}}' > "$4"
exit {code}
"""


def _fake(tmp_path, name, code, p99, missed=0):
    path = tmp_path / name
    path.write_text(FAKE.format(log=tmp_path / "order.log", p50=p99 // 4, p99=p99, missed=missed, code=code))
    path.chmod(0o755)
    return str(path)


def test_rounds_alternate_and_the_table_counts_passes_and_p99(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(tb, "TESTBEDS", {"swarm": _fake(tmp_path, "swarm", 0, 1_500_000, 3),
                                         "compose": _fake(tmp_path, "compose", 1, 500_000)})
    out_json = tmp_path / "runs.json"
    assert tb.main(["--runs", "2", "--no-build", "--json", str(out_json)]) == 0
    assert (tmp_path / "order.log").read_text().split() == ["swarm", "compose", "swarm", "compose"]
    out = capsys.readouterr().out
    assert "swarm    2 of 2 passed  RTT p50 median 0.38 ms (0.38–0.38)  p99 median 1.50 ms (1.50–1.50)  missed 6" in out
    assert "compose  0 of 2 passed  RTT p50 median 0.12 ms (0.12–0.12)  p99 median 0.50 ms (0.50–0.50)  missed 0" in out
    runs = json.loads(out_json.read_text())
    assert [r["code"] for r in runs["compose"]] == [1, 1] and runs["swarm"][0]["rtt_p99_ns"] == 1_500_000
    assert runs["swarm"][0]["rtt_p50_ns"] == 375_000 and runs["command"].endswith("--runs 2 --no-build --json " + str(out_json))


def test_two_nodes_alternate_the_one_node_swarm_and_the_two_node_swarm_across_the_delayed_link(tmp_path, monkeypatch,
                                                                                                 capsys):
    monkeypatch.setattr(tb, "TESTBEDS", {"swarm": _fake(tmp_path, "swarm", 0, 1_000_000), "compose": "unused"})
    assert tb.main(["--runs", "2", "--no-build", "--nodes", "2", "--link-delay", "300us"]) == 0
    assert (tmp_path / "order.log").read_text().splitlines() == ["swarm  ", "swarm --nodes 2"] * 2
    out = capsys.readouterr().out
    assert "swarm    2 of 2 passed" in out and "swarm-2  2 of 2 passed" in out


def test_a_testbed_that_cannot_run_stops_the_measurement_with_its_reason(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(tb, "TESTBEDS", {"swarm": _fake(tmp_path, "swarm", 2, 0), "compose": _fake(tmp_path, "c", 0, 0)})
    assert tb.main(["--runs", "1", "--no-build"]) == 2
    assert "could not run" in capsys.readouterr().err


def test_a_run_without_a_report_counts_and_says_so():
    side = tb.Side("swarm", [tb.Run(1, 3.0, None, None)])
    assert tb.summarize(side) == "swarm    0 of 1 passed  no report  missed 0"


def test_bad_runs_is_a_usage_error():
    with pytest.raises(SystemExit) as exc:
        tb.main(["--runs", "0"])
    assert exc.value.code == 2
