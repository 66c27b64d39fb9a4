"""The impairment layer on real sockets (mlink_sim/aio/transport/impaired.py): a delayed datagram leaves at its time, a
dropped one never, responses go through the layer too, and the master's socket is wrapped only while a fault is
in place (docs/faults.md). Loopback UDP, port 0; bounded in time."""

from __future__ import annotations

import asyncio
import socket
import time

from mlink_sim.aio.transport.impaired import ImpairedSocket
from mlink_sim.aio.master.runner import Master, NullMetrics
from mlink_sim.impair import Impairment, ImpairmentLayer
from mlink_sim.master import MasterCore, NetworkPlan, StationPlan
from mlink_sim.wire import Link

MS = 1_000_000


def _sock() -> socket.socket:
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.bind(("127.0.0.1", 0))
    s.setblocking(False)
    return s


def _pair() -> tuple[socket.socket, socket.socket]:
    return _sock(), _sock()


def _datagram(station: int = 0x21) -> bytes:
    return bytes([0x4D, 2, 1, station]) + bytes(46)


async def _recv(sock: socket.socket, timeout: float) -> tuple[bytes, int] | None:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        try:
            return sock.recv(4096), time.monotonic_ns()
        except BlockingIOError:
            await asyncio.sleep(0.0005)
    return None


async def test_commands_are_delayed_dropped_and_responses_go_through_the_layer() -> None:
    a, b = _pair()
    layer = ImpairmentLayer(seed=1)
    layer.impair(Impairment(delay=20 * MS, direction="to-station"), 0x21, time.monotonic_ns())
    layer.impair(Impairment(loss=1.0), 0x22, time.monotonic_ns())
    ready, idle = [], []
    wrapped = ImpairedSocket(a, layer, asyncio.get_running_loop(), on_ready=lambda: ready.append(1),
                             on_error=lambda exc: None, on_idle=lambda: idle.append(1))
    try:
        sent = time.monotonic_ns()
        wrapped.sendto(_datagram(0x22), b.getsockname())  # lost
        wrapped.sendto(_datagram(0x21), b.getsockname())  # 20 ms late
        got = await _recv(b, 1.0)
        assert got is not None and got[0] == _datagram(0x21) and got[1] - sent >= 20 * MS
        assert await _recv(b, 0.05) is None
        b.sendto(_datagram(0x22), a.getsockname())  # a response from 22H: lost on the way back
        b.sendto(_datagram(0x21), a.getsockname())  # 21H's responses are not impaired
        await asyncio.sleep(0.02)
        assert wrapped.recv(4096) == _datagram(0x21)
        assert layer.injected() == {0x21: {"delays": 1}, 0x22: {"drops": 2}}
        layer.heal(None, time.monotonic_ns())
        wrapped.sendto(_datagram(0x22), b.getsockname())
        assert idle == [1]  # nothing in place, nothing held: the master may take its socket back
    finally:
        wrapped.close()
        b.close()


async def test_the_master_socket_is_wrapped_only_while_a_fault_is_in_place() -> None:
    plan = NetworkPlan(Link.ML2, 4 * MS, (StationPlan(0x21, Link.ML2),))
    loop = asyncio.get_running_loop()
    master = Master(MasterCore(plan), {0x21: ("127.0.0.1", 9)}, NullMetrics(), loop)
    raw, peer = _pair()
    master._sock = raw
    layer = ImpairmentLayer(seed=1)
    master.impair_with(layer)
    assert master._sock is raw  # idle layer: not in the path
    layer.impair(Impairment(loss=0.5, for_ns=5 * MS), None, time.monotonic_ns())
    master.impair_with(layer)
    assert isinstance(master._sock, ImpairedSocket)
    await asyncio.sleep(0.01)
    master._sock.sendto(_datagram(0x21), peer.getsockname())  # the fault has ended by now
    assert master._sock is raw
    raw.close()
    peer.close()


async def test_the_proxy_forwards_both_ways_per_link_and_impairs_per_station() -> None:
    from mlink_sim.aio.tools.proxy import ImpairingProxy

    loop = asyncio.get_running_loop()
    slaves = [_sock() for _ in range(2)]  # echo "slaves" for 21H and 22H

    def echo(sock: socket.socket) -> None:
        while True:
            try:
                data, addr = sock.recvfrom(4096)
            except BlockingIOError:
                return
            sock.sendto(data, addr)

    for s in slaves:
        loop.add_reader(s.fileno(), echo, s)
    proxy = ImpairingProxy([(("127.0.0.1", 0), s.getsockname()) for s in slaves], ImpairmentLayer(seed=1))
    await proxy.start()
    master = _sock()
    try:
        proxy.impair(0x22, Impairment(loss=1.0, direction="to-master"))
        for link, station in zip(proxy.links, (0x21, 0x22)):
            master.sendto(_datagram(station), link.listen)
        got = await _recv(master, 1.0)
        assert got is not None and got[0] == _datagram(0x21)
        assert await _recv(master, 0.1) is None  # 22H's answer was lost on the way back
        totals = proxy.totals()
        assert totals["to_station"] == 2 and totals["to_master"] == 2
        assert proxy.impairments.injected() == {0x22: {"drops": 1}}
        assert proxy.heal() == ["loss-22H-1"] and not proxy.impairments.active
    finally:
        proxy.close()
        master.close()
        for s in slaves:
            loop.remove_reader(s.fileno())
            s.close()
