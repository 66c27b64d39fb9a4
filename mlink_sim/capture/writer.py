"""Write datagrams to a pcapng file off the hot path (``--capture FILE.pcapng``).

The hot path only appends ``(ts_ns, datagram, src, dst)`` to a deque (a tapped socket, or
:attr:`CaptureWriter.record` for a driver with its own clock). A writer thread wakes every ``flush_s`` (250 ms) and
takes the whole queue as one batch (without a thread, ``start(background=False)``, the driver calls :meth:`flush`
itself: the virtual clock does, every 250 ms of simulated time). Without notes in the batch, every per-datagram
step is a C-level ``map``/``zip`` over the batch: the Enhanced Packet Block template of the datagram's flow and size
(dpkt's block header with the IPv4/IPv6 + UDP header built by dpkt appended, made once per flow and size), and
its Unix time in integer µs. :class:`~mlink_sim.capture.epb.EpbPacker` then packs :data:`_CHUNK` blocks at a time
in the layout dpkt declares, and each chunk goes to the unbuffered file in one ``write``: that system call releases
the GIL, so the event loop never waits behind the writer for longer than one chunk. dpkt writes the Section Header
and Interface Description Blocks and every block with comments (``EnhancedPacketBlockLE`` with its options); how
this reads issue 20's "use a well-kept library; do not write the blocks by hand", and why, is in
:mod:`mlink_sim.capture.epb`. What this costs per datagram is measured by ``scripts/bench_capture.py``
(docs/performance.md, "Capture").

Notes (:meth:`CaptureWriter.note`: alarms, phase changes, injected faults) travel in the same deque, so they keep
their order with the datagrams; each becomes a pcapng ``opt_comment`` on the datagram recorded just before it
(the one whose processing raised the event), or on the first datagram when none came before.

Timestamps are whatever clock the caller keeps, in ns: the real monotonic clock in ``up``/``master``/``slave``,
a simulated clock in a virtual-time driver. ``epoch_offset_ns`` turns them into Unix time for the file (by default
the offset between ``time.time_ns()`` and ``time.monotonic_ns()`` when the writer is created), truncated to the
microsecond (the file's resolution, pcapng's default ``if_tsresol``).

The file is bounded: once it holds ``max_bytes``, the last datagram written carries a comment saying so and the
rest of the run is counted in :attr:`CaptureStats.not_recorded`, never written.
"""

from __future__ import annotations

import dataclasses
import socket
import threading
import time
from collections import deque
from collections.abc import Iterator
from itertools import repeat
from pathlib import Path
from typing import Any, BinaryIO

import dpkt
from dpkt import pcapng

from .._log import get_logger
from .epb import EpbPacker

__all__ = ["CaptureWriter", "CaptureStats", "LINKTYPE_RAW", "ip_packet", "event_text"]

log = get_logger("mlink_sim.capture")

LINKTYPE_RAW = 101  #: pcapng link type "raw IP" (IPv4 or IPv6 by the version nibble), tcpdump.org/linktypes
_CHUNK = 128  #: blocks packed between two file writes (each releases the GIL): a GIL hold well under 0.1 ms
_SNAPLEN = 65535
_popleft = deque.popleft
_MAX_OVERHEAD = 32 + 40 + 8 + 3  #: an EPB's bytes beyond its datagram at most: block fields, IPv6, UDP, padding
_MAX_DATAGRAM = 4096  #: what the sockets read at most (the size bound keeps room for one more)
#: a template of :class:`~mlink_sim.capture.epb.EpbPacker` for one flow and size, and the IP/UDP header alone
_Flow = tuple[bytes, bytes, bytes, bytes]


@dataclasses.dataclass
class CaptureStats:
    """What a capture holds so far."""

    path: str
    datagrams: int = 0
    notes: int = 0
    bytes: int = 0
    not_recorded: int = 0  #: datagrams after the size bound was reached
    max_bytes: int = 0
    writer_cpu_s: float = 0.0  #: CPU time of the writer thread (turning the queue into the file)

    def summary(self) -> str:
        text = f"capture {self.path}: {self.datagrams} datagrams, {self.notes} notes, {self.bytes} bytes"
        if self.datagrams:
            text += f", writer {self.writer_cpu_s * 1e6 / self.datagrams:.1f} us CPU per datagram"
        if self.not_recorded:
            text += f"; {self.not_recorded} datagrams not recorded (--capture-max {self.max_bytes} bytes reached)"
        return text


def _addr(a: Any) -> tuple[str, int]:
    return str(a[0]), int(a[1])


def ip_packet(payload: bytes, src: Any, dst: Any) -> bytes:
    """*payload* in a UDP datagram from *src* to *dst* ``(host, port)``, in an IPv4 header (IPv6 for ``:``
    addresses), built with dpkt. The UDP checksum is left 0 ("not computed", RFC 768) on IPv4."""
    (shost, sport), (dhost, dport) = _addr(src), _addr(dst)
    udp = dpkt.udp.UDP(sport=sport, dport=dport, data=payload)
    udp.ulen = len(udp)
    if ":" in shost or ":" in dhost:
        ip6 = dpkt.ip6.IP6(src=socket.inet_pton(socket.AF_INET6, _v6(shost)),
                           dst=socket.inet_pton(socket.AF_INET6, _v6(dhost)), nxt=17, hlim=64, data=udp)
        ip6.plen = len(udp)
        return bytes(ip6)
    udp.sum = 0xFFFF  # a non-zero value keeps dpkt from summing; reset to 0 below
    ip = dpkt.ip.IP(src=socket.inet_aton(shost), dst=socket.inet_aton(dhost), p=17, ttl=64, df=1, data=udp)
    raw = bytearray(bytes(ip))
    raw[26:28] = b"\0\0"
    return bytes(raw)


def _v6(host: str) -> str:
    if ":" not in host:  # an IPv4 peer of an IPv6 socket
        return "::ffff:" + host
    return host.split("%", 1)[0]


def event_text(event: Any) -> str:
    """One line for a note: a string as it is, a dataclass event as ``Name station 21H: field=value …``."""
    if isinstance(event, str):
        return event
    if dataclasses.is_dataclass(event):
        fields = {f.name: getattr(event, f.name) for f in dataclasses.fields(event)}
        station = fields.pop("station", None)
        parts = [f"{k}={getattr(v, 'value', v)}" for k, v in fields.items()]
        where = f" station {station:02X}H" if isinstance(station, int) else ""
        return f"{type(event).__name__}{where}: {' '.join(parts)}"
    return str(event)


class _Blocks:
    """What dpkt's pcapng ``Writer`` writes its header blocks into: a list (``write`` is the list's ``append``),
    written to the file by :meth:`CaptureWriter._flush_blocks`."""

    __slots__ = ("parts", "write")

    def __init__(self) -> None:
        self.parts: list[bytes] = []
        self.write = self.parts.append


class CaptureWriter:
    """A pcapng file being written off the hot path. ``start()``, then :meth:`record`/:meth:`note` from the hot
    path, ``close()`` at the end (flushes everything recorded before it). ``start(background=False)`` writes
    without a thread: the driver calls :meth:`flush` at points of its choosing (the virtual clock, every 250 ms of
    simulated time)."""

    def __init__(self, path: str | Path, *, max_bytes: int = 100_000_000, epoch_offset_ns: int | None = None,
                 flush_s: float = 0.25) -> None:
        self.path = Path(path)
        self.max_bytes = max_bytes
        self.epoch_offset_ns = (time.time_ns() - time.monotonic_ns()) if epoch_offset_ns is None else epoch_offset_ns
        self.flush_s = flush_s
        self.stats = CaptureStats(str(self.path), max_bytes=max_bytes)
        self._queue: deque[tuple[int, Any, Any, Any]] = deque()
        append = self._queue.append

        def record(ts_ns: int, data: bytes, src: Any, dst: Any) -> None:
            append((ts_ns, data, src, dst))

        #: the hook for drivers with their own clock (a virtual clock):
        #: ``record(ts_ns, datagram, (src_host, src_port), (dst_host, dst_port))``. A wildcard host (0.0.0.0, ::)
        #: is replaced by the address the kernel would send from. Sockets use :meth:`wrap` (one call less).
        self.record = record
        #: what a socket's tap feeds: one ``(ts_ns, datagram, src, dst)`` tuple per datagram (the queue's append;
        #: :meth:`wrap`, :func:`mlink_sim.aio.tapped.tap`)
        self.sink = append
        self._file: BinaryIO | None = None
        self._blocks = _Blocks()
        self._packer = EpbPacker()
        self._thread: threading.Thread | None = None
        self._wake = threading.Event()
        self._closing = False
        #: (src, dst, size) -> the EPB template of that flow and size, its IP/UDP header appended (EpbPacker)
        self._templates: dict[tuple[Any, Any, int], _Flow] = {}
        #: datagrams read from the queue, not written yet (time stamp in ns, template, datagram), in three lists:
        #: the last one waits for the notes that may follow it
        self._stamps: list[int] = []
        self._flows: list[_Flow] = []
        self._datas: list[bytes] = []
        self._notes: dict[int, list[str]] = {}  #: index in the pending lists -> its comments
        self._noted = 0  #: notes queued by :meth:`note` (counted before they are queued)
        self._notes_taken = 0  #: notes the writer has taken from the queue
        self._full = False
        self._limit_reserve = _epb_size(0, [self._limit_text()]) - 32

    # ------------------------------------------------------------------ life cycle
    def start(self, *, background: bool = True) -> CaptureWriter:
        """Open the file (OSError when it cannot be created); start the writer thread unless *background* is
        False (then :meth:`flush` writes, in the caller's thread)."""
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._file = open(self.path, "wb", buffering=0)  # noqa: SIM115 - closed in close(); one write per chunk
        shb = pcapng.SectionHeaderBlockLE(opts=[
            pcapng.PcapngOptionLE(code=pcapng.PCAPNG_OPT_SHB_USERAPPL, data=b"mlink-sim"),
            pcapng.PcapngOptionLE(code=pcapng.PCAPNG_OPT_ENDOFOPT)])
        pcapng.Writer(self._blocks, snaplen=_SNAPLEN, linktype=LINKTYPE_RAW, shb=shb)  # writes the SHB and IDB
        self._flush_blocks()
        if background:
            self._thread = threading.Thread(target=self._run, name="mlink-capture", daemon=True)
            self._thread.start()
        return self

    def close(self) -> CaptureStats:
        """Write what is queued, end the thread, close the file; returns the final :class:`CaptureStats`."""
        if self._thread is not None:
            self._closing = True
            self._wake.set()
            self._thread.join()
            self._thread = None
        if self._file is not None:
            self._drain_timed(final=True)
            if self._notes:
                log.warning("capture_notes_unwritten", notes=sum(map(len, self._notes.values())),
                            reason="no datagram to attach to")
            self._file.close()
            self._file = None
        return self.stats

    def flush(self) -> None:
        """Write what is queued now, in this thread (all but the last datagram, which waits for its notes): for
        a writer started with ``background=False``; nothing when the writer thread runs (it writes)."""
        if self._file is not None and self._thread is None:
            self._drain_timed()

    def __enter__(self) -> CaptureWriter:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.close()

    # ------------------------------------------------------------------ producers
    def note(self, ts_ns: int, event: Any) -> None:
        """A comment (a string, or an event dataclass formatted in the writer thread) on the last datagram."""
        self._noted += 1  # before the note is queued: a writer that sees it queued sees it counted
        self._queue.append((ts_ns, event, None, None))

    def wrap(self, sock: socket.socket) -> Any:
        """*sock* as a :class:`~mlink_sim.capture.tap.TappedSocket` recording into this capture (one system call
        per datagram; the I/O layer taps its batched calls instead, :func:`mlink_sim.aio.tapped.tap`)."""
        from .tap import TappedSocket

        return TappedSocket(sock, self.sink)

    # ------------------------------------------------------------------ writer
    def _run(self) -> None:
        while not self._closing:
            self._wake.wait(self.flush_s)
            self._drain_timed()

    def _drain_timed(self, final: bool = False) -> None:
        cpu = time.thread_time()
        try:
            self._drain(final)
        except Exception as exc:  # noqa: BLE001 - disk full, file gone: stop, say so, run on
            self._write_failed(exc)
        self.stats.writer_cpu_s += time.thread_time() - cpu

    def _write_failed(self, exc: Exception) -> None:
        if not self._full:
            log.error("capture_write_failed", path=str(self.path), error=f"{type(exc).__name__}: {exc}")
        self._full = True

    def _drain(self, final: bool = False) -> None:
        """Take everything queued, then write all but the last datagram (all when *final*): the last waits for
        the notes that may come next (its comments).

        Every step is a C-level ``map``/``zip``/slice over the batch (the template of each flow and size, the
        timestamps); notes, when the batch holds any, are found with ``tuple.index`` and split it into runs.
        :class:`~mlink_sim.capture.epb.EpbPacker` then packs :data:`_CHUNK` blocks per file write."""
        queue = self._queue
        count = len(queue)
        if count:
            batch = list(map(_popleft, repeat(queue, count)))
            noted = self._noted  # read after the pops: every note in the batch is counted in it
            stamps, datas, srcs, dsts = zip(*batch, strict=True)
            if noted == self._notes_taken:
                self._take(stamps, datas, srcs, dsts)
            else:
                start = 0
                for i in _notes_in(srcs):
                    if i > start:
                        self._take(stamps[start:i], datas[start:i], srcs[start:i], dsts[start:i])
                    self._notes_taken += 1
                    self.stats.notes += 1
                    self._notes.setdefault(max(len(self._datas) - 1, 0), []).append(event_text(datas[i]))
                    start = i + 1
                if start < count:
                    self._take(stamps[start:], datas[start:], srcs[start:], dsts[start:])
        pending = len(self._datas)
        if final and pending:
            self._write(pending)
        elif pending > 1:
            self._write(pending - 1)

    def _take(self, stamps: tuple[int, ...], datas: tuple[bytes, ...], srcs: tuple[Any, ...],
              dsts: tuple[Any, ...]) -> None:
        """Datagrams (no notes) into the pending lists: their flows' templates, their stamps (ns), themselves."""
        flows = self._templates
        try:
            got = list(map(flows.__getitem__, zip(srcs, dsts, map(len, datas), strict=True)))
        except KeyError:  # a flow or size not seen before: made once
            for key in set(zip(srcs, dsts, map(len, datas), strict=True)).difference(flows):
                flows[key] = self._flow(*key)
            got = list(map(flows.__getitem__, zip(srcs, dsts, map(len, datas), strict=True)))
        self._flows.extend(got)
        self._stamps.extend(stamps)
        self._datas.extend(datas)

    def _flow(self, src: Any, dst: Any, size: int) -> _Flow:
        """The EPB template of a *size*-byte datagram from *src* to *dst*, its IP + UDP header appended. A wildcard
        source (a socket bound to 0.0.0.0 or ::) is replaced by the address the kernel sends from to reach
        *dst*."""
        from .tap import WILDCARDS, source_address_for

        if src[0] in WILDCARDS:
            src = source_address_for(dst, src[1])
        elif dst[0] in WILDCARDS:
            dst = source_address_for(src, dst[1])
        header = ip_packet(bytes(size), src, dst)[:-size] if size else ip_packet(b"", src, dst)
        return (*self._packer.template(len(header) + size, header), header)

    def _limit_text(self) -> str:
        return f"capture limit of {self.max_bytes} bytes reached: later datagrams are not recorded"

    def _flush_blocks(self) -> None:
        """Write the blocks dpkt made since the last flush to the file."""
        parts = self._blocks.parts
        if parts:
            data = b"".join(parts)
            parts.clear()
            self._out(data)

    def _out(self, data: bytes) -> None:
        """*data* to the file: one system call (it releases the GIL)."""
        assert self._file is not None
        view = memoryview(data)
        while view:
            view = view[self._file.write(view) or 0:]
        self.stats.bytes += len(data)

    def _write(self, count: int) -> None:
        """Write the first *count* pending datagrams with their notes; keep the size bound."""
        stamps, flows, datas = self._stamps[:count], self._flows[:count], self._datas[:count]
        del self._stamps[:count], self._flows[:count], self._datas[:count]
        notes = self._notes
        mine: dict[int, list[str]] = {}
        if notes:
            mine = {i: notes.pop(i) for i in sorted(notes) if i < count}
            self._notes = {i - count: c for i, c in notes.items()}
        if self._full:
            self.stats.not_recorded += count
            return
        bound = (self.stats.bytes + count * _MAX_OVERHEAD + sum(map(len, datas))
                 + sum(_epb_size(0, c) - 32 for c in mine.values()))
        if bound + self._limit_reserve + _MAX_OVERHEAD + _MAX_DATAGRAM > self.max_bytes:
            self._write_bounded(stamps, flows, datas, mine)
            return
        start = 0
        for i, comments in mine.items():  # commented datagrams one by one, the runs between them in chunks
            self._write_run(stamps, flows, datas, start, i)
            self._write_commented(stamps[i], flows[i], datas[i], comments)
            start = i + 1
        self._write_run(stamps, flows, datas, start, count)
        self.stats.datagrams += count

    def _write_run(self, stamps: list[int], flows: list[_Flow], datas: list[bytes], start: int, end: int) -> None:
        """Uncommented datagrams ``start:end``: packed by the EpbPacker, one file write per :data:`_CHUNK`."""
        pack, out = self._packer.pack_parts, self._out
        for j in range(start, end, _CHUNK):
            k = min(j + _CHUNK, end)
            out(pack(stamps[j:k], flows[j:k], datas[j:k], offset=self.epoch_offset_ns))

    def _write_commented(self, ts_ns: int, flow: _Flow, data: bytes, comments: list[str]) -> None:
        """One datagram with comments: dpkt's own Enhanced Packet Block with ``opt_comment`` options."""
        us = (ts_ns + self.epoch_offset_ns) // 1000
        opts = [pcapng.PcapngOptionLE(code=pcapng.PCAPNG_OPT_COMMENT, text=c) for c in comments]
        opts.append(pcapng.PcapngOptionLE(code=pcapng.PCAPNG_OPT_ENDOFOPT))
        self._out(bytes(pcapng.EnhancedPacketBlockLE(pkt_data=flow[3] + data, opts=opts, ts_high=us >> 32,
                                                     ts_low=us & 0xFFFFFFFF)))

    def _write_bounded(self, stamps: list[int], flows: list[_Flow], datas: list[bytes],
                       notes: dict[int, list[str]]) -> None:
        """One datagram at a time near ``max_bytes``: the last one that fits carries the limit comment."""
        size = self.stats.bytes
        for i, (ts_ns, flow, data) in enumerate(zip(stamps, flows, datas, strict=True)):
            comments = notes.get(i)
            caplen = len(flow[3]) + len(data)
            block = _epb_size(caplen, comments)
            if size + 2 * block + self._limit_reserve > self.max_bytes:  # another one would not fit after it
                self._full = True
                comments = [*(comments or ()), self._limit_text()]
                log.warning("capture_limit_reached", path=str(self.path), max_bytes=self.max_bytes)
                block = _epb_size(caplen, comments)
                if size + block > self.max_bytes:  # not even this one fits with its comments
                    self.stats.not_recorded += len(datas) - i
                    return
            if comments:
                self._write_commented(ts_ns, flow, data, comments)
            else:
                self._out(self._packer.pack_parts([ts_ns], [flow], [data], offset=self.epoch_offset_ns))
            self.stats.datagrams += 1
            size += block
            if self._full:
                self.stats.not_recorded += len(datas) - i - 1
                return


def _notes_in(srcs: tuple[Any, ...]) -> Iterator[int]:
    """Where the notes are in a batch (their source is None), by C-level scans."""
    i = -1
    while True:
        try:
            i = srcs.index(None, i + 1)
        except ValueError:
            return
        yield i


def _pad4(n: int) -> int:
    return (n + 3) & ~3


def _epb_size(caplen: int, comments: list[str] | None) -> int:
    """Bytes of the Enhanced Packet Block of a *caplen*-byte packet (pcapng §4.3: 32 + data padded to 4, then the
    options: each 4 + value padded, and an end-of-options)."""
    size = 32 + _pad4(caplen)
    if comments:
        size += sum(4 + _pad4(len(c.encode())) for c in comments) + 4
    return size
