"""Batched UDP calls (mlink_sim.aio.mmsg): a burst goes out in order to every destination, reads return what is
waiting (and [] rather than an exception when nothing is), source addresses read as ``recvfrom`` reads them, a
failed datagram does not take the rest of the burst with it, and where the calls are switched off every user
falls back to the per-datagram calls."""

from __future__ import annotations

import asyncio
import os
import socket
import time

import pytest

from mlink_sim.aio import mmsg
from mlink_sim.aio.udp import BatchEndpoint, open_batch_endpoint

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


@pytest.mark.skipif(not mmsg.stamps_supported(), reason="kernel receive timestamps not supported here")
def test_stamped_reads_keep_the_kernels_arrival_time() -> None:
    """SO_TIMESTAMPNS (<asm-generic/socket.h>): a datagram read long after it came keeps the time it came, on the
    monotonic clock; the stamps come in arrival order, and beyond one recvmmsg the slots' control buffers are
    reused."""
    tx, rx = _udp(), mmsg.BurstSocket(_udp())
    try:
        assert rx.enable_stamps() and rx.enable_stamps() and rx.stamped
        # The kernel turns receive stamping on a moment after the first socket asks (net/core/dev.c, netstamp_work);
        # until then a datagram is stamped when it is read (later than it came, never earlier).
        time.sleep(0.05)
        before = time.monotonic_ns()
        for i in range(mmsg.CAPACITY + 6):
            tx.sendto(b"%d" % i, rx.getsockname())
        after = time.monotonic_ns()
        time.sleep(0.05)  # read 50 ms after they came
        read_at = time.monotonic_ns()
        got: list[tuple[bytes, int]] = []
        while batch := rx.recv_burst_stamped(1000):
            assert len(batch) <= mmsg.CAPACITY
            got += batch
        assert [d for d, _ in got] == [b"%d" % i for i in range(mmsg.CAPACITY + 6)]
        stamps = [t for _, t in got]
        assert stamps == sorted(stamps)
        assert before - 1_000_000 <= stamps[0] and stamps[-1] <= after + 1_000_000 < read_at  # 1 ms: clock offset
        assert rx.recv_burst_stamped() == []
        tx.sendto(b"again", rx.getsockname())  # the control lengths were restored after the first reads
        time.sleep(0.02)
        ((data, t),) = rx.recv_burst_stamped(1)
        assert data == b"again" and read_at < t <= time.monotonic_ns()
    finally:
        tx.close()
        rx.close()


def test_stamps_are_opt_in(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("MLINK_RX_STAMPS", raising=False)
    assert not mmsg.stamps_enabled()
    monkeypatch.setenv("MLINK_RX_STAMPS", "0")
    assert not mmsg.stamps_enabled()
    monkeypatch.setenv("MLINK_RX_STAMPS", "1")
    assert mmsg.stamps_enabled() is mmsg.stamps_supported()


def test_the_yield_after_a_send_is_on_unless_switched_off(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("MLINK_YIELD", raising=False)
    assert mmsg.yield_after_send() is getattr(os, "sched_yield", None)
    monkeypatch.setenv("MLINK_YIELD", "off")
    assert mmsg.yield_after_send() is None
    assert mmsg.yielder("MLINK_POLL_YIELD") is getattr(os, "sched_yield", None)  # each switch its own
    monkeypatch.setenv("MLINK_POLL_YIELD", "0")
    assert mmsg.yielder("MLINK_POLL_YIELD") is None


def test_switched_off_the_sockets_stay_plain(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("MLINK_MMSG", "0")
    sock = _udp()
    try:
        assert not mmsg.supported() and mmsg.wrap(sock) is sock
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
