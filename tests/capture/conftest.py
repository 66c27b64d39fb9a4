"""What the capture tests share: dpkt's own Writer as the reference the writer's blocks are compared with."""

from __future__ import annotations

import io
from collections.abc import Callable

import pytest
from dpkt import pcapng as dpkt_pcapng

EPB = dpkt_pcapng.EnhancedPacketBlockLE


def _dpkt_file(items: list[tuple[int, bytes, list[str]]]) -> bytes:
    """What dpkt's Writer writes: ``writepkts`` for uncommented packets, ``writepkt`` of an EPB for the others. dpkt
    takes the time as float seconds; where ``us / 1e6`` does not round back to *us* (far-future stamps: its own
    float limit), the EPB is given its two timestamp fields instead (dpkt's ``writepkt`` path without ``ts``)."""
    out = io.BytesIO()
    writer = dpkt_pcapng.Writer(out, snaplen=65535, linktype=101)
    for us, packet, comments in items:
        exact = round(us / 1e6 * 1e6) == us
        opts = None
        if comments:
            opts = [dpkt_pcapng.PcapngOptionLE(code=dpkt_pcapng.PCAPNG_OPT_COMMENT, text=c) for c in comments]
            opts.append(dpkt_pcapng.PcapngOptionLE(code=dpkt_pcapng.PCAPNG_OPT_ENDOFOPT))
        if not exact:  # us > 0 here (0 is exact)
            writer.writepkt(EPB(pkt_data=packet, opts=opts or [], ts_high=us >> 32, ts_low=us & 0xFFFFFFFF))
        elif comments:
            writer.writepkt(EPB(pkt_data=packet, opts=opts), ts=us / 1e6)
        else:
            writer.writepkts([(us / 1e6, packet)])
    return out.getvalue()


@pytest.fixture(scope="session")
def dpkt_file() -> Callable[[list[tuple[int, bytes, list[str]]]], bytes]:
    """:func:`_dpkt_file` (session-scoped: the hypothesis tests take it)."""
    return _dpkt_file
