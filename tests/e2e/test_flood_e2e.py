"""A flood of strangers' datagrams beside a cyclic master (docs/cards.md, "Who may change a station"): ``mlink-sim
up`` runs the three cards at 2 ms while another process sends 200,000 commands and garbage from other ports of the
same host at the workers' station ports, as fast as it can. The kernel drops them at the workers' sockets
(connected to their master, or a socket filter), so the flood costs the master at most 1 % of the cycles of its
window and never a communications alarm (bUS). What is asserted is the master's loss in the report, not a time."""

from __future__ import annotations

import json
import re
import subprocess
import sys
import time
from pathlib import Path

import pytest

from .conftest import MLINK

pytestmark = pytest.mark.e2e

FLOOD = 200_000
CYCLE_S = 0.002
FLOOD_SCRIPT = Path(__file__).with_name("flood.py")
CONFIG = """
[network]
transmission_cycle = "2ms"

[[station]]
address = 0x21
card = "si-t3"

[[station]]
address = 0x22
card = "si-t-v7"

[[station]]
address = 0x23
card = "si-et3"
"""


def _station_ports(run_dir: Path, timeout: float = 30.0) -> list[int]:
    """The UDP ports the workers' stations listen on, from their ready lines (``0x21@127.0.0.1:PORT``)."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        found = {int(p) for log in run_dir.glob("worker-*.log")
                 for p in re.findall(r"0x2[123]@127\.0\.0\.1:(\d+)", log.read_text())}
        if len({a for log in run_dir.glob("worker-*.log") for a in re.findall(r"(0x2[123])@", log.read_text())}) == 3:
            return sorted(found)
        time.sleep(0.05)
    raise AssertionError(f"no ready line of every station in {run_dir}")


@pytest.mark.parametrize("workers", ["station", "packed"])
def test_a_flood_from_other_ports_costs_the_master_no_cycle_and_raises_no_alarm(workers: str, tmp_path: Path) -> None:
    """``--workers station``: each worker's socket is connected to its master; packed: one worker hosts the three
    stations on two ports (one per link), each with a socket filter naming both masters. ``--no-realtime``: the
    flood competes with the master and the workers on equal terms."""
    config = tmp_path / "net.toml"
    config.write_text(CONFIG)
    report, run_dir = tmp_path / "report.json", tmp_path / "run"
    argv = [*MLINK, "up", str(config), "--no-timeline", "--duration", "6s", "--no-status", "--no-realtime",
            "--report", str(report), "--run-dir", str(run_dir), "--log-level", "info"]
    if workers == "station":
        argv += ["--workers", "station"]
    up = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        assert up.stdout is not None
        head = []
        for line in up.stdout:
            head.append(line)
            if "network_up" in line:
                break
        else:
            raise AssertionError("".join(head))
        ports = _station_ports(run_dir)
        time.sleep(0.5)
        flood = subprocess.run([sys.executable, str(FLOOD_SCRIPT), str(FLOOD), *map(str, ports)],
                               capture_output=True, text=True, timeout=120)
        assert flood.returncode == 0, flood.stderr
        window = json.loads(flood.stdout)
        (tmp_path / "flood.json").write_text(flood.stdout)  # the window beside the report (docs/performance.md)
        out = up.communicate(timeout=60)[0]
    finally:
        if up.poll() is None:
            up.kill()
            up.wait()
    assert up.returncode == 0, "".join(head) + out
    doc = json.loads(report.read_text())
    cycles = window["seconds"] / CYCLE_S * 3  # the commands the three stations were due in the flood's window
    assert window["sent"] >= FLOOD * 0.9
    assert doc["missing"] <= 0.01 * cycles, (doc["missing"], cycles, window)
    for address, station in doc["station"].items():
        assert station["alarms"] == 0 and station["foreign_source"] == 0, (address, station)
