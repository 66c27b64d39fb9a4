"""A standalone ``mlink-sim slave`` answers the station operations that make sense without a master of ours
(mlink_sim.aio.control.slave): ``mlink-sim status``, ``param get|set`` by name in the card's own parameter store as
the drive's keypad would (SI-T3 Table 4 parameters, the VS-606V7's n-numbers), a drive fault that ends by itself; and
``status`` / ``param`` pointed at a station's data port say so and how to find the control port."""

from __future__ import annotations

import json
import re
import time
from pathlib import Path

from .conftest import run_cli


def test_param_get_and_set_by_name_on_a_standalone_slave(slave, tmp_path: Path) -> None:
    s = slave("--card", "si-t3", "--station", "21H", "--control", "127.0.0.1:0", "--state-dir", str(tmp_path))
    where = f"127.0.0.1:{s.ready['control']}"
    got = run_cli("param", "get", where, "21H", "C1-01")
    assert got.returncode == 0 and got.stdout.strip() == "C1-01 = 10.0 s (raw 100, register 0200H)", got.stderr
    put = run_cli("param", "set", where, "21H", "C1-01=2.5", "--eeprom")
    assert put.returncode == 0 and put.stdout.strip() == "C1-01 = 2.5 s (raw 25, register 0200H)", put.stderr
    assert run_cli("param", "get", where, "0x21", "c1-01").stdout.startswith("C1-01 = 2.5 s")
    deadline = time.monotonic() + 5
    while not list(tmp_path.glob("*.json")) and time.monotonic() < deadline:  # the EEPROM image, written apart
        time.sleep(0.05)
    image = json.loads(next(tmp_path.glob("*.json")).read_text())
    assert image["params"]["C1-01"] == 25
    bad = run_cli("param", "set", where, "21H", "C1-01=99999")
    assert bad.returncode == 2 and "C1-01: 99999.0 s is out of range 0.0 … 6000.0 s" in bad.stderr
    other = run_cli("param", "get", where, "22H", "C1-01")
    assert other.returncode == 2 and "station 22H is not served by this slave (it serves 21H)" in other.stderr
    status = run_cli("status", where)
    assert status.returncode == 0 and status.stdout.splitlines()[2].split()[:4] == ["21H", "SI-T3", "ML2", "P1"]


def test_an_a1000_name_on_a_vs606v7_names_its_own() -> None:
    s_args = ("--card", "si-t-v7", "--station", "22H", "--control", "127.0.0.1:0")
    from .conftest import SlaveProc

    s = SlaveProc(*s_args)
    try:
        r = run_cli("param", "get", f"127.0.0.1:{s.ready['control']}", "22H", "C1-01")
        assert r.returncode == 2
        assert "C1-01 is the A1000's Acceleration Time 1; the VS-606V7's is n019" in r.stderr, r.stderr
        assert "U-01" not in r.stderr
    finally:
        s.stop()


def test_a_drive_fault_with_for_ends_by_itself(slave) -> None:
    s = slave("--card", "si-t3", "--station", "21H", "--control", "127.0.0.1:0")
    where = f"127.0.0.1:{s.ready['control']}"
    r = run_cli("control", where, "fault", "21H", "mains-loss,for=300ms")
    assert r.returncode == 0, r.stderr
    handle = json.loads(r.stdout)["handle"]
    time.sleep(0.8)
    again = run_cli("control", where, "release", "21H", str(handle))
    assert again.returncode == 2 and f"no drive fault {handle} in force" in again.stderr


def test_status_or_param_at_a_data_port_says_it_is_one(slave) -> None:
    s = slave("--card", "si-et3", "--station", "23H", "--control", "127.0.0.1:0")
    data = f"127.0.0.1:{s.port}"
    for args in (["status", data], ["param", "get", data, "23H", "C1-01"]):
        t0 = time.monotonic()
        r = run_cli(*args)
        took = time.monotonic() - t0
        assert r.returncode == 2, r.stderr
        assert re.search(r"127\.0\.0\.1:\d+ is the data port of station 23H \(MECHATROLINK-III, 64-byte\)", r.stderr)
        assert "'mlink-sim slave control: HOST:PORT'" in r.stderr and "--ready-json" in r.stderr
        assert took < 10  # the first attempt's second and the probe, then the answer (bounds: docs/ci.md)
