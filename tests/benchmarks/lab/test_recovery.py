"""benchmarks.lab.recovery and its helper benchmarks.lab.stall_inject: the figure of cycles missed per stall (from
synthetic windows), and a stall injector that always continues what it stopped (against a ``sleep`` child)."""

from __future__ import annotations

import json
import signal
import subprocess
import threading
import time
from pathlib import Path

import pytest

from mlink_sim.metrics import LatencyHistogram

from benchmarks.common import child_env, module_command
from benchmarks.lab import recovery as rec
from benchmarks.lab import stall_inject as inj

MS = 1_000_000
INJECT = module_command("benchmarks.lab.stall_inject")
ENV = child_env()  # the helpers import benchmarks from any working directory


@pytest.fixture
def sleeper():
    proc = subprocess.Popen(["sleep", "60"])
    yield proc
    proc.kill()
    proc.wait()


def _state(pid: int) -> str:
    """The process state letter of /proc/PID/stat (T: stopped)."""
    text = Path(f"/proc/{pid}/stat").read_text()
    return text[text.rindex(")") + 2]


def _window(cycles: int, stations: int, late_cycles: int):
    """A window of *cycles* cycles of *stations* answers each, those of *late_cycles* cycles 2 ms late."""
    rtt = LatencyHistogram()
    for i in range(cycles * stations):
        rtt.record(2 * MS if i < late_cycles * stations else 200_000)
    return rec.Window(MS, wall_s=cycles / 1000, started=cycles, sent=cycles * stations, rtt=rtt)


def test_what_a_stall_stops() -> None:
    pids = [10, 20, 21]  # the master (the floor's client) first, then the workers (its server)
    assert rec.stalled_pids("both", pids) == [10, 20, 21]
    assert rec.stalled_pids("master", pids) == [10]
    assert rec.stalled_pids("workers", pids) == [20, 21]


def test_with_a_lag_the_workers_are_continued_first_and_the_master_later() -> None:
    pids = [10, 20, 21]
    assert rec.injector_args("both", pids, 500_000) == ["20", "21", "--later", "500000", "10"]
    assert rec.injector_args("both", pids) == ["10", "20", "21"]
    assert rec.injector_args("workers", pids) == ["20", "21"]


def test_cycles_missed_per_stall_beyond_the_calm_rate() -> None:
    calm = _window(1000, 8, late_cycles=2)       # 0.2 % missed without stalls
    stalled = _window(2000, 8, late_cycles=4 + 5 * 3)  # the calm rate's 4, and 5 stalls of 3 cycles each
    f = rec.recovery(calm, stalled, [3 * MS, 3 * MS, 3_100_000, 3 * MS, 3 * MS], stations=8)
    assert f["missed_rate_calm"] == pytest.approx(0.002)
    assert f["missed_rate_stalled"] == pytest.approx(19 / 2000)
    assert f["cycles_per_stall"] == 3.0
    assert (f["stalls"], f["stall_median_ns"], f["stall_max_ns"]) == (5, 3 * MS, 3_100_000)


def _side(side: str, calm: list, stalled: list, stalls: int):
    """A side whose undisturbed and stalled turns are *calm* and *stalled*, added up as a run adds them."""
    r = rec.Recovery(side, 8)
    for key, windows in ((False, calm), (True, stalled)):
        for w in windows:
            rec.add_window(r.windows, key, w)
    r.stalls_ns = [3 * MS] * stalls
    return r


def test_the_table_says_what_the_simulator_loses_beyond_its_floor() -> None:
    sides = [_side(side, [_window(1000, 8, late_cycles=0)], [_window(1000, 8, late_cycles=late)], 5)
             for side, late in (("simulator", 5 * 4), ("floor", 5 * 1))]
    text = rec.table(sides)
    assert "+3.00 cycles missed per stall beyond its floor's (4.0×)" in text


def test_windows_of_one_side_add_up() -> None:
    r = _side("floor", [_window(2000, 8, late_cycles=0)],
              [_window(1000, 8, late_cycles=3), _window(1000, 8, late_cycles=3)], 6)
    assert r.windows[True].sent == 16000
    assert r.figures()["cycles_per_stall"] == 1.0


def test_the_injector_stops_each_period_and_leaves_the_process_running(sleeper) -> None:
    start = time.monotonic_ns()
    lengths = inj.inject([sleeper.pid], 5 * MS, 50 * MS, start, start + 230 * MS)
    assert len(lengths) == 4  # at 50, 100, 150 and 200 ms; one at 250 ms would end after 230 ms
    assert all(n >= 5 * MS for n in lengths)
    assert time.monotonic_ns() - start >= 230 * MS  # it lasts the window
    assert _state(sleeper.pid) != "T"


def test_the_injector_continues_the_later_processes_after_the_lag(sleeper) -> None:
    later = subprocess.Popen(["sleep", "60"])
    every = 10_000 * MS
    # one stall of 50 ms, 20 ms from now, the later process stopped 1.5 s more: long enough that this thread's
    # polling cannot miss either state on a loaded machine
    start = time.monotonic_ns() - every + 20 * MS
    result: list[list[int]] = []
    t = threading.Thread(target=lambda: result.append(
        inj.inject([sleeper.pid], 50 * MS, every, start, start + every + 1_600 * MS, [later.pid], 1_500 * MS)))
    try:
        t.start()
        deadline = time.monotonic() + 10
        while _state(later.pid) != "T" and time.monotonic() < deadline:  # both stopped …
            time.sleep(0.002)
        while _state(sleeper.pid) == "T" and time.monotonic() < deadline:  # … the first continued …
            time.sleep(0.002)
        meanwhile = _state(later.pid)
        t.join(timeout=10)
        assert meanwhile == "T"  # … while the later one stays stopped for the lag
        assert _state(later.pid) != "T" and _state(sleeper.pid) != "T"
        assert len(result[0]) == 1 and 50 * MS <= result[0][0] < 1_500 * MS  # measured to the first SIGCONT
    finally:
        later.kill()
        later.wait()
        t.join(timeout=15)


def test_the_injector_continues_a_process_gone_or_not(sleeper) -> None:
    start = time.monotonic_ns()
    lengths = inj.inject([sleeper.pid, 2 ** 22 + 1], 2 * MS, 20 * MS, start, start + 50 * MS)  # one pid unused
    assert len(lengths) == 2
    assert _state(sleeper.pid) != "T"


def test_the_helper_reports_its_stalls_as_json(sleeper) -> None:
    start = time.monotonic_ns()
    out = subprocess.run([*INJECT, str(3 * MS), str(40 * MS), str(start), str(start + 100 * MS),
                          str(sleeper.pid)], capture_output=True, text=True, timeout=30, env=ENV)
    assert out.returncode == 0, out.stderr
    report = json.loads(out.stdout)
    assert len(report["stalls_ns"]) == 2
    assert report["scheduling"]  # SCHED_FIFO where granted, else why not
    assert _state(sleeper.pid) != "T"


def test_the_helper_takes_later_processes_and_continues_them(sleeper) -> None:
    later = subprocess.Popen(["sleep", "60"])
    try:
        start = time.monotonic_ns()
        out = subprocess.run([*INJECT, str(3 * MS), str(40 * MS), str(start), str(start + 100 * MS),
                              str(sleeper.pid), "--later", str(5 * MS), str(later.pid)],
                             capture_output=True, text=True, timeout=30, env=ENV)
        assert out.returncode == 0, out.stderr
        assert len(json.loads(out.stdout)["stalls_ns"]) == 2  # at 40 and 80 ms: 80 + 3 + 5 ms ends by 100 ms
        assert _state(sleeper.pid) != "T" and _state(later.pid) != "T"
    finally:
        later.kill()
        later.wait()


def test_a_terminated_helper_continues_what_it_stopped(sleeper) -> None:
    every = 30_000 * MS  # a stall of 20 s from about now on: terminated in the middle of it
    start = time.monotonic_ns() - every
    helper = subprocess.Popen([*INJECT, str(20_000 * MS), str(every), str(start),
                               str(start + 3 * every), str(sleeper.pid)], stdout=subprocess.PIPE, env=ENV)
    deadline = time.monotonic() + 10
    while _state(sleeper.pid) != "T" and time.monotonic() < deadline:
        time.sleep(0.01)
    assert _state(sleeper.pid) == "T"
    helper.send_signal(signal.SIGTERM)
    assert helper.wait(timeout=10) == 143
    assert _state(sleeper.pid) != "T"


@pytest.mark.parametrize("args", [["1", "2"], ["5", "5", "0", "10", "1"], ["x", "10", "0", "10", "1"],
                                  ["5", "10", "0", "10", "1", "--later"], ["5", "10", "0", "10", "1", "--later", "5"],
                                  ["5", "10", "0", "10", "1", "--later", "6", "2"]])
def test_the_helper_refuses_bad_arguments(args) -> None:
    out = subprocess.run([*INJECT, *args], capture_output=True, text=True, timeout=30, env=ENV)
    assert out.returncode == 2 and "usage" in out.stderr


@pytest.mark.parametrize("option, reason", [
    (["--stall", "600ms"], "shorter than --every"),
    (["--duration", "600ms"], "two --every periods"),
    (["--link", "ML2", "--stations", "31"], "at most 30 stations"),
    (["--link", "ML9"], "ML2 or ML3"),
    (["--stall", "soon"], "--stall"),
    (["--who", "master", "--lag", "500us"], "--lag needs --who both"),
    (["--lag", "498ms"], "--stall + --lag shorter than --every"),
    (["--json", "/nonexistent-dir/r.json"], "--json: no directory /nonexistent-dir"),
])
def test_bad_options_exit_2_with_the_reason(option, reason) -> None:
    out = subprocess.run(module_command("benchmarks.lab.recovery", *option), capture_output=True, text=True,
                         timeout=60, env=ENV)
    assert out.returncode == 2 and reason in out.stderr


def test_a_side_that_missed_more_undisturbed_is_flagged() -> None:
    r = _side("floor", [_window(1000, 8, late_cycles=5)],  # a host hiccup in the undisturbed turn
              [_window(1000, 8, late_cycles=2)], 2)
    assert r.figures()["cycles_per_stall"] < 0
    assert "! floor: it missed more undisturbed (0.50 %) than with the stalls" in rec.table([r])
