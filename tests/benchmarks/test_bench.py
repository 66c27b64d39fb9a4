"""benchmarks.bench and benchmarks.targets: the capacity targets judged against the floor of the same run, the
tables and the rendering of earlier runs (no network: synthetic cells); and a run stopped by a signal (a real run
of one station)."""

from __future__ import annotations

import json
import os
import signal
import sys
from dataclasses import asdict

import pytest

from benchmarks import bench, figures, floor, tables, targets
from benchmarks.common import ROOT, child_env, module_command


def _floor(**kw):
    base = {"batched": True, "missed_rate": 0.0005, "rtt_p99_ns": 500_000, "lateness_p99_ns": 2_000,
            "cpu_per_exchange_us": 20.0, "cpu_per_exchange_nospin_us": 10.0, "wakeups_client": 1.0,
            "wakeups_server": 1.0}
    return {**base, **kw}


def _cell(link, n, cycle_ns, **kw):
    cell = bench.Cell(link, n, cycle_ns, 1, duration_s=60.0, floor=_floor(batched=False, cpu_per_exchange_us=25.0),
                      floor_batched=_floor())
    for k, v in kw.items():
        setattr(cell, k, v)
    return cell


def _good(link, n, cycle_ns, **kw):
    figures = {"missed_rate": 0.0007, "rtt_p99_ns": 700_000, "lateness_p99_ns": 30_000, "cpu_per_exchange_us": 25.0}
    return _cell(link, n, cycle_ns, **{**figures, **kw})


def _all_good():
    return [_good(link, n, int(cycle.replace("us", "000").replace("ms", "000000")))
            for link, n, cycle, _ in targets.CELLS]


def test_targets_cover_the_capacity_cells() -> None:
    assert [c[:3] for c in targets.CELLS[:4]] == [
        ("ML3", 62, "1ms"), ("ML3", 62, "500us"), ("ML2", 30, "1ms"), ("ML3", 8, "250us")]
    assert [c[3] for c in targets.CELLS[:4]] == ["60s", "30s", "60s", "30s"]
    assert [t[4] for t in targets.TARGETS] == [1.3, 2.0, 2.0, 2.0]


def test_all_six_targets_met() -> None:
    text, rows = targets.verdicts(_all_good())
    assert all(r["met"] for r in rows), rows
    bounds = [(r["target"].split(",")[0], r["bound"]) for r in rows]
    assert bounds == [
        ("62 ML3 @ 1ms", "missed ≤ floor + 0.05 points"), ("62 ML3 @ 1ms", "RTT p99 ≤ 2 × floor p99"),
        ("62 ML3 @ 500us", "missed ≤ floor + 0.05 points"), ("62 ML3 @ 500us", "RTT p99 ≤ 2 × floor p99"),
        ("30 ML2 @ 1ms", "missed ≤ floor + 0.05 points"), ("30 ML2 @ 1ms", "RTT p99 ≤ 2 × floor p99"),
        ("8 ML3 @ 250us", "lateness p99 ≤ 50 µs"), ("8 ML3 @ 250us", "missed ≤ floor + 0.05 points"),
        ("62 ML3 @ 1ms", "CPU per exchange ≤ 1.3 × floor"), ("62 ML3 @ 500us", "CPU per exchange ≤ 2 × floor"),
        ("30 ML2 @ 1ms", "CPU per exchange ≤ 2 × floor"), ("8 ML3 @ 250us", "CPU per exchange ≤ 2 × floor"),
        ("1 ms knee (ML3)", "reaches 62 stations")]
    assert text.splitlines()[-1] == "13 of 13 bounds met"


def test_not_met_says_what_bounds_it() -> None:
    cells = _all_good()
    cells[0].missed_rate, cells[0].cpu_master, cells[0].cpu_slaves = 0.0138, 99.0, 97.0  # 62 @ 1 ms
    cells[0].cpu_per_exchange_us, cells[0].notes = 48.0, ["3 station(s) not up"]
    cells[3].lateness_p99_ns = 206_000  # 8 @ 250 µs, the floor at 2 µs
    _, rows = targets.verdicts(cells)
    missed = rows[0]
    assert (missed["measured"], missed["floor"], missed["limit"], missed["met"]) == ("1.38 %", "0.05 %", "0.10 %",
                                                                                    False)
    assert missed["verdict"].startswith("not met: CPU: master 99 %, workers 97 % of a CPU; 48.0 µs per exchange "
                                        "= 2.4 × the floor's 20.0")
    assert missed["verdict"].endswith("3 station(s) not up")
    late = next(r for r in rows if r["bound"] == "lateness p99 ≤ 50 µs")
    assert late["met"] is False and "floor breaks it too" not in late["verdict"]
    cpu = next(r for r in rows if r["bound"].startswith("CPU") and r["target"].startswith("62"))
    assert (cpu["measured"], cpu["floor"], cpu["limit"], cpu["met"]) == ("48.0 µs", "20.0 µs", "26.0 µs", False)
    knee = rows[-1]
    assert (knee["measured"], knee["met"]) == ("45", False) and "at 62:" in knee["verdict"]


def test_a_missed_bound_not_met_gives_each_turn_beside_the_floor_s() -> None:
    """An excess in one turn of six (a host event the floor's turns did not meet) reads differently from one spread
    over all six (the simulator's own): the verdict lists both sides' answers not back within a cycle per turn."""
    cells = _all_good()
    cells[2].missed_rate, cells[2].missed_by_turn = 0.0015, [30, 30, 990, 30, 30, 30]  # 30 ML-II @ 1 ms
    cells[2].floor_batched["missed_by_turn"] = [30, 30, 30, 30, 30, 30]
    cells[2].stalls_by_turn = [[0, 0, 0, 0]] * 2 + [[32, 31_000_000, 1, 4_000_000]] + [[1, 1_200_000, 0, 0]] * 3
    _, rows = targets.verdicts(cells)
    row = next(r for r in rows if r["target"].startswith("30 ML2") and r["bound"].startswith("missed"))
    assert row["verdict"].startswith(
        "not met: not back within a cycle per turn 30, 30, 990, 30, 30, 30 (floor 30, 30, 30, 30, 30, 30); the "
        "master's clock per turn, cycles its host stalls delayed / the longest: 0 / 0ns, 0 / 0ns, 32 / 31ms, "
        "1 / 1.2ms, 1 / 1.2ms, 1 / 1.2ms; the workers' stalls of 3 ms or more per turn / the longest: 0 / 0ns, "
        "0 / 0ns, 1 / 4ms, 0 / 0ns, 0 / 0ns, 0 / 0ns; master ")


@pytest.mark.parametrize(("held", "says"), [
    ([0, 0, 960, 30, 30, 30], "late answers those stalls can account for, per turn: 0, 0, 960, 30, 30, 30 (up to 1,050 "
     "in all), at least the 900 by which the cell is over its limit: the host's stalls can explain it; master "),
    ([0, 0, 120, 30, 30, 30], "late answers those stalls can account for, per turn: 0, 0, 120, 30, 30, 30 (up to 210 "
     "in all), fewer than the 900 by which the cell is over its limit: the rest is the simulator's own, or a "
     "holdup neither process logged; master "),
])
def test_a_missed_bound_not_met_weighs_the_logged_stalls_against_the_excess(held, says) -> None:
    """The late answers the logged stalls account for (the fifth figure of each turn), against the answers by which
    the cell is over its limit (0.15 % of 1,800,000 due against the floor's 0.05 % + 0.05 points: 900): a host
    event that the logs caught, or an excess they do not explain."""
    cells = _all_good()
    cell = cells[2]  # 30 ML-II @ 1 ms, 60 s
    cell.missed_rate, cell.due, cell.missed_by_turn = 0.0015, 1_800_000, [30, 30, 990, 30, 30, 30]
    cell.stalls_by_turn = [[0, 0, 0, 0, n] for n in held]
    _, rows = targets.verdicts(cells)
    row = next(r for r in rows if r["target"].startswith("30 ML2") and r["bound"].startswith("missed"))
    assert not row["met"] and says in row["verdict"], row["verdict"]


def test_the_late_answers_a_turns_stalls_account_for() -> None:
    """Each stall of the master's clock: the cycle then on its way (every station's answer); each worker's stalled
    time: that many cycles (rounded up) of its own stations' answers. Beside it, the master's cycles delayed and
    longest stall (the report's ``host.by_process.master``), the workers' stalls and their longest."""
    master = {"host": {"by_process": {"master": {"count": 2, "cycles": 5, "max": 3_000_000}}}}
    one = [{"stations": {str(a): {} for a in range(62)},
            "stall_totals": {"count": 2, "total": 7_500_000, "max": 5_000_000}}]
    assert bench._turn_stalls(master, one, 62, 1_000_000) == (5, 3_000_000, 2, 5_000_000, 2 * 62 + 8 * 62)
    two = [{"stations": {"3": {}, "4": {}}, "stall_totals": {"count": 1, "total": 500_000, "max": 500_000}},
           {"stations": {str(a): {} for a in range(6)}, "stall_totals": {}}]  # the second worker logged none
    assert bench._turn_stalls({}, two, 8, 250_000)[4] == 2 * 2
    assert bench._turn_stalls({}, [{**w, "stall_totals": {}} for w in two], 8, 250_000) == (0, 0, 0, 0, 0)


def test_the_knees_verdict_weighs_the_failing_cells_logged_stalls() -> None:
    """A knee cell of one turn (10 s) put over by three stalls of its worker (450 answers late against the floor's
    45): the knee's verdict gives that cell's turn and what its logged stalls account for."""
    cells = _all_good()
    c45 = next(c for c in cells if c.stations == 45)
    c45.missed_rate, c45.due, c45.missed_by_turn = 0.001, 450_045, [450]
    c45.floor_batched.update(missed_rate=0.0001, missed_by_turn=[45])
    c45.stalls_by_turn = [[0, 0, 3, 3_620_428, 450]]
    knee = targets.verdicts(cells)[1][-1]
    assert (knee["measured"], knee["met"]) == ("30", False)
    assert ("at 45: not back within a cycle per turn 450 (floor 45); " in knee["verdict"]
            and "the workers' stalls of 3 ms or more per turn / the longest: 3 / 3.62ms; " in knee["verdict"]
            and "(up to 450 in all), at least the 180 by which the cell is over its limit: the host's stalls can explain it"
            in knee["verdict"]), knee["verdict"]


def test_the_knee_stops_at_the_first_cell_that_fails() -> None:
    cells = _all_good()
    next(c for c in cells if c.stations == 30 and c.link == "ML3").missed_rate = 0.05
    assert targets.knee(cells)[0] == 15


def test_the_floor_with_the_simulators_own_system_calls_is_the_reference() -> None:
    cell = _cell("ML3", 8, 1_000_000, cpu_per_exchange_us=50.0)
    assert cell.ref is cell.floor_batched and cell.ratio("cpu_per_exchange_us", 50.0) == 2.5
    cell.io = "plain"
    assert cell.ref is cell.floor and cell.ratio("cpu_per_exchange_us", 50.0) == 2.0
    cell.floor = None
    assert cell.ref is cell.floor_batched


def test_failed_or_missing_cells_are_reported_not_judged() -> None:
    cells = _all_good()
    cells[2].status = "failed: OSError: boom"
    cells[3].floor = cells[3].floor_batched = None
    _, rows = targets.verdicts(cells[:4])
    assert [r["verdict"] for r in rows if r["target"].startswith("30")] == ["failed: OSError: boom"]
    assert [r["verdict"] for r in rows if r["target"].startswith("8")] == ["no floor measured"]


def test_tables_show_the_floor_and_the_ratios() -> None:
    cells = [bench.Cell("ML2", 1, 250_000, 1, status="n/a: MECHATROLINK-II's shortest cycle is 0.5 ms"),
             _cell("ML3", 8, 250_000, missed_rate=0.0029, rtt_p50_ns=662_000, rtt_p99_ns=1_620_000,
                   lateness_p99_ns=246_000, cpu_master=99.6, cpu_slaves=98.7, cpu_per_exchange_us=41.0,
                   cpu_per_exchange_nospin_us=30.0, notes=["6 station(s) not up"]),
             bench.Cell("ML3", 62, 250_000, 1, status="failed: OSError: boom")]
    text = bench.table(cells)
    assert "µs/exch" in text and "41.0" in text and "2.05" in text  # 41 / 20 µs
    lines = bench.markdown(cells).splitlines()
    assert lines[0] == tables.MD_HEAD and len(lines) == 4  # the n/a cell is left out
    assert lines[2] == ("| ML3 | 8 | 250 µs | batched | 0.29 % (6 not up) | 662 µs | 1.62 ms | 246 µs | 100 / 99 "
                        "| 41.0 (30.0) µs | 0.05 % | 500 µs | 2 µs | 25.0 (10.0) / 20.0 (10.0) µs | 2.05 (3.00) "
                        "| 3.24 |")
    assert lines[3].startswith("| ML3 | 62 | 250 µs | batched | failed: OSError: boom |")
    assert all(line.count("|") == lines[0].count("|") for line in lines)


def test_host_steal_is_read_from_proc_stat_and_noted_in_the_row() -> None:
    """/proc/stat's first line: user nice system idle iowait irq softirq steal …, in clock ticks (proc(5)). The
    steal between two readings is a share of all the time that passed; a row says so from 0.5 %."""
    before = floor.host_ticks("cpu  100 0 50 800 0 0 10 40 0 0\ncpu0 1 2 3\n")
    after = floor.host_ticks("cpu  400 0 150 1200 0 0 30 100 0 0\n")
    assert before == (100, 0, 50, 800, 0, 0, 10, 40) and after[7] == 100
    assert figures.Window(1, ticks=tuple(b - a for a, b in zip(before, after))).steal_pct() == 6.8  # 60 of 880
    assert figures.Window(1).steal_pct() == 0.0 and floor.host_ticks("intr 1 2\n") == ()
    quiet = _good("ML3", 8, 250_000, steal_pct=0.2)
    assert "steal" not in bench.table([quiet])
    busy = _good("ML3", 8, 250_000, steal_pct=0.1, floor_batched=_floor(steal_pct=2.6))
    assert "host steal 0.1 % (floor 2.6 %)" in bench.table([busy])


def test_render_prints_earlier_runs_without_running_them(tmp_path, capsys) -> None:
    old = {"link": "ML2", "stations": 9, "cycle_ns": 1_000_000, "workers": 1, "missed_rate": 0.0026,
           "rtt_p99_ns": 1_380_000, "echo_p99_ns": 410_000}  # a field a Cell does not have
    new = asdict(_cell("ML3", 62, 1_000_000, cpu_per_exchange_us=30.0))
    a, b = tmp_path / "a.json", tmp_path / "b.json"
    a.write_text(json.dumps({"host": {}, "cells": [old]}))
    b.write_text(json.dumps({"host": {}, "cells": [new]}))
    assert bench.render([a, b], True, None) == 0
    out = capsys.readouterr().out
    assert "| ML2 | 9 | 1 ms | batched | 0.26 % |" in out and "1.38 ms" in out and "| ML3 | 62 | 1 ms |" in out


def test_render_of_a_file_that_is_not_a_run_exits_2(tmp_path, capsys) -> None:
    path = tmp_path / "other.json"
    path.write_text('{"cells": [{"nope": 1}]}')
    assert bench.render([path], False, None) == 2
    assert "not a benchmarks.bench --json file" in capsys.readouterr().err
    assert bench.render([tmp_path / "missing.json"], False, None) == 2


def test_pm_qos_refused_exits_2_before_any_cell_runs(monkeypatch, capsys) -> None:
    def must_not_run(*_a, **_k):
        raise AssertionError("a cell ran although --pm-qos was refused")

    monkeypatch.setattr(bench, "run_cell", must_not_run)
    monkeypatch.setattr(bench.realtime, "hold_wakeup_latency",
                        lambda: "CPU wake-up latency refused (Permission denied)")
    monkeypatch.setattr("sys.argv", ["bench", "--pm-qos", "--stations", "1", "--cycles", "1ms", "--links", "ML2"])
    assert bench.main() == 2
    assert "bench: --pm-qos: CPU wake-up latency refused (Permission denied)" in capsys.readouterr().err


def test_realtime_refused_exits_2_before_any_cell_runs(monkeypatch, capsys) -> None:
    def must_not_run(*_a, **_k):
        raise AssertionError("a cell ran although --realtime was refused")

    monkeypatch.setattr(bench, "run_cell", must_not_run)
    monkeypatch.setattr(bench.realtime, "apply", lambda priority, cpus=None: (
        "SCHED_FIFO refused (Operation not permitted), memory locked, CPU wake-up latency 0 µs, CPU 1"))
    monkeypatch.setattr("sys.argv", ["bench", "--realtime", "--stations", "1", "--cycles", "1ms", "--links", "ML2"])
    assert bench.main() == 2
    assert "bench: --realtime: SCHED_FIFO refused (Operation not permitted)" in capsys.readouterr().err


@pytest.mark.parametrize("flag", [[], ["--no-realtime"]])
def test_without_real_time_every_cell_runs_with_ordinary_scheduling(monkeypatch, tmp_path, capsys,
                                                                     flag) -> None:
    """By default the sweep asks for what ``mlink-sim up`` asks for by default; refused (an unprivileged user), it
    withdraws whatever part it got and runs every cell with ordinary scheduling, saying so; ``--no-realtime`` does
    not ask at all. Either way no cell gets a CPU plan and the JSON records no real-time grant."""
    asked: list[str] = []
    cells: list[object] = []

    def run_cell(loop, tmp, link, n, cycle, workers, seconds, poll, cpus):
        cells.append(cpus)
        return bench.Cell(link, n, cycle, workers)

    monkeypatch.setattr(bench, "run_cell", run_cell)
    monkeypatch.setattr(bench, "table", lambda cells: "")
    monkeypatch.setattr(bench, "draw", lambda cells, png: None)
    monkeypatch.setattr(bench.realtime, "apply", lambda priority, cpus=None: asked.append("apply") or (
        "SCHED_FIFO refused (Operation not permitted), memory not locked (Operation not permitted), "
        "CPU wake-up latency refused (Permission denied), CPUs left to the kernel (no wake-up latency held)"))
    monkeypatch.setattr(bench.realtime, "withdraw", lambda: asked.append("withdraw"))
    out = tmp_path / "b.json"
    monkeypatch.setattr("sys.argv", ["bench", *flag, "--stations", "1", "--cycles", "1ms", "--links", "ML2",
                                     "--json", str(out)])
    assert bench.main() == 0
    captured = capsys.readouterr()
    assert asked == ([] if flag else ["apply", "withdraw"]) and cells == [None]
    assert ("real-time requests refused" in captured.err) is not bool(flag)
    assert "ordinary scheduling for every process" in captured.out
    assert json.loads(out.read_text())["host"]["realtime"] is None


def test_real_time_granted_by_default_plans_the_cpus(monkeypatch, tmp_path, capsys) -> None:
    """Granted (root), the default run is ``--realtime``'s: every cell gets the CPU plan, the JSON says what was
    granted."""
    cells: list[object] = []
    monkeypatch.setattr(bench, "run_cell", lambda *a: cells.append(a[-1]) or bench.Cell("ML2", 1, 1_000_000, 1))
    monkeypatch.setattr(bench, "table", lambda cells: "")
    monkeypatch.setattr(bench, "draw", lambda cells, png: None)
    monkeypatch.setattr(bench.realtime, "cpu_plan", lambda: ({1}, {0}))
    monkeypatch.setattr(bench.realtime, "apply", lambda priority, cpus=None: "SCHED_FIFO 40, CPU 1")
    out = tmp_path / "b.json"
    monkeypatch.setattr("sys.argv", ["bench", "--stations", "1", "--cycles", "1ms", "--links", "ML2",
                                     "--json", str(out)])
    assert bench.main() == 0
    assert cells == [({1}, {0})] and json.loads(out.read_text())["host"]["realtime"] == "SCHED_FIFO 40, CPU 1"
    assert "real time: SCHED_FIFO 40, CPU 1" in capsys.readouterr().out


def test_realtime_asks_the_same_of_the_network_and_its_floors(monkeypatch, tmp_path) -> None:
    """With ``--realtime``'s CPU plan the network is opened with the session's real-time requests and both floors
    get the same plan (client on the master's CPUs, server on the workers'); before each network turn the process
    may run on every CPU again, so that the session plans from them all and not from the floor client's one."""
    from mlink_sim.aio.transport import mmsg

    seen: list[tuple[str, object]] = []

    async def network(path, workers, turn, cell, rt=False):
        seen.append(("network", rt))
        return figures.Window(1_000_000, wall_s=turn, started=10, sent=10)

    async def floor(n, size, cycle, turn, batched, absorb_ns, shared=False, cpus=None):
        seen.append(("floor", cpus))
        return figures.Window(1_000_000, wall_s=turn, started=10, sent=10)

    monkeypatch.setattr(bench, "measure_network", network)
    monkeypatch.setattr(bench, "floor_window", floor)
    monkeypatch.setattr(mmsg, "supported", lambda: True)
    monkeypatch.setattr(bench.os, "sched_setaffinity", lambda pid, cpus: seen.append(("affinity", set(cpus))))
    plan = ({1}, {0})
    loop = bench.new_event_loop()
    try:
        bench.run_cell(loop, tmp_path, "ML3", 2, 1_000_000, 1, 1.0, cpus=plan)
    finally:
        loop.close()
    assert seen == [("affinity", {0, 1}), ("network", True), ("floor", plan), ("floor", plan)]


def test_a_cell_is_measured_in_turns_with_its_floors_and_their_counts_add_up(monkeypatch, tmp_path) -> None:
    """A 25 s cell: three turns of 8.3 s, each the network, the plain floor, the batched floor, in that order
    (``benchmarks.figures.turns``), so each side sees the same phases of the host; each side's figures are read from the
    sum of its turns (missed from the summed counts, RTT from the merged histograms, the answers made ahead and any
    the cards contradicted from the summed counts: a contradicted one is a note)."""
    from mlink_sim.aio.transport import mmsg

    order: list[tuple[str, float]] = []

    def window(side: str, turn: float, late_ns: int, late: int) -> object:
        w = figures.Window(250_000, wall_s=turn, started=100, sent=800, cpu_a_s=0.01, cpu_b_s=0.01)
        for i in range(800):
            w.rtt.record(late_ns if i < late else 100_000)
        order.append((side, round(turn, 2)))
        return w

    async def network(path, workers, turn, cell, rt=False):
        w = window("network", turn, 300_000, 8)  # 8 of 800 answers later than the 250 µs cycle
        w.stalls_by_turn = [(len(order), 1_000_000 * len(order), 0, 0)]  # master: cycles delayed, longest; workers
        w.ahead, w.mispredicted = 780, len(order) == 1  # answers made ahead; one contradicted, in the first turn
        return w

    async def floor(n, size, cycle, turn, batched, absorb_ns, shared=False, cpus=None):
        return window("batched" if batched else "plain", turn, 300_000, 1 if batched else 4)

    monkeypatch.setattr(bench, "measure_network", network)
    monkeypatch.setattr(bench, "floor_window", floor)
    monkeypatch.setattr(mmsg, "supported", lambda: True)
    loop = bench.new_event_loop()
    try:
        cell = bench.run_cell(loop, tmp_path, "ML3", 8, 250_000, 1, 25.0)
    finally:
        loop.close()
    assert order == [("network", 8.33), ("plain", 8.33), ("batched", 8.33)] * 3
    assert (cell.turns, cell.due, cell.on_time, cell.missed_rate) == (3, 2400, 2376, 0.01)
    assert (cell.floor["turns"], cell.floor["missed_rate"]) == (3, 0.005)
    assert (cell.floor_batched["turns"], cell.floor_batched["missed_rate"]) == (3, 0.00125)
    assert cell.ref is cell.floor_batched and cell.cpu_master == 0.1  # 0.03 s of 25 s
    assert (cell.ahead_pct, cell.mispredicted) == (97.5, 1)  # 3 × 780 of 2,400 answers made ahead
    assert cell.missed_by_turn == [8, 8, 8] and cell.floor_batched["missed_by_turn"] == [1, 1, 1]
    assert cell.stalls_by_turn == [[1, 1_000_000, 0, 0], [4, 4_000_000, 0, 0], [7, 7_000_000, 0, 0]]
    assert any("contradicted" in note for note in cell.notes)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_no_control_query_reaches_a_worker_inside_the_window(monkeypatch, tmp_path) -> None:
    """A real network of two stations at 500 µs, one worker: the workers' counters (answers made ahead) are asked for
    before the measuring window and after it, never inside (a ``cpu`` query can make answers late at 250 µs),
    and the worker's CPU comes from the kernel's accounting: the window still has both."""
    calls: list[tuple[str, float]] = []
    ask = bench._ask_workers

    async def counted(session, op, **fields):
        calls.append(("query", bench.time.monotonic()))
        return await ask(session, op, **fields)

    async def during(pids, duration_s):
        calls.append(("start", bench.time.monotonic()))
        await bench.asyncio.sleep(duration_s)
        calls.append(("end", bench.time.monotonic()))

    monkeypatch.setattr(bench, "_ask_workers", counted)
    path = tmp_path / "net.toml"
    bench.write_config(path, "ML3", 2, 500_000)
    cell = bench.Cell("ML3", 2, 500_000, 1, duration_s=1.0)
    loop = bench.new_event_loop()
    try:
        w = loop.run_until_complete(bench.measure_network(path, 1, 1.0, cell, during=during))
    finally:
        loop.close()
    assert [what for what, _ in calls] == ["query", "start", "end", "query"], cell.notes
    assert w.cpu_b_s > 0 and w.mispredicted == 0  # ticks of /proc/PID/stat: 10 ms each
    # the answers made ahead, counted by the queries around the window, scaled to it: at most the answers read
    assert 0 < w.ahead <= w.summary()["exchanges"]
    # master's and workers' (host.by_process, stall_totals), and the answers those made late (none expected here)
    assert len(w.stalls_by_turn) == 1 and len(w.stalls_by_turn[0]) == 5 and w.stalls_by_turn[0][4] >= 0


def _descendants(pid: int) -> set[int]:
    """The processes below *pid* (Linux /proc), children of children included."""
    parent: dict[int, int] = {}
    for name in os.listdir("/proc"):
        if name.isdigit():
            try:
                with open(f"/proc/{name}/stat") as f:
                    fields = f.read().rsplit(")", 1)[1].split()
            except OSError:
                continue
            if fields[0] != "Z":
                parent[int(name)] = int(fields[1])
    found, frontier = set(), {pid}
    while frontier:
        frontier = {p for p, pp in parent.items() if pp in frontier} - found
        found |= frontier
    return found


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
@pytest.mark.parametrize("sig, code, word", [(signal.SIGTERM, 143, "terminated"), (signal.SIGINT, 130, "interrupted")])
def test_a_signal_stops_the_run_writes_nothing_and_leaves_no_process_behind(tmp_path, sig, code, word) -> None:
    """SIGTERM or Ctrl-C while a cell is measured: what runs is stopped on the way out, the sweep says so and exits
    143 / 130 without a traceback and without writing, and none of its processes (the network's workers, a floor's
    server) outlives it."""
    import subprocess
    import time

    out = tmp_path / "bench.json"
    proc = subprocess.Popen(module_command("benchmarks.bench", "--stations", "1", "--cycles", "2ms", "--links", "ML3",
                                           "--duration", "20s", "--json", str(out), "--png", ""),
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=ROOT, env=child_env(),
                            preexec_fn=_as_at_a_terminal)
    try:
        kids: set[int] = set()
        until = time.monotonic() + 60
        while not kids and time.monotonic() < until:
            time.sleep(0.2)
            kids = _descendants(proc.pid)
        assert kids, "the sweep started no process"
        time.sleep(1.0)
        kids |= _descendants(proc.pid)
        proc.send_signal(sig)
        _, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == code, err
    assert f"bench: {word}, nothing written" in err and "Traceback" not in err
    assert not out.exists()
    until = time.monotonic() + 10
    while time.monotonic() < until and any(_alive(p) for p in kids):
        time.sleep(0.2)
    assert not [p for p in kids if _alive(p)]


def _as_at_a_terminal() -> None:
    """In the child: Ctrl-C as at a terminal. A test run started in the background (``cmd &``) inherits SIGINT
    ignored, and Python then leaves it ignored (no KeyboardInterrupt), as it should for such a job."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _alive(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False
