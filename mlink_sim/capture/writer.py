"""Write datagrams to a pcapng file off the hot path (``--capture FILE.pcapng``).

The hot path only appends ``(ts_ns, datagram, src, dst)`` to a deque (:meth:`wrap`'s tapped socket, or
:attr:`CaptureWriter.record` for a driver with its own clock). A writer thread wakes every ``flush_s`` (250 ms) and
takes the whole queue as one batch: without notes in it, every per-datagram step on our side is a C-level
``map``/``zip`` over the batch (the IPv4/IPv6 + UDP header comes from a cache keyed by flow and size, built with
dpkt once per key; header + datagram; Unix time in s). dpkt's pcapng ``Writer.writepkts`` then makes the Enhanced
Packet Blocks (LINKTYPE_RAW, microsecond timestamps) into a list, and the list goes to the unbuffered file in one
``write`` per :data:`_CHUNK` packets: each such system call releases the GIL, so the event loop never waits behind
the writer for longer than one chunk. What this costs per datagram is measured by ``scripts/bench_capture.py``
(docs/performance.md, "Capture").

Notes (:meth:`CaptureWriter.note`: alarms, phase changes, injected faults) travel in the same deque, so they keep
their order with the datagrams; each becomes a pcapng ``opt_comment`` on the datagram recorded just before it
(the one whose processing raised the event), or on the first datagram when none came before.

Timestamps are whatever clock the caller keeps, in ns: the real monotonic clock in ``up``/``master``/``slave``,
a simulated clock in a virtual-time driver. ``epoch_offset_ns`` turns them into Unix time for the file (by default
the offset between ``time.time_ns()`` and ``time.monotonic_ns()`` when the writer is created).

The file is bounded: once it holds ``max_bytes``, the last datagram written carries a comment saying so and the
rest of the run is counted in :attr:`CaptureStats.not_recorded`, never written.
"""

from __future__ import annotations

import dataclasses
import socket
import threading
import time
from collections import deque
from itertools import repeat
from operator import add, mul
from pathlib import Path
from typing import Any, BinaryIO

import dpkt
from dpkt import pcapng

from .._log import get_logger

__all__ = ["CaptureWriter", "CaptureStats", "LINKTYPE_RAW", "ip_packet", "event_text"]

log = get_logger("mlink_sim.capture")

LINKTYPE_RAW = 101  #: pcapng link type "raw IP" (IPv4 or IPv6 by the version nibble), tcpdump.org/linktypes
_CHUNK = 128  #: packets dpkt writes between two file writes (each releases the GIL): a GIL hold of ~0.15 ms
_SNAPLEN = 65535
_popleft = deque.popleft
_MAX_BLOCK = 32 + 40 + 8 + 80  # the largest EPB of a datagram (78 bytes, padded) over IPv6 and UDP


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
    """What dpkt's pcapng ``Writer`` writes into: its blocks are collected in a list (``write`` is the list's
    ``append``) and go to the file in one system call per chunk (:meth:`CaptureWriter._flush_blocks`)."""

    __slots__ = ("parts", "write")

    def __init__(self) -> None:
        self.parts: list[bytes] = []
        self.write = self.parts.append


class CaptureWriter:
    """A pcapng file being written by a background thread. ``start()``, then :meth:`record`/:meth:`note` from
    the hot path, ``close()`` at the end (flushes everything recorded before it)."""

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
        self._file: BinaryIO | None = None
        self._blocks = _Blocks()
        self._writer: Any = None
        self._thread: threading.Thread | None = None
        self._wake = threading.Event()
        self._closing = False
        self._headers: dict[tuple[Any, Any, int], bytes] = {}
        #: datagrams read from the queue, not written yet: the last one waits for the notes that may follow it
        self._pending: list[tuple[float, bytes]] = []
        self._notes: dict[int, list[str]] = {}  #: index in _pending -> its comments
        self._noted = 0  #: notes queued by :meth:`note` (counted before they are queued)
        self._notes_taken = 0  #: notes the writer has taken from the queue
        self._full = False
        self._limit_reserve = _epb_size(b"", [self._limit_text()]) - 32

    # ------------------------------------------------------------------ life cycle
    def start(self) -> CaptureWriter:
        """Open the file (OSError when it cannot be created) and start the writer thread."""
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._file = open(self.path, "wb", buffering=0)  # noqa: SIM115 - closed in close(); one write per chunk
        shb = pcapng.SectionHeaderBlockLE(opts=[
            pcapng.PcapngOptionLE(code=pcapng.PCAPNG_OPT_SHB_USERAPPL, data=b"mlink-sim"),
            pcapng.PcapngOptionLE(code=pcapng.PCAPNG_OPT_ENDOFOPT)])
        self._writer = pcapng.Writer(self._blocks, snaplen=_SNAPLEN, linktype=LINKTYPE_RAW, shb=shb)
        self._flush_blocks()
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
            cpu = time.thread_time()
            try:
                self._drain(final=True)
            except OSError as exc:
                self._write_failed(exc)
            self.stats.writer_cpu_s += time.thread_time() - cpu
            if self._notes:
                log.warning("capture_notes_unwritten", notes=sum(map(len, self._notes.values())),
                            reason="no datagram to attach to")
            self._file.close()
            self._file = None
        return self.stats

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
        """*sock* as a :class:`~mlink_sim.capture.tap.TappedSocket` recording into this capture."""
        from .tap import TappedSocket

        return TappedSocket(sock, self._queue.append)

    # ------------------------------------------------------------------ writer thread
    def _run(self) -> None:
        while not self._closing:
            self._wake.wait(self.flush_s)
            cpu = time.thread_time()
            try:
                self._drain()
            except Exception as exc:  # noqa: BLE001 - disk full, file gone: stop, say so, run on
                self._write_failed(exc)
            self.stats.writer_cpu_s += time.thread_time() - cpu

    def _write_failed(self, exc: Exception) -> None:
        if not self._full:
            log.error("capture_write_failed", path=str(self.path), error=f"{type(exc).__name__}: {exc}")
        self._full = True

    def _drain(self, final: bool = False) -> None:
        """Take everything queued and turn it into packets, then write all but the last (all when *final*): the
        last waits for the notes that may come next (its comments).

        Without notes in the batch every step is a C-level ``map``/``zip`` over the whole batch (header lookup,
        header + datagram, Unix time in s); dpkt's ``writepkts`` then runs its own loop, :data:`_CHUNK` packets
        per file write."""
        queue = self._queue
        count = len(queue)
        if count:
            batch = list(map(_popleft, repeat(queue, count)))
            noted = self._noted  # read after the pops: every note in the batch is counted in it
            if noted != self._notes_taken:
                self._take_with_notes(batch)
            else:
                stamps, datas, srcs, dsts = zip(*batch, strict=True)
                self._pending.extend(zip(map(mul, map(add, stamps, repeat(self.epoch_offset_ns)), repeat(1e-9)),
                                         map(add, self._headers_of(srcs, dsts, datas), datas), strict=True))
        pending = len(self._pending)
        if final and pending:
            self._write(pending)
        elif pending > 1:
            self._write(pending - 1)

    def _headers_of(self, srcs: tuple[Any, ...], dsts: tuple[Any, ...], datas: tuple[bytes, ...]) -> list[bytes]:
        """The IP + UDP header of each datagram: one dict lookup per datagram, built once per flow and size."""
        headers = self._headers
        try:
            return list(map(headers.__getitem__, zip(srcs, dsts, map(len, datas), strict=True)))
        except KeyError:
            for key in set(zip(srcs, dsts, map(len, datas), strict=True)).difference(headers):
                headers[key] = self._header(*key)
            return list(map(headers.__getitem__, zip(srcs, dsts, map(len, datas), strict=True)))

    def _take_with_notes(self, batch: list[tuple[int, Any, Any, Any]]) -> None:
        """A batch with notes in it, one item at a time: each note becomes a comment on the datagram before it."""
        headers = self._headers
        offset = self.epoch_offset_ns
        pending = self._pending
        append = pending.append
        for ts_ns, data, src, dst in batch:
            if src is None:  # a note (a str or an event)
                self._notes_taken += 1
                self.stats.notes += 1
                self._notes.setdefault(max(len(pending) - 1, 0), []).append(event_text(data))
                continue
            key = (src, dst, len(data))
            header = headers.get(key)
            if header is None:
                header = headers[key] = self._header(*key)
            append(((ts_ns + offset) * 1e-9, header + data))

    def _header(self, src: Any, dst: Any, size: int) -> bytes:
        """IP + UDP header for a *size*-byte datagram; a wildcard source (a socket bound to 0.0.0.0 or ::) is
        replaced by the address the kernel sends from to reach *dst*."""
        from .tap import WILDCARDS, source_address_for

        if src[0] in WILDCARDS:
            src = source_address_for(dst, src[1])
        elif dst[0] in WILDCARDS:
            dst = source_address_for(src, dst[1])
        return ip_packet(bytes(size), src, dst)[:-size] if size else ip_packet(b"", src, dst)

    def _limit_text(self) -> str:
        return f"capture limit of {self.max_bytes} bytes reached: later datagrams are not recorded"

    def _flush_blocks(self) -> None:
        """Write the blocks dpkt made since the last flush to the file: one system call (it releases the GIL)."""
        parts = self._blocks.parts
        if not parts:
            return
        data = b"".join(parts)
        parts.clear()
        assert self._file is not None
        view = memoryview(data)
        while view:
            view = view[self._file.write(view) or 0:]
        self.stats.bytes += len(data)

    def _write(self, count: int) -> None:
        """Write the first *count* pending packets with their notes; keep the size bound."""
        pending, notes = self._pending, self._notes
        items = pending[:count]
        del pending[:count]
        mine: dict[int, list[str]] = {}
        if notes:
            mine = {i: notes.pop(i) for i in sorted(notes) if i < count}
            self._notes = {i - count: c for i, c in notes.items()}
        if self._full:
            self.stats.not_recorded += count
            return
        bound = self.stats.bytes + count * _MAX_BLOCK + sum(_epb_size(b"", c) - 32 for c in mine.values())
        if bound + self._limit_reserve + _MAX_BLOCK > self.max_bytes:
            self._write_bounded(items, mine)
            self._flush_blocks()
            return
        writepkts, flush = self._writer.writepkts, self._flush_blocks
        start = 0
        for i, comments in mine.items():  # commented packets one by one, the runs between them in chunks
            for j in range(start, i, _CHUNK):
                writepkts(items[j:min(j + _CHUNK, i)])
                flush()
            self._write_commented(items[i], comments)
            start = i + 1
        for j in range(start, count, _CHUNK):
            writepkts(items[j:j + _CHUNK])
            flush()
        flush()
        self.stats.datagrams += count

    def _write_commented(self, item: tuple[float, bytes], comments: list[str]) -> None:
        ts, packet = item
        opts = [pcapng.PcapngOptionLE(code=pcapng.PCAPNG_OPT_COMMENT, text=c) for c in comments]
        opts.append(pcapng.PcapngOptionLE(code=pcapng.PCAPNG_OPT_ENDOFOPT))
        self._writer.writepkt(pcapng.EnhancedPacketBlockLE(pkt_data=packet, caplen=len(packet), pkt_len=len(packet),
                                                           opts=opts), ts=ts)

    def _write_bounded(self, items: list[tuple[float, bytes]], notes: dict[int, list[str]]) -> None:
        """One packet at a time near ``max_bytes``: the last one that fits carries the limit comment."""
        size = self.stats.bytes
        for i, item in enumerate(items):
            comments = notes.get(i)
            block = _epb_size(item[1], comments)
            if size + 2 * block + self._limit_reserve > self.max_bytes:  # another one would not fit after it
                self._full = True
                comments = [*(comments or ()), self._limit_text()]
                log.warning("capture_limit_reached", path=str(self.path), max_bytes=self.max_bytes)
                block = _epb_size(item[1], comments)
                if size + block > self.max_bytes:  # not even this one fits with its comments
                    self.stats.not_recorded += len(items) - i
                    return
            if comments:
                self._write_commented(item, comments)
            else:
                self._writer.writepkts([item])
            self.stats.datagrams += 1
            size += block
            if self._full:
                self.stats.not_recorded += len(items) - i - 1
                return


def _pad4(n: int) -> int:
    return (n + 3) & ~3


def _epb_size(packet: bytes, comments: list[str] | None) -> int:
    """Bytes of the Enhanced Packet Block dpkt writes for *packet* (pcapng §4.3: 32 + data padded to 4, then the
    options: each 4 + value padded, and an end-of-options)."""
    size = 32 + _pad4(len(packet))
    if comments:
        size += sum(4 + _pad4(len(c.encode())) for c in comments) + 4
    return size
