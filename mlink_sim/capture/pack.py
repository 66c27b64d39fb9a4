"""The capture writer's per-record loop: queued records to uncommented Enhanced Packet Blocks, compiled with mypyc.

This module is in :data:`mlink_sim._accel.COMPILED_MODULES` (the ``.py`` is the pure-Python fallback, as for the
cores) and imports nothing, dpkt included: it declares no block field. The layout comes from dpkt through
:class:`~mlink_sim.capture.epb.EpbPacker`: a block template per flow and size (the bytes dpkt's
``EnhancedPacketBlockLE`` header struct packs around the timestamp and the data, the IP/UDP header in the middle)
and the byte order of dpkt's two timestamp fields (``ts_high``, ``ts_low``: two 32-bit unsigned integers, checked
there), handed in as bytes and a flag. What is here is only the loop, run once per datagram: take a record, look
its flow template up in a dict, make the 8 timestamp bytes, append the block's five parts; one ``bytes.join`` per
call. Without intermediate sequences (no ``zip(*batch)``): that first pass over the records was the step slowed
most by running beside the master (4.5x).

The output is byte-identical to dpkt's ``Writer.writepkts`` (tests/capture/test_epb.py and test_pack.py, compiled
and with ``MLINK_PURE=1``).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

__all__ = ["Flow", "Record", "pack_records", "packet", "udp_checksum"]

#: one queued item: ``(ts_ns, datagram, src, dst)``, or a note ``(ts_ns, event, None, None)``
Record = tuple[int, Any, Any, Any]
#: the block template of one flow and size: ``(head, middle, tail, overhead, prefix)``; a block is ``head +
#: timestamp + middle + data + tail``, ``overhead`` its bytes beyond the data, ``prefix`` the packet's bytes that
#: *middle* ends with (the IP/UDP header), for a block written by dpkt instead (one with comments)
#: *csum*: -1 when the prefix is the same for every datagram of the flow (IPv4: its UDP checksum 0, "not computed",
#: RFC 768); else (IPv6, where the checksum is mandatory, RFC 8200 §8.1) the one's-complement sum, unfolded, of the
#: flow's pseudo-header and UDP header with a zero checksum: *middle* then ends before the checksum's two bytes, and
#: the loop appends them, summed over each datagram (:func:`udp_checksum`)
Flow = tuple[bytes, bytes, bytes, int, bytes, int]


def pack_records(records: list[Record], start: int, end: int, count: int, budget: int,
                 flows: dict[tuple[Any, Any, int], Flow], make: Callable[[Any, Any, int], Flow],
                 offset: int, unit: int, little: bool) -> tuple[bytes, int, int]:
    """The blocks of the datagrams ``records[start:end]``, at most *count* of them, each stamped ``(ts + offset) //
    unit`` µs (Unix time). Returns ``(blocks, stop, size)``: the bytes, the index of the first record not packed and
    ``len(blocks)``.

    It stops before ``end`` at the first record that is a note (its source is None), at a datagram followed by a
    note (its comments: dpkt writes that block), and before a block that would leave less than its own size of
    *budget* (``size + 2 * block > budget``: the capture's size bound, as the writer's one-by-one path decides).
    *flows* maps ``(src, dst, len(datagram))`` to its :data:`Flow`; a miss is made by ``make(src, dst, size)`` (which
    stores it). *little*: dpkt's ``ts_high``/``ts_low`` are little-endian (else big-endian)."""
    parts: list[Any] = []
    size = 0
    last = len(records) - 1
    stop = min(end, start + count)
    i = start
    if i >= stop:
        return b"", i, 0
    rec = records[i]
    while i < stop:
        ts, data, src, dst = rec
        if src is None:  # a note before any datagram: the writer attaches it to the next one
            break
        if i < last:
            rec = records[i + 1]
            if rec[2] is None:  # this datagram has comments
                break
        n = len(data)
        flow = flows.get((src, dst, n))
        if flow is None:
            flow = make(src, dst, n)
        head, middle, tail, overhead, _, csum = flow
        block = overhead + n
        if size + block + block > budget:
            break
        us = (ts + offset) // unit
        parts.append(head)
        if little:  # dpkt's "<II" (ts_high, ts_low) is the 64-bit little-endian integer ts_low << 32 | ts_high
            parts.append(((us & 0xFFFFFFFF) << 32 | us >> 32).to_bytes(8, "little"))
        else:  # ">II": the µs count itself, big-endian
            parts.append(us.to_bytes(8, "big"))
        parts.append(middle)
        if csum >= 0:  # IPv6: the UDP checksum of this datagram
            parts.append(udp_checksum(csum, data).to_bytes(2, "big"))
        parts.append(data)
        parts.append(tail)
        size += block
        i += 1
    return b"".join(parts), i, size


def udp_checksum(partial: int, data: bytes) -> int:
    """The UDP checksum (RFC 768, over IPv6 RFC 8200 §8.1) of *data* after a pseudo-header and UDP header whose
    one's-complement sum (unfolded) is *partial*: 16-bit big-endian words, an odd last byte padded with zero,
    folded and complemented; a result of 0 is sent as FFFFH."""
    total = partial
    n = len(data)
    for i in range(0, n - 1, 2):
        total += data[i] << 8 | data[i + 1]
    if n & 1:
        total += data[n - 1] << 8
    while total >> 16:
        total = (total & 0xFFFF) + (total >> 16)
    total = ~total & 0xFFFF
    return total or 0xFFFF


def packet(flow: Flow, data: bytes) -> bytes:
    """The IP packet of *data* in *flow*: its prefix (the IP/UDP header) and the datagram, the UDP checksum of
    this datagram in it where the flow has one (what a block with comments carries, written by dpkt)."""
    prefix, csum = flow[4], flow[5]
    if csum < 0:
        return prefix + data
    return prefix[:-2] + udp_checksum(csum, data).to_bytes(2, "big") + data
