"""Read captures back: every UDP datagram with its time, addresses and pcapng comments.

Reads pcapng (python-pcapng's ``FileScanner``, which keeps the ``opt_comment`` options mlink-sim writes) and
classic pcap (dpkt's ``pcap.Reader``), on the link types a capture of this traffic comes in: raw IP (mlink-sim's
own files), Ethernet, Linux cooked (SLL, SLL2) and BSD loopback. Packets that are not UDP over IPv4/IPv6 are
counted in :attr:`Capture.skipped`, not returned.

A capture is read as a stream, from its first byte on (no seek): ``-`` reads standard input (``mlink-sim up …
--capture - | mlink-sim decode --pcap -``), and ``follow=True`` keeps reading a file that is still being written
(``--capture run.pcapng`` of a running network), waiting at its end for the next block instead of ending there.
"""

from __future__ import annotations

import contextlib
import dataclasses
import socket
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import dpkt
import pcapng
from pcapng import blocks

__all__ = ["Datagram", "Capture", "CaptureError", "CaptureFile", "read_capture"]

_PCAPNG_MAGIC = b"\x0a\x0d\x0d\x0a"
_PCAP_MAGICS = (b"\xd4\xc3\xb2\xa1", b"\xa1\xb2\xc3\xd4", b"\x4d\x3c\xb2\xa1", b"\xa1\xb2\x3c\x4d")


class CaptureError(ValueError):
    """A file that is not a readable pcap/pcapng capture; the message says why in one line."""


@dataclasses.dataclass(frozen=True)
class Datagram:
    """One UDP datagram of a capture."""

    ts_ns: int  #: Unix time, ns (the file's resolution: µs for mlink-sim's captures)
    src: tuple[str, int]
    dst: tuple[str, int]
    data: bytes  #: the UDP payload
    comments: tuple[str, ...] = ()


@dataclasses.dataclass
class Capture:
    datagrams: list[Datagram]
    skipped: int = 0  #: packets that are not UDP over IP


def _ip_of(linktype: int, frame: bytes) -> Any:
    if linktype == 101:  # LINKTYPE_RAW
        version = frame[0] >> 4 if frame else 0
        return dpkt.ip.IP(frame) if version == 4 else dpkt.ip6.IP6(frame) if version == 6 else None
    if linktype in (228, 229):  # LINKTYPE_IPV4 / IPV6
        return dpkt.ip.IP(frame) if linktype == 228 else dpkt.ip6.IP6(frame)
    if linktype == 1:
        return dpkt.ethernet.Ethernet(frame).data
    if linktype == 113:
        return dpkt.sll.SLL(frame).data
    if linktype == 276:
        return dpkt.sll2.SLL2(frame).data
    if linktype == 0:
        return dpkt.loopback.Loopback(frame).data
    return None


def _datagram(linktype: int, frame: bytes, ts_ns: int, comments: tuple[str, ...]) -> Datagram | None:
    try:
        ip = _ip_of(linktype, frame)
    except (dpkt.UnpackError, IndexError, ValueError):
        return None
    if isinstance(ip, dpkt.ip.IP):
        family, src, dst = socket.AF_INET, ip.src, ip.dst
    elif isinstance(ip, dpkt.ip6.IP6):
        family, src, dst = socket.AF_INET6, ip.src, ip.dst
    else:
        return None
    udp = ip.data
    if not isinstance(udp, dpkt.udp.UDP):
        return None
    return Datagram(ts_ns, (socket.inet_ntop(family, src), udp.sport), (socket.inet_ntop(family, dst), udp.dport),
                    bytes(udp.data), comments)


def _comments(block: Any) -> tuple[str, ...]:
    opts = block.options
    if "opt_comment" not in opts:
        return ()
    return tuple(str(c) for c in opts.get_all("opt_comment"))


def _pcapng_frames(f: Any) -> Iterator[tuple[int, bytes, int, tuple[str, ...]]]:
    for block in pcapng.FileScanner(f):
        if isinstance(block, blocks.EnhancedPacket):
            raw = (block.timestamp_high << 32) | block.timestamp_low
            per_s = round(1 / block.timestamp_resolution) if block.timestamp_resolution else 1_000_000
            yield block.interface.link_type, bytes(block.packet_data), raw * 1_000_000_000 // per_s, _comments(block)
        elif isinstance(block, blocks.SimplePacket):  # no time, no comments
            yield block.interface.link_type, bytes(block.packet_data), 0, ()


def _pcap_frames(f: Any) -> Iterator[tuple[int, bytes, int, tuple[str, ...]]]:
    reader = dpkt.pcap.Reader(f)
    linktype = reader.datalink()
    for ts, frame in reader:
        yield linktype, frame, round(ts * 1e9), ()


class _Stream:
    """A binary file read from its start: ``read`` and the ``tell`` python-pcapng asks for (a pipe has no position),
    the first bytes given back after the format was told by them; with *wait* (a file still being written), a read
    that meets the end waits for the rest, ``wait()`` saying whether to go on waiting."""

    def __init__(self, raw: Any, wait: Callable[[], bool] | None = None, poll_s: float = 0.1) -> None:
        self._raw, self._wait, self._poll_s = raw, wait, poll_s
        self._head = b""
        self._pos = 0

    def peek_magic(self) -> bytes:
        self._head = self._read(4)
        return self._head

    def _read(self, n: int) -> bytes:
        data = self._raw.read(n) or b""
        while len(data) < n and self._wait is not None and self._wait():
            time.sleep(self._poll_s)
            data += self._raw.read(n - len(data)) or b""
        return data

    def read(self, n: int) -> bytes:
        head = self._head
        if head:
            self._head = head[n:]
            data = head[:n] + (self._read(n - len(head)) if len(head) < n else b"")
        else:
            data = self._read(n)
        self._pos += len(data)
        return data

    def tell(self) -> int:
        return self._pos


class CaptureFile:
    """The UDP datagrams of a capture file, read as they are iterated (a 100 MB capture is never held whole);
    :attr:`skipped` counts the packets that are not UDP over IP. Iterating raises :class:`CaptureError`.

    *path* ``-`` reads standard input (a pcapng or pcap stream). *follow*: the file is still being written; at its
    end, wait for more (every 0.1 s) as long as *follow* returns True, then end there."""

    def __init__(self, path: str | Path, follow: Callable[[], bool] | None = None) -> None:
        self.path = path
        self.skipped = 0
        self.follow = follow

    def _open(self) -> Any:
        if str(self.path) == "-":
            return contextlib.nullcontext(sys.stdin.buffer)
        return open(self.path, "rb")

    def __iter__(self) -> Iterator[Datagram]:
        path = "standard input" if str(self.path) == "-" else self.path
        try:
            with self._open() as raw:
                if self.follow is None and raw.seekable():  # a whole file: read as it is, the fastest
                    f, magic = raw, raw.read(4)
                    raw.seek(0)
                else:
                    f = _Stream(raw, self.follow)
                    magic = f.peek_magic()
                if magic == _PCAPNG_MAGIC:
                    frames = _pcapng_frames(f)
                elif magic in _PCAP_MAGICS:
                    frames = _pcap_frames(f)
                else:
                    raise CaptureError(f"{path}: not a pcap or pcapng file (magic {magic.hex() or 'empty'})")
                for linktype, frame, ts_ns, comments in frames:
                    d = _datagram(linktype, frame, ts_ns, comments)
                    if d is None:
                        self.skipped += 1
                    else:
                        yield d
        except CaptureError:
            raise
        except OSError as exc:
            raise CaptureError(f"cannot read {path}: {exc.strerror or exc}") from None
        except Exception as exc:  # noqa: BLE001 - the libraries raise assorted errors on a damaged file
            raise CaptureError(f"{path}: not a readable capture ({type(exc).__name__}: {exc})") from None


def read_capture(path: str | Path) -> Capture:
    """Every UDP datagram of the capture at *path*, in file order. Raises :class:`CaptureError`."""
    source = CaptureFile(path)
    datagrams = list(source)
    return Capture(datagrams, source.skipped)
