"""``mlink-sim control`` against a standalone slave: the slave's operations of the table (status, get-param, set-param,
fault, release, stats, cpu, drive, ping; mlink_sim.aio.control.slave), a request checked by the table before anything
is sent, and an operation another endpoint answers named as such."""

from __future__ import annotations

import json

from .conftest import run_cli


def test_control_speaks_a_slaves_operations(slave) -> None:
    s = slave("--card", "si-t3", "--station", "21H", "--control", "127.0.0.1:0")
    where = f"127.0.0.1:{s.ready['control']}"
    cpu = run_cli("control", where, "cpu")
    assert cpu.returncode == 0 and json.loads(cpu.stdout)["cpu_s"] >= 0
    stats = run_cli("control", where, "stats")
    assert stats.returncode == 0 and "0x21" in json.loads(stats.stdout)["stations"]
    fault = run_cli("control", where, "fault", "0x21", "load,torque=5")
    assert fault.returncode == 0, fault.stderr
    handle = json.loads(fault.stdout)["handle"]
    assert run_cli("control", where, "release", "21H", str(handle)).returncode == 0
    again = run_cli("control", where, "release", "21H", str(handle))
    assert again.returncode == 2 and "refused release: release: no drive fault" in again.stderr
    assert run_cli("control", where, "ping").returncode == 0
    other = run_cli("control", where, "impair", "21H", "loss=5%")
    assert other.returncode == 2 and "'impair' is answered by a network or a proxy, not by this slave" in other.stderr


def test_control_refuses_a_malformed_request_before_sending() -> None:
    cases = [(["release", "21H", "one"], "handle: expected a whole number 1 or more, got 'one'"),
             (["cpu", "21H"], "Got unexpected extra argument (21H)"),
             (["run", "21H", "--hz", "fast"], "hz: expected a number, got 'fast'"),
             (["run", "21H"], "run: hz is missing"),
             (["set-param", "21H", "C1-01"], "Missing argument 'VALUE'"),
             (["impair", "21X", "loss=5%"], "station: expected a station address such as 0x21 or 21H, got '21X'")]
    for args, expected in cases:
        r = run_cli("control", "127.0.0.1:9", *args)
        assert r.returncode == 2 and expected in r.stderr, (args, r.stderr)
