"""Who may change a station, and its EEPROM, from outside, as a master or an attacker on the network meets them:
real ``mlink-sim slave`` processes on loopback, a scripted master and a flooder over UDP, ``mlink-sim probe``,
kill -9 (docs/cards.md, "Who may change a station" and "EEPROM")."""

from __future__ import annotations

import os
import signal
import socket
import time
from pathlib import Path

import pytest

from .conftest import run_cli
from .udp_master import ACCEL, ACCEL_DEFAULT, UdpMaster, params_saved, snapshot, wait_for, write_config

pytestmark = pytest.mark.e2e

CARDS = ["si-t3", "si-t-v7", "si-et3"]


def _flood(port: int, master: UdpMaster, seconds: float = 0.5, sockets: int = 4) -> int:
    """Datagrams at the station from several sockets for *seconds* (bounded): NOP status queries, INV_CTL run
    commands and garbage, while the master is silent (its commands are lost in the flood)."""
    socks = [socket.socket(socket.AF_INET, socket.SOCK_DGRAM) for _ in range(sockets)]
    payloads = [master.datagram(master.m.Nop()), master.datagram(master.m.InvCtl()), b"\x4d\x02\x01\x21garbage"]
    sent = 0
    end = time.monotonic() + seconds
    try:
        while time.monotonic() < end and sent < 200_000:
            for s in socks:
                s.sendto(payloads[sent % len(payloads)], ("127.0.0.1", port))
                sent += 1
    finally:
        for s in socks:
            s.close()
    return sent


def _drained(ctl: int, quiet: float = 0.3, timeout: float = 30.0) -> None:
    """Wait until the slave has worked through the flood's backlog (its counters stop moving)."""
    def seen() -> int:
        c = snapshot(ctl)["counters"]
        return c["rx_ok"] + c["status_queries"] + c["foreign_source"] + sum(c["dropped_by_reason"].values())

    end = time.monotonic() + timeout
    last = seen()
    while time.monotonic() < end:
        time.sleep(quiet)
        now = seen()
        if now == last:
            return
        last = now
    raise AssertionError("the slave is still working through the flood")


@pytest.mark.parametrize("card", CARDS)
def test_flood_then_foreign_writes_and_a_probe_change_nothing_and_the_master_gets_its_station_back(
        card: str, slave, tmp_path: Path) -> None:
    """A flood cuts the master off until the station declares bUS and releases the connection; the
    flooder's PRM_WR (77.7 s acceleration) and CONFIG to EEPROM change nothing, a probe binds nothing, and the
    master's next command tells it to CONNECT again, after which it owns the station and reads the old value."""
    state = tmp_path / "state"
    proc = slave("--config", str(write_config(tmp_path / "net.toml", card)), "--state-dir", str(state))
    port, ctl = proc.port, proc.ready["control"]
    master = UdpMaster(port, card)
    flooder = UdpMaster(port, card)
    try:
        assert master.connect() is not None and master.run() is not None
        assert snapshot(ctl)["connected_source"] == master.source
        _flood(port, flooder)
        assert wait_for(lambda: snapshot(ctl)["connected_source"] is None), "the station never lost its master"
        _drained(ctl)
        reg = ACCEL[card]
        flooder.cycle += 100
        for answer in (flooder.prm_wr(reg, 777), flooder.send(flooder.m.Config(1)), flooder.run(6000)):
            assert answer is not None and flooder.refused(answer)
        if card == "si-t-v7":
            answer = flooder.send(flooder.m.Nop(), flooder.m.Config(1))
            assert answer is not None and answer.message.substatus & 0x03  # SUBWARNG: not executed
        assert flooder.send(flooder.m.Disconnect()) is not None
        snap = snapshot(ctl)
        assert snap["connected_source"] is None and snap["phase"] == 2 and params_saved(state) == {}
        assert run_cli("probe", f"127.0.0.1:{port}", "--station", "0x21", "--timeout", "3").returncode == 0
        assert snapshot(ctl)["connected_source"] is None  # the probe bound nothing

        master.cycle += 1000
        answer = master.run()
        assert answer is not None and master.refused(answer)  # "as from phase 1": the master must CONNECT
        assert master.connect() is not None
        assert snapshot(ctl)["connected_source"] == master.source
        assert master.send(master.m.AlmClr(0)) is not None
        assert master.prm_rd(reg) == ACCEL_DEFAULT
        assert master.prm_wr(reg, 50) is not None and master.prm_rd(reg) == 50  # the master writes, as ever
        for _ in range(20):
            answer = master.run()
            assert answer is not None and not master.refused(answer)
        assert snapshot(ctl)["connected_source"] == master.source
    finally:
        master.close()
        flooder.close()


@pytest.mark.parametrize("card", ["si-t3", "si-et3"])
def test_probe_never_changes_station_state(card: str, slave, tmp_path: Path) -> None:
    """``mlink-sim probe`` in phase 1 and against a connected station: the station looks the same afterwards
    (phase, owner, alarms, CMD_ALM, LED colours, drive). SI-ET3 answers the phase-1 NOP with CMD_ALM 0."""
    # the scripted master pauses while the probe runs: no silence verdict in this test (60 s tolerance)
    proc = slave("--config", str(write_config(tmp_path / "net.toml", card, silence_tolerance_ms=60_000)))
    port, ctl = proc.port, proc.ready["control"]

    def view() -> dict:
        s = snapshot(ctl)
        return {k: s[k] for k in ("phase", "connected_source", "alarm_code", "alarm_name", "warnings", "cmd_alm",
                                  "led_colors", "station_error", "tcycle_ns")} | {"drive": s["drive"]}

    before = view()
    probe = run_cli("probe", f"127.0.0.1:{port}", "--station", "0x21", "--timeout", "3")
    assert probe.returncode == 0, probe.stderr
    assert view() == before
    master = UdpMaster(port, card)
    try:
        assert master.connect() is not None and master.send(master.m.Nop()) is not None
        before = view()
        assert run_cli("probe", f"127.0.0.1:{port}", "--station", "0x21", "--timeout", "3").returncode == 0
        assert view() == before
        answer = master.send(master.m.Nop())
        assert answer is not None and not master.refused(answer)
    finally:
        master.close()


@pytest.mark.parametrize("card", CARDS)
def test_eeprom_write_acknowledged_only_once_durable_survives_kill_9(
        card: str, slave, tmp_path: Path) -> None:
    """CONFIG to EEPROM answers CMDRDY = 0 until the image is written, fsync'd and renamed; kill -9 right
    after the completed answer, restart: the value is there. Stale temporary files are gone after a start."""
    state = tmp_path / "state"
    state.mkdir()
    stale = state / f".{card}-21H.eeprom.json.k1ll3d.tmp"
    stale.write_bytes(b'{"version": 1, "car')
    config = write_config(tmp_path / "net.toml", card)
    proc = slave("--config", str(config), "--state-dir", str(state))
    reg = ACCEL[card]
    sub = card == "si-t-v7"  # the V7 CONFIG sub-command (§7.2): SUBCMDRDY
    master = UdpMaster(proc.port, card)
    try:
        assert not stale.exists()
        assert master.connect() is not None
        answer = master.prm_wr(reg, 777)
        assert answer is not None and not master.refused(answer)

        def store():
            return master.send(master.m.Nop(), master.m.Config(1)) if sub else master.send(master.m.Config(1))

        answer = store()
        assert answer is not None and not master.ready(answer, sub)  # not complete before the image is durable
        busy = 1
        while not master.ready(answer, sub):
            assert busy < 500
            answer = store()
            assert answer is not None
            busy += 1
        assert not master.refused(answer)
        os.kill(proc.proc.pid, signal.SIGKILL)  # right after the acknowledgement
        proc.proc.wait(5)
    finally:
        master.close()
    again = slave("--config", str(config), "--state-dir", str(state))
    master = UdpMaster(again.port, card)
    try:
        assert master.connect() is not None
        assert master.prm_rd(reg) == 777
        assert not list(state.glob("*.tmp"))
    finally:
        master.close()


@pytest.mark.parametrize("command", ["validate", "up"])
def test_more_stations_than_the_link_allows_exit_2(command: str, tmp_path: Path) -> None:
    """Item 5: 63 SI-ET3 stations on one MECHATROLINK-III link (SI-ET3 Table 28: 62 max.) – `validate` and `up`
    exit 2 with one line naming the file and what is expected, before anything starts."""
    stations = "".join(f'[[station]]\naddress = {0x03 + i}\ncard = "si-et3"\n' for i in range(63))
    path = tmp_path / "big.toml"
    path.write_text('[network]\ntransmission_cycle = "1ms"\n' + stations)
    result = run_cli(command, str(path))
    assert result.returncode == 2
    assert result.stderr.strip().splitlines() == [
        f"mlink-sim: {path}: station: 63 MECHATROLINK-III stations, but one link carries at most 62 (SI-ET3 Table 28)"
    ]
