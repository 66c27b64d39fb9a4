"""Segmentation offload (mlink_sim.aio.transport.mmsg, "Segmentation offload"): a burst's datagrams of one size to one
destination leave as one offloaded message (``UDP_SEGMENT``) and still arrive as separate datagrams, in order; a socket
that reads with ``UDP_GRO`` gets such a burst as one buffer and every read cuts it again (the batched reads and the
per-datagram ``recv``/``recvfrom``); where the kernel refuses the offload the burst still goes; ``gso=False``
turns it off for a socket; a capture's socket never reads coalesced buffers."""

from __future__ import annotations

import socket
import struct
import time
from collections import deque
from typing import Any

import pytest

from mlink_sim.aio.transport import mmsg
from mlink_sim.aio.transport.tapped import TappedBurstSocket

from .test_mmsg import _drain

pytestmark = pytest.mark.skipif(not mmsg.gso_supported(), reason="UDP segmentation offload not available here")


def _udp() -> socket.socket:
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.bind(("127.0.0.1", 0))
    s.setblocking(False)
    return s


def _settle() -> None:
    time.sleep(0.02)  # loopback delivers at once; a margin for a loaded machine


def _plain_reads(sock: socket.socket) -> list[bytes]:
    return [data for data, _ in _drain(sock)]


def test_an_offloaded_burst_reaches_a_plain_socket_as_separate_datagrams() -> None:
    tx, rx = mmsg.BurstSocket(_udp()), _udp()
    try:
        items = [(bytes([i]) * 46, rx.getsockname()) for i in range(62)] + [(b"short", rx.getsockname())]
        assert tx.send_burst(items) == []
        assert tx._sgroups is not None  # the offload was used
        assert _plain_reads(rx) == [d for d, _ in items]
    finally:
        tx.close()
        rx.close()


def test_a_gro_reader_cuts_every_burst_again() -> None:
    tx, rx = mmsg.BurstSocket(_udp()), mmsg.BurstSocket(_udp())
    try:
        assert rx.enable_gro() and rx.gro
        here = rx.getsockname()
        burst = [(i.to_bytes(2, "big") * 23, here) for i in range(40)]
        assert tx.send_burst(burst + [(b"tail", here)]) == []
        _settle()
        got = rx.recvfrom_burst(1)  # a coalesced buffer is never cut off: all of it comes, beyond the limit
        assert [d for d, _ in got] == [d for d, _ in burst]
        assert {a for _, a in got} == {tx.getsockname()}
        assert rx.recv_burst() == [b"tail"]  # sent alone: a datagram of its own
        assert rx.recv_burst() == []
        # one read takes up to four buffers, never more buffers than datagrams are asked for
        for _ in range(3):
            assert tx.send_burst(burst[:6] + [(b"tail", here)]) == []
        _settle()
        assert rx.recv_burst(2) == [d for d, _ in burst[:6]] + [b"tail"]
        assert rx.recv_burst(8) == ([d for d, _ in burst[:6]] + [b"tail"]) * 2
        assert rx.recv_burst() == []
        # one datagram at a time (what an impaired master's reads use): the rest of a buffer waits for the next
        assert tx.send_burst(burst[:5]) == []
        _settle()
        assert [rx.recv(4096) for _ in range(3)] == [d for d, _ in burst[:3]]
        assert rx.recvfrom(4096) == (burst[3][0], tx.getsockname())
        assert rx.recv_burst() == [burst[4][0]]
        with pytest.raises(BlockingIOError):
            rx.recvfrom(4096)
    finally:
        tx.close()
        rx.close()


def test_a_gro_reader_cuts_a_peers_short_last_segment_and_keeps_each_shape_apart() -> None:
    """A peer's offloaded send may end with a shorter datagram (UDP_SEGMENT cuts the tail as it is): the read gives
    it as it was sent. Bursts of different shapes one after the other are each cut by their own size."""
    tx, rx = _udp(), mmsg.BurstSocket(_udp())
    try:
        assert rx.enable_gro()
        here = rx.getsockname()
        seg = struct.pack("=H", 10)
        blob = bytes(range(35))
        tx.sendmsg([blob], [(socket.SOL_UDP, 103, seg)], 0, here)  # UDP_SEGMENT, <linux/udp.h>
        tx.sendmsg([bytes(range(64))], [(socket.SOL_UDP, 103, struct.pack("=H", 16))], 0, here)
        _settle()
        got = rx.recvfrom_burst()
        assert [d for d, _ in got] == [blob[0:10], blob[10:20], blob[20:30], blob[30:35]] + [
            bytes(range(i, i + 16)) for i in range(0, 64, 16)]
        assert {a for _, a in got} == {tx.getsockname()}
    finally:
        tx.close()
        rx.close()


_SO_NO_CHECK = 11  # <asm-generic/socket.h>: no UDP checksum on send, which the kernel's offload refuses (EINVAL)


def _no_offload() -> socket.socket:
    """A socket whose every offloaded send the kernel refuses, as a route whose device cannot checksum does."""
    s = _udp()
    s.setsockopt(socket.SOL_SOCKET, _SO_NO_CHECK, 1)
    return s


@pytest.mark.parametrize("lead", [0, 3], ids=["refused-first", "refused-after-singles"])
def test_an_offload_the_kernel_refuses_falls_back_and_loses_nothing(lead: int) -> None:
    tx, rx, other = mmsg.BurstSocket(_no_offload()), _udp(), _udp()
    try:
        singles = [(b"s" * (i + 1), other.getsockname()) for i in range(lead)]  # one message each, sent first
        items = singles + [(bytes([i]) * 30, rx.getsockname()) for i in range(70)]  # two offloaded messages
        assert tx.send_burst(items) == []
        assert not tx._gso and tx._sgroups is None  # one message per datagram from then on
        assert tx.send_burst(items) == []
        assert _plain_reads(rx) == [d for d, _ in items[lead:]] * 2
        assert _plain_reads(other) == [d for d, _ in singles] * 2
    finally:
        tx.close()
        rx.close()


def test_without_the_offload_each_datagram_is_its_own_message() -> None:
    tx, rx = mmsg.BurstSocket(_udp(), gso=False), mmsg.BurstSocket(_udp(), gso=False)
    try:
        assert not rx.enable_gro()
        items = [(b"x" * 20, rx.getsockname())] * 4
        assert tx.send_burst(items) == [] and tx._sgroups is None
        _settle()
        assert rx.recv_burst() == [b"x" * 20] * 4
    finally:
        tx.close()
        rx.close()


def test_a_captured_socket_reads_datagram_by_datagram() -> None:
    queue: deque[Any] = deque()
    tx, rx = mmsg.BurstSocket(_udp()), TappedBurstSocket(_udp(), queue.append)
    try:
        assert not rx.enable_gro()
        items = [(bytes([i]) * 12, rx.getsockname()) for i in range(6)]
        assert tx.send_burst(items) == []
        _settle()
        assert rx.recv_burst() == [d for d, _ in items]
        assert [d for _, d, _, _ in queue] == [d for d, _ in items]  # each recorded on its own
    finally:
        tx.close()
        rx.close()
