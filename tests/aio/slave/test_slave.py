"""The slave server's I/O (mlink_sim.aio.slave.server): a backlog of commands from one source is cut to the newest eight
(the older ones counted SUPERSEDED), each source of a batch is answered, and a single command is answered at once."""

from __future__ import annotations

import asyncio
import socket
import time

import pytest

from mlink_sim.aio.slave import server as slave_module
from mlink_sim.aio.control.slave import serve_slave
from mlink_sim.aio.slave.server import HostedStation, SlaveServer
from mlink_sim.aio.transport import mmsg
from mlink_sim.cards import create_card, settings_for
from mlink_sim.config.units import parse_arrival_poll
from mlink_sim.wire import Frame, Kind, Link, decode, encode, ml2

TCYCLE = 1_000_000


def _nop(cycle: int) -> bytes:
    """NOP (SI-T3 Table 6: allowed in phase 1) to station 21H."""
    return encode(Frame(Link.ML2, Kind.COMMAND, 0x21, cycle, TCYCLE, ml2.M2Command(ml2.Nop(), 0)))


async def _server(arrival_poll: tuple[int, int | None] | None = None) -> tuple[SlaveServer, tuple[str, int]]:
    card = create_card("si-t3", settings=settings_for("si-t3", 0x21, 17, []), now=0)
    server = SlaveServer([HostedStation(card, "127.0.0.1", 0)], arrival_poll=arrival_poll)
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


@pytest.mark.parametrize("poll", [None, "1ms"])
async def test_tick_reads_waiting_commands_before_it_counts_silence(poll: str | None) -> None:
    """A worker held up past a station's reception deadline: the tick runs before the reader, so it must read the
    queued commands first; otherwise they count as reception failures (SI-T3 Table 22, E6 after two). The same
    with an arrival poll set and armed on the socket (mlink_sim.aio.timing.arrival): the tick's read is the poll's too."""
    server, addr = await _server(parse_arrival_poll(poll) if poll else None)
    master = _client()
    station = server.stations[0].station
    endpoint = server.stations[0].endpoint
    assert endpoint is not None and (endpoint.poll is not None) == bool(poll)
    if endpoint.poll is not None:  # a 1 ms cycle learned, the next burst due now: the poll set and waiting
        endpoint.poll.period_ns = 1_000_000
        endpoint.poll.arrived(time.monotonic_ns() - 1_000_000)
        assert endpoint.poll.armed
    set_at = endpoint.poll.poll_at_ns if endpoint.poll is not None else 0
    try:
        station.silence_due = lambda now: True  # type: ignore[method-assign]  # deadline passed
        station.next_deadline = lambda: 0  # type: ignore[method-assign]
        for cycle in (1, 2):
            master.sendto(_nop(cycle), addr)  # on loopback: waiting in the receive buffer at once
        assert station.counters.rx_ok == 0  # no await since: the loop's reader has not run
        server._on_tick()
        assert station.counters.rx_ok == 2  # read by the tick itself, before it polled
        if endpoint.poll is not None:  # the burst the tick read set the poll for the next cycle
            assert endpoint.poll.armed and endpoint.poll.poll_at_ns >= set_at + 1_000_000
        assert await _answers(master, settle=0.05) == [1, 2]
    finally:
        master.close()
        await server.close()


def test_no_silence_is_due_before_phase_2() -> None:
    card = create_card("si-t3", settings=settings_for("si-t3", 0x21, 17, []), now=0)
    assert card.phase == 1 and card.silence_due(10**12) is False


async def _shared_server(*addresses: int, batched: bool = True) -> SlaveServer:
    stations = [HostedStation(create_card("si-t3", settings=settings_for("si-t3", a, 17, []), now=0), "127.0.0.1", 0)
                for a in addresses]
    server = SlaveServer(stations, shared=True, batched=batched)
    await server.start()
    return server


def _nop_to(address: int, cycle: int) -> bytes:
    return encode(Frame(Link.ML2, Kind.COMMAND, address, cycle, TCYCLE, ml2.M2Command(ml2.Nop(), 0)))


@pytest.mark.parametrize("batched", [True, False], ids=["recvmmsg", "recvfrom"])
async def test_shared_port_the_address_byte_picks_the_station(batched: bool) -> None:
    """A packed worker's stations share one port, as stations share a bus (``SlaveServer(shared=True)``): each
    command reaches the station its address byte names (docs/wire-format.md, byte 3: the station address each card
    is set to with F6-20, SI-T3 Table 4, SI-ET3 Table 7), the answers come back from that port, and a command for
    no station there is counted, not answered; the same with the batched calls and without them."""
    server = await _shared_server(0x21, 0x22, 0x23, batched=batched)
    master = _client()
    try:
        sock = server.stations[0].endpoint._sock  # type: ignore[union-attr]
        assert isinstance(sock, mmsg.BurstSocket) is (batched and mmsg.supported())
        ports = {hs.port for hs in server.stations}
        assert len(ports) == 1 and 0 not in ports
        addr = ("127.0.0.1", ports.pop())
        for address in (0x23, 0x21, 0x22, 0x30):
            master.sendto(_nop_to(address, 7), addr)
        await asyncio.sleep(0.2)
        answers = []
        while True:
            try:
                data, source = master.recvfrom(4096)
            except BlockingIOError:
                break
            assert source == addr
            answers.append(decode(data, kind=Kind.RESPONSE).station)
        assert sorted(answers) == [0x21, 0x22, 0x23]
        assert server.unaddressed == 1 and server.stats()["unaddressed"] == 1
        assert [hs.responses for hs in server.stations] == [1, 1, 1]
    finally:
        master.close()
        await server.close()


async def test_shared_port_yields_after_the_answers_went_and_before_the_cards_settle(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """A packed worker sends a read's answers, yields once (``realtime.yield_after_send``: the master, woken on this
    CPU, reads them now, not after the cards' work), then settles (``Bus.settle``)."""
    events: list[str] = []
    master = _client()
    real_bus = slave_module.Bus

    class SpyBus:  # the compiled Bus, its settle recorded
        def __init__(self, *args: object, **kwargs: object) -> None:
            self._bus = real_bus(*args, **kwargs)

        def __getattr__(self, name: str) -> object:
            return getattr(self._bus, name)

        def settle(self) -> None:
            events.append("settle")
            self._bus.settle()

    def pause() -> None:  # the answers are on the master's socket already
        events.append("yield with answers waiting" if master.recv(4096, socket.MSG_PEEK) else "yield")

    monkeypatch.setattr(slave_module, "Bus", SpyBus, raising=True)
    monkeypatch.setattr(slave_module.os, "sched_yield", pause)  # what realtime.yield_after_send hands out
    expected = ["yield with answers waiting", "settle"]
    server = await _shared_server(0x21, 0x22)
    try:
        addr = ("127.0.0.1", server.stations[0].port)
        master.sendto(_nop_to(0x21, 1), addr)
        master.sendto(_nop_to(0x22, 1), addr)
        await asyncio.sleep(0.2)
        assert events == expected * (len(events) // len(expected)) and events
        assert sorted(await _answers(master, settle=0)) == [1, 1]
    finally:
        await server.close()
    master.close()


async def test_shared_port_keeps_each_stations_backlog_rule() -> None:
    server = await _shared_server(0x21, 0x22)
    master = _client()
    try:
        addr = ("127.0.0.1", server.stations[0].port)
        for cycle in range(1, 13):  # station 21H twelve cycles behind, 22H three: one batch
            master.sendto(_nop_to(0x21, cycle), addr)
            if cycle <= 3:
                master.sendto(_nop_to(0x22, 100 + cycle), addr)
        await asyncio.sleep(0.2)
        got: dict[int, list[int]] = {}
        while True:
            try:
                frame = decode(master.recv(4096), kind=Kind.RESPONSE)
            except BlockingIOError:
                break
            got.setdefault(frame.station, []).append(frame.cycle)
        assert got == {0x21: list(range(5, 13)), 0x22: [101, 102, 103]}
        assert server.stations[0].station.counters.as_dict()["dropped_by_reason"].get("SUPERSEDED") == 4
        assert "SUPERSEDED" not in server.stations[1].station.counters.as_dict()["dropped_by_reason"]
    finally:
        master.close()
        await server.close()


async def test_stations_of_different_links_keep_ports_of_their_own() -> None:
    t3 = create_card("si-t3", settings=settings_for("si-t3", 0x21, 17, []), now=0)
    et3 = create_card("si-et3", settings=settings_for("si-et3", 0x21, 32, []), now=0)
    server = SlaveServer([HostedStation(t3, "127.0.0.1", 0), HostedStation(et3, "127.0.0.1", 0)],
                         shared=True)
    await server.start()
    try:  # the same address on two links: two buses, two ports
        assert server.stations[0].port != server.stations[1].port
    finally:
        await server.close()


async def test_arrival_poll_on_each_shared_socket_or_a_lone_station_s_only() -> None:
    """``SlaveServer(arrival_poll=…)`` (mlink_sim.aio.timing.arrival): a poll on each shared socket and on a worker's
    only socket, none on the sockets of a worker hosting several stations each on its own port (their polls would hold
    each other up); the worker's ``cpu`` reply carries the polls' counters."""
    setting = parse_arrival_poll("auto")

    def cards(*addresses: int) -> list[HostedStation]:
        return [HostedStation(create_card("si-t3", settings=settings_for("si-t3", a, 17, []), now=0), "127.0.0.1", 0)
                for a in addresses]

    for stations, shared, polls in ((cards(0x21, 0x22), True, 1), (cards(0x21), False, 1),
                                    (cards(0x21, 0x22), False, 0)):
        server = SlaveServer(stations, shared=shared, arrival_poll=setting)
        await server.start()
        try:
            endpoints = {id(hs.endpoint): hs.endpoint for hs in server.stations}.values()
            assert sum(ep is not None and ep.poll is not None for ep in endpoints) == polls
            keys = {"period_ns", "windows", "caught", "spun_ns", "lead_ns", "idle_cpus_poll"}
            assert set(server.cpu()["arrival_poll"]) == (keys if polls else set())
        finally:
            await server.close()
    server = SlaveServer(cards(0x21))  # the default: no poll
    await server.start()
    try:
        assert server.stations[0].endpoint is not None and server.stations[0].endpoint.poll is None
    finally:
        await server.close()


async def test_a_stats_reply_is_built_between_bursts_and_says_what_stats_says() -> None:
    """``{"op": "stats"}`` is answered one station at a time (``SlaveServer.stats_text``): a command that came
    while the reply was built is answered before the reply goes, and the reply is :meth:`SlaveServer.stats` as
    one compact JSON datagram (docs/performance.md)."""
    import json

    addresses = list(range(0x21, 0x29))
    stations = [HostedStation(create_card("si-t3", settings=settings_for("si-t3", a, 17, []), now=0), "127.0.0.1", 0)
                for a in addresses]
    server = SlaveServer(stations, shared=True)
    await server.start()
    endpoint, _, control = await serve_slave(server, "127.0.0.1", 0, None)
    client = _client()
    try:
        client.sendto(json.dumps({"op": "stats"}).encode(), control)
        client.sendto(_nop_to(0x21, 7), ("127.0.0.1", stations[0].port))
        got: list[bytes] = []
        for _ in range(200):
            await asyncio.sleep(0.005)
            try:
                got.append(client.recv(65536))
            except BlockingIOError:
                pass
            if len(got) == 2:
                break
        assert len(got) == 2
        assert decode(got[0], kind=Kind.RESPONSE).station == 0x21  # the command first
        reply = json.loads(got[1])
        expected = {"ok": True, **server.stats(), "control_refused": 0, "regulation": {}}  # no drive regulating
        assert sorted(reply) == sorted(expected)
        assert reply["stations"] == json.loads(json.dumps(expected["stations"]))
        assert sorted(reply["stations"]) == [f"{a:#04x}" for a in addresses]
        assert reply["ok"] is True and reply["unaddressed"] == 0
        assert b", " not in got[1] and b": " not in got[1][:200]  # compact, as every control reply
    finally:
        client.close()
        endpoint.close()
        await server.close()


async def test_a_stats_reply_still_being_built_is_dropped_at_close() -> None:
    stations = [HostedStation(create_card("si-t3", settings=settings_for("si-t3", a, 17, []), now=0), "127.0.0.1", 0)
                for a in (0x21, 0x22)]
    server = SlaveServer(stations, shared=True)
    await server.start()
    endpoint, _, control = await serve_slave(server, "127.0.0.1", 0, None)
    client = _client()
    try:
        import json

        client.sendto(json.dumps({"op": "stats"}).encode(), control)
        for _ in range(200):
            await asyncio.sleep(0)
            if endpoint._tasks:
                break
        assert endpoint._tasks
        endpoint.close()
        await server.close()
        await asyncio.sleep(0)
        assert not endpoint._tasks
        await asyncio.sleep(0.05)
        with pytest.raises(BlockingIOError):
            client.recv(65536)
    finally:
        client.close()


async def test_a_stats_reply_is_paced_only_for_so_long(monkeypatch) -> None:
    """The pause between two stations (``_STATS_PACE_S``) stops once the build has taken ``_STATS_PACED_S``: with
    a 0.5 s pause and no paced time at all, eight stations answer at once instead of after 4 s."""
    import json

    monkeypatch.setattr(slave_module, "_STATS_PACE_S", 0.5)
    monkeypatch.setattr(slave_module, "_STATS_PACED_S", 0.0)
    stations = [HostedStation(create_card("si-t3", settings=settings_for("si-t3", a, 17, []), now=0), "127.0.0.1", 0)
                for a in range(0x21, 0x29)]
    server = SlaveServer(stations, shared=True)
    await server.start()
    endpoint, _, control = await serve_slave(server, "127.0.0.1", 0, None)
    client = _client()
    try:
        client.sendto(json.dumps({"op": "stats"}).encode(), control)
        for _ in range(100):  # 0.5 s at most: a single paced pause would take that long
            await asyncio.sleep(0.005)
            try:
                reply = json.loads(client.recv(65536))
                break
            except BlockingIOError:
                continue
        else:
            raise AssertionError("no stats reply within 0.5 s")
        assert len(reply["stations"]) == 8
    finally:
        client.close()
        endpoint.close()
        await server.close()


async def _until(predicate, timeout: float = 5.0) -> bool:
    """Poll *predicate* every 20 ms for up to *timeout* seconds of the wall clock (a generous bound: the outcome
    is what the test checks, not how soon)."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if predicate():
            return True
        await asyncio.sleep(0.02)
    return False


async def test_a_host_name_s_filter_follows_it_and_a_source_the_kernel_refused_makes_it_resolve_again() -> None:
    """``--allow-master localhost:PORT``: the kernel's filter takes the master once the name resolved and drops a
    stranger's datagram (the card never counts it); that drop makes the list resolve the name again (a container's
    address may have changed), once a second at most."""
    from mlink_sim.aio.slave.allow import AllowList

    master, stranger = _client(), _client()
    allow = AllowList([f"localhost:{master.getsockname()[1]}"])
    resolved = []
    resolve = allow.resolve
    allow.resolve = lambda: (resolve(), resolved.append(time.monotonic()))[0]
    card = create_card("si-t3", settings=settings_for("si-t3", 0x21, 17, []), now=0)
    server = SlaveServer([HostedStation(card, "127.0.0.1", 0)], allow=allow)
    await server.start()
    addr = ("127.0.0.1", server.stations[0].port)
    try:
        assert await _until(lambda: len(resolved) == 1 and not allow.stale)
        master.sendto(_nop(1), addr)
        assert await _answers(master) == [1]
        stranger.sendto(_nop(2), addr)
        assert await _answers(stranger) == []
        assert await _until(lambda: len(resolved) == 2)
        assert card.counters.as_dict()["foreign_source"] == 0 and (server.socket_drops() or 0) >= 1
    finally:
        master.close()
        stranger.close()
        await server.close()
