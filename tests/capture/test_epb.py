"""EpbPacker: its blocks are byte-identical to dpkt's own Writer for the same packets and times, commented blocks
interleaved, and python-pcapng's and dpkt's readers read them back (the condition the module sets itself)."""

from __future__ import annotations

import io

import pcapng
import pytest
from dpkt import pcapng as dpkt_pcapng
from hypothesis import given, settings
from hypothesis import strategies as st

from mlink_sim.capture.epb import EpbPacker

EPB = dpkt_pcapng.EnhancedPacketBlockLE
#: Unix time in integer µs, from 0 to beyond 2100 (ts_high changes every 2**32 µs, about 71 minutes), or close to
#: one instant (a batch of a run: one ts_high for all, or across a change of ts_high)
STAMPS = st.one_of(st.integers(min_value=0, max_value=4_200_000_000_000_000),
                   st.integers(min_value=-3_000_000, max_value=3_000_000).map(lambda d: 396_000 * 2**32 + d))
PACKETS = st.lists(st.tuples(STAMPS, st.binary(min_size=0, max_size=90), st.lists(st.text(max_size=20), max_size=2)),
                   max_size=40)


def _packer_file(items: list[tuple[int, bytes, list[str]]], packer: EpbPacker) -> bytes:
    """The same, with every run of uncommented packets packed at once by the packer."""
    out = io.BytesIO()
    writer = dpkt_pcapng.Writer(out, snaplen=65535, linktype=101)
    run: list[tuple[int, bytes]] = []
    for i, (us, packet, comments) in enumerate([*items, (0, b"", ["the end"])]):
        if not comments:
            run.append((us, packet))
            continue
        if run:
            out.write(_pack(packer, [u for u, _ in run], [p for _, p in run]))
            run.clear()
        if i < len(items):
            opts = [dpkt_pcapng.PcapngOptionLE(code=dpkt_pcapng.PCAPNG_OPT_COMMENT, text=c) for c in comments]
            opts.append(dpkt_pcapng.PcapngOptionLE(code=dpkt_pcapng.PCAPNG_OPT_ENDOFOPT))
            if us:  # as the capture writer does: dpkt's EPB with its two timestamp fields
                writer.writepkt(EPB(pkt_data=packet, opts=opts, ts_high=us >> 32, ts_low=us & 0xFFFFFFFF))
            else:  # both 0 would make dpkt stamp it with the time of day
                writer.writepkt(EPB(pkt_data=packet, opts=opts), ts=0.0)
    return out.getvalue()


@settings(max_examples=300, deadline=None)
@given(PACKETS)
def test_blocks_are_byte_identical_to_dpkt_and_read_back(dpkt_file, items: list[tuple[int, bytes, list[str]]]) -> None:
    packer = EpbPacker()
    ours = _packer_file(items, packer)
    assert ours == dpkt_file(items)
    # dpkt's reader: every packet, its time in µs
    got = [(round(ts * 1e6), bytes(buf)) for ts, buf in dpkt_pcapng.Reader(io.BytesIO(ours))]
    assert got == [(us, packet) for us, packet, _ in items]
    # python-pcapng's reader: the same packets, times and comments
    blocks = [b for b in pcapng.FileScanner(io.BytesIO(ours)) if isinstance(b, pcapng.blocks.EnhancedPacket)]
    assert [(b.timestamp_high << 32 | b.timestamp_low, bytes(b.packet_data), list(b.options.get_all("opt_comment")))
            for b in blocks] == [(us, packet, comments) for us, packet, comments in items]


def _records_packed(packer: EpbPacker, records: list, prefix: bytes = b"", **kw: int) -> bytes:
    """The packer's records path (the writer's): every record packed, a flow per size with *prefix* in it."""
    def make(src: object, dst: object, size: int):
        flow = flows[(src, dst, size)] = packer.flow(len(prefix) + size, prefix)
        return flow

    flows: dict = {}
    blocks, stop, size = packer.pack_records(records, 0, len(records), flows, make, **kw)
    assert (stop, size) == (len(records), len(blocks))
    return blocks


def _pack(packer: EpbPacker, stamps_us: list[int], packets: list[bytes]) -> bytes:
    """Whole *packets* stamped *stamps_us* (Unix µs), each its own flow without a prefix: what dpkt's
    ``writepkts`` writes for ``[(us / 1e6, packet), …]``."""
    return _records_packed(packer, [(us, packet, 0, 0) for us, packet in zip(stamps_us, packets, strict=True)], unit=1)


@given(st.lists(st.tuples(STAMPS, st.binary(max_size=60)), max_size=30), st.binary(min_size=0, max_size=48))
def test_a_template_with_a_prefix_is_the_packet_with_that_prefix(items: list[tuple[int, bytes]], prefix: bytes) -> None:
    """The writer's path: the IP/UDP header lives in the template of its flow, the datagram is the data."""
    packer = EpbPacker()
    records = [(us, data, "s", "d") for us, data in items]
    assert _records_packed(packer, records, prefix, unit=1) == \
        _pack(packer, [us for us, _ in items], [prefix + d for _, d in items])


@given(st.lists(st.tuples(st.integers(min_value=0, max_value=10**16), st.binary(max_size=20)), max_size=30),
       st.integers(min_value=0, max_value=1_800_000_000 * 10**9))
def test_stamps_in_ns_with_an_offset_are_truncated_to_the_microsecond(items: list[tuple[int, bytes]],
                                                                      offset: int) -> None:
    """The writer's stamps: monotonic ns + the epoch offset, in µs (truncated, as libpcap does)."""
    packer = EpbPacker()
    records = [(ns, data, "s", "d") for ns, data in items]
    assert _records_packed(packer, records, offset=offset) == \
        _pack(packer, [(ns + offset) // 1000 for ns, _ in items], [d for _, d in items])


def test_sizes_zero_and_not_multiples_of_four_and_the_71_minute_wrap(dpkt_file) -> None:
    items = [(2**32 - 1, b"", []), (2**32, b"a", []), (2**32 + 1, b"abcde", ["c"]), (0, b"abcd", []),
             (1_700_000_000_123_456, bytes(range(78)), [])]
    assert _packer_file(items, EpbPacker()) == dpkt_file(items)
    assert _pack(EpbPacker(), [], []) == b""


def test_lengths_must_agree() -> None:
    with pytest.raises(ValueError):
        _pack(EpbPacker(), [1, 2], [b"x"])
