"""Batched UDP system calls: ``sendmmsg(2)`` and ``recvmmsg(2)`` for a burst of datagrams (Linux).

:class:`BurstSocket` stands in for a non-blocking UDP ``socket.socket`` (``sendto``, ``recv``, ``recvfrom``,
``fileno``, ``getsockname``, ``close`` are the socket's own) and adds three batched calls:

* ``send_burst([(datagram, addr), …])``: the whole burst in one ``sendmmsg`` (the master's N commands; a worker's
  answers, however many cycles they answer);
* ``recv_burst(limit)``: every datagram waiting, up to *limit*, in one ``recvmmsg`` (the master's answers);
* ``recvfrom_burst(limit)``: the same with each source address (a slave station's commands).

Each returns what it did without raising for "nothing waiting": an empty list, not ``BlockingIOError``, so a
read needs no second system call to learn that the socket is empty. Other socket errors raise ``OSError`` as
``recv``/``sendto`` do.

**Why ctypes.** Python 3.11's ``socket`` module has ``sendmsg``/``recvmsg`` but neither ``sendmmsg`` nor
``recvmmsg``, and the package index has no well-kept wrapper (the one found, ``pysockmmsg`` 0.0.2 of 2021, is a
0.0 release with no activity since). A compiled extension would need a compiler on every machine that installs
the package. ctypes on libc needs nothing: a ctypes call costs about a microsecond more than a method of
``socket.socket``, and one call per burst spreads that over the burst. The read buffers and headers are
allocated once per socket; a burst copies its datagrams into the send buffer with one slice assignment, and its
headers are laid out once per shape (sizes, destinations; the socket keeps its last few,
:mod:`mlink_sim.aio.transport.sendlayout`).

**Segmentation offload.** Where the kernel has it (Linux ≥ 4.18, :func:`gso_supported`; ``BurstSocket(gso=False)``
turns it off), ``send_burst`` sends the datagrams of a burst that go to one destination with one size as *one* message
of its ``sendmmsg``, with ``UDP_SEGMENT`` (up to 64 datagrams to a message, 128 where the kernel takes them,
:mod:`mlink_sim.aio.transport.sendlayout`): the kernel builds one packet for the group and cuts it into the datagrams
only where it must (before a device without the offload; at the receiving socket unless that socket asked for
``UDP_GRO``). Each datagram on a network is an
ordinary UDP datagram. A socket that reads with ``UDP_GRO`` (:meth:`BurstSocket.enable_gro`) gets such a group as
one buffer with its segment size, and the reads cut it again (one ``recvmmsg`` for up to four buffers, one
``struct`` call to cut each), so every caller still sees one datagram per frame. The kernel's path is paid per
packet, not per datagram: an offloaded group costs about as much as one datagram (docs/performance.md, "Batched
calls"). It pays where many stations share a port: the
slave workers of ``mlink-sim up`` (``SlaveServer(shared=True)``).

**One system call per burst**, whatever its size (up to 1024 messages), and one offloaded send per group of up to
128 datagrams. A worker that answers two cycles' commands after a stall (124 answers at 62 stations) sends them as
one packet; cut at 64 into two, the master woke on the first, ran, and found the second half a cycle late
(docs/performance.md).

Where the calls are missing (not Linux, no libc, a platform ctypes cannot load) :func:`supported` is False and
callers keep the per-datagram calls: the transport works the same either way (``mlink_sim.aio.master.runner``,
``mlink_sim.aio.transport.udp.BatchEndpoint``). A caller may also ask for the per-datagram calls where the batched ones
exist (``wrap(sock, batched=False)``; the tests compare both paths that way).

Touches: the socket it wraps, libc through ctypes.
"""

from __future__ import annotations

import ctypes
import errno
import os
import platform
import socket
import struct
import sys
from collections import deque
from collections.abc import Callable, Iterator, Sequence
from typing import Any

from .gro import SOL_UDP as _SOL_UDP
from .gro import UDP_GRO as _UDP_GRO
from .gro import CoalescedReads
from .msghdr import CALLS as _calls
from .msghdr import EAGAIN as _EAGAIN
from .msghdr import HDR_SIZE as _HDR_SIZE
from .msghdr import MSG_DONTWAIT as _MSG_DONTWAIT
from .msghdr import NAME_SIZE as _NAME_SIZE
from .msghdr import IoVec as _IoVec
from .msghdr import MMsgHdr as _MMsgHdr
from .msghdr import MsgHdr as _MsgHdr
from .ports import PeerPort
from .sendlayout import MAX_VECTOR, Group, Layout, Shapes, encode

__all__ = ["BurstSocket", "CAPACITY", "drain", "gso_supported", "supported", "wrap"]

CAPACITY = 64  #: messages per read (more waiting are read in several calls); a send takes up to sendlayout.MAX_VECTOR
_BUFSIZE = 4096  # bytes per received datagram, as the per-datagram reads (``recv(4096)``)
_NO_GSO = (errno.EINVAL, errno.EIO, errno.ENOPROTOOPT, errno.EOPNOTSUPP)  # the offload refused (not a lost datagram)




def supported() -> bool:
    """True where ``sendmmsg``/``recvmmsg`` can be called (Linux with glibc or musl)."""
    return _calls is not None


def gso_supported() -> bool:
    """True where the batched calls are :func:`supported` and the kernel is Linux 4.18 or newer (``UDP_SEGMENT``;
    ``UDP_GRO`` needs 5.0, which :meth:`BurstSocket.enable_gro` finds out itself)."""
    return _GSO_KERNEL and supported()


def _kernel_has_gso() -> bool:
    """Linux 4.18 or newer. Asked of the version, not found out by trying: an older kernel ignores a ``SOL_UDP``
    control message it does not know and would send a group as one datagram holding all its frames."""
    try:
        major, minor = (int(x) for x in platform.release().split("-")[0].split(".")[:2])
    except ValueError:
        return False
    return sys.platform.startswith("linux") and (major, minor) >= (4, 18)


_GSO_KERNEL = _kernel_has_gso()


def wrap(sock: socket.socket, *, batched: bool = True) -> PeerPort:
    """*sock* as a :class:`BurstSocket` where the batched calls are :func:`supported`, else *sock* itself.
    *batched*: False keeps *sock* itself (the per-datagram calls) where the batched ones exist too."""
    return BurstSocket(sock) if batched and supported() and sock.type == socket.SOCK_DGRAM else sock


def drain(burst: Callable[[int], list[Any]], limit: int, on_error: Callable[[OSError], None]) -> Iterator[list[Any]]:
    """What is waiting on a socket, at most *limit* datagrams in all, one batch per ``recvmmsg`` (*burst*: a
    :class:`BurstSocket`'s ``recv_burst`` or ``recvfrom_burst``). A batch shorter than it asked for means the
    socket is empty: no further call to learn it. A socket error (e.g. ``ConnectionRefusedError`` after an ICMP
    port unreachable) goes to *on_error* and counts as one datagram read."""
    while limit > 0:
        want = min(limit, CAPACITY)
        try:
            got = burst(want)
        except OSError as exc:
            on_error(exc)
            limit -= 1
            continue
        yield got
        if len(got) < want:
            return
        limit -= want


def _decode(name: bytes) -> Any:
    """A source address as ``socket.recvfrom`` gives it."""
    family = int.from_bytes(name[:2], sys.byteorder)
    port = int.from_bytes(name[2:4], "big")
    if family == socket.AF_INET:
        return socket.inet_ntop(socket.AF_INET, name[4:8]), port
    if family == socket.AF_INET6:
        flow, raw, scope = struct.unpack_from("=I16sI", name, 4)
        host = socket.inet_ntop(socket.AF_INET6, raw)
        if scope:
            try:
                host = f"{host}%{socket.if_indextoname(scope)}"
            except OSError:
                host = f"{host}%{scope}"
        return host, port, flow, scope
    return name  # pragma: no cover - a UDP/IP socket receives from IP addresses only


class BurstSocket:
    """A non-blocking UDP socket with batched sends and reads (see the module docstring)."""

    __slots__ = ("sock", "sendto", "recv", "recvfrom", "fileno", "getsockname", "close", "setsockopt", "_fd",
                 "_cap", "_slay", "_shapes", "_step", "_sdata", "_sview", "_skey", "_names", "_rmsgs", "_riov",
                 "_rbuf", "_rview", "_rnames", "_rnview", "_rwords", "_stride", "_len_at", "_namelen_at", "_bufsize",
                 "_sources", "_offload", "_gso", "gro", "_coalesced", "_gleft", "_gerr")

    def __init__(self, sock: socket.socket, capacity: int = CAPACITY, bufsize: int = _BUFSIZE, *,
                 gso: bool = True) -> None:
        """*gso*: False sends one ``sendmmsg`` message per datagram and reads without ``UDP_GRO`` where the kernel
        has the offload too (the tests compare both paths that way)."""
        if _calls is None:
            raise OSError(errno.ENOSYS, "sendmmsg/recvmmsg are not available on this platform")
        self.sock = sock
        self.sendto, self.recv, self.recvfrom = sock.sendto, sock.recv, sock.recvfrom
        self.fileno, self.getsockname, self.close, self.setsockopt = (sock.fileno, sock.getsockname, sock.close,
                                                                       sock.setsockopt)
        self._fd = sock.fileno()
        self._cap = capacity
        # sending: the datagrams in one buffer, the headers laid out once per shape (mlink_sim.aio.transport.sendlayout)
        self._sdata = ctypes.create_string_buffer(capacity * 128)
        self._sview = memoryview(self._sdata).cast("B")
        self._skey: tuple[tuple[int, ...], tuple[Any, ...]] | None = None  #: the sizes and destinations laid out
        self._slay: Layout | None = None  #: their headers (None: a destination is not numeric)
        self._shapes = Shapes()
        self._names: dict[Any, Any] = {}  # addr -> its struct sockaddr (a ctypes buffer), None: not numeric
        # reading: one fixed slot (datagram buffer, source address) per message
        self._bufsize = bufsize
        self._rmsgs = (_MMsgHdr * capacity)()
        self._riov = (_IoVec * capacity)()
        self._rbuf = ctypes.create_string_buffer(capacity * bufsize)
        self._rview = memoryview(self._rbuf).cast("B")
        self._rnames = ctypes.create_string_buffer(capacity * _NAME_SIZE)
        self._rnview = memoryview(self._rnames).cast("B")
        base, names, iov = ctypes.addressof(self._rbuf), ctypes.addressof(self._rnames), ctypes.addressof(self._riov)
        for i in range(capacity):
            self._riov[i].iov_base, self._riov[i].iov_len = base + i * bufsize, bufsize
            hdr = self._rmsgs[i].msg_hdr
            hdr.msg_iov, hdr.msg_iovlen = iov + i * ctypes.sizeof(_IoVec), 1
            hdr.msg_name, hdr.msg_namelen = names + i * _NAME_SIZE, _NAME_SIZE
        # msg_len and msg_namelen of message i, as indices into the headers seen as 32-bit words
        self._rwords = memoryview(self._rmsgs).cast("B").cast("I")
        self._stride = ctypes.sizeof(_MMsgHdr) // 4
        self._len_at = _MMsgHdr.msg_len.offset // 4
        self._namelen_at = (_MMsgHdr.msg_hdr.offset + _MsgHdr.msg_namelen.offset) // 4
        self._sources: dict[bytes, Any] = {}
        # segmentation offload (see "Segmentation offload" in the module docstring)
        self._offload = gso and gso_supported()  #: this socket may use the offload (sending and reading)
        self._gso = self._offload  #: a burst's datagrams of one size to one destination go as one message
        self.gro = False  #: True once enable_gro() succeeded
        self._coalesced: Any = None  #: the UDP_GRO reads (gro.CoalescedReads), once enable_gro() succeeded
        self._gleft: deque[tuple[bytes, Any]] = deque()  #: segments read but not handed over yet (recv/recvfrom)
        self._gerr: OSError | None = None  #: an error met after some segments were read: raised on the next read

    # ------------------------------------------------------------------ sending
    def send_burst(self, items: Sequence[tuple[bytes, Any]]) -> list[tuple[int, OSError]]:
        """Send every ``(datagram, addr)`` of *items* in order, in one ``sendmmsg`` (one per
        :data:`~mlink_sim.aio.transport.sendlayout.MAX_VECTOR` messages). Returns the datagrams that were not sent,
        ``[(index, OSError), …]`` (empty when all went)."""
        failures: list[tuple[int, OSError]] = []
        step = MAX_VECTOR
        if len(items) <= step:
            self._send_chunk(items, 0, failures)
        else:
            for start in range(0, len(items), step):
                self._send_chunk(items[start:start + step], start, failures)
        return failures

    def _send_chunk(self, items: Sequence[tuple[bytes, Any]], first: int,
                    failures: list[tuple[int, OSError]]) -> None:
        if not items:
            return
        datas, addrs = zip(*items)  # two tuples in C: the layout's check is a tuple compare (identical addresses)
        sizes = tuple(map(len, datas))
        lay = self._slay
        if (sizes, addrs) != self._skey:
            lay = self._shape(sizes, addrs)
        if lay is None:
            for i, (data, addr) in enumerate(items):  # a destination given by name: the datagrams one by one
                try:
                    self.sendto(data, addr)
                except OSError as exc:
                    failures.append((first + i, exc))
            return
        blob = b"".join(datas)
        self._sview[:len(blob)] = blob
        n = lay.count
        sent = _calls[0](self._fd, lay.msgs, n, 0)  # type: ignore[index]  # not None: checked in __init__
        if sent != n:
            self._send_rest(lay, sent, items, first, failures)

    def _send_rest(self, lay: Layout, sent: int, items: Sequence[tuple[bytes, Any]], first: int,
                   failures: list[tuple[int, OSError]]) -> None:
        """A message of *lay* failed (or the call was interrupted) after *sent*: its datagrams' error, then the
        messages after it. Where the kernel refuses the offload (a route whose device cannot do it; an error of
        ``_NO_GSO`` on a message of several segments) this socket sends without it from then on, and the datagrams
        not sent yet go one by one."""
        send, fd, msgs, n, j = _calls[0], self._fd, lay.msgs, lay.count, 0  # type: ignore[index]
        while True:
            if sent > 0:
                j += sent
            else:
                err = ctypes.get_errno() if sent < 0 else errno.EIO
                if err != errno.EINTR:
                    carried = lay.members[j]
                    if len(carried) > 1 and lay.groups is not None and err in _NO_GSO:
                        self._refused([i for rest in lay.members[j:] for i in rest], items, first, failures)
                        return
                    failures.extend((first + i, OSError(err, os.strerror(err))) for i in carried)  # those are lost
                    j += 1
            if j >= n:
                return
            sent = send(fd, ctypes.byref(msgs, j * _HDR_SIZE), n - j, 0)

    def _refused(self, left: list[int], items: Sequence[tuple[bytes, Any]], first: int,
                 failures: list[tuple[int, OSError]]) -> None:
        """The kernel refused the offload: this socket sends one message per datagram from now on, and the
        datagrams of *items* at *left*, not sent yet, go one by one."""
        self._gso, self._slay, self._skey = False, None, None
        self._shapes.clear()
        for i in left:
            try:
                self.sendto(*items[i])
            except OSError as exc:
                failures.append((first + i, exc))

    @property
    def _sgroups(self) -> list[Group] | None:
        """The offload's groups of the shape last laid out (None: one message per datagram, or none laid out)."""
        return None if self._slay is None else self._slay.groups

    def _shape(self, sizes: tuple[int, ...], addrs: tuple[Any, ...]) -> Layout | None:
        """The :class:`~mlink_sim.aio.transport.sendlayout.Layout` of a burst of *sizes* to *addrs* (laid out once, kept
        among the socket's last few shapes); None when a destination is not a numeric address."""
        total = sum(sizes)
        if total > len(self._sview):  # the buffer moves: every shape laid out over it goes
            self._sdata = ctypes.create_string_buffer(max(total, 2 * len(self._sview)))
            self._sview = memoryview(self._sdata).cast("B")
            self._shapes.clear()
        key = (sizes, addrs)
        lay = self._shapes.get(key, lambda: Layout.build(sizes, addrs, ctypes.addressof(self._sdata), self._gso,
                                                         self._name))
        self._skey, self._slay = key, lay
        return lay

    def _name(self, addr: Any) -> Any:
        """*addr*'s ``struct sockaddr`` as a ctypes buffer kept for the socket's life; None: not numeric."""
        name = self._names.get(addr, False)
        if name is False:
            raw = encode(addr)
            name = self._names[addr] = None if raw is None else ctypes.create_string_buffer(raw, len(raw))
        return name

    # ------------------------------------------------------------------ reading
    def _receive(self, limit: int) -> int:
        """How many datagrams one ``recvmmsg`` read (0: none waiting); raises OSError for a socket error."""
        n: int = _calls[1](self._fd, self._rmsgs, limit if limit < self._cap else self._cap,  # type: ignore[index]
                           _MSG_DONTWAIT, None)
        while n < 0:
            err = ctypes.get_errno()
            if err in _EAGAIN:
                return 0
            if err != errno.EINTR:
                raise OSError(err, os.strerror(err))
            n = _calls[1](self._fd, self._rmsgs, limit if limit < self._cap else self._cap,  # type: ignore[index]
                          _MSG_DONTWAIT, None)
        return n

    def enable_gro(self) -> bool:
        """Let the kernel hand over the datagrams a peer sent in one offloaded burst as one buffer (``UDP_GRO``),
        which the reads split again (:meth:`recv_burst`, :meth:`recvfrom_burst`, ``recv``, ``recvfrom``): one
        read for the whole burst. False (nothing changed) where it is not supported, the socket was made with
        ``gso=False``, or the option is refused."""
        if self.gro:
            return True
        if not self._offload:
            return False
        try:
            self.sock.setsockopt(_SOL_UDP, _UDP_GRO, 1)
        except OSError:
            return False
        self._coalesced = CoalescedReads(self._fd)
        self.recv, self.recvfrom = self._recv_one, self._recvfrom_one
        self.gro = True
        return True

    def _read_gro(self, limit: int) -> list[tuple[bytes, Any]]:
        """At least what is waiting up to *limit* datagrams, each with its source; [] when none is waiting. A read
        may give more: a coalesced buffer's segments are never cut off, and one call takes up to four buffers
        (never more buffers than datagrams are still wanted, so ``limit=1`` reads one buffer)."""
        out: list[tuple[bytes, Any]] = []
        left = self._gleft
        while left and len(out) < limit:
            out.append(left.popleft())
        err, self._gerr = self._gerr, None
        if err is not None:
            if out:
                self._gerr = err
                return out
            raise err
        try:
            self._coalesced.read(limit, out, self._sources.get, self._source)
        except OSError as exc:
            if not out:
                raise
            self._gerr = exc  # the segments read first are handed over; the error comes with the next read
        return out

    def _recvfrom_one(self, bufsize: int, flags: int = 0) -> tuple[bytes, Any]:
        """``recvfrom`` on a socket with ``UDP_GRO``: one datagram, never a coalesced buffer."""
        left = self._gleft
        if not left:
            left.extend(self._read_gro(1))
            if not left:
                raise BlockingIOError(errno.EAGAIN, "Resource temporarily unavailable")
        data, addr = left.popleft()
        return data[:bufsize], addr

    def _recv_one(self, bufsize: int, flags: int = 0) -> bytes:
        return self._recvfrom_one(bufsize)[0]

    def recv_burst(self, limit: int = CAPACITY) -> list[bytes]:
        """Every datagram waiting, at most *limit* (and at most :data:`CAPACITY`), in one system call; [] when
        none is waiting. A datagram longer than 4096 bytes is cut there, as ``recv(4096)`` cuts it. With
        :meth:`enable_gro`, one read per offloaded burst, whose datagrams all come (even beyond *limit*)."""
        if self.gro:
            return [data for data, _ in self._read_gro(limit)]
        n = self._receive(limit)
        if n == 1:  # the common case: one answer per wake-up
            words = self._rwords
            words[self._namelen_at] = _NAME_SIZE
            return [self._rview[:words[self._len_at]].tobytes()]
        if not n:
            return []
        view, words, stride, at, nl, size = (self._rview, self._rwords, self._stride, self._len_at,
                                             self._namelen_at, self._bufsize)
        out = []
        for i in range(n):
            w = i * stride
            words[w + nl] = _NAME_SIZE
            out.append(view[i * size:i * size + words[w + at]].tobytes())
        return out

    def recvfrom_burst(self, limit: int = CAPACITY) -> list[tuple[bytes, Any]]:
        """As :meth:`recv_burst`, each datagram with its source address as ``recvfrom`` gives it."""
        if self.gro:
            return self._read_gro(limit)
        n = self._receive(limit)
        if n == 1:  # the common case: one command per station socket and wake-up
            words, nl = self._rwords, self._namelen_at
            raw = self._rnview[:words[nl]].tobytes()
            words[nl] = _NAME_SIZE
            addr = self._sources.get(raw)
            if addr is None:
                addr = self._source(raw)
            return [(self._rview[:words[self._len_at]].tobytes(), addr)]
        if not n:
            return []
        view, names, words, stride, at, nl, size = (self._rview, self._rnview, self._rwords, self._stride,
                                                    self._len_at, self._namelen_at, self._bufsize)
        sources = self._sources
        out = []
        for i in range(n):
            w = i * stride
            raw = names[i * _NAME_SIZE:i * _NAME_SIZE + words[w + nl]].tobytes()
            words[w + nl] = _NAME_SIZE
            addr = sources.get(raw)
            if addr is None:
                addr = self._source(raw)
            out.append((view[i * size:i * size + words[w + at]].tobytes(), addr))
        return out

    def _source(self, raw: bytes) -> Any:
        """The address of *raw* (a struct sockaddr), decoded once and kept (at most 4096 sources)."""
        if len(self._sources) >= 4096:  # a flood of sources: keep the cache bounded
            self._sources.clear()
        addr = self._sources[raw] = _decode(raw)
        return addr
