"""mlink_sim.aio.timing.realtime: what is asked for and how a refusal reads (docs/timing.md, "Real-time scheduling")."""

from __future__ import annotations

import errno
import os
import struct
import subprocess
import sys
from pathlib import Path

import pytest

from mlink_sim.aio.timing import realtime


def test_cpu_plan_gives_the_master_a_cpu_of_its_own():
    assert realtime.cpu_plan({0, 1}) == ({1}, {0})
    assert realtime.cpu_plan({0, 1, 2, 3}) == ({3}, {0, 1, 2})
    assert realtime.cpu_plan({5}) == ({5}, {5})


def test_cpu_lists_read_and_write_as_the_slave_cpus_flag_takes_them():
    assert realtime.parse_cpus("0") == {0}
    assert realtime.parse_cpus("2,0") == {0, 2}
    assert realtime.format_cpus({2, 0}) == "0,2"
    for bad in ("", "a", "0,,1", "-1", "0-3"):
        with pytest.raises(ValueError, match="CPU"):
            realtime.parse_cpus(bad)


def test_a_session_plans_the_cpus_once_so_a_restarted_worker_keeps_off_the_masters(monkeypatch, tmp_path):
    """The session plans (master CPUs, worker CPUs) when it is made, before its master takes its CPU. A worker it
    starts (a restart included) is started on the CPUs the session had (``unplace_child``) and plans the same;
    CPUs the user chose (``--cpus``) are passed on, with or without real time."""
    from mlink_sim.aio.run import session as session_mod
    from mlink_sim.config import load_config

    affinity = {0, 1}
    monkeypatch.setattr(realtime.os, "sched_getaffinity", lambda pid: set(affinity))
    path = Path(__file__).parents[3] / "configs" / "quickstart.toml"
    s = session_mod.NetworkSession(load_config(path), path, realtime=True)
    assert s.cpus == ({1}, {0})
    affinity = {1}  # the master pinned itself: what a worker started now would inherit
    assert s._realtime_flags() == ["--realtime"]
    assert session_mod.NetworkSession(load_config(path), path)._realtime_flags() == []
    chosen = session_mod.NetworkSession(load_config(path), path, cpus={0, 1, 2})
    assert chosen.cpus == ({2}, {0, 1}) and chosen._realtime_flags() == ["--cpus", "0,1"]
    chosen = session_mod.NetworkSession(load_config(path), path, realtime=True, cpus={3})
    assert chosen.cpus == ({3}, {3}) and chosen._realtime_flags() == ["--realtime", "--cpus", "3"]


def test_pin_takes_the_allowed_cpus_and_names_the_refused_ones(monkeypatch):
    """``--cpus`` places a process with ``sched_setaffinity`` on the CPUs it may use; a CPU outside that set (a
    container's cpuset, ``taskset``) is named in the one line that says what was granted, never raised."""
    placed: list[set[int]] = []
    monkeypatch.setattr(realtime, "_allowed", None)
    monkeypatch.setattr(realtime.os, "sched_getaffinity", lambda pid: {0, 1})
    monkeypatch.setattr(realtime.os, "sched_setaffinity", lambda _pid, cpus: placed.append(set(cpus)))
    assert realtime.pin({1}) == "CPU 1" and placed == [{1}]
    assert realtime.pin({0, 7}) == "CPU 0 (CPU 7 refused: not among those allowed, 0,1)" and placed[-1] == {0}
    assert realtime.pin({7, 8}) == "CPU affinity refused (CPU 7,8 not among those allowed, 0,1)"
    assert len(placed) == 2


def test_chosen_cpus_are_placed_under_realtime_without_the_wakeup_latency(monkeypatch, tmp_path):
    placed: list[set[int]] = []
    monkeypatch.setattr(realtime, "_allowed", None)
    monkeypatch.setattr(os, "sched_setscheduler", lambda *_a: None)
    monkeypatch.setattr(realtime.os, "sched_getaffinity", lambda pid: {0, 1})
    monkeypatch.setattr(os, "sched_setaffinity", lambda _pid, cpus: placed.append(set(cpus)))
    monkeypatch.setattr(realtime, "PM_QOS_PATH", str(tmp_path / "no-such-device"))
    text = realtime.apply(realtime.WORKER_PRIORITY, {0}, placed=True)
    assert placed == [{0}] and text.endswith("CPU wake-up latency refused (No such file or directory), CPU 0")


def _apply_held(monkeypatch, tmp_path, priority: int, cpus: set[int]) -> str:
    """``realtime.apply`` with the wake-up latency request granted (a file standing in for the PM QoS device),
    released afterwards."""
    device = tmp_path / "cpu_dma_latency"
    device.write_bytes(b"")
    monkeypatch.setattr(realtime, "PM_QOS_PATH", str(device))
    try:
        return realtime.apply(priority, cpus)
    finally:
        realtime.release_wakeup_latency(str(device))


def test_refusals_are_reported_not_raised(monkeypatch, tmp_path):
    def refuse(*_a):
        raise PermissionError(errno.EPERM, "Operation not permitted")

    monkeypatch.setattr(os, "sched_setscheduler", refuse)
    monkeypatch.setattr(os, "sched_setaffinity", refuse)
    monkeypatch.setattr(realtime, "PM_QOS_PATH", str(tmp_path / "no-such-device"))
    text = realtime.apply(realtime.WORKER_PRIORITY, {0})
    assert text.startswith("SCHED_FIFO refused (Operation not permitted), ")
    assert "CPU wake-up latency refused (No such file or directory)" in text
    assert text.endswith("CPUs left to the kernel (no wake-up latency held)")  # not even asked: see below
    text = _apply_held(monkeypatch, tmp_path, realtime.WORKER_PRIORITY, {0})
    assert "CPU wake-up latency 0 µs" in text and text.endswith("CPU affinity refused (Operation not permitted)")


def test_the_cpus_are_placed_only_where_the_wakeup_latency_is_held(monkeypatch, tmp_path):
    """Apart, each command and answer wakes the other CPU; without the hold that CPU has halted and the round trip
    grows (docs/performance.md), so the kernel keeps the placement."""
    placed: list[set[int]] = []
    monkeypatch.setattr(os, "sched_setscheduler", lambda *_a: None)
    monkeypatch.setattr(os, "sched_setaffinity", lambda _pid, cpus: placed.append(set(cpus)))
    monkeypatch.setattr(realtime, "PM_QOS_PATH", str(tmp_path / "no-such-device"))
    text = realtime.apply(realtime.MASTER_PRIORITY, {1})
    assert placed == [] and text.endswith("CPUs left to the kernel (no wake-up latency held)")
    text = _apply_held(monkeypatch, tmp_path, realtime.MASTER_PRIORITY, {1})
    assert placed == [{1}]
    assert text.startswith("SCHED_FIFO 40, ") and text.endswith("CPU wake-up latency 0 µs, CPU 1")


def test_wakeup_latency_request_is_an_s32_zero_held_open_until_released(tmp_path):
    device = tmp_path / "cpu_dma_latency"  # a file standing in for the PM QoS device: what is written, and when
    device.write_bytes(b"")
    try:
        assert realtime.hold_wakeup_latency(str(device)) == "CPU wake-up latency 0 µs"
        assert realtime.wakeup_latency_held(str(device))
        assert device.read_bytes() == b"\0\0\0\0"  # Documentation/power/pm_qos_interface.rst: a signed 32-bit value, in µs
        fd = realtime._held[str(device)]
        assert realtime.hold_wakeup_latency(str(device)) == "CPU wake-up latency 0 µs"  # held once, not reopened
        assert realtime._held[str(device)] == fd and device.stat().st_size == 4
        os.fstat(fd)  # still open: the request stands while the process lives
    finally:
        realtime.release_wakeup_latency(str(device))
    assert not realtime.wakeup_latency_held(str(device))
    with pytest.raises(OSError):
        os.fstat(fd)  # closed: the kernel withdraws the request
    realtime.release_wakeup_latency(str(device))  # nothing held: nothing to do


def test_wakeup_latency_on_this_kernel_reads_back_zero_while_held():
    """On the real device (root): while a process holds its request, the device reads back the machine's
    effective constraint, 0 µs; without permission the refusal says why."""
    code = ("import struct; from mlink_sim.aio.timing import realtime as r; print(r.hold_wakeup_latency()); "
            "print(struct.unpack('=i', open(r.PM_QOS_PATH, 'rb').read(4))[0] if r.wakeup_latency_held() else '-'); "
            "print(r.wakeup_latency_limit())")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=30).stdout.split("\n")
    if out[0] == "CPU wake-up latency 0 µs":
        assert out[1] == "0" and out[2] == "0"  # wakeup_latency_limit reads the same
    else:
        assert out[0].startswith("CPU wake-up latency refused (") and out[2] == "None"  # unreadable: unknown


def test_the_wakeup_latency_limit_is_the_device_s_s32_or_none(tmp_path):
    """What the kernel holds for the whole system: the signed 32-bit value the device reads back (µs; 0: idle CPUs
    poll); None where it cannot be read (missing, root's only) or reads short."""
    device = tmp_path / "cpu_dma_latency"
    device.write_bytes(struct.pack("=i", 2_000_000_000))  # PM_QOS_DEFAULT_VALUE: no request held
    assert realtime.wakeup_latency_limit(str(device)) == 2_000_000_000
    device.write_bytes(struct.pack("=i", 0))
    assert realtime.wakeup_latency_limit(str(device)) == 0
    device.write_bytes(b"\0\0")
    assert realtime.wakeup_latency_limit(str(device)) is None
    assert realtime.wakeup_latency_limit(str(tmp_path / "missing")) is None


def test_granted_in_a_child_process_says_what_it_got():
    code = ("import os; from mlink_sim.aio.timing import realtime as r; "
            "print(r.apply(r.WORKER_PRIORITY, r.cpu_plan()[1])); print(os.sched_getscheduler(0))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=30).stdout.split("\n")
    if out[0].startswith("SCHED_FIFO 30"):
        assert int(out[1]) == os.SCHED_FIFO
    else:  # not permitted here: said so, and the process kept ordinary scheduling
        assert out[0].startswith("SCHED_FIFO refused") and int(out[1]) == os.SCHED_OTHER
    assert "memory" in out[0]


def test_a_second_session_of_one_process_plans_from_the_cpus_it_had_before_it_placed_itself(monkeypatch, tmp_path):
    """A program that opens a network after its master placed itself (``run_up`` twice): planned from the
    affinity the master had just narrowed to its one CPU, every worker went onto it too, under the master's
    higher priority (a starved worker: 8 stations of 8 not up, once in six bring-ups here)."""
    affinity = {0, 1}
    monkeypatch.setattr(realtime, "_allowed", None)
    monkeypatch.setattr(os, "sched_setscheduler", lambda *_a: None)
    monkeypatch.setattr(os, "sched_getaffinity", lambda _pid: set(affinity))

    def place(_pid: int, cpus: set[int]) -> None:
        nonlocal affinity
        affinity = set(cpus)

    monkeypatch.setattr(os, "sched_setaffinity", place)
    master, workers = realtime.cpu_plan()
    assert (master, workers) == ({1}, {0})
    assert _apply_held(monkeypatch, tmp_path, realtime.MASTER_PRIORITY, master).endswith("CPU 1")
    assert affinity == {1} and realtime.allowed_cpus() == {0, 1}
    assert realtime.cpu_plan() == ({1}, {0})  # the next session's plan: the workers still apart
    _apply_held(monkeypatch, tmp_path, realtime.MASTER_PRIORITY, master)  # placed again: still what it had first
    assert realtime.allowed_cpus() == {0, 1}


def test_a_child_of_a_placed_process_starts_unplaced(monkeypatch):
    """``unplace_child`` (a worker's ``preexec_fn``): ordinary scheduling and every CPU the parent had before it
    placed itself; a restarted worker otherwise began at the master's SCHED_FIFO 40 on the master's CPU, and the
    master's clock stalled 170–270 ms (docs/timing.md, "Real-time scheduling")."""
    calls: list[tuple[str, object]] = []
    monkeypatch.setattr(os, "sched_setscheduler", lambda _pid, policy, _param: calls.append(("policy", policy)))
    monkeypatch.setattr(os, "sched_setaffinity", lambda _pid, cpus: calls.append(("cpus", set(cpus))))
    monkeypatch.setattr(os, "sched_getscheduler", lambda _pid: os.SCHED_OTHER)
    monkeypatch.setattr(realtime, "_allowed", None)
    realtime.unplace_child()
    assert calls == []  # never placed, ordinary: nothing to undo
    monkeypatch.setattr(realtime, "_allowed", {0, 1})
    realtime.unplace_child()
    assert calls == [("policy", os.SCHED_OTHER), ("cpus", {0, 1})]

    def refuse(*_a):
        raise PermissionError(errno.EPERM, "Operation not permitted")

    monkeypatch.setattr(os, "sched_setscheduler", refuse)
    realtime.unplace_child()  # a refusal leaves what was inherited, and says nothing


def test_withdraw_undoes_what_apply_asked_for(monkeypatch, tmp_path):
    """``withdraw`` (a benchmark after a partial refusal, so that its floor and network run alike): the
    wake-up latency request is let go, ordinary scheduling and every CPU the process had come back."""
    calls: list[tuple[str, object]] = []
    monkeypatch.setattr(os, "sched_setscheduler", lambda _pid, policy, _param: calls.append(("policy", policy)))
    monkeypatch.setattr(os, "sched_getaffinity", lambda _pid: {0, 1})
    monkeypatch.setattr(os, "sched_setaffinity", lambda _pid, cpus: calls.append(("cpus", set(cpus))))
    monkeypatch.setattr(realtime, "_allowed", None)
    device = tmp_path / "cpu_dma_latency"
    device.write_bytes(b"")
    monkeypatch.setattr(realtime, "PM_QOS_PATH", str(device))
    assert realtime.apply(realtime.MASTER_PRIORITY, {1}).endswith("CPU wake-up latency 0 µs, CPU 1")
    assert realtime.wakeup_latency_held() and calls == [("policy", os.SCHED_FIFO), ("cpus", {1})]
    realtime.withdraw()
    assert not realtime.wakeup_latency_held()
    assert calls[2:] == [("policy", os.SCHED_OTHER), ("cpus", {0, 1})]


def test_a_worker_process_is_unplaced_before_it_starts(monkeypatch):
    from mlink_sim.aio.run import supervisor

    done: list[str] = []
    monkeypatch.setattr(supervisor.os, "setpgid", lambda *_a: done.append("group"))
    monkeypatch.setattr(supervisor, "die_with_parent", lambda: done.append("dies with parent"))
    monkeypatch.setattr(supervisor, "unplace_child", lambda: done.append("unplaced"))
    supervisor.child_setup()
    assert done == ["group", "dies with parent", "unplaced"]


def test_the_yield_after_a_send_is_the_schedulers_yield() -> None:
    assert realtime.yield_after_send() is getattr(os, "sched_yield", None)
