"""capture.pack, the writer's compiled per-record loop: what a CaptureWriter makes of its records (notes, several
flows, sizes 0-90, a change of ts_high, drains anywhere) is byte for byte what dpkt's own Writer writes for the same
IP packets, times and comments; and the loop is the compiled one when the cores are."""

from __future__ import annotations

import struct
from pathlib import Path

import dpkt

from hypothesis import given, settings
from hypothesis import strategies as st

from mlink_sim import _accel
from mlink_sim.capture import CaptureWriter, ip_packet
from mlink_sim.capture import pack as pack_module

#: IPv4 flows (UDP checksum 0, "not computed") and IPv6 flows (the checksum of each datagram, RFC 8200 §8.1)
FLOWS = [(("127.0.0.1", 40000), ("127.0.0.1", 47001)), (("127.0.0.1", 47001), ("127.0.0.1", 40000)),
         (("10.0.0.1", 40000), ("10.0.0.22", 47002)), (("10.0.0.1", 40000), ("10.0.0.23", 47003)),
         (("::1", 40000, 0, 0), ("::1", 47001, 0, 0)), (("fd00::1", 47002, 0, 0), ("fd00::2", 40000, 0, 0))]
#: ns since the Unix epoch: anywhere, or around a change of ts_high (every 2**32 µs)
STAMPS = st.one_of(st.integers(min_value=0, max_value=4_200_000_000_000_000_000),
                   st.integers(min_value=-3_000_000_000, max_value=3_000_000_000).map(lambda d: 396_000 * 2**32 * 1000 + d))
#: a datagram (flow, size 0-90, a time) or a note; True after it: the writer drains there
RECORDS = st.lists(st.tuples(st.one_of(st.tuples(st.sampled_from(range(len(FLOWS))), st.binary(max_size=90), STAMPS),
                                       st.text(min_size=1, max_size=12)), st.booleans()), max_size=60)


def _reference(data: bytes, src: tuple, dst: tuple) -> bytes:
    """The IP packet dpkt makes of *data* (``ip_packet``); a UDP checksum computed as 0 is sent as FFFFH (RFC 768),
    which dpkt leaves 0."""
    raw = ip_packet(data, src, dst)
    if raw[0] >> 4 == 6 and raw[46:48] == b"\0\0":
        raw = raw[:46] + b"\xff\xff" + raw[48:]
    return raw


def _sum16(data: bytes) -> int:
    data += b"\0" * (len(data) & 1)
    total = sum(struct.unpack(f"!{len(data) // 2}H", data))
    while total >> 16:
        total = (total & 0xFFFF) + (total >> 16)
    return total


def _header_size(path: Path) -> int:
    """The bytes CaptureWriter writes before any datagram (its Section Header and Interface Description Blocks)."""
    CaptureWriter(path).start(background=False).close()
    return path.stat().st_size


@settings(max_examples=200, deadline=None)
@given(RECORDS)
def test_the_writer_s_blocks_are_dpkt_s_for_notes_flows_sizes_and_ts_high(tmp_path_factory, dpkt_file,
                                                                        records) -> None:
    tmp = tmp_path_factory.mktemp("pack")
    w = CaptureWriter(tmp / "c.pcapng", epoch_offset_ns=0).start(background=False)
    expected: list[tuple[int, bytes, list[str]]] = []
    early: list[str] = []  # notes before any datagram: comments of the first one
    for item, drain in records:
        if isinstance(item, str):
            w.note(0, item)
            (expected[-1][2] if expected else early).append(item)
        else:
            flow, data, ns = item
            w.record(ns, data, *FLOWS[flow])
            expected.append((ns // 1000, _reference(data, *FLOWS[flow]), early if not expected else []))
        if drain:
            w.flush()
    stats = w.close()
    written = (tmp / "c.pcapng").read_bytes()
    reference = dpkt_file(expected)
    assert written[_header_size(tmp / "e.pcapng"):] == reference[len(dpkt_file([])):]
    assert (stats.datagrams, stats.notes) == (len(expected), sum(isinstance(item, str) for item, _ in records))


def test_the_loop_is_compiled_with_the_cores() -> None:
    compiled = not pack_module.__file__.endswith(".py")
    assert compiled == (_accel.MODE == "compiled")


@settings(max_examples=100, deadline=None)
@given(st.lists(st.tuples(st.binary(max_size=90), st.booleans()), min_size=1, max_size=20))
def test_ipv6_datagrams_carry_their_own_udp_checksum(tmp_path_factory, items) -> None:
    """Every IPv6 packet of a capture, with comments or without, passes the receiver's check (RFC 8200 §8.1: the
    one's-complement sum over the pseudo-header and the UDP datagram is FFFFH), computed here independently."""
    path = tmp_path_factory.mktemp("v6") / "c.pcapng"
    src, dst = FLOWS[5]
    with CaptureWriter(path, epoch_offset_ns=0).start(background=False) as w:
        for data, noted in items:
            w.record(0, data, src, dst)
            if noted:
                w.note(0, "a comment")
    with path.open("rb") as f:
        packets = [bytes(buf) for _, buf in dpkt.pcapng.Reader(f)]
    assert [p[48:] for p in packets] == [data for data, _ in items]
    for raw in packets:
        pseudo = raw[8:40] + struct.pack("!IxxxB", len(raw) - 40, 17)
        assert _sum16(pseudo + raw[40:]) == 0xFFFF
        assert raw[46:48] != b"\0\0"  # zero is not a checksum over IPv6


def test_a_checksum_of_zero_is_sent_as_ffff() -> None:
    """RFC 768: a computed checksum of 0 is transmitted as all ones (a partial sum of FFFFH and no data)."""
    assert pack_module.udp_checksum(0xFFFF, b"") == 0xFFFF
    assert pack_module.udp_checksum(0, b"\x12\x34\x56") == ~(0x1234 + 0x5600) & 0xFFFF
