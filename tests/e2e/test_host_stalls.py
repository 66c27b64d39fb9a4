"""Host stalls from outside (docs/timing.md, "Host stalls"): the ``up`` process and a slave worker are stopped
for 20 ms at a time with SIGSTOP/SIGCONT, the way a busy host deschedules them. With the policy ``absorb`` no
command is lost and every check holds whenever the host stalled less than the bound; with ``strict`` the slaves
count the same stalls as reception failures, as the manuals' wall-clock rules say (SI-T3 Table 22)."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import time
from pathlib import Path

import pytest

from .conftest import MLINK, children_of

pytestmark = pytest.mark.e2e

CONFIG = """
[network]
name = "stalls"
transmission_cycle = "2ms"

[[station]]
address = 0x21
card = "si-t3"
params = { "b1-01" = 3, "b1-02" = 3, "C1-01" = 1.0, "C1-02" = 1.0 }

[[station]]
address = 0x22
card = "si-t-v7"
frame_size = 32
params = { "n003" = 3, "n004" = 9, "n019" = 1.0, "n020" = 1.0 }

[[timeline]]
at = "0.2s"
do = "run"
hz = 20.0

[[timeline]]
at = "3s"
expect = "output-hz"
output_hz = 20.0

[[timeline]]
at = "3.1s"
do = "stop"

[[timeline]]
at = "5s"
expect = "stopped"
"""

STOP_S = 0.020


def _hold(pid: int) -> None:
    os.kill(pid, signal.SIGSTOP)
    time.sleep(STOP_S)
    os.kill(pid, signal.SIGCONT)


def run_with_stalls(tmp_path: Path, *flags: str) -> tuple[int, dict, str]:
    config = tmp_path / "stalls.toml"
    config.write_text(CONFIG)
    report = tmp_path / "report.json"
    proc = subprocess.Popen([*MLINK, "up", str(config), "--no-status", "--workers", "1", "--log-level", "info",
                             "--report", str(report), *flags], stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                            text=True)
    lines = []
    try:
        assert proc.stdout is not None
        for line in proc.stdout:  # the stalls go into the measured span: after bring-up
            lines.append(line)
            if "network_up" in line:
                break
        time.sleep(0.5)
        for _ in range(3):  # the master's process: its clock stops
            _hold(proc.pid)
            time.sleep(0.5)
        for worker in children_of(proc.pid):  # the slave worker: its commands wait on the socket
            _hold(worker)
        out, _ = proc.communicate(timeout=60)
        out = "".join(lines) + out
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    return proc.returncode, json.loads(report.read_text()), out


def test_absorb_loses_no_command_to_stalls_within_the_bound(tmp_path):
    code, report, out = run_with_stalls(tmp_path)
    host = report["host"]
    assert host["policy"] == "absorb" and host["bound"] == 100_000_000
    assert host["by_process"]["master"]["count"] >= 3, out
    assert host["by_process"].get("worker:0", {}).get("count", 0) >= 1, (host["by_process"], out)
    if host["stall"]["max"] < host["bound"]:  # the invariant the policy promises (the host may add its own)
        assert host["stall"]["lost"] == 0 and report["missed"] == 0, out
        assert report["reception_failures"] == 0 and report["missing"] == 0, out
        assert code == 0, out
        assert "host stalls" in out and "lost (policy absorbs up to 100ms)" in out


def test_strict_counts_the_same_stalls_as_lost_cycles(tmp_path):
    code, report, out = run_with_stalls(tmp_path, "--host-stalls", "strict")
    host = report["host"]
    assert host["policy"] == "strict" and host["bound"] == 0
    assert host["stall"]["lost"] >= 3 * 9 and report["missed"] == host["stall"]["lost"], out
    assert report["reception_failures"] > 0, out
