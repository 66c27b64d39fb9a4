"""Faults on purpose end to end (docs/faults.md): the impairing proxy between a master and a slave,
controlled while it runs; ``up --control``; the shipped example; bad input is exit 2. Loopback, port 0."""

from __future__ import annotations

import json
import signal
import subprocess
import time
from pathlib import Path

import pytest

from .conftest import MLINK, assert_held, lines_until, run_cli

pytestmark = pytest.mark.e2e

ONE = """
[network]
name = "one"
transmission_cycle = "2ms"

[[station]]
address = 0x21
card = "si-t3"
"""


def _stop(proc: subprocess.Popen[str]) -> tuple[int, str]:
    proc.send_signal(signal.SIGTERM)
    out, _ = proc.communicate(timeout=10)
    return proc.returncode, out


def test_proxy_between_a_master_and_a_slave_impaired_while_it_runs(tmp_path: Path, slave) -> None:
    cfg = tmp_path / "one.toml"
    cfg.write_text(ONE)
    s = slave("--config", str(cfg), "--host-stalls", "absorb")
    capture = tmp_path / "proxy.pcapng"
    proxy = subprocess.Popen([*MLINK, "proxy", "--listen", "127.0.0.1:0", "--to", f"127.0.0.1:{s.port}",
                              "--seed", "3", "--capture", str(capture)], stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, text=True)
    try:
        _, m = lines_until(proxy.stdout, r"127\.0\.0\.1:(\d+) -> ")
        port = int(m.group(1))
        _, m = lines_until(proxy.stdout, r"control: 127\.0\.0\.1:(\d+)")
        control = f"127.0.0.1:{m.group(1)}"
        master = subprocess.Popen([*MLINK, "master", str(cfg), "--no-status", "--duration", "3s",
                                   "--endpoint", f"0x21=127.0.0.1:{port}", "--report", str(tmp_path / "r.json")],
                                  stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        time.sleep(1.5)
        r = run_cli("control", control, "impair", "0x21", "loss=30%,direction=to-master,for=0.3s", "--timeout", "6")
        assert r.returncode == 0 and json.loads(r.stdout)["ok"], r.stdout + r.stderr
        out, err = master.communicate(timeout=60)
        faults = json.loads(run_cli("control", control, "faults", "--timeout", "6").stdout)
        assert faults["faults"] == [] and faults["injected"]["0x21"]["drops"] > 0
        # named, as toxiproxy's toxics: listed by name, healed one by one (docs/faults.md, "Names")
        ask = lambda *a: json.loads(run_cli("control", control, *a, "--timeout", "6").stdout)  # noqa: E731
        assert ask("impair", "0x21", "delay=50us", "--name", "slow")["name"] == "slow"
        assert ask("impair", "all", "loss=1%")["name"] == "loss-all-1"
        listed = ask("faults")["faults"]
        assert [(f["name"], f["stations"], f["given"]) for f in listed] == [("slow", ["0x21"], True),
                                                                            ("loss-all-1", ["all"], False)]
        assert ask("heal", "slow") == {"ok": True, "ended": 1, "names": ["slow"]}
        assert [f["name"] for f in ask("faults")["faults"]] == ["loss-all-1"]
        assert ask("heal") == {"ok": True, "ended": 1, "names": ["loss-all-1"]} and ask("faults")["faults"] == []
        report = json.loads((tmp_path / "r.json").read_text())
        assert report["station"]["0x21"]["missing"] > 0  # the answers the proxy lost
        bad = run_cli("control", control, "impair", "0x21", "loss=2")
        assert bad.returncode == 2 and "loss: a probability" in bad.stderr
    finally:
        code, out = _stop(proxy)
    assert code == 143 and "stopped by SIGTERM" in out and '"drops"' in out
    assert capture.stat().st_size > 1000


def test_up_control_impairs_a_running_network(tmp_path: Path) -> None:
    cfg = tmp_path / "one.toml"
    cfg.write_text(ONE)
    up = subprocess.Popen([*MLINK, "up", str(cfg), "--no-status", "--duration", "3s", "--control", "127.0.0.1:0",
                           "--assert", "station[0x21].injected.delays > 0"],
                          stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    _, m = lines_until(up.stderr, r"control: (127\.0\.0\.1:\d+)")
    time.sleep(0.5)
    r = run_cli("control", m.group(1), "impair", "all", "delay=100us,for=0.5s", "--timeout", "6")
    assert r.returncode == 0, r.stdout + r.stderr
    out, _ = up.communicate(timeout=60)
    assert up.returncode == 0, out
    assert "ok   assert station[0x21].injected.delays > 0" in out


def test_the_network_faults_example_passes_on_the_real_clock(tmp_path: Path) -> None:
    r = run_cli("up", "faults-network", "--no-status", "--report", str(tmp_path / "r.json"),
                "--assert", "station[0x21].injected.drops > 0", "--assert", "station[0x23].injected.corruptions > 0",
                timeout=90)
    assert_held(r)


@pytest.mark.parametrize("args, message", [
    (["proxy", "--listen", "127.0.0.1:0", "--to", "127.0.0.1:9", "--impair", "loss=150%"], "loss: a probability"),
    (["proxy", "--listen", "127.0.0.1:0", "--to", "127.0.0.1:9", "--to", "127.0.0.1:10"], "one --to per --listen"),
    (["proxy", "--listen", "nowhere", "--to", "127.0.0.1:9"], "expected HOST:PORT"),
    (["control", "127.0.0.1:9", "impair", "0x21"], "impair: nothing to do; give at least one of loss"),
    (["control", "127.0.0.1:9", "heal", "300"], "station:"),
    (["control", "127.0.0.1:9", "impair", "21H", "loss=1%", "--name", "22H"], "name: '22H' reads as a station"),
])
def test_bad_proxy_and_control_input_is_exit_2(args: list[str], message: str) -> None:
    r = run_cli(*args)
    assert r.returncode == 2 and message in r.stderr, r.stderr
