"""``mlink-sim control`` against a standalone slave offers the slave's operations (stats, cpu, plant, release,
ping; aio/slave/server.py) and says which command answers an operation the slave refuses."""

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
    plant = run_cli("control", where, "plant", "0x21", "load,torque=5")
    assert plant.returncode == 0, plant.stderr
    handle = json.loads(plant.stdout)["handle"]
    assert run_cli("control", where, "release", "21H", str(handle)).returncode == 0
    again = run_cli("control", where, "release", "21H", str(handle))
    assert again.returncode == 1 and "refused release: no drive fault" in again.stderr
    assert run_cli("control", where, "ping").returncode == 0
    other = run_cli("control", where, "impair", "21H", "loss=5%")
    assert other.returncode == 1 and "impair is answered by: up/master --control, proxy" in other.stderr


def test_control_refuses_a_malformed_request_before_sending() -> None:
    cases = [(["plant", "21H"], "plant needs ADDR and SPEC"), (["plant", "21H", "silence,for=1s"], "plant takes a drive fault"),
             (["release", "21H", "one"], "HANDLE is the number plant answered"), (["cpu", "21H"], "cpu takes no station"),
             (["stats", "21H", "x"], "stats takes no SPEC")]
    for args, expected in cases:
        r = run_cli("control", "127.0.0.1:9", *args)
        assert r.returncode == 2 and expected in r.stderr, (args, r.stderr)
