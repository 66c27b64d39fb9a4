"""The slave server's I/O (mlink_sim.aio.slave): a backlog of commands from one source is cut to the newest eight
(the older ones counted SUPERSEDED), each source of a batch is answered, and a single command is answered at once."""

from __future__ import annotations

import asyncio
import socket

from mlink_sim.aio.slave import HostedStation, SlaveServer
from mlink_sim.cards import create_card, settings_for
from mlink_sim.wire import Frame, Kind, Link, decode, encode, ml2

TCYCLE = 1_000_000


def _nop(cycle: int) -> bytes:
    """NOP (SI-T3 Table 6: allowed in phase 1) to station 21H."""
    return encode(Frame(Link.ML2, Kind.COMMAND, 0x21, cycle, TCYCLE, ml2.M2Command(ml2.Nop(), 0)))


async def _server() -> tuple[SlaveServer, tuple[str, int]]:
    card = create_card("si-t3", settings=settings_for("si-t3", 0x21, 17, []), now=0)
    server = SlaveServer([HostedStation(card, "127.0.0.1", 0)], control=None)
    await server.start()
    return server, ("127.0.0.1", server.stations[0].port)


def _client() -> socket.socket:
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.bind(("127.0.0.1", 0))
    s.setblocking(False)
    return s


async def _answers(sock: socket.socket, settle: float = 0.2) -> list[int]:
    await asyncio.sleep(settle)
    cycles = []
    while True:
        try:
            data = sock.recv(4096)
        except BlockingIOError:
            return cycles
        cycles.append(decode(data, kind=Kind.RESPONSE).cycle)


async def test_backlog_from_one_source_keeps_the_newest_eight() -> None:
    server, addr = await _server()
    master, other = _client(), _client()
    try:
        for cycle in range(1, 13):  # all queued before the loop runs: one batch
            master.sendto(_nop(cycle), addr)
        other.sendto(_nop(100), addr)
        assert await _answers(master) == list(range(5, 13))
        assert await _answers(other, settle=0.0) == [100]
        counters = server.stations[0].station.counters.as_dict()
        assert counters["dropped_by_reason"].get("SUPERSEDED") == 4
    finally:
        master.close()
        other.close()
        await server.close()


async def test_a_short_backlog_is_answered_in_full() -> None:
    server, addr = await _server()
    master = _client()
    try:
        for cycle in range(1, 4):  # a 3-cycle hiccup: late, not lost
            master.sendto(_nop(cycle), addr)
        assert await _answers(master) == [1, 2, 3]
        assert "SUPERSEDED" not in server.stations[0].station.counters.as_dict()["dropped_by_reason"]
    finally:
        master.close()
        await server.close()


async def test_tick_reads_waiting_commands_before_it_counts_silence() -> None:
    """A worker held up past a station's reception deadline: the tick runs before the reader, so it must read the
    queued commands first; otherwise they count as reception failures (SI-T3 Table 22, E6 after two)."""
    server, addr = await _server()
    master = _client()
    station = server.stations[0].station
    try:
        station.silence_due = lambda now: True  # type: ignore[method-assign]  # deadline passed
        station.next_deadline = lambda: 0  # type: ignore[method-assign]
        for cycle in (1, 2):
            master.sendto(_nop(cycle), addr)  # on loopback: waiting in the receive buffer at once
        assert station.counters.rx_ok == 0  # no await since: the loop's reader has not run
        server._on_tick()
        assert station.counters.rx_ok == 2  # read by the tick itself, before it polled
        assert await _answers(master, settle=0.05) == [1, 2]
    finally:
        master.close()
        await server.close()


def test_no_silence_is_due_before_phase_2() -> None:
    card = create_card("si-t3", settings=settings_for("si-t3", 0x21, 17, []), now=0)
    assert card.phase == 1 and card.silence_due(10**12) is False
