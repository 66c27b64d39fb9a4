"""Batched UDP calls (mlink_sim.aio.transport.mmsg): a burst goes out in order to every destination, reads return what
is waiting (and [] rather than an exception when nothing is), source addresses read as ``recvfrom`` reads them, a
failed datagram does not take the rest of the burst with it, and where a caller asks for the per-datagram calls
(``batched=False``) it gets them."""

from __future__ import annotations

import asyncio
import socket
import time

import pytest

from mlink_sim.aio.transport import mmsg
from mlink_sim.aio.transport.udp import BatchEndpoint, open_batch_endpoint

pytestmark = pytest.mark.skipif(not mmsg.supported(), reason="sendmmsg/recvmmsg not available here")


def _udp(family: int = socket.AF_INET) -> socket.socket:
    s = socket.socket(family, socket.SOCK_DGRAM)
    s.bind(("::1" if family == socket.AF_INET6 else "127.0.0.1", 0))
    s.setblocking(False)
    return s


def _drain(sock: socket.socket) -> list[tuple[bytes, object]]:
    time.sleep(0.02)  # loopback delivers at once; a margin for a loaded machine
    out = []
    while True:
        try:
            out.append(sock.recvfrom(4096))
        except BlockingIOError:
            return out


def test_a_burst_reaches_every_destination_in_order() -> None:
    tx, rx = mmsg.BurstSocket(_udp()), [_udp() for _ in range(3)]
    try:
        items = [(bytes([i]) * (5 + i), rx[i % 3].getsockname()) for i in range(9)]
        assert tx.send_burst(items) == []
        for k, sock in enumerate(rx):
            got = _drain(sock)
            assert [d for d, _ in got] == [bytes([i]) * (5 + i) for i in range(k, 9, 3)]
            assert {a for _, a in got} == {tx.getsockname()}
        # the same layout again (headers reused), then a new one (rewritten)
        assert tx.send_burst(items[:3]) == [] and tx.send_burst(items[:3]) == []
        assert tx.send_burst([(b"longer datagram", rx[0].getsockname())]) == []
        assert [d for d, _ in _drain(rx[0])] == [b"\x00" * 5, b"\x00" * 5, b"longer datagram"]
    finally:
        tx.close()
        for s in rx:
            s.close()


def test_bursts_beyond_one_call_and_beyond_the_buffer() -> None:
    tx, rx = mmsg.BurstSocket(_udp()), mmsg.BurstSocket(_udp())
    try:
        items = [(i.to_bytes(2, "big") * 150, rx.getsockname()) for i in range(mmsg.CAPACITY * 2 + 5)]
        assert tx.send_burst(items) == []
        time.sleep(0.02)
        got: list[bytes] = []
        while batch := rx.recv_burst(1000):
            assert len(batch) <= mmsg.CAPACITY
            got += batch
        assert got == [d for d, _ in items]
    finally:
        tx.close()
        rx.close()


def test_reads_return_nothing_without_raising_and_respect_the_limit() -> None:
    tx, rx = _udp(), mmsg.BurstSocket(_udp())
    try:
        assert rx.recv_burst() == [] and rx.recvfrom_burst() == []
        for i in range(5):
            tx.sendto(b"%d" % i, rx.getsockname())
        time.sleep(0.02)
        assert rx.recvfrom_burst(2) == [(b"0", tx.getsockname()), (b"1", tx.getsockname())]
        assert rx.recv_burst() == [b"2", b"3", b"4"]
        assert rx.recv_burst() == []
    finally:
        tx.close()
        rx.close()


def test_ipv6_sources_read_as_recvfrom_reads_them() -> None:
    try:
        tx = _udp(socket.AF_INET6)
    except OSError:
        pytest.skip("no IPv6 loopback here")
    rx = mmsg.BurstSocket(_udp(socket.AF_INET6))
    try:
        assert mmsg.BurstSocket(tx).send_burst([(b"six", rx.getsockname())]) == []
        time.sleep(0.02)
        assert rx.recvfrom_burst() == [(b"six", tx.getsockname())]
    finally:
        tx.close()
        rx.close()


def test_a_failed_datagram_is_reported_and_the_rest_go() -> None:
    tx, rx = mmsg.BurstSocket(_udp()), _udp()
    try:
        # port 0 is no destination: EINVAL for that one (the kernel refuses it), the others are sent
        items = [(b"a", rx.getsockname()), (b"b", ("127.0.0.1", 0)), (b"c", rx.getsockname())]
        failures = tx.send_burst(items)
        assert [i for i, _ in failures] == [1] and isinstance(failures[0][1], OSError)
        assert [d for d, _ in _drain(rx)] == [b"a", b"c"]
    finally:
        tx.close()
        rx.close()


def test_a_destination_by_name_is_sent_one_by_one() -> None:
    tx, rx = mmsg.BurstSocket(_udp()), _udp()
    try:
        assert tx.send_burst([(b"x", ("localhost", rx.getsockname()[1])), (b"y", rx.getsockname())]) == []
        assert [d for d, _ in _drain(rx)] == [b"x", b"y"]
    finally:
        tx.close()
        rx.close()


def test_asked_for_plain_calls_the_sockets_stay_plain() -> None:
    sock = _udp()
    try:
        assert mmsg.wrap(sock, batched=False) is sock
        wrapped = mmsg.wrap(sock)
        assert isinstance(wrapped, mmsg.BurstSocket) and wrapped.sock is sock
    finally:
        sock.close()


@pytest.mark.parametrize("batched", [True, False], ids=["recvmmsg", "recvfrom"])
async def test_batch_endpoint_reads_the_same_either_way(batched: bool) -> None:
    batches: list[list[tuple[bytes, object]]] = []
    ep = await open_batch_endpoint(batches.append, batched=batched, burst=100)
    tx = _udp()
    try:
        assert isinstance(ep, BatchEndpoint)
        assert isinstance(ep._sock, mmsg.BurstSocket) is batched
        for i in range(mmsg.CAPACITY + 10):  # more than one recvmmsg holds: read in one wake-up all the same
            tx.sendto(b"%d" % i, ep.local_address)
        await asyncio.sleep(0.05)
        assert len(batches) == 1
        assert batches[0] == [(b"%d" % i, tx.getsockname()) for i in range(mmsg.CAPACITY + 10)]
    finally:
        tx.close()
        ep.close()
