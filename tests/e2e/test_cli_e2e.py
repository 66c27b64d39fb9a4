"""End-to-end over real UDP on loopback: slave, probe, master, up (port 0 everywhere, bounded time)."""

from __future__ import annotations

import json
import re
import signal
import subprocess
import time
from pathlib import Path

import jsonschema
import pytest

from mlink_sim.metrics import REPORT_SCHEMA

from .conftest import MLINK, assert_held, children_of, run_cli, wait_gone

pytestmark = pytest.mark.e2e

CONFIG = """
[network]
name = "e2e"
transmission_cycle = "2ms"

[[station]]
address = 0x21
card = "si-t3"
params = { "b1-01" = 3, "b1-02" = 3, "C1-01" = 1.0, "C1-02" = 1.0 }
load = { kind = "fan" }

[[station]]
address = 0x23
card = "si-et3"
params = { "b1-01" = 3, "b1-02" = 3, "C1-01" = 1.0, "C1-02" = 1.0 }
load = { kind = "fan" }

[[timeline]]
at = "0.2s"
do = "run"
hz = 20.0

[[timeline]]
at = "2s"
expect = "output-hz"
output_hz = 20.0

[[timeline]]
at = "2.1s"
do = "stop"

[[timeline]]
at = "3.5s"
expect = "stopped"
"""


@pytest.fixture
def config(tmp_path: Path) -> Path:
    path = tmp_path / "e2e.toml"
    path.write_text(CONFIG)
    return path


def test_slave_rejects_bad_input_with_exit_2() -> None:
    r = run_cli("slave", "--card", "si-t3", "--station", "0x21", "--param", "C1-01=99999")
    assert r.returncode == 2 and "C1-01" in r.stderr and "Traceback" not in r.stderr
    r = run_cli("slave", "--card", "si-t3", "--station", "0x21", "--param", "Q9-99=1")
    assert r.returncode == 2 and "unknown parameter" in r.stderr
    r = run_cli("slave", "--card", "si-t3", "--station", "0x21", "--frame-size", "64")
    assert r.returncode == 2 and "frame size 64" in r.stderr
    r = run_cli("slave", "--card", "si-t3", "--station", "0x21", "--bogus")
    assert r.returncode == 2 and "No such option" in r.stderr
    r = run_cli("slave", "--card", "si-t3", "--station", "0x21", "--arrival-poll", "soon")
    assert r.returncode == 2 and "--arrival-poll" in r.stderr and "'auto', 'off' or a lead" in r.stderr
    r = run_cli("slave", "--card", "si-t3", "--station", "0x21", "--realtime", "--cpus", "zero")
    assert r.returncode == 2 and "--cpus" in r.stderr and "CPU numbers separated by commas" in r.stderr
    assert "Traceback" not in r.stderr


def test_probe_answers_from_a_live_slave_and_fails_on_a_dead_port(slave) -> None:
    s = slave("--card", "si-t3", "--station", "0x21", "--listen", "127.0.0.1:0")
    ok = run_cli("probe", f"127.0.0.1:{s.port}", "--station", "0x21", "--timeout", "3")
    assert ok.returncode == 0, ok.stderr
    assert "MECHATROLINK-II" in ok.stdout
    wrong = run_cli("probe", f"127.0.0.1:{s.port}", "--station", "0x22", "--timeout", "0.5")
    assert wrong.returncode == 1 and "no valid answer" in wrong.stderr
    s.stop()
    dead = run_cli("probe", f"127.0.0.1:{s.port}", "--station", "0x21", "--timeout", "0.5")
    assert dead.returncode == 1


def test_up_runs_the_timeline_and_writes_a_valid_report(config: Path, tmp_path: Path) -> None:
    report = tmp_path / "report.json"
    r = run_cli("up", str(config), "--no-status", "--report", str(report), "--assert", "missed_rate < 0.5",
                "--assert", "station[0x21].sent > 100", timeout=90)
    assert_held(r)
    doc = json.loads(report.read_text())
    jsonschema.validate(doc, REPORT_SCHEMA)
    assert doc["rtt"]["count"] > 100
    assert {c["ok"] for c in doc["checks"]} == {True} and len(doc["checks"]) == 4
    assert doc["station"]["0x21"]["answered"] > 0 and doc["station"]["0x23"]["answered"] > 0
    assert doc["meta"]["measured_from"] == "bring-up done"  # figures count from the end of bring-up by default


def test_up_assertions_fail_with_the_bound_and_the_measured_value(config: Path, tmp_path: Path) -> None:
    report = tmp_path / "report.json"
    r = run_cli("up", str(config), "--no-status", "--duration", "1s", "--assert", "rtt.p99 < 1ns",
                "--include-bringup", "--report", str(report), timeout=60)
    assert r.returncode == 1
    assert "rtt.p99 < 1ns failed: measured" in r.stdout
    doc = json.loads(report.read_text())
    assert doc["meta"]["measured_from"] == "start" and doc["meta"]["duration_s"] >= 1.0
    bad = run_cli("up", str(config), "--assert", "rtt.p99 <")
    assert bad.returncode == 2 and "--assert" in bad.stderr


def test_up_bad_config_is_exit_2(tmp_path: Path) -> None:
    path = tmp_path / "bad.toml"
    path.write_text(CONFIG.replace('card = "si-et3"', 'card = "si-et4"'))
    r = run_cli("up", str(path))
    assert r.returncode == 2 and "bad.toml: station[1].card" in r.stderr and "Traceback" not in r.stderr


def test_up_bad_workers_is_exit_2_and_says_what_is_expected(config: Path) -> None:
    r = run_cli("up", str(config), "--workers", "two")
    assert r.returncode == 2 and "Traceback" not in r.stderr
    assert "expected a number of processes (≥ 1), 'auto' or 'station', got 'two'" in r.stderr


def test_master_alone_against_slaves_started_elsewhere(config: Path, slave) -> None:
    # the master is ours, as in a compose testbed: the slaves forgive its stalls (docs/timing.md, "Host stalls")
    a = slave("--config", str(config), "--only", "0x21", "--host-stalls", "absorb")
    b = slave("--config", str(config), "--only", "0x23", "--host-stalls", "absorb")
    r = run_cli("master", str(config), "--no-status", "--endpoint", f"0x21=127.0.0.1:{a.port}",
                "--endpoint", f"0x23=127.0.0.1:{b.port}", timeout=60)
    assert_held(r)
    missing = run_cli("master", str(config))
    assert missing.returncode == 2 and "no endpoint for station" in missing.stderr


def test_killed_slave_is_reported_restarted_and_the_rest_keeps_cycling(tmp_path: Path) -> None:
    cfg = tmp_path / "kill.toml"
    cfg.write_text(CONFIG.split("[[timeline]]")[0] + """
[[timeline]]
at = "0.5s"
station = 0x21
do = "kill-slave"

[[timeline]]
at = "4s"
expect = "phase"
phase = 3
""")
    report = tmp_path / "r.json"
    proc = subprocess.Popen([*MLINK, "up", str(cfg), "--no-status", "--report", str(report)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    time.sleep(2.0)
    kids = children_of(proc.pid)
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == 0, out + err
    assert "exited with code" in out  # the death is reported
    doc = json.loads(report.read_text())
    other = doc["station"]["0x23"]
    assert other["answered"] > 0.9 * other["sent"]  # the rest of the network kept cycling
    assert not wait_gone(kids), "worker processes left behind"


def test_sigterm_stops_everything_without_orphans(config: Path) -> None:
    proc = subprocess.Popen([*MLINK, "up", str(config), "--no-status", "--duration", "60s"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 20
    kids: list[int] = []
    while time.monotonic() < deadline and len(kids) < 2:
        time.sleep(0.2)
        kids = children_of(proc.pid)
    assert len(kids) == 2
    time.sleep(1.5)
    proc.send_signal(signal.SIGTERM)
    out, err = proc.communicate(timeout=30)
    assert "Traceback" not in err
    assert not wait_gone(kids), "worker processes left behind"


PACKED = """
[network]
name = "packed"
transmission_cycle = "2ms"
""" + "".join(f"""
[[station]]
address = 0x{a:02X}
card = "si-t3"
params = {{ "b1-01" = 3, "b1-02" = 3 }}
""" for a in (0x21, 0x22, 0x23)) + """
[[timeline]]
at = "0.5s"
station = 0x22
do = "kill-slave"
""" + "".join(f"""
[[timeline]]
at = "4s"
station = 0x{a:02X}
expect = "phase"
phase = 3
""" for a in (0x21, 0x22, 0x23))


def test_a_packed_worker_shares_one_port_and_keeps_it_when_restarted(tmp_path: Path) -> None:
    """`up` packs the stations of one link into one worker on one port (docs/cards.md, "Silence, sockets and shared ports"); killed, the worker comes back on that same port and every station returns to phase 3."""
    cfg = tmp_path / "packed.toml"
    cfg.write_text(PACKED)
    report = tmp_path / "r.json"
    run_dir = tmp_path / "run"
    r = run_cli("up", str(cfg), "--workers", "1", "--no-status", "--report", str(report), "--run-dir", str(run_dir),
                timeout=60)
    assert r.returncode == 0, r.stdout + r.stderr
    assert "exited with code" in r.stdout  # the kill happened and was reported
    log = (run_dir / "worker-0.log").read_text()
    starts = [line for line in log.splitlines() if "0x21@" in line]  # the worker's "ready" log line, each start
    assert len(starts) >= 2, "the worker was not restarted:\n" + log
    ports = [set(re.findall(r"0x2[123]@127\.0\.0\.1:(\d+)", line)) for line in starts]
    assert all(len(p) == 1 for p in ports), ports  # one port for the three stations
    assert ports[0] == ports[-1]  # and the same one after the restart
    doc = json.loads(report.read_text())
    assert all(doc["station"][f"0x{a:02x}"]["answered"] > 0 for a in (0x21, 0x22, 0x23))
