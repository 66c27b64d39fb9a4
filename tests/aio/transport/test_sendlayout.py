"""A burst's send headers (mlink_sim.aio.transport.sendlayout): the offload's groups (one destination, one size, at most
64 datagrams and below 64 KiB each), a burst of any size in one ``sendmmsg`` (a worker's answers to two cycles after a
stall: docs/performance.md), and the last few shapes kept so that alternating bursts
are not laid out again."""

from __future__ import annotations

import functools
import socket
from typing import Any

import pytest

from mlink_sim.aio.transport import mmsg, sendlayout
from mlink_sim.aio.transport.sendlayout import Layout, Shapes

from .test_gso import _settle, _udp
from .test_mmsg import _drain

pytestmark = pytest.mark.skipif(not mmsg.supported(), reason="sendmmsg/recvmmsg not available here")


def test_datagrams_to_one_destination_are_grouped_by_size_in_order() -> None:
    a, b = ("127.0.0.1", 1), ("127.0.0.1", 2)
    layout = [(46, a), (46, b), (46, a), (10, a), (46, a)]
    groups = sendlayout.groups(layout)
    assert groups is not None
    assert [(idx, addr) for idx, addr, _ in groups] == [([0, 2, 4], a), ([1], b), ([3], a)]
    assert [size for _, _, size in groups] == [46, 46, 10]  # the segment size of each
    assert sendlayout.groups([(46, a), (46, b)]) is None  # nothing shared: one message per datagram


def test_a_group_is_cut_below_64_kib_and_at_the_kernels_segments() -> None:
    assert sendlayout.members_of(sendlayout.groups([(20_000, ("127.0.0.1", 1))] * 7) or []) == [
        [0, 1, 2], [3, 4, 5], [6]]
    cut = sendlayout.groups([(64, ("127.0.0.1", 1))] * 130) or []
    assert [len(idx) for idx in sendlayout.members_of(cut)] == [64, 64, 2]  # UDP_MAX_SEGMENTS of Linux 4.18
    assert [i for idx in sendlayout.members_of(cut) for i in idx] == list(range(130))
    wide = sendlayout.groups([(64, ("127.0.0.1", 1))] * 130, 128) or []
    assert [len(idx) for idx in sendlayout.members_of(wide)] == [128, 2]


@pytest.mark.skipif(not mmsg.gso_supported(), reason="UDP segmentation offload not available here")
def test_the_kernels_segments_per_send_are_found_out_once() -> None:
    most = sendlayout.max_segments()
    assert most in (64, 128) and sendlayout.max_segments() is most
    rx = _udp()
    try:  # as many as it says, to a socket of our own: taken; one more: refused
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as tx:
            seg = [(socket.SOL_UDP, sendlayout.UDP_SEGMENT, (1).to_bytes(2, "little"))]
            assert tx.sendmsg([bytes(most)], seg, 0, rx.getsockname()) == most
            if most == 128:
                with pytest.raises(OSError):
                    tx.sendmsg([bytes(most + 1)], seg, 0, rx.getsockname())
    finally:
        rx.close()


def _counting(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    """The ``sendmmsg`` calls the batched sockets make from now on, each with its message count."""
    real_send, real_recv = mmsg._calls  # type: ignore[misc]
    counts: list[int] = []

    def send(fd: int, msgs: Any, n: int, flags: int) -> int:
        counts.append(n)
        return int(real_send(fd, msgs, n, flags))

    monkeypatch.setattr(mmsg, "_calls", (send, real_recv))
    return counts


def _backlog(here: Any) -> list[tuple[bytes, Any]]:
    """Two cycles' answers of 62 stations, newest cycle first (``Bus.serve``): 124 datagrams to one master."""
    return [(bytes([cycle, station]) * 32, here) for cycle in (2, 1) for station in range(62)]


@pytest.mark.parametrize("gso", [True, False], ids=["offload", "one-message-each"])
def test_a_backlog_of_124_answers_goes_in_one_system_call_in_order(gso: bool,
                                                                     monkeypatch: pytest.MonkeyPatch) -> None:
    if gso and not mmsg.gso_supported():
        pytest.skip("UDP segmentation offload not available here")
    counts = _counting(monkeypatch)
    tx, rx = mmsg.BurstSocket(_udp(), gso=gso), _udp()
    try:
        items = _backlog(rx.getsockname())
        assert tx.send_burst(items) == []
        # one sendmmsg: one offloaded message of 124 (two of 64 and 60 on a kernel that takes 64), or 124 messages
        assert counts == ([1 if sendlayout.max_segments() >= 124 else 2] if gso else [124])
        assert [d for d, _ in _drain(rx)] == [d for d, _ in items]
    finally:
        tx.close()
        rx.close()


def test_a_gro_reader_gets_a_backlog_in_one_read() -> None:
    if not mmsg.gso_supported():
        pytest.skip("UDP segmentation offload not available here")
    tx, rx = mmsg.BurstSocket(_udp()), mmsg.BurstSocket(_udp())
    try:
        assert rx.enable_gro()
        items = _backlog(rx.getsockname())
        assert tx.send_burst(items) == []
        _settle()
        buffers = 1 if sendlayout.max_segments() >= len(items) else 2  # one offloaded send (two of one call)
        assert rx.recv_burst(buffers) == [d for d, _ in items]  # read at once, cut again, in order
        assert rx.recv_burst() == []
    finally:
        tx.close()
        rx.close()


def test_more_than_the_kernel_takes_in_one_call_goes_in_several(monkeypatch: pytest.MonkeyPatch) -> None:
    counts = _counting(monkeypatch)
    tx, rx = mmsg.BurstSocket(_udp(), gso=False), _udp()
    rx.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 22)
    try:
        items = [(i.to_bytes(2, "big"), rx.getsockname()) for i in range(sendlayout.MAX_VECTOR + 5)]
        assert tx.send_burst(items) == []
        assert counts == [sendlayout.MAX_VECTOR, 5]  # UIO_MAXIOV messages per sendmmsg
        assert [d for d, _ in _drain(rx)] == [d for d, _ in items]
    finally:
        tx.close()
        rx.close()


def test_alternating_shapes_are_laid_out_once_each() -> None:
    tx, rx = mmsg.BurstSocket(_udp()), _udp()
    try:
        here = rx.getsockname()
        one, two = _backlog(here)[:62], _backlog(here)
        laid = []
        for burst in (one, two, one, two):
            assert tx.send_burst(burst) == []
            laid.append(tx._slay)
            assert [d for d, _ in _drain(rx)] == [d for d, _ in burst]
        assert laid[0] is not laid[1] and laid[2] is laid[0] and laid[3] is laid[1]  # kept, not laid out again
    finally:
        tx.close()
        rx.close()


def test_a_socket_keeps_its_last_few_shapes() -> None:
    made: list[int] = []
    shapes = Shapes()

    def make(i: int) -> Layout | None:
        made.append(i)
        return None

    for i in [*range(Shapes.KEEP + 1), Shapes.KEEP, 0]:  # the last known: not laid out again; the oldest forgotten
        shapes.get(((i,), ()), functools.partial(make, i))
    assert made == [*range(Shapes.KEEP + 1), 0]
