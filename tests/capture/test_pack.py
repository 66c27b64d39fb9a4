"""capture.pack, the writer's compiled per-record loop: what a CaptureWriter makes of its records (notes, several
flows, sizes 0-90, a change of ts_high, drains anywhere) is byte for byte what dpkt's own Writer writes for the same
IP packets, times and comments; and the loop is the compiled one when the cores are."""

from __future__ import annotations

from pathlib import Path

from hypothesis import given, settings
from hypothesis import strategies as st

from mlink_sim import _accel
from mlink_sim.capture import CaptureWriter, ip_packet
from mlink_sim.capture import pack as pack_module

#: IPv4 flows (their UDP checksum is 0, so the packet is ip_packet's whatever the datagram; an IPv6 flow's template
#: carries the UDP checksum of a datagram of zeros, as before this loop: docs/performance.md, "Capture")
FLOWS = [(("127.0.0.1", 40000), ("127.0.0.1", 47001)), (("127.0.0.1", 47001), ("127.0.0.1", 40000)),
         (("10.0.0.1", 40000), ("10.0.0.22", 47002)), (("10.0.0.1", 40000), ("10.0.0.23", 47003))]
#: ns since the Unix epoch: anywhere, or around a change of ts_high (every 2**32 µs)
STAMPS = st.one_of(st.integers(min_value=0, max_value=4_200_000_000_000_000_000),
                   st.integers(min_value=-3_000_000_000, max_value=3_000_000_000).map(lambda d: 396_000 * 2**32 * 1000 + d))
#: a datagram (flow, size 0-90, a time) or a note; True after it: the writer drains there
RECORDS = st.lists(st.tuples(st.one_of(st.tuples(st.sampled_from(range(len(FLOWS))), st.binary(max_size=90), STAMPS),
                                       st.text(min_size=1, max_size=12)), st.booleans()), max_size=60)


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
            expected.append((ns // 1000, ip_packet(data, *FLOWS[flow]), early if not expected else []))
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
