"""benchmarks.lab.late_causes: late answers grouped into late cycles, and each named by what the perf samples show in
its window (synthetic samples: no perf, no network)."""

from __future__ import annotations

import asyncio
import os
from pathlib import Path

from benchmarks.lab import late_causes as lc

MS = 1_000_000
OURS = {100, 101}  # the master and its worker
NAMES = {75: "kdamond.0", 7591: "memfd:sealed-91"}


def _samples(start: int, end: int, cpu: int, pid: int, sym: str = "main") -> list:
    """A sample each 50 µs of [start, end) on *cpu*."""
    return [lc.Sample(t, cpu, pid, sym) for t in range(start, end, lc.SAMPLE_NS)]


def _cycle(sent: int = 10 * MS, rtt: int = 2 * MS):
    log = lc.LateLog(capacity=64)
    for _ in range(62):  # one cycle's 62 answers, all late
        log.add(sent + rtt, rtt)
    [cycle] = log.cycles()
    return cycle


def test_perf_script_lines_become_samples_by_time() -> None:
    lines = [  # perf script -F pid,cpu,time,event,ip,sym (the comm taken off by the reader)
        "8464 [000] 12803.132803:                cpu-clock:  ffffffff8225295b pv_native_safe_halt",
        "75 [001] 12803.132700:                cpu-clock:  ffffffff81aa1234 damon_pa_apply_scheme",
        "10508 [001] 12803.132900:                cpu-clock:      7f9b3b77351f",
        "10502 [000] 12803.132800:       sched:sched_switch:  ffffffff82258a08 __schedule",
        "not a sample line",
    ]
    assert lc.parse_samples(lines) == [lc.Sample(12803132700000, 1, 75, "damon_pa_apply_scheme"),
                                       lc.Sample(12803132803000, 0, 8464, "pv_native_safe_halt"),
                                       lc.Sample(12803132900000, 1, 10508, "")]


def test_late_answers_of_one_cycle_are_one_late_cycle_and_cycles_apart_are_two() -> None:
    log = lc.LateLog(capacity=4)
    log.add(12 * MS, 2 * MS)        # sent at 10 ms
    log.add(12 * MS + 50_000, 2 * MS)  # sent 50 µs later: the same cycle
    log.add(13 * MS, 2 * MS)        # sent at 11 ms: the next cycle
    log.add(13 * MS, 2 * MS)
    log.add(14 * MS, 2 * MS)        # no room: counted, not kept
    cycles = log.cycles()
    assert [(c.sent, c.answers, c.end) for c in cycles] == [(10 * MS, 2, 12 * MS + 50_000), (11 * MS, 2, 13 * MS)]
    assert log.dropped == 1


def test_a_host_task_holding_a_cpu_is_named() -> None:
    c = _cycle()
    samples = (_samples(10 * MS, 11_800_000, 0, 75, "damon_pa_apply_scheme")  # 1.8 ms of 2 ms on CPU 0
               + _samples(11_800_000, 12 * MS, 0, 101) + _samples(10 * MS, 12 * MS, 1, 0))
    lc.attribute([c], sorted(samples, key=lambda s: s.t), OURS, 2, NAMES)
    assert c.cause == "held by kdamond.0" and c.shares["held by kdamond.0"] == 0.9


def test_a_cpu_without_samples_is_a_vcpu_not_run() -> None:
    c = _cycle()
    samples = _samples(10 * MS, 12 * MS, 0, 100) + _samples(10 * MS, 10_500_000, 1, 101)  # CPU 1: 1.5 ms gone
    lc.attribute([c], sorted(samples, key=lambda s: s.t), OURS, 2, NAMES)
    assert c.cause == "vCPU not running" and c.shares["vCPU not running"] == 0.75


def test_the_collector_in_our_processes_is_named_and_our_own_work_otherwise() -> None:
    gc, busy, idle = _cycle(), _cycle(), _cycle()
    lc.attribute([gc], _samples(10 * MS, 12 * MS, 0, 100, "gc_collect_main")
                 + _samples(10 * MS, 12 * MS, 1, 0), OURS, 2, NAMES)
    lc.attribute([busy], sorted(_samples(10 * MS, 12 * MS, 0, 100) + _samples(10 * MS, 12 * MS, 1, 101),
                                key=lambda s: s.t), OURS, 2, NAMES)
    lc.attribute([idle], _samples(10 * MS, 12 * MS, 0, 0) + _samples(10 * MS, 12 * MS, 1, 0), OURS, 2, NAMES)
    assert (gc.cause, busy.cause, idle.cause) == ("garbage collection", "own work", "unexplained")


def test_the_summary_counts_cycles_and_answers_per_cause_as_a_share_of_all_answers() -> None:
    a, b, c = _cycle(), _cycle(), _cycle()
    a.cause = b.cause = "held by kdamond.0"
    summary = lc.summarise([a, b, c], 62_000)
    assert summary == {"held by kdamond.0": {"cycles": 2, "answers": 124, "pct_of_answers": 0.2},
                       "unexplained": {"cycles": 1, "answers": 62, "pct_of_answers": 0.1}}


def test_without_perf_or_root_it_exits_2_and_says_why(monkeypatch, capsys) -> None:
    monkeypatch.setattr("sys.argv", ["late_causes.py", "--duration", "1s"])
    monkeypatch.setattr(lc.shutil, "which", lambda name: None)
    assert lc.main() == 2
    assert "perf is not installed" in capsys.readouterr().err
    monkeypatch.setattr(lc.shutil, "which", lambda name: "/usr/bin/perf")
    monkeypatch.setattr(lc.os, "geteuid", lambda: 1000)
    assert lc.main() == 2
    assert "needs root" in capsys.readouterr().err
    monkeypatch.setattr("sys.argv", ["late_causes.py", "--stations", "63"])
    assert lc.main() == 2
    assert "--stations 1–62" in capsys.readouterr().err


# --sched: where the answering process was when the commands went out (synthetic scheduler events)
WORKER = 101


def test_perf_script_scheduler_lines_become_switches_and_wakeups_by_time() -> None:
    lines = [  # perf script -F trace:comm,pid,cpu,time,event,trace (the comm taken off by the reader)
        "101 [001] 100.000200: sched:sched_switch: prev_comm=python3 prev_pid=101 prev_prio=120 prev_state=S ==> "
        "next_comm=swapper/1 next_pid=0 next_prio=120",
        "0 [001] 100.000100: sched:sched_wakeup: comm=python3 pid=101 prio=120 target_cpu=001",
        "75 [000] 100.000300: sched:sched_switch: prev_comm=kdamond.0 prev_pid=75 prev_prio=120 prev_state=R+ ==> "
        "next_comm=kworker/0:2 mm_percpu next_pid=12 next_prio=120",
        "8464 [000] 100.000400:                cpu-clock:  ffffffff8225295b pv_native_safe_halt",
    ]
    switches, wakeups = lc.parse_sched(lines)
    assert switches == [lc.Switch(100000200000, 1, 101, "S", 0), lc.Switch(100000300000, 0, 75, "R+", 12)]
    assert wakeups == [lc.Wakeup(100000100000, 101, 1)]


def _late(sent: int):
    return lc.LateCycle(sent, 8, sent + 300_000)


def test_the_answerer_s_state_at_the_send_running_waiting_or_asleep_and_how_late_it_was_woken() -> None:
    S, W = lc.Switch, lc.Wakeup
    switches = [
        S(1 * MS, 1, 0, "R", WORKER),             # 1 ms: in (its poll)
        S(1 * MS + 80_000, 1, WORKER, "S", 0),    # out asleep
        S(2 * MS + 70_000, 1, 0, "R", WORKER),    # woken 50 µs after the 2 ms send, on a CPU 70 µs after it
        S(2 * MS + 150_000, 1, WORKER, "R+", 75),  # preempted by kdamond.0
        S(4 * MS, 1, 75, "S", WORKER),
        S(4 * MS + 50_000, 1, WORKER, "S", 0),
        S(5 * MS + 160_000, 1, 0, "R", WORKER),
        S(5 * MS + 200_000, 1, WORKER, "S", 0),
        S(6 * MS + 30_000, 1, 0, "R", WORKER),
        S(6 * MS + 60_000, 1, 1234, "R", 0),       # another task: ignored
        S(7 * MS + 500_000, 1, WORKER, "S", 0),
        S(8 * MS + 90_000, 1, 0, "R", WORKER),     # woken at 7.95 ms, on a CPU only 90 µs after the 8 ms send
    ]
    wakeups = [W(2 * MS + 50_000, WORKER, 1), W(5 * MS + 120_000, WORKER, 1), W(6 * MS + 20_000, WORKER, 1),
               W(6 * MS + 25_000, 1234, 0), W(7 * MS + 950_000, WORKER, 1)]
    cycles = [_late(t) for t in (1 * MS + 40_000, 2 * MS, 3 * MS, 5 * MS, 6 * MS, 7 * MS, 8 * MS)]
    lc.answerer_states(cycles, switches, wakeups, {WORKER})
    assert [(c.answerer, c.woken_us, c.running_us) for c in cycles] == [
        ("running at the send", None, None),
        ("asleep, woken 40–100 µs after", 50.0, 70.0),
        ("waiting for a CPU at the send", None, 1000.0),
        ("asleep, woken over 100 µs after", 120.0, 160.0),
        ("asleep, woken within 40 µs", 20.0, 30.0),
        ("running at the send", None, None),  # on a CPU since 6.03 ms
        ("waiting for a CPU at the send", None, 90.0),
    ]
    nothing = [_late(1 * MS)]
    lc.answerer_states(nothing, [], [], {WORKER})
    assert nothing[0].answerer == "not seen"
    summary = lc.summarise(cycles, 8_000, "answerer")
    assert summary["running at the send"] == {"cycles": 2, "answers": 16, "pct_of_answers": 0.2}


def test_the_floor_s_processes_are_its_client_and_server_never_perf(monkeypatch) -> None:
    """The floor's processes are the ones its window names (its client, its server); perf, started before the
    window, is a host task, not the floor's."""
    made, seen = [], {}

    class Proc:
        def __init__(self, argv, **kwargs) -> None:
            self.pid = 5000 + len(made)
            made.append(argv[0])

    async def floor_window(*args, during, **kwargs) -> None:
        await during([os.getpid(), 5001], 0.0)  # the client, the server

    def judge(side, log, answers, samples, names, ours, events=([], []), answerers=None):
        seen.update(ours=ours, answerers=answerers)
        return {}

    monkeypatch.setattr(lc.subprocess, "Popen", Proc)
    monkeypatch.setattr(lc._Perf, "samples", lambda self: ([], {}, ([], [])))
    monkeypatch.setattr(lc.floor, "floor_window", floor_window)
    monkeypatch.setattr(lc, "_judge", judge)
    monkeypatch.setattr(lc, "PERF_LEAD_S", 0.0)
    asyncio.run(lc._floor(8, 32, 250_000, 1.0, Path("/tmp"), sched=True))
    perf_pid, server_pid = 5000, 5001
    assert made == ["perf"]
    assert seen["ours"] == {os.getpid(), server_pid} and seen["answerers"] == {server_pid}
    assert perf_pid not in seen["ours"]
