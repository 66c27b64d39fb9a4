"""mlink_sim.aio.realtime: what is asked for and how a refusal reads (docs/timing.md, "Real-time scheduling")."""

from __future__ import annotations

import errno
import os
import subprocess
import sys

from mlink_sim.aio import realtime


def test_cpu_plan_gives_the_master_a_cpu_of_its_own():
    assert realtime.cpu_plan({0, 1}) == ({1}, {0})
    assert realtime.cpu_plan({0, 1, 2, 3}) == ({3}, {0, 1, 2})
    assert realtime.cpu_plan({5}) == ({5}, {5})


def test_refusals_are_reported_not_raised(monkeypatch):
    def refuse(*_a):
        raise PermissionError(errno.EPERM, "Operation not permitted")

    monkeypatch.setattr(os, "sched_setscheduler", refuse)
    monkeypatch.setattr(os, "sched_setaffinity", refuse)
    text = realtime.apply(realtime.WORKER_PRIORITY, {0})
    assert text.startswith("SCHED_FIFO refused (Operation not permitted), ")
    assert text.endswith("CPU affinity refused (Operation not permitted)")


def test_granted_in_a_child_process_says_what_it_got():
    code = ("import os; from mlink_sim.aio import realtime as r; "
            "print(r.apply(r.WORKER_PRIORITY, r.cpu_plan()[1])); print(os.sched_getscheduler(0))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=30).stdout.split("\n")
    if out[0].startswith("SCHED_FIFO 30"):
        assert int(out[1]) == os.SCHED_FIFO
    else:  # not permitted here: said so, and the process kept ordinary scheduling
        assert out[0].startswith("SCHED_FIFO refused") and int(out[1]) == os.SCHED_OTHER
    assert "memory" in out[0]
