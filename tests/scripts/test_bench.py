"""scripts/bench.py: the capacity targets' verdicts (no network: synthetic cells)."""

from __future__ import annotations

import pytest

from .scripts_loader import load_script


@pytest.fixture(scope="module")
def bench():
    yield from load_script("bench.py", "mlink_bench")


def _cells(bench, **per_target):
    cells = []
    for t in bench.TARGETS:
        cell = bench.Cell(t.link, t.stations, 0, 1)
        for k, v in per_target.get(f"{t.link}{t.stations}", {}).items():
            setattr(cell, k, v)
        cells.append(cell)
    return cells


def test_targets_cover_the_issue_cells(bench) -> None:
    assert [(t.link, t.stations, t.cycle) for t in bench.TARGETS] == [
        ("ML2", 30, "1ms"), ("ML3", 62, "1ms"), ("ML3", 8, "250us")]
    assert bench.TARGETS[0].duration == "60s"


def test_verdict_tells_platform_floor_from_cpu_bound(bench) -> None:
    cells = _cells(
        bench,
        ML230={"missed": 50, "echo_missed": 30, "ratio_p99": 1.2},           # both miss: floor; ratio met
        ML362={"missed_rate": 0.004, "echo_missed_rate": 0.0002},           # echo holds: ours
        ML38={"lateness_p99_ns": 40_000, "echo_lateness_p99_ns": 9_000},    # met
    )
    text, rows = bench.verdicts(cells)
    by_bound = {r["bound"]: r for r in rows}
    assert by_bound["missed cycles == 0 over 60 s"]["met"] is False
    assert by_bound["missed cycles == 0 over 60 s"]["verdict"] == (
        "not met: platform floor (the bare echo breaks it too)")
    assert by_bound["missed cycles == 0 over 60 s"]["measured"] == "50"
    assert by_bound["RTT p99 ≤ 1.5 × echo p99"]["verdict"] == "met"
    assert by_bound["RTT p99 ≤ 1.5 × echo p99"]["echo"] == "—"
    assert by_bound["missed < 0.1 %"]["met"] is False
    assert by_bound["missed < 0.1 %"]["verdict"] == "not met: CPU per exchange (the bare echo holds it)"
    assert by_bound["missed < 0.1 %"]["measured"] == "0.40 %"
    assert by_bound["lateness p99 ≤ 50 µs"]["met"] is True
    assert "platform floor" in text and "verdict" in text.splitlines()[0]


def test_far_beyond_the_floor_names_both_bounds(bench) -> None:
    cells = _cells(bench, ML362={"missed_rate": 0.4979, "echo_missed_rate": 0.0011})  # measured 2026-11-23
    _, rows = bench.verdicts(cells)
    row = next(r for r in rows if r["bound"] == "missed < 0.1 %")
    assert row["verdict"] == "not met: platform floor (the bare echo breaks it too), and CPU per exchange"
    assert (row["measured"], row["echo"]) == ("49.79 %", "0.11 %")


def test_failed_cell_is_reported_not_judged(bench) -> None:
    cells = _cells(bench)
    cells[1].status = "failed: OSError: boom"
    _, rows = bench.verdicts(cells)
    assert [r["verdict"] for r in rows if r["target"].startswith("62")] == ["failed: OSError: boom"]


def test_table_shows_the_echo_floor_columns(bench) -> None:
    cell = bench.Cell("ML3", 8, 250_000, 1, missed_rate=0.29, rtt_p99_ns=1_620_000, echo_p99_ns=186_000,
                      echo_missed_rate=0.0037, echo_lateness_p99_ns=12_000)
    out = bench.table([cell])
    assert "echo missed" in out and "echo late p99" in out
    assert "0.37%" in out and "12us" in out.replace("µs", "us")


def test_markdown_is_the_docs_table(bench) -> None:
    cells = [
        bench.Cell("ML2", 1, 250_000, 1, status="n/a: MECHATROLINK-II's shortest cycle is 0.5 ms"),
        bench.Cell("ML3", 8, 250_000, 1, missed_rate=0.29, rtt_p50_ns=662_000, rtt_p99_ns=1_620_000,
                   lateness_p99_ns=246_000, cpu_master=99.6, cpu_slaves=98.7, echo_p99_ns=186_000, ratio_p99=8.71,
                   echo_missed_rate=0.0011, echo_lateness_p99_ns=139, notes=["6 station(s) not up"]),
        bench.Cell("ML3", 62, 250_000, 1, status="failed: OSError: boom"),
    ]
    lines = bench.markdown(cells).splitlines()
    assert lines[0].startswith("| gen | stations | cycle | missed |") and lines[0].endswith("| echo lateness p99 |")
    assert len(lines) == 4  # header, rule, two rows: the n/a cell is left out
    assert lines[2] == ("| ML3 | 8 | 250 µs | 29.00 % (6 not up) | 662 µs | 1.62 ms | 246 µs | 100 / 99 | 186 µs "
                        "| 8.71 | 0.11 % | 139 ns |")
    assert lines[3].startswith("| ML3 | 62 | 250 µs | failed: OSError: boom |")
    assert all(line.count("|") == lines[0].count("|") for line in lines)


def test_render_prints_an_earlier_run_without_running_it(bench, tmp_path, capsys) -> None:
    import json
    from dataclasses import asdict

    cell = bench.Cell("ML2", 9, 1_000_000, 1, missed_rate=0.0026, rtt_p99_ns=1_380_000, echo_p99_ns=410_000)
    path = tmp_path / "bench.json"
    path.write_text(json.dumps({"host": {}, "duration_s": 5.0, "cells": [asdict(cell)]}))
    assert bench.render(path, True, None) == 0
    out = capsys.readouterr().out
    assert "| ML2 | 9 | 1 ms | 0.26 % |" in out and "1.38 ms" in out


def test_render_of_a_file_that_is_not_a_run_exits_2(bench, tmp_path, capsys) -> None:
    path = tmp_path / "other.json"
    path.write_text('{"cells": [{"nope": 1}]}')
    assert bench.render(path, False, None) == 2
    assert "not a bench.py --json file" in capsys.readouterr().err
    assert bench.render(tmp_path / "missing.json", False, None) == 2
