"""Write datagrams to a pcapng file off the hot path (``--capture FILE.pcapng``).

The hot path only appends ``(ts_ns, datagram, src, dst)`` to a deque (a tapped socket, or
:attr:`CaptureWriter.record` for a driver with its own clock). A writer thread wakes every ``flush_s`` (250 ms) and
takes the whole queue as one batch (without a thread, ``start(background=False)``, the driver calls :meth:`flush`
itself: the virtual clock does, every 250 ms of simulated time). The records go, as they are, to a loop compiled
with mypyc (:func:`mlink_sim.capture.pack.pack_records`, through :class:`~mlink_sim.capture.epb.EpbPacker`): per
datagram, the Enhanced Packet Block template of its flow and size (dpkt's block header with the IPv4/IPv6 + UDP
header built by dpkt in it, made once per flow and size, found in a dict), its Unix time in integer µs, the
block's parts appended; :data:`_CHUNK` blocks per call, and each chunk goes to the unbuffered file in one
``write``: that system call releases the GIL, so the event loop never waits behind the writer for longer than one
chunk. dpkt writes the Section Header and Interface Description Blocks and every block with comments
(``EnhancedPacketBlockLE`` with its options); how this reads the rule "use a well-kept library; do not write the
blocks by hand", and why, is in :mod:`mlink_sim.capture.epb`. What this costs per datagram: docs/capture.md
(``python -m benchmarks.micro.capture`` measures it).

Notes (:meth:`CaptureWriter.note`: alarms, phase changes, injected faults) travel in the same deque, so they keep
their order with the datagrams; each becomes a pcapng ``opt_comment`` on the datagram recorded just before it
(the one whose processing raised the event), or on the first datagram when none came before.

Timestamps are whatever clock the caller keeps, in ns: the real monotonic clock in ``up``/``master``/``slave``,
a simulated clock in a virtual-time driver. ``epoch_offset_ns`` turns them into Unix time for the file (by default
the offset between ``time.time_ns()`` and ``time.monotonic_ns()`` when the writer is created), truncated to the
microsecond (the file's resolution, pcapng's default ``if_tsresol``).

The file is bounded: once it holds ``max_bytes``, the last datagram written carries a comment saying so and the
rest of the run is counted in :attr:`CaptureStats.not_recorded`, never written.

A *stream* instead of a file (``--capture -``: standard output, for ``| wireshark -k -i -`` or ``| mlink-sim watch
-``) gets the same blocks as they are written, every ``flush_s``: a pcapng stream is the file read from its start,
so a reader that joins at the first byte sees a valid capture at every flush. When the reader goes away (a closed
pipe) the writer stops, says so once, and counts the rest as not recorded; the run goes on.
"""

from __future__ import annotations

import dataclasses
import socket
import struct
import threading
import time
from collections import deque
from itertools import repeat
from pathlib import Path
from typing import Any, BinaryIO

import dpkt
from dpkt import pcapng

from .._log import get_logger
from .epb import EpbPacker
from .pack import Flow, Record, packet
from .tap import WILDCARDS, source_address_for

__all__ = ["CaptureWriter", "CaptureStats", "LINKTYPE_RAW", "ip_packet", "event_text"]

log = get_logger("mlink_sim.capture")

LINKTYPE_RAW = 101  #: pcapng link type "raw IP" (IPv4 or IPv6 by the version nibble), tcpdump.org/linktypes
_CHUNK = 128  #: blocks packed between two file writes (each releases the GIL): a GIL hold well under 0.1 ms
_SNAPLEN = 65535
_popleft = deque.popleft


@dataclasses.dataclass
class CaptureStats:
    """What a capture holds so far."""

    path: str  #: the file, or ``-`` for standard output
    datagrams: int = 0
    notes: int = 0
    bytes: int = 0
    not_recorded: int = 0  #: datagrams after the size bound was reached
    max_bytes: int = 0
    writer_cpu_s: float = 0.0  #: CPU time of the writer thread (turning the queue into the file)
    stopped: str = ""  #: why the writer stopped before the bound (the reader of the stream went away, a full disk)

    def summary(self) -> str:
        where = "to stdout" if self.path == "-" else self.path
        text = f"capture {where}: {self.datagrams} datagrams, {self.notes} notes, {self.bytes} bytes"
        if self.datagrams:
            text += f", writer {self.writer_cpu_s * 1e6 / self.datagrams:.1f} us CPU per datagram"
        if self.not_recorded:
            why = self.stopped or f"--capture-max {self.max_bytes} bytes reached"
            text += f"; {self.not_recorded} datagrams not recorded ({why})"
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
    simulated time).

    *stream*: write to this binary file object (unbuffered: each write goes out as it is made) instead of
    creating *path*, which then only names it (``-``: standard output); ``close()`` closes it, so that its reader
    sees the end of the capture."""

    def __init__(self, path: str | Path, *, max_bytes: int = 100_000_000, epoch_offset_ns: int | None = None,
                 flush_s: float = 0.25, stream: BinaryIO | None = None) -> None:
        self.path = Path(path)
        self._stream = stream
        self.max_bytes = max_bytes
        self.epoch_offset_ns = (time.time_ns() - time.monotonic_ns()) if epoch_offset_ns is None else epoch_offset_ns
        self.flush_s = flush_s
        self.stats = CaptureStats(str(path), max_bytes=max_bytes)
        self._queue: deque[tuple[int, Any, Any, Any]] = deque()
        append = self._queue.append

        def record(ts_ns: int, data: bytes, src: Any, dst: Any) -> None:
            append((ts_ns, data, src, dst))

        #: the hook for drivers with their own clock (a virtual clock):
        #: ``record(ts_ns, datagram, (src_host, src_port), (dst_host, dst_port))``. A wildcard host (0.0.0.0, ::)
        #: is replaced by the address the kernel would send from. Sockets are tapped instead
        #: (:func:`mlink_sim.aio.transport.tapped.tap`: one call less).
        self.record = record
        #: what a socket's tap feeds: one ``(ts_ns, datagram, src, dst)`` tuple per datagram (the queue's append;
        #: :func:`mlink_sim.aio.transport.tapped.tap`)
        self.sink = append
        self._file: BinaryIO | None = None
        self._blocks = _Blocks()
        self._packer = EpbPacker()
        self._thread: threading.Thread | None = None
        self._wake = threading.Event()
        self._closing = False
        #: (src, dst, size) -> the EPB template of that flow and size, its IP/UDP header in it (EpbPacker.flow)
        self._templates: dict[tuple[Any, Any, int], Flow] = {}
        #: records taken from the queue, not written yet: the last datagram, and the notes after it, wait for the
        #: notes that may follow it
        self._pending: list[Record] = []
        self._full = False
        self._limit_reserve = _epb_size(0, [self._limit_text()]) - 32

    # ------------------------------------------------------------------ life cycle
    def start(self, *, background: bool = True) -> CaptureWriter:
        """Open the file (OSError when it cannot be created), or take the stream; start the writer thread unless
        *background* is False (then :meth:`flush` writes, in the caller's thread)."""
        if self._stream is not None:
            self._file = self._stream
        else:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self._file = open(self.path, "wb", buffering=0)  # noqa: SIM115 - closed in close(); one write per chunk
        shb = pcapng.SectionHeaderBlockLE(opts=[
            pcapng.PcapngOptionLE(code=pcapng.PCAPNG_OPT_SHB_USERAPPL, data=b"mlink-sim"),
            pcapng.PcapngOptionLE(code=pcapng.PCAPNG_OPT_ENDOFOPT)])
        pcapng.Writer(self._blocks, snaplen=_SNAPLEN, linktype=LINKTYPE_RAW, shb=shb)  # writes the SHB and IDB
        try:
            self._flush_blocks()
        except OSError as exc:  # a stream whose reader is already gone: as on any later write
            self._write_failed(exc)
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
            if self._pending:  # notes only: no datagram came
                self.stats.notes += len(self._pending)
                log.warning("capture_notes_unwritten", notes=len(self._pending), reason="no datagram to attach to")
                self._pending.clear()
            try:
                self._file.close()
            except OSError as exc:  # a stream whose reader went away
                self._write_failed(exc)
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
        self._queue.append((ts_ns, event, None, None))

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
            gone = isinstance(exc, BrokenPipeError)
            self.stats.stopped = "the reader of the stream went away" if gone else f"{type(exc).__name__}: {exc}"
            log.error("capture_write_failed", path=self.stats.path, error=f"{type(exc).__name__}: {exc}",
                      why=self.stats.stopped)
        self._full = True

    def _drain(self, final: bool = False) -> None:
        """Take everything queued, then write all but the last datagram (all when *final*): the last waits for
        the notes that may come next (its comments)."""
        queue, pending = self._queue, self._pending
        count = len(queue)
        if count:
            pending.extend(map(_popleft, repeat(queue, count)))
        end = len(pending)
        if not final:  # up to the last datagram, which stays with the notes after it
            end -= 1
            while end > 0 and pending[end][2] is None:
                end -= 1
        if end > 0:
            self._write(end)

    def _write(self, end: int) -> None:
        """Write the records ``pending[:end]`` and drop them: the compiled loop packs the runs of uncommented
        datagrams, :data:`_CHUNK` per file write, up to the size bound; a datagram with notes goes by
        :meth:`_write_one`, and so does each one near the bound."""
        pending, flows, make, pack = self._pending, self._templates, self._make, self._packer.pack_records
        offset, stats = self.epoch_offset_ns, self.stats
        i = 0
        try:
            while i < end:
                if self._full:  # the bound was reached (or the disk failed): counted, not written
                    datagrams = sum(1 for record in pending[i:end] if record[2] is not None)
                    stats.not_recorded += datagrams
                    stats.notes += end - i - datagrams
                    i = end
                    break
                blocks, stop, _ = pack(pending, i, end, flows, make, offset=offset, count=_CHUNK,
                                       budget=self.max_bytes - self._limit_reserve - stats.bytes)
                if stop > i:
                    self._out(blocks)
                    stats.datagrams += stop - i
                    i = stop
                else:
                    stop = self._write_one(i, end)
                    if stop == i:  # notes with no datagram to attach to yet
                        break
                    i = stop
        finally:
            del pending[:i]

    def _write_one(self, i: int, end: int) -> int:
        """The datagram at or after ``pending[i]`` with the notes before it (when no datagram came before them)
        and after it, as its comments; near the bound, the last one that fits carries the limit comment. Returns
        the index after its notes (*i* when no datagram is before *end*)."""
        pending = self._pending
        k = i
        while k < end and pending[k][2] is None:
            k += 1
        if k == end:
            return i
        record = pending[k]
        comments = [event_text(note[1]) for note in pending[i:k]]
        k += 1
        while k < len(pending) and pending[k][2] is None:
            comments.append(event_text(pending[k][1]))
            k += 1
        self.stats.notes += len(comments)
        ts_ns, data, src, dst = record
        flow = self._templates.get((src, dst, len(data))) or self._make(src, dst, len(data))
        caplen = len(flow[4]) + len(data)
        size, block = self.stats.bytes, _epb_size(caplen, comments)
        if size + 2 * block + self._limit_reserve > self.max_bytes:  # another one would not fit after it
            self._full = True
            comments.append(self._limit_text())
            log.warning("capture_limit_reached", path=str(self.path), max_bytes=self.max_bytes)
            if size + _epb_size(caplen, comments) > self.max_bytes:  # not even this one fits with its comments
                self.stats.not_recorded += 1
                return k
        if comments:
            self._write_commented(ts_ns, flow, data, comments)
        else:
            self._out(self._packer.pack_records([record], 0, 1, self._templates, self._make,
                                                offset=self.epoch_offset_ns)[0])
        self.stats.datagrams += 1
        return k

    def _make(self, src: Any, dst: Any, size: int) -> Flow:
        """The EPB template of a *size*-byte datagram from *src* to *dst*, its IP + UDP header in it, made and kept.
        A wildcard source (a socket bound to 0.0.0.0 or ::) is replaced by the address the kernel sends from to
        reach *dst*."""
        key = (src, dst, size)
        if src[0] in WILDCARDS:
            src = source_address_for(dst, src[1])
        elif dst[0] in WILDCARDS:
            dst = source_address_for(src, dst[1])
        header = ip_packet(bytes(size), src, dst)[:-size] if size else ip_packet(b"", src, dst)
        csum = _pseudo_sum(header) if header[0] >> 4 == 6 else -1  # IPv4: checksum 0 ("not computed")
        flow = self._templates[key] = self._packer.flow(len(header) + size, header, csum)
        return flow

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

    def _write_commented(self, ts_ns: int, flow: Flow, data: bytes, comments: list[str]) -> None:
        """One datagram with comments: dpkt's own Enhanced Packet Block with ``opt_comment`` options."""
        us = (ts_ns + self.epoch_offset_ns) // 1000
        opts = [pcapng.PcapngOptionLE(code=pcapng.PCAPNG_OPT_COMMENT, text=c) for c in comments]
        opts.append(pcapng.PcapngOptionLE(code=pcapng.PCAPNG_OPT_ENDOFOPT))
        self._out(bytes(pcapng.EnhancedPacketBlockLE(pkt_data=packet(flow, data), opts=opts, ts_high=us >> 32,
                                                     ts_low=us & 0xFFFFFFFF)))


def _pseudo_sum(header: bytes) -> int:
    """The one's-complement sum, unfolded, of an IPv6 + UDP *header*'s pseudo-header (source, destination, the UDP
    length and next header 17, RFC 8200 §8.1) and its UDP header with the checksum taken as 0: the part of the UDP
    checksum that is the same for every datagram of the flow (:func:`mlink_sim.capture.pack.udp_checksum`)."""
    udp = header[40:48]
    pseudo = header[8:40] + struct.pack("!IxxxB", int.from_bytes(udp[4:6], "big"), 17) + udp[:6]
    return sum(struct.unpack(f"!{len(pseudo) // 2}H", pseudo))


def _pad4(n: int) -> int:
    return (n + 3) & ~3


def _epb_size(caplen: int, comments: list[str] | None) -> int:
    """Bytes of the Enhanced Packet Block of a *caplen*-byte packet (pcapng §4.3: 32 + data padded to 4, then the
    options: each 4 + value padded, and an end-of-options)."""
    size = 32 + _pad4(caplen)
    if comments:
        size += sum(4 + _pad4(len(c.encode())) for c in comments) + 4
    return size
