"""Many Enhanced Packet Blocks at once, in the layout dpkt declares: the capture writer's batch loop.

**How the rule "use a well-kept library for pcapng; do not write the blocks by hand" is read here.** dpkt
stays the library that *declares* every block: the Section Header and Interface Description Blocks, every
Enhanced Packet Block that carries comments (``dpkt.pcapng.EnhancedPacketBlockLE`` with its options), and the
layout of the uncommented Enhanced Packet Blocks packed here. Nothing here declares a field: the block type,
the interface id, the header struct (``_pack_hdr``, ``__hdr_fmt__``), its length (``__hdr_len__``), where the
timestamp fields sit and their byte order (``__hdr__``) and the options of a block without comments
(``_do_pack_options()``) all come from dpkt's ``EnhancedPacketBlockLE``. What replaces dpkt's *loop*
(``Writer.writepkts``, which runs in Python for each block, most of the 2 µs a datagram may cost in all:
docs/performance.md, "Batched calls") is :func:`mlink_sim.capture.pack.pack_records`, a loop compiled with mypyc
that is handed the templates made here and the timestamp's byte order (docs/capture.md).

How: every block of a given captured length is the same bytes except its timestamp and its data. dpkt's own header
struct packs that block once with a zero timestamp (:meth:`EpbPacker.template`); the template is cut around the
timestamp and the data, and a block is ``head, timestamp, middle, data, tail`` joined. The output is
byte-identical to dpkt's ``Writer.writepkts``/``writepkt`` for the same packets and integer-microsecond times
(``tests/capture/test_epb.py`` proves it with hypothesis, and reads it back with dpkt's and python-pcapng's
readers; ``tests/capture/test_pack.py`` pins the writer's records path; the tshark tests read the writer's files).
"""

from __future__ import annotations

import struct
from collections.abc import Callable
from typing import Any

from dpkt import pcapng

from .pack import Flow, Record, pack_records

__all__ = ["EpbPacker", "Template"]

#: one block's constant parts around its timestamp and data: (head, middle, tail); see :meth:`EpbPacker.template`
Template = tuple[bytes, bytes, bytes]


class EpbPacker:
    """Packs uncommented Enhanced Packet Blocks in dpkt's layout (see the module docstring). *kls*: dpkt's block
    class, ``EnhancedPacketBlockLE`` (the byte order mlink-sim writes on every host, as dpkt's ``Writer`` does on a
    little-endian one)."""

    def __init__(self, kls: Any = pcapng.EnhancedPacketBlockLE) -> None:  # a dpkt block class (untyped)
        proto = kls()
        self._pack_hdr = proto._pack_hdr  # dpkt's header struct: every field of the block but the data and options
        self._type, self._iface = proto.type, proto.iface_id
        self._hdr_len = kls.__hdr_len__
        self._opts = proto._do_pack_options()  # what dpkt writes after the data of a block without options
        order = kls.__hdr_fmt__[0]
        names = [name for name, _, _ in kls.__hdr__]
        fmts = [fmt for _, fmt, _ in kls.__hdr__]
        hi = names.index("ts_high")
        if names[hi + 1] != "ts_low":  # dpkt changed its declaration: refuse rather than write wrong bytes
            raise RuntimeError(f"dpkt's {kls.__name__} has no ts_high/ts_low pair: {names}")
        self._ts_at = struct.calcsize(order + "".join(fmts[:hi]))  # where the timestamp starts in the header
        self._ts = struct.Struct(order + fmts[hi] + fmts[hi + 1])  # dpkt's two timestamp fields
        if self._ts.size != 8 or fmts[hi] != fmts[hi + 1] or fmts[hi] not in "IL" or order not in "<>!":
            raise RuntimeError(f"dpkt's {kls.__name__} timestamp is not two 32-bit unsigned fields: {self._ts.format}")
        self.little = order == "<"  #: the byte order of dpkt's ts_high/ts_low, for the compiled loop
        self._trailer = struct.calcsize(order + fmts[-1])  # the header's last field follows the data (dpkt's Writer)

    def template(self, caplen: int, prefix: bytes = b"") -> Template:
        """``(head, middle, tail)`` of a block whose packet is *caplen* bytes: ``head + timestamp + middle + data +
        tail`` is the block. *prefix*, the packet's first bytes when they are the same for every packet of this
        template (an IP/UDP header), goes at the end of *middle*; *data* is then the rest of the packet."""
        padded = (caplen + 3) & ~3  # pcapng §4.3: the data is padded to 32 bits (dpkt's _align32b)
        n = self._hdr_len + padded + len(self._opts)
        hdr = self._pack_hdr(self._type, n, self._iface, 0, 0, caplen, caplen, n)
        at, cut = self._ts_at, len(hdr) - self._trailer
        return (hdr[:at], hdr[at + self._ts.size:cut] + prefix,
                bytes(padded - caplen) + self._opts + hdr[cut:])

    def flow(self, caplen: int, prefix: bytes = b"", csum: int = -1) -> Flow:
        """The :data:`~mlink_sim.capture.pack.Flow` of :meth:`template` (what the compiled loop takes): the
        template, the block's bytes beyond its data, *prefix* and *csum* (-1: the prefix is every datagram's; else
        the partial sum of the UDP checksum, whose two bytes end *prefix* and are cut from the template's middle,
        the loop making them per datagram)."""
        head, middle, tail = self.template(caplen, prefix)
        overhead = len(head) + self._ts.size + len(middle) + len(tail)
        return head, middle if csum < 0 else middle[:-2], tail, overhead, prefix, csum

    def pack_records(self, records: list[Record], start: int, end: int, flows: dict[tuple[Any, Any, int], Flow],
                     make: Callable[[Any, Any, int], Flow], *, offset: int = 0, unit: int = 1000,
                     count: int = 1 << 60, budget: int = 1 << 60) -> tuple[bytes, int, int]:
        """:func:`mlink_sim.capture.pack.pack_records` in this packer's byte order: the blocks of the records
        ``start:end`` (``(ts, datagram, src, dst)``, stamped ``(ts + offset) // unit`` µs: by default ns), up to the
        first note, the first datagram with comments, *count* blocks or the size *budget*; returns ``(blocks,
        stop, size)``."""
        return pack_records(records, start, end, count, budget, flows, make, offset, unit, self.little)
