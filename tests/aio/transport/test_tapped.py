"""A capture's tap on the batched calls (aio.transport.tapped.TappedBurstSocket): bursts and recvmmsg reads recorded
with their real addresses, failed datagrams left out, the per-datagram calls still tapped, and ``batched=False`` keeps
TappedSocket."""

from __future__ import annotations

import socket
import time
from collections import deque
from pathlib import Path

import pytest

from mlink_sim.aio.transport import mmsg
from mlink_sim.capture import CaptureWriter, read_capture
from mlink_sim.aio.transport.tapped import TappedBurstSocket, tap
from mlink_sim.aio.transport.udp import bound_socket
from mlink_sim.capture.tap import TappedSocket

pytestmark = pytest.mark.skipif(not mmsg.supported(), reason="sendmmsg/recvmmsg not available here")


def _udp(family: int = socket.AF_INET) -> socket.socket:
    return bound_socket("::1" if family == socket.AF_INET6 else "127.0.0.1", 0)


def _settle() -> None:
    time.sleep(0.02)  # loopback delivers at once; a margin for a loaded machine


@pytest.mark.parametrize("family", [socket.AF_INET, socket.AF_INET6])
def test_bursts_and_batched_reads_are_recorded_with_their_addresses(family: int) -> None:
    queue: deque = deque()
    master = TappedBurstSocket(_udp(family), queue.append)
    peers = [_udp(family) for _ in range(3)]
    try:
        here = master.getsockname()[:2]
        items = [(bytes([i]) * (10 + i), p.getsockname()) for i, p in enumerate(peers)]
        assert master.send_burst(items) == []
        assert [(d, s, r) for _, d, s, r in queue] == [(d, here, a) for d, a in items]
        assert len({ts for ts, *_ in queue}) == 1  # one burst, one time
        queue.clear()
        for i, p in enumerate(peers):  # three answers, read by one recvmmsg
            p.sendto(bytes([0x80 + i]) * 5, master.getsockname())
        _settle()
        got = master.recv_burst()
        assert got == [bytes([0x80 + i]) * 5 for i in range(3)]
        assert [(d, s[:2], r) for _, d, s, r in queue] == [(d, p.getsockname()[:2], here) for d, p in zip(got, peers)]
        queue.clear()
        peers[1].sendto(b"one", master.getsockname())  # one answer: the common case
        _settle()
        assert master.recv_burst(1) == [b"one"]
        ((_, data, src, dst),) = queue
        assert (data, src[:2], dst) == (b"one", peers[1].getsockname()[:2], here)
        queue.clear()
        assert master.recv_burst() == [] and not queue  # nothing waiting: nothing recorded
        peers[2].sendto(b"from", master.getsockname())
        _settle()
        assert [(d, a[:2]) for d, a in master.recvfrom_burst()] == [(b"from", peers[2].getsockname()[:2])]
        ((_, data, src, dst),) = queue
        assert (data, src[:2], dst) == (b"from", peers[2].getsockname()[:2], here)
    finally:
        master.close()
        for p in peers:
            p.close()


def test_a_datagram_that_was_not_sent_is_not_recorded() -> None:
    queue: deque = deque()
    master, peer = TappedBurstSocket(_udp(), queue.append), _udp()
    try:
        items = [(b"a" * 8, peer.getsockname()), (b"b" * 70000, peer.getsockname()), (b"c" * 8, peer.getsockname())]
        failures = master.send_burst(items)
        assert [i for i, _ in failures] == [1]
        assert [d for _, d, _, _ in queue] == [b"a" * 8, b"c" * 8]
    finally:
        master.close()
        peer.close()


def test_the_per_datagram_calls_are_tapped_too() -> None:
    queue: deque = deque()
    master = TappedBurstSocket(_udp(), queue.append)
    try:
        here = master.getsockname()[:2]
        master.sendto(b"self", here)
        _settle()
        assert master.recvfrom(100) == (b"self", here)
        assert [(d, s, r) for _, d, s, r in queue] == [(b"self", here, here)] * 2
    finally:
        master.close()


def test_tap_is_the_batched_tap_unless_asked_for_plain_calls(tmp_path: Path) -> None:
    w = CaptureWriter(tmp_path / "c.pcapng")
    a = _udp()
    assert isinstance(tap(w, a), TappedBurstSocket)
    b = _udp()
    assert isinstance(tap(w, b, batched=False), TappedSocket)
    a.close()
    b.close()


def test_a_batched_capture_reads_back(tmp_path: Path) -> None:
    path = tmp_path / "c.pcapng"
    with CaptureWriter(path) as w:
        master, peer = tap(w, _udp()), _udp()
        try:
            assert master.send_burst([(b"\x4d" * 31, peer.getsockname()), (b"\x4d" * 46, peer.getsockname())]) == []
            peer.sendto(b"\x4e" * 31, master.getsockname())
            _settle()
            assert master.recv_burst() == [b"\x4e" * 31]
        finally:
            master.close()
            peer.close()

    got = read_capture(path).datagrams
    assert [len(d.data) for d in got] == [31, 46, 31]
    assert got[0].dst == got[1].dst == got[2].src and got[0].src == got[2].dst
    assert got[0].ts_ns == got[1].ts_ns <= got[2].ts_ns
