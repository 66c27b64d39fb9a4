"""CaptureWriter: datagrams and notes in order, comments on the right packet, the size bound, IPv6, read back."""

from __future__ import annotations

import io
import socket
import threading
from pathlib import Path

import dpkt
import pytest

from mlink_sim.aio.transport.tapped import tap
from mlink_sim.capture import CaptureWriter, event_text, ip_packet, read_capture
from mlink_sim.capture.tap import TappedSocket, source_address_for
from mlink_sim.master import StateChanged, StationState

A = ("127.0.0.1", 40000)
B = ("127.0.0.1", 47001)


def test_datagrams_times_addresses_and_comments_round_trip(tmp_path: Path) -> None:
    path = tmp_path / "c.pcapng"
    with CaptureWriter(path, epoch_offset_ns=1_700_000_000 * 10**9) as w:
        w.note(0, "before anything")
        w.record(1_000, b"\x4d" * 31, A, B)
        w.note(2_000, StateChanged(0x21, StationState.PHASE1, StationState.CONNECTING))
        w.note(2_500, "second note")
        w.record(3_000_000, b"\x4d" * 46, B, A)
        w.record(4_000_000, b"\x4d" * 78, A, B)
    cap = read_capture(path)
    assert [len(d.data) for d in cap.datagrams] == [31, 46, 78]
    assert cap.datagrams[0].comments == ("before anything", "StateChanged station 21H: old=phase1 new=connecting",
                                         "second note")
    assert cap.datagrams[1].comments == () and cap.datagrams[2].comments == ()
    assert (cap.datagrams[0].src, cap.datagrams[0].dst) == (A, B)
    assert (cap.datagrams[1].src, cap.datagrams[1].dst) == (B, A)
    assert cap.datagrams[1].ts_ns - cap.datagrams[0].ts_ns == 2_999_000  # microsecond resolution
    assert cap.datagrams[0].ts_ns == 1_700_000_000 * 10**9 + 1_000
    assert w.stats.datagrams == 3 and w.stats.notes == 3 and w.stats.not_recorded == 0


def test_comments_are_not_shared_between_packets(tmp_path: Path) -> None:
    path = tmp_path / "c.pcapng"
    with CaptureWriter(path) as w:
        for i in range(5):
            w.record(i, bytes([i]) * 31, A, B)
            if i == 2:
                w.note(i, "after the third")
    assert [d.comments for d in read_capture(path).datagrams] == [(), (), ("after the third",), (), ()]


def test_size_bound_stops_the_file_and_says_so(tmp_path: Path) -> None:
    path = tmp_path / "c.pcapng"
    with CaptureWriter(path, max_bytes=8192) as w:
        for i in range(1000):
            w.record(i * 1000, b"\x4d" * 46, A, B)
    stats = w.stats
    assert path.stat().st_size < 8192 + 200
    cap = read_capture(path)
    assert stats.datagrams == len(cap.datagrams) and stats.datagrams + stats.not_recorded == 1000
    assert stats.not_recorded > 800
    assert "capture limit of 8192 bytes reached" in cap.datagrams[-1].comments[-1]
    assert "not recorded" in stats.summary()


def test_the_writer_thread_flushes_while_running(tmp_path: Path) -> None:
    path = tmp_path / "c.pcapng"
    w = CaptureWriter(path, flush_s=0.01).start()
    try:
        w.record(0, b"\x4d" * 31, A, B)
        w.record(1, b"\x4d" * 31, A, B)
        deadline = threading.Event()
        for _ in range(200):
            if w.stats.datagrams >= 1:
                break
            deadline.wait(0.01)
        assert w.stats.datagrams >= 1  # the first one is written; the last waits for its comments
    finally:
        w.close()
    assert len(read_capture(path).datagrams) == 2


def test_ip_packet_is_a_valid_ipv4_udp_packet_and_ipv6_too() -> None:
    pkt = dpkt.ip.IP(ip_packet(b"hello", ("10.0.0.1", 1234), ("10.0.0.2", 47001)))
    assert pkt.p == 17 and socket.inet_ntoa(pkt.src) == "10.0.0.1" and pkt.df == 1
    assert pkt.data.sport == 1234 and pkt.data.dport == 47001 and bytes(pkt.data.data) == b"hello"
    assert pkt.data.sum == 0 and pkt.len == 20 + 8 + 5
    ip6 = dpkt.ip6.IP6(ip_packet(b"hi", ("::1", 5, 0, 0), ("::1", 6, 0, 0)))
    assert ip6.nxt == 17 and bytes(ip6.data.data) == b"hi"


def test_ipv6_capture_reads_back(tmp_path: Path) -> None:
    path = tmp_path / "c.pcapng"
    with CaptureWriter(path) as w:
        w.record(0, b"\x4d" * 31, ("::1", 40000, 0, 0), ("::1", 47001, 0, 0))
    (d,) = read_capture(path).datagrams
    assert d.src == ("::1", 40000) and d.dst == ("::1", 47001)


def test_unwritable_path_raises_oserror(tmp_path: Path) -> None:
    (tmp_path / "file").write_text("x")
    with pytest.raises(OSError):
        CaptureWriter(tmp_path / "file" / "c.pcapng").start()


def test_event_text() -> None:
    assert event_text("plain") == "plain"
    assert event_text(StateChanged(0x23, StationState.PHASE2, StationState.PHASE3)) == \
        "StateChanged station 23H: old=phase2 new=phase3"


def test_tapped_socket_records_both_directions_with_real_addresses(tmp_path: Path) -> None:
    server = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    server.bind(("127.0.0.1", 0))
    raw = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    raw.bind(("0.0.0.0", 0))  # wildcard: the writer records the address the kernel sends from
    port, server_addr = raw.getsockname()[1], server.getsockname()
    path = tmp_path / "c.pcapng"
    with CaptureWriter(path) as w:
        tapped = tap(w, raw)  # what --capture wraps a socket in
        try:
            tapped.sendto(b"ping" * 8, server.getsockname())
            data, peer = server.recvfrom(100)
            server.sendto(b"pong" * 8, peer)
            assert tapped.recv(100) == b"pong" * 8
            assert tapped.fileno() == raw.fileno()
        finally:
            tapped.close()
            server.close()
    first, second = read_capture(path).datagrams
    assert (first.data, first.src, first.dst) == (b"ping" * 8, ("127.0.0.1", port), server_addr)
    assert (second.data, second.src, second.dst) == (b"pong" * 8, server_addr, ("127.0.0.1", port))
    assert second.ts_ns >= first.ts_ns


def test_tapped_socket_feeds_tuples_to_its_sink() -> None:
    got: list[tuple] = []
    a = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    a.bind(("127.0.0.1", 0))
    tapped, here = TappedSocket(a, got.append), a.getsockname()
    try:
        tapped.sendto(b"x", here)
        assert tapped.recvfrom(10) == (b"x", here)
    finally:
        tapped.close()
    assert [(d, s, r) for _, d, s, r in got] == [(b"x", here, here)] * 2


def test_source_address_for_unreachable_peer_falls_back_to_wildcard() -> None:
    assert source_address_for(("127.0.0.1", 9), 5) == ("127.0.0.1", 5)


def test_reader_rejects_what_is_not_a_capture(tmp_path: Path) -> None:
    from mlink_sim.capture import CaptureError

    (tmp_path / "x").write_bytes(b"not a capture")
    with pytest.raises(CaptureError, match="not a pcap or pcapng"):
        read_capture(tmp_path / "x")
    with pytest.raises(CaptureError, match="cannot read"):
        read_capture(tmp_path / "missing")
    (tmp_path / "t").write_bytes(b"\x0a\x0d\x0d\x0a\x00")
    with pytest.raises(CaptureError, match="not a readable capture"):
        read_capture(tmp_path / "t")


def test_reader_takes_classic_pcap_on_ethernet(tmp_path: Path) -> None:
    buf = io.BytesIO()
    writer = dpkt.pcap.Writer(buf, linktype=dpkt.pcap.DLT_EN10MB)
    eth = dpkt.ethernet.Ethernet(type=dpkt.ethernet.ETH_TYPE_IP, data=dpkt.ip.IP(ip_packet(b"\x4d" * 31, A, B)))
    writer.writepkt(bytes(eth), ts=1.5)
    writer.writepkt(b"\x00" * 20, ts=2.0)  # not IP: skipped, counted
    (tmp_path / "c.pcap").write_bytes(buf.getvalue())
    cap = read_capture(tmp_path / "c.pcap")
    assert [(d.src, d.dst, d.data, d.ts_ns) for d in cap.datagrams] == [(A, B, b"\x4d" * 31, 1_500_000_000)]
    assert cap.skipped == 1


def test_batches_chunks_and_notes_between_drains(tmp_path: Path) -> None:
    """The writer's wake-ups fall anywhere: a note right after a drain still lands on the datagram before it, and
    batches longer than a chunk (128 packets) keep their order and headers per flow and size."""
    path = tmp_path / "c.pcapng"
    w = CaptureWriter(path, epoch_offset_ns=0, flush_s=3600).start()  # its thread sleeps: the drains are ours
    try:
        for i in range(300):
            src, dst = (A, B) if i % 2 else (B, A)
            w.record(i * 1_000, bytes([i % 256]) * (31 + i % 3), src, dst)
        w._drain()  # writes 299, holds the last back for the notes that may follow
        w.note(300_000, "after the 300th")
        for i in range(300, 310):
            w.record(i * 1_000, bytes([i % 256]) * 31, A, B)
        w.note(310_000, "after the last")
        w._drain()
    finally:
        stats = w.close()
    cap = read_capture(path)
    assert [d.ts_ns for d in cap.datagrams] == [i * 1_000 for i in range(310)]
    assert [len(d.data) for d in cap.datagrams[:3]] == [31, 32, 33]
    assert all((d.src, d.dst) == ((A, B) if i % 2 else (B, A)) for i, d in enumerate(cap.datagrams[:300]))
    assert {i: d.comments for i, d in enumerate(cap.datagrams) if d.comments} == {299: ("after the 300th",),
                                                                                309: ("after the last",)}
    assert stats.datagrams == 310 and stats.notes == 2 and stats.bytes == path.stat().st_size


def test_a_connected_socket_is_read_with_recv_and_recorded_from_its_peer() -> None:
    """A connected UDP socket only gets its peer's datagrams (the kernel drops the rest): recv, source = peer."""
    got: list[tuple] = []
    peer = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    other = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    for s in (peer, other, sock):
        s.bind(("127.0.0.1", 0))
    sock.connect(peer.getsockname())
    tapped = TappedSocket(sock, got.append)
    names = peer.getsockname(), sock.getsockname()
    try:
        other.sendto(b"not from the peer", sock.getsockname())  # dropped by the kernel
        peer.sendto(b"from the peer", sock.getsockname())
        sock.settimeout(2.0)
        assert tapped.recv(100) == b"from the peer"
    finally:
        for s in (peer, other, sock):
            s.close()
    assert [(d, s, r) for _, d, s, r in got] == [(b"from the peer", *names)]
