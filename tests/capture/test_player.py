"""``mlink-sim replay`` as a player (python-can's ``can.player``): ``--no-compare`` sends only, as the slave's own
counters show; ``--loop`` plays the capture again, ``--gap`` spaces the frames (as the slave's capture of them
shows), ``--station`` sends one station's frames of a capture of several; a difference in a status field names
the bits and the setting behind them."""

from __future__ import annotations

import asyncio
import json
import signal
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

from mlink_sim.aio.control.endpoint import query_control
from mlink_sim.capture import CaptureWriter, read_capture
from mlink_sim.capture.replay import HINTS, compare, hints_for
from mlink_sim.wire import Frame, Kind, Link, M2Status, encode, ml2

HERE = Path(__file__).parent
CONFIG = HERE / "one_station.toml"
MLINK = [sys.executable, "-m", "mlink_sim"]


def _rsp(status: int) -> bytes:
    return encode(Frame(Link.ML2, Kind.RESPONSE, 0x21, 5, 2_000_000,
                        ml2.M2Response(ml2.Nop(), 0, status, 1, ml2.Nop(), 4)))


def test_a_status_difference_names_its_bits_and_the_setting_behind_it() -> None:
    ready = int(M2Status.CMDRDY | M2Status.PON | M2Status.ZSP | M2Status.INV_READY)
    diffs = compare(_rsp(ready | int(M2Status.REMOTE)), _rsp(ready))
    assert diffs == ["status: recorded 9300, live 1108 (recorded only: REMOTE)"]
    both = compare(_rsp(ready | int(M2Status.REMOTE)), _rsp(ready | int(M2Status.OPE)))
    assert both == [f"status: recorded 9300, live {ready | int(M2Status.OPE)} (recorded only: REMOTE; live only: OPE)"]
    assert hints_for([f"cycle 3 station 21H INV_CTL/NOP: {diffs[0]}"]) == [HINTS["REMOTE"]]
    assert hints_for(both) == [HINTS["REMOTE"], HINTS["OPE"]]
    assert "b1-01 = 3" in HINTS["REMOTE"] and "b1-02 = 3" in HINTS["REMOTE"] and "n003 = 3" in HINTS["REMOTE"]
    assert hints_for(["cycle 3 station 21H CONNECT/NOP: main.com_tim: recorded 2, live 1"]) == []


class _Slave:
    """A fresh SI-T3 station of CONFIG on loopback, with its control endpoint (its counters)."""

    def __init__(self, *extra: str) -> None:
        self.proc = subprocess.Popen([*MLINK, "slave", "--config", str(CONFIG), "--only", "0x21", "--endpoint",
                                      "0x21=127.0.0.1:0", "--ready-json", "--control", "127.0.0.1:0",
                                      "--host-stalls", "absorb", *extra],
                                     stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        assert self.proc.stdout is not None
        line = self.proc.stdout.readline()
        assert line, self.proc.stderr.read() if self.proc.stderr else ""
        ready = json.loads(line)
        self.port, self.control = ready["stations"][0]["port"], ready["control"]

    def counters(self) -> dict[str, Any]:
        reply = asyncio.run(query_control("127.0.0.1", self.control, "stats", timeout=3.0))
        assert reply is not None
        counters: dict[str, Any] = reply["stations"]["0x21"]["counters"]
        return counters

    def stop(self) -> None:
        self.proc.send_signal(signal.SIGTERM)
        self.proc.communicate(timeout=20)


def _replay(capture: Path, slave: _Slave, *extra: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([*MLINK, "replay", str(capture), "--to", f"127.0.0.1:{slave.port}", *extra],
                          capture_output=True, text=True, timeout=120)


@pytest.fixture(scope="module")
def recorded(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A master's 2 s against a slave of CONFIG, as the slave recorded it (255 commands at 8 ms)."""
    path = tmp_path_factory.mktemp("player") / "slave.pcapng"
    slave = _Slave("--capture", str(path))
    try:
        run = subprocess.run([*MLINK, "master", str(CONFIG), "--endpoint", f"0x21=127.0.0.1:{slave.port}",
                              "--duration", "2s", "--no-status"], capture_output=True, text=True, timeout=60)
    finally:
        slave.stop()
    assert run.returncode == 0, run.stdout + run.stderr
    return path


def _commands(path: Path, station: int = 0x21) -> int:
    return sum(1 for d in read_capture(path).datagrams if d.data[2] == Kind.COMMAND and d.data[3] == station)


@pytest.mark.e2e
def test_no_compare_sends_every_frame_and_loop_sends_them_again(recorded: Path) -> None:
    frames = _commands(recorded)
    slave = _Slave()
    try:
        sent = _replay(recorded, slave, "--no-compare")
        after_one = slave.counters()
        looped = _replay(recorded, slave, "--loop", "2")
        after_three = slave.counters()
    finally:
        slave.stop()
    assert sent.returncode == 0, sent.stdout + sent.stderr
    assert sent.stdout.strip() == f"{frames} frames sent, {frames} answers received; not compared (--no-compare)"
    assert after_one["rx_ok"] == frames  # what the slave received: every frame, once
    assert looped.returncode == 0, looped.stdout + looped.stderr  # each pass from its bring-up: equal again
    assert f"{2 * frames} frames sent in 2 pass(es)" in looped.stdout and "all equal" in looped.stdout
    assert f"{frames} frames" in looped.stderr and "2 times" in looped.stderr
    assert after_three["rx_ok"] == 3 * frames


def _first(src: Path, dst: Path, commands: int, extra_station: int | None = None) -> None:
    """The first *commands* commands of *src* with their answers; with *extra_station*, a NOP to that station
    beside each command."""
    n = 0
    with CaptureWriter(dst, epoch_offset_ns=0) as w:
        for d in read_capture(src).datagrams:
            if d.data[2] == Kind.COMMAND:
                n += 1
                if n > commands:
                    break
                if extra_station is not None:
                    nop = encode(Frame(Link.ML2, Kind.COMMAND, extra_station, n, 8_000_000,
                                       ml2.M2Command(ml2.Nop(), 0, ml2.Nop())))
                    w.record(d.ts_ns, nop, d.src, ("127.0.0.1", 9))
            w.record(d.ts_ns, d.data, d.src, d.dst)


@pytest.mark.e2e
def test_gap_spaces_the_frames_as_the_slave_receives_them(recorded: Path, tmp_path: Path) -> None:
    short = tmp_path / "short.pcapng"
    _first(recorded, short, 12)
    at_slave = tmp_path / "at_slave.pcapng"
    slave = _Slave("--capture", str(at_slave))
    try:
        result = _replay(short, slave, "--no-compare", "--gap", "40ms")
    finally:
        slave.stop()
    assert result.returncode == 0, result.stdout + result.stderr
    assert "at least 40ms apart" in result.stderr
    times = [d.ts_ns for d in read_capture(at_slave).datagrams if d.data[2] == Kind.COMMAND]
    assert len(times) == 12
    assert min(b - a for a, b in zip(times, times[1:])) >= 39_000_000  # the capture's own 8 ms, spaced to 40 ms


@pytest.mark.e2e
def test_station_sends_only_that_stations_frames(recorded: Path, tmp_path: Path) -> None:
    two = tmp_path / "two.pcapng"
    _first(recorded, two, 20, extra_station=0x22)
    slave = _Slave()
    try:
        refused = _replay(two, slave, "--no-compare")
        one = _replay(two, slave, "--no-compare", "--station", "0x21")
        counters = slave.counters()
    finally:
        slave.stop()
    assert refused.returncode == 2 and "no slave for station(s) 21H, 22H" in refused.stderr
    assert one.returncode == 0, one.stdout + one.stderr
    assert one.stdout.startswith("20 frames sent")
    assert counters["rx_ok"] == 20 and counters["other_station"] == 0  # no 22H frame reached it


@pytest.mark.e2e
def test_a_slave_without_the_captures_settings_gets_the_remote_hint(recorded: Path) -> None:
    """The capture's slave ran with b1-01 = b1-02 = 3 (CONFIG); a bare SI-T3 answers without REMOTE."""
    bare = subprocess.Popen([*MLINK, "slave", "--card", "si-t3", "--station", "21H", "--link", "ML2", "--frame-size",
                             "32", "--listen", "127.0.0.1:0", "--ready-json", "--control", "off", "--host-stalls",
                             "absorb"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    assert bare.stdout is not None
    port = json.loads(bare.stdout.readline())["stations"][0]["port"]
    try:
        result = subprocess.run([*MLINK, "replay", str(recorded), "--to", f"127.0.0.1:{port}"], capture_output=True,
                                text=True, timeout=120)
    finally:
        bare.send_signal(signal.SIGTERM)
        bare.communicate(timeout=20)
    assert result.returncode == 1, result.stdout + result.stderr
    assert "(recorded only: REMOTE)" in result.stdout
    assert f"hint: {HINTS['REMOTE']}" in result.stdout.splitlines()
