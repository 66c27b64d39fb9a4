"""``--cpus LIST`` without ``--realtime``: each process places itself (``sched_setaffinity``) and says on stderr
what it was granted, in one line, a CPU it may not use included (docs/timing.md, "Real-time scheduling")."""

from __future__ import annotations

import os
import re
import subprocess
import time

import pytest

from .conftest import MLINK, run_cli

pytestmark = pytest.mark.e2e

ALLOWED = sorted(os.sched_getaffinity(0))
OUTSIDE = max(ALLOWED) + 64  # a CPU number no process here may use


def _affinity(pid: int) -> set[int]:
    return os.sched_getaffinity(pid)


def test_a_slave_pins_itself_and_names_a_refused_cpu():
    wanted = f"{ALLOWED[0]},{OUTSIDE}"
    proc = subprocess.Popen([*MLINK, "slave", "--card", "si-t3", "--station", "0x21", "--cpus", wanted],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert proc.stdout is not None and "ready" in proc.stdout.readline()
        assert _affinity(proc.pid) == {ALLOWED[0]}
    finally:
        proc.terminate()
        _, err = proc.communicate(timeout=10)
    lines = [line for line in err.splitlines() if "cpus:" in line]
    assert lines == [f"mlink-sim slave: cpus: CPU {ALLOWED[0]} (CPU {OUTSIDE} refused: not among those allowed, "
                     f"{','.join(map(str, ALLOWED))})"]
    assert "Traceback" not in err


def test_a_slave_refused_every_cpu_runs_on_and_says_so():
    proc = subprocess.Popen([*MLINK, "slave", "--card", "si-t3", "--station", "0x21", "--cpus", str(OUTSIDE)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert proc.stdout is not None and "ready" in proc.stdout.readline()
        assert _affinity(proc.pid) == set(ALLOWED)
    finally:
        proc.terminate()
        _, err = proc.communicate(timeout=10)
    assert f"mlink-sim slave: cpus: CPU affinity refused (CPU {OUTSIDE} not among those allowed" in err
    assert "Traceback" not in err


def test_up_places_master_and_workers_on_the_chosen_cpus_without_realtime(tmp_path):
    """The master's clock on the highest CPU of the list, the workers on the rest; stderr says what each got."""
    if len(ALLOWED) < 2:
        pytest.skip("needs two CPUs this process may use")
    cpus = f"{ALLOWED[0]},{ALLOWED[1]}"
    t0 = time.monotonic()
    r = run_cli("up", "quickstart", "--no-timeline", "--duration", "1s", "--no-status", "--no-realtime",
                "--cpus", cpus, timeout=60)
    assert r.returncode == 0, r.stderr[-2000:]
    line = next(x for x in r.stderr.splitlines() if x.startswith("cpus: "))
    assert f"master CPU {ALLOWED[1]}" in line
    workers = re.findall(r"worker:\d+ CPU (\d+)", line)
    assert workers and set(workers) == {str(ALLOWED[0])}, line
    assert time.monotonic() - t0 < 60


def test_master_alone_takes_every_chosen_cpu_and_a_bad_list_is_a_usage_error(slave, tmp_path):
    s = slave("--card", "si-t3", "--station", "0x21", "--listen", "127.0.0.1:0")
    path = tmp_path / "one.toml"
    path.write_text("[network]\nname = 'one'\ntransmission_cycle = '2ms'\n[[station]]\naddress = 0x21\n"
                    "card = 'si-t3'\n", encoding="utf-8")
    cpus = ",".join(map(str, ALLOWED[:2]))
    r = run_cli("master", str(path), "--endpoint", f"0x21=127.0.0.1:{s.port}", "--duration", "0.5s", "--no-status",
                "--no-realtime", "--cpus", cpus, timeout=60)
    assert r.returncode == 0, r.stderr[-2000:]
    assert f"cpus: master CPU {cpus}" in r.stderr
    bad = run_cli("master", str(path), "--cpus", "zero")
    assert bad.returncode == 2 and "--cpus" in bad.stderr and "CPU numbers separated by commas" in bad.stderr
    assert "Traceback" not in bad.stderr
