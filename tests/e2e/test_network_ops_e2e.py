"""A running ``mlink-sim up --control`` seen and steered through its control endpoint (aio/control/network.py,
docs/control.md): ``mlink-sim param get|set`` (PRM_RD, PRM_WR + CONFIG through the master; SI-T3 Tables 8/9/12),
``mlink-sim status``, and the operations run, stop, alarm-clear, network, report, with an error ``kind`` for each
kind of bad request. One real network of processes on 127.0.0.1, port 0."""

from __future__ import annotations

import asyncio
import json
import subprocess
import threading
import time
from collections.abc import Callable, Iterator
from typing import Any

import pytest

from mlink_sim.aio.control.endpoint import query_control

from .conftest import MLINK, lines_until, run_cli


class Network:
    """The quickstart under ``up --no-timeline --control 127.0.0.1:0``; stderr drained in a thread."""

    def __init__(self) -> None:
        self.proc = subprocess.Popen([*MLINK, "up", "quickstart", "--no-timeline", "--no-status", "--duration",
                                      "300s", "--control", "127.0.0.1:0"],
                                     stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        assert self.proc.stderr is not None
        _, m = lines_until(self.proc.stderr, r"control: (127\.0\.0\.1):(\d+)", timeout=30)
        self.address = f"{m.group(1)}:{m.group(2)}"
        self.port = int(m.group(2))
        self.stderr: list[str] = []
        threading.Thread(target=lambda: self.stderr.extend(self.proc.stderr or []), daemon=True).start()

    def ask(self, op: str, timeout: float = 5.0, **fields: Any) -> dict[str, Any]:
        reply = asyncio.run(query_control("127.0.0.1", self.port, op, timeout=timeout, **fields))
        assert reply is not None, f"no answer to {op}"
        return reply

    def station(self, address: str) -> dict[str, Any]:
        return next(s for s in self.ask("status")["stations"] if s["address"] == address)

    def wait(self, address: str, pred: Callable[[dict[str, Any]], bool], timeout: float = 15.0) -> dict[str, Any]:
        end = time.monotonic() + timeout
        while True:
            st = self.station(address)
            if pred(st) or time.monotonic() > end:
                return st
            time.sleep(0.2)

    def stop(self) -> None:
        self.proc.terminate()
        self.proc.communicate(timeout=30)


@pytest.fixture(scope="module")
def network() -> Iterator[Network]:
    net = Network()
    try:
        net.wait("0x23", lambda s: s["phase"] == 3)
        yield net
    finally:
        net.stop()


def test_param_get_and_set_by_name_through_the_master(network: Network) -> None:
    """C1-01 is register 0200H in 0.1 s (SI-T3 Table 8); the config sets 2.0 s; set writes, enters and reads
    back."""
    got = run_cli("param", "get", network.address, "0x21", "C1-01")
    assert got.returncode == 0 and got.stdout.strip() == "C1-01 = 2.0 s (raw 20, register 0200H)", got.stderr
    put = run_cli("param", "set", network.address, "21H", "C1-01=5.0")
    assert put.returncode == 0 and put.stdout.strip() == "C1-01 = 5.0 s (raw 50, register 0200H)", put.stderr
    again = run_cli("param", "get", network.address, "33", "C1-01")
    assert again.stdout.strip() == "C1-01 = 5.0 s (raw 50, register 0200H)"
    v7 = run_cli("param", "set", network.address, "0x22", "n019=3.5", "--eeprom")  # VS-606V7 n019 (accel time 1)
    assert v7.returncode == 0 and v7.stdout.startswith("n019 = 3.5 s (raw 35, register"), v7.stderr


@pytest.mark.parametrize("args, message", [
    (["get", "0x29", "C1-01"], "station 29H is not a station of this network"),
    (["get", "0x21", "Z9-99"], "unknown parameter 'Z9-99'"),
    (["get", "0x21", "n019"], "unknown parameter 'n019'"),  # a VS-606V7 name on an SI-T3 (A1000)
    (["set", "0x21", "C1-01=99999"], "out of range"),
    (["set", "0x21", "C1-01=0.05"], "finer than the setting resolution"),
    (["set", "0x21", "C1-01"], "NAME=VALUE: expected e.g. C1-01=5.0"),
    (["get", "nowhere", "C1-01"], "station: expected a station address such as 0x21 or 21H, got 'nowhere'"),
])
def test_a_bad_parameter_request_is_a_usage_error(network: Network, args: list[str], message: str) -> None:
    r = run_cli("param", args[0], network.address, *args[1:])
    assert r.returncode == 2 and message in r.stderr and len(r.stderr.strip().splitlines()) == 1, r.stderr


def test_status_prints_every_station_and_json_the_reply(network: Network) -> None:
    r = run_cli("status", network.address)
    assert r.returncode == 0, r.stderr
    lines = r.stdout.splitlines()
    assert lines[0].startswith("quickstart") and "ADDR" in lines[1] and "LEDS" in lines[1]
    assert [ln.split()[0] for ln in lines[2:]] == ["21H", "22H", "23H"]
    assert all(" P3 " in ln for ln in lines[2:])
    raw = json.loads(run_cli("status", network.address, "--json").stdout)
    assert raw["ok"] and [s["address"] for s in raw["stations"]] == ["0x21", "0x22", "0x23"]
    phases = [e for e in raw["events"] if e["kind"] == "phase" and e["state"] == "phase3"]
    assert {e["station"] for e in phases} == {"0x21", "0x22", "0x23"}
    assert raw["seq"] == raw["events"][-1]["seq"]
    later = network.ask("status", since=raw["seq"])
    assert all(e["seq"] > raw["seq"] for e in later["events"])


def test_status_watch_shows_it_again_until_interrupted(network: Network) -> None:
    proc = subprocess.Popen([*MLINK, "status", network.address, "--watch", "0.3s", "--json"], stdout=subprocess.PIPE,
                            text=True, bufsize=1)
    assert proc.stdout is not None
    try:
        replies = [json.loads(proc.stdout.readline()) for _ in range(3)]  # one line per reply, as they come
    finally:
        proc.terminate()
        proc.communicate(timeout=10)
    assert all(r["ok"] for r in replies) and replies[0]["elapsed_s"] < replies[1]["elapsed_s"] < replies[2]["elapsed_s"]
    assert proc.returncode == 143


def test_run_and_stop_steer_the_drive_and_the_figures_follow(network: Network) -> None:
    reply = network.ask("run", station="0x23", direction="reverse", hz=15.0)
    assert reply["ok"] and reply["station"]["address"] == "0x23"
    st = network.wait("0x23", lambda s: s["output_hz"] and abs(s["output_hz"] + 15.0) < 0.1)  # reverse: below 0
    assert st["running"] and st["direction"] == "reverse" and st["reference_hz"] == pytest.approx(-15.0, abs=0.01)
    assert st["output_current_a"] > 0 and st["motor_speed_rpm"] < 0
    assert st["dc_bus_v"] and st["dc_bus_v"] > 200  # the slave's snapshot
    assert network.ask("stop", station="23H")["ok"]
    st = network.wait("0x23", lambda s: s["output_hz"] == 0 and not s["running"])
    assert st["output_hz"] == 0 and st["direction"] is None
    actions = [e for e in network.ask("status")["events"] if e["kind"] == "action"]
    assert [a["describe"] for a in actions if a["station"] == "0x23"][-2:] == ["run reverse 15 Hz", "stop"]


def test_alarm_clear_is_answered_once_the_station_did_it(network: Network) -> None:
    reply = network.ask("alarm-clear", station="0x21", id="clear-1")
    assert reply["ok"] and reply["station"]["alarm"] is None
    assert network.ask("alarm-clear", station="0x21", id="clear-1") == reply  # a repeat: the same answer


@pytest.mark.parametrize("op, fields, kind", [
    ("run", {"station": "0x21", "direction": "forward", "hz": 500.0}, "out_of_range"),
    ("run", {"station": "0x21", "direction": "sideways", "hz": 5.0}, "bad_request"),
    ("run", {"station": "0x21", "direction": "forward", "hz": "fast"}, "bad_request"),
    ("stop", {"station": "0x40"}, "unknown_station"),
    ("fault", {"station": "0x40", "spec": "silence,for=1s"}, "unknown_station"),
    ("fault", {"station": "0x21", "spec": "silence,for=forever"}, "bad_request"),
    ("stop", {}, "bad_request"),
    ("get-param", {"station": "0x21"}, "bad_request"),
    ("set-param", {"station": "0x21", "param": "C1-01", "value": [1]}, "bad_request"),
    ("get-param", {"station": "0x21", "param": "C9-99"}, "unknown_param"),
    ("run", {"station": "0x21", "speed_hz": 5.0}, "bad_request"),
    ("status", {"since": -1}, "bad_request"),
    ("teleport", {}, "bad_request"),
])
def test_a_bad_request_gets_its_error_kind(network: Network, op: str, fields: dict[str, Any], kind: str) -> None:
    reply = network.ask(op, **fields)
    assert not reply["ok"] and reply["kind"] == kind and "\n" not in reply["error"], reply


def test_a_station_that_does_not_answer_refuses_a_run(network: Network) -> None:
    """A station cut off (all its datagrams lost) falls to phase 0 in the master's view: a run command is refused
    until it is back."""
    assert network.ask("impair", station="0x22", spec="loss=100%,for=4s")["ok"]
    network.wait("0x22", lambda s: not s["connected"], timeout=5)
    refused = network.ask("run", station="0x22", direction="forward", hz=10.0)
    assert not refused["ok"] and refused["kind"] == "refused" and "needs a connection" in refused["error"]
    st = network.wait("0x22", lambda s: s["phase"] == 3, timeout=20)
    assert st["phase"] == 3


def test_network_and_report(network: Network) -> None:
    net = network.ask("network")
    assert net["cycle"] == "2ms" and net["cycle_ns"] == 2_000_000
    assert net["stations"][2] == {"address": "0x23", "name": "23H", "card": "si-et3", "link": "ML3",
                                  "frame_size": 64}
    report = network.ask("report", timeout=10)["report"]
    assert report["meta"]["network"] == "quickstart" and set(report["station"]) == {"0x21", "0x22", "0x23"}
    assert report["rtt"]["count"] > 0
    stop = run_cli("control", network.address, "stop", "21H")  # the same requests from mlink-sim control
    assert stop.returncode == 0 and json.loads(stop.stdout)["station"]["address"] == "0x21", stop.stderr
    assert json.loads(run_cli("control", network.address, "network").stdout)["name"] == "quickstart"
    assert run_cli("control", network.address, "stop").returncode == 2


def test_a_standalone_slaves_status(slave) -> None:
    s = slave("--card", "si-et3", "--station", "23H", "--control", "127.0.0.1:0")
    where = f"127.0.0.1:{s.ready['control']}"
    r = run_cli("status", where)
    assert r.returncode == 0, r.stderr
    lines = r.stdout.splitlines()
    assert lines[0].startswith("slave pid") and lines[2].split()[:4] == ["23H", "SI-ET3", "ML3", "P1"]
    assert "R/E CON- LK1- LK2-" in lines[2]  # SI-ET3 Table 4: powered, no connection, no frames
    raw = json.loads(run_cli("status", where, "--json").stdout)
    assert [st["address"] for st in raw["stations"]] == ["0x23"]  # the slave's own status: the same figures
    assert raw["stations"][0]["rtt_p99_us"] is None  # only a master measures a round trip


def test_no_answer_names_the_address_and_exits_1() -> None:
    r = run_cli("status", "127.0.0.1:9", "--timeout", "0.6s")
    assert r.returncode == 1 and "no answer from 127.0.0.1:9" in r.stderr
    r = run_cli("param", "get", "127.0.0.1:9", "0x21", "C1-01", "--timeout", "0.6s")
    assert r.returncode == 1 and "no answer from 127.0.0.1:9" in r.stderr
    r = run_cli("status", "nowhere")
    assert r.returncode == 2 and "HOST:PORT 'nowhere'" in r.stderr
