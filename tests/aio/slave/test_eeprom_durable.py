"""A CONFIG to EEPROM is answered complete only once its image is durable (docs/cards.md, "EEPROM"): the slave
server's writer thread reports the image written, fsync'd and renamed, and until then the card answers CMDRDY = 0
(SI-T3 "STATUS Field" bit 2 "Command ready: 0 Busy"; SI-ET3 CMD_STAT.CMDRDY). A failed write completes it with
A.94. Stale temporary files of an interrupted write are removed at start."""

from __future__ import annotations

import asyncio
import json
import socket
import threading
from pathlib import Path

import pytest

from mlink_sim.aio.slave import server as slave_mod
from mlink_sim.aio.slave.server import HostedStation, SlaveServer
from mlink_sim.aio.slave.state import atomic_write, eeprom_path, remove_stale_temps
from mlink_sim.cards import CardOptions, create_card, settings_for
from mlink_sim.wire import Frame, Kind, Link, M2Alarm, M2Status, decode, encode, ml2

TCYCLE = 1_000_000


class _Udp:
    """A scripted master on loopback: one command per call, cycle numbers and WDT counts advancing."""

    def __init__(self, addr: tuple[str, int]) -> None:
        self.addr = addr
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", 0))
        self.sock.setblocking(False)
        self.cycle = 10

    async def send(self, body: object) -> Frame:
        self.cycle += 1
        msg = ml2.M2Command(body, (self.cycle & 0xF) << 4, ml2.Nop())
        self.sock.sendto(encode(Frame(Link.ML2, Kind.COMMAND, 0x21, self.cycle, TCYCLE, msg)), self.addr)
        for _ in range(200):
            await asyncio.sleep(0.005)
            try:
                return decode(self.sock.recv(4096), kind=Kind.RESPONSE)
            except BlockingIOError:
                continue
        raise AssertionError("no answer")


async def _server(state: Path) -> tuple[SlaveServer, _Udp]:
    # a scripted master sends when it likes: no silence verdicts (SI-T3 Table 22) in this test
    patient = CardOptions(silence_tolerance_ns=60_000_000_000)
    card = create_card("si-t3", settings=settings_for("si-t3", 0x21, 32, [], options=patient), now=0)
    server = SlaveServer([HostedStation(card, "127.0.0.1", 0)], state_dir=state)
    await server.start()
    master = _Udp(("127.0.0.1", server.stations[0].port))
    assert (await master.send(ml2.Connect(0x21, 0x80, 1))).message.alarm == 0
    return server, master


async def test_config_to_eeprom_is_not_complete_before_the_image_is_durable(tmp_path: Path,
                                                                             monkeypatch: pytest.MonkeyPatch) -> None:
    entered, release = threading.Event(), threading.Event()

    def slow_write(path: Path, data: bytes) -> None:
        entered.set()
        assert release.wait(10)
        atomic_write(path, data)

    monkeypatch.setattr(slave_mod, "atomic_write", slow_write)
    server, master = await _server(tmp_path)
    path = eeprom_path(tmp_path, "si-t3", 0x21)
    try:
        await master.send(ml2.PrmWr(0x0200, 2, (777).to_bytes(2, "little").ljust(8, b"\0")))
        first = await master.send(ml2.Config(1))
        assert not first.message.status & M2Status.CMDRDY  # busy: the image is not on disk yet
        await asyncio.get_running_loop().run_in_executor(None, entered.wait, 10)
        for _ in range(3):  # the master repeats the busy command; still busy while the write is in progress
            again = await master.send(ml2.Config(1))
            assert not again.message.status & M2Status.CMDRDY and not path.exists()
        # "command reception disabled": another command meanwhile is answered busy and not executed
        other = await master.send(ml2.PrmWr(0x0201, 2, (55).to_bytes(2, "little").ljust(8, b"\0")))
        assert not other.message.status & M2Status.CMDRDY
        assert server.stations[0].station.store.value("C1-02") == 100
        release.set()
        for _ in range(100):
            done = await master.send(ml2.Config(1))
            if done.message.status & M2Status.CMDRDY:
                break
        assert done.message.status & M2Status.CMDRDY and done.message.alarm == 0
        assert json.loads(path.read_bytes())["params"] == {"C1-01": 777}  # durable before the completion
        ready = await master.send(ml2.Nop())
        assert ready.message.status & M2Status.CMDRDY
    finally:
        release.set()
        master.sock.close()
        await server.close()


async def test_failed_write_completes_config_with_a94(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    def failing_write(path: Path, data: bytes) -> None:
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(slave_mod, "atomic_write", failing_write)
    server, master = await _server(tmp_path)
    try:
        for _ in range(100):
            r = await master.send(ml2.Config(1))
            if r.message.status & M2Status.CMDRDY:
                break
        assert r.message.alarm == M2Alarm.DATA_SETTING_WARNING and server.write_errors == 1
        assert (await master.send(ml2.Nop())).message.status & M2Status.CMDRDY
    finally:
        master.sock.close()
        await server.close()


async def test_stale_temporary_files_are_removed_at_start(tmp_path: Path) -> None:
    path = eeprom_path(tmp_path, "si-t3", 0x21)
    stale = [tmp_path / f".{path.name}.abc{i}.tmp" for i in range(3)]
    other = tmp_path / ".si-t3-22H.eeprom.json.xyz.tmp"  # another process's station: not ours to remove
    for p in (*stale, other):
        p.write_bytes(b"partial")
    server, master = await _server(tmp_path)
    try:
        assert not any(p.exists() for p in stale) and other.exists()
    finally:
        master.sock.close()
        await server.close()
    assert remove_stale_temps(path) == 0
