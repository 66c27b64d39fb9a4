"""A burst's send headers, laid out once per shape, for :mod:`mlink_sim.aio.transport.mmsg` (ctypes only; no
socket of its own but the one-time probe of the kernel's segment limit).

A *shape* is a burst's datagram sizes and destinations. :class:`Layout` points one ``sendmmsg(2)`` vector at the
datagrams of a burst of that shape, copied one after the other into the socket's send buffer, so that a burst of
a known shape costs one copy and one system call. The headers are built once per shape; a socket keeps the last
few shapes (:class:`Shapes`): a worker's burst after a backlog (two cycles' answers) and its usual burst (one
cycle's) alternate without laying either out again.

**Segmentation offload** (``UDP_SEGMENT``, Linux 4.18; see "Segmentation offload" in
:mod:`mlink_sim.aio.transport.mmsg`). Where the socket uses it, the datagrams of one size to one destination form a
*group* (:func:`groups`), and the vector holds one message per group rather than one per datagram: the group's datagrams
as one ``iovec`` each, and a control message naming the segment size. A datagram alone is a message without one. So a
burst of any number of groups leaves in **one** system call, and a group of up to 128 datagrams (where the kernel takes
that many, :func:`max_segments`) as **one** offloaded send, which a reader with ``UDP_GRO`` gets as one buffer, all at
once. Why one send: a worker's 124 answers to two cycles after a stall, cut into two sends, wake the master on the
first, and the master can run before the second arrives and find it a cycle late. One system call of two messages does
not prevent that (the kernel delivers the messages of a ``sendmmsg`` one after the other, and the master read
between them in about a quarter of such sends); one send of 124 segments does (2 of 217 such sends read in two
parts in a trace; docs/performance.md).

Limits, all from the kernel:

* ``UIO_MAXIOV`` (1024): messages per ``sendmmsg`` and ``iovec`` entries per message (:data:`MAX_VECTOR`);
* ``UDP_MAX_SEGMENTS``: segments per offloaded send, 64 in Linux 4.18 (:data:`MAX_SEGMENTS`, which holds on every
  kernel with the offload); later kernels take 128 (Linux 6.18 does), which :func:`max_segments` finds out once
  per process by trying, on loopback;
* an offloaded send is one IP datagram before it is cut, below 64 KiB: :data:`GSO_BYTES` per group.
"""

from __future__ import annotations

import ctypes
import functools
import socket
import struct
from collections.abc import Callable
from typing import Any

from .gro import SOL_UDP
from .msghdr import IoVec, MMsgHdr

__all__ = ["GSO_BYTES", "Layout", "MAX_SEGMENTS", "MAX_VECTOR", "Shapes", "UDP_SEGMENT", "encode", "groups",
           "max_segments", "members_of"]

MAX_VECTOR = 1024  #: UIO_MAXIOV, <uapi/linux/uio.h>: messages per sendmmsg, iovecs per message
MAX_SEGMENTS = 64  #: UDP_MAX_SEGMENTS of Linux 4.18, <linux/udp.h>; later kernels take 128 (:func:`max_segments`)
GSO_BYTES = 60_000  #: one offloaded send at most (the IP datagram it builds must stay below 64 KiB)
UDP_SEGMENT = 103  #: <uapi/linux/udp.h>, at level SOL_UDP

# struct cmsghdr { size_t cmsg_len; int cmsg_level; int cmsg_type; } then the data, each aligned to size_t
# (CMSG_ALIGN): the UDP_SEGMENT message carries a uint16_t, CMSG_LEN(2) long, CMSG_SPACE(2) apart.
_ALIGN = ctypes.sizeof(ctypes.c_size_t)
_CMSG_HDR = (_ALIGN + 8 + _ALIGN - 1) // _ALIGN * _ALIGN
_CMSG_LEN = _CMSG_HDR + 2
_CMSG_SPACE = _CMSG_HDR + (2 + _ALIGN - 1) // _ALIGN * _ALIGN
_CMSG = struct.Struct("=QiiH" if _ALIGN == 8 else "=IiiH")
_IOV = ctypes.sizeof(IoVec)

Group = tuple[list[int], Any, int]  #: a group's datagram indices, its destination and its segment size


def encode(addr: Any) -> bytes | None:
    """The ``struct sockaddr`` of a numeric ``(host, port)`` (IPv4) or ``(host, port[, flowinfo, scope_id])``
    (IPv6); None for anything else (a name: the caller sends that datagram with ``sendto``)."""
    try:
        host, port = str(addr[0]), int(addr[1])
        if ":" in host:
            flow = int(addr[2]) if len(addr) > 2 else 0
            scope = int(addr[3]) if len(addr) > 3 else 0
            return struct.pack("=HHI16sI", socket.AF_INET6, socket.htons(port), flow,
                               socket.inet_pton(socket.AF_INET6, host.split("%")[0]), scope)
        return struct.pack("=HH4s8x", socket.AF_INET, socket.htons(port), socket.inet_pton(socket.AF_INET, host))
    except (OSError, TypeError, ValueError, IndexError, OverflowError, struct.error):
        return None


@functools.cache
def max_segments() -> int:
    """The most datagrams this kernel takes in one offloaded send: 128 where it takes a send of 128 one-byte
    segments to a socket of its own on loopback (Linux 6.18 here), else :data:`MAX_SEGMENTS`. Asked once per
    process, the first time a socket lays out a burst with the offload. Why it matters: the kernel hands a socket that
    reads with ``UDP_GRO`` one offloaded send as one buffer, all of it at once; two sends arrive one after the other,
    and the reader may run between them (a worker's answers to two cycles: docs/performance.md)."""
    big = 2 * MAX_SEGMENTS
    try:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as rx, socket.socket(socket.AF_INET,
                                                                                   socket.SOCK_DGRAM) as tx:
            rx.bind(("127.0.0.1", 0))
            tx.sendmsg([bytes(big)], [(SOL_UDP, UDP_SEGMENT, struct.pack("=H", 1))], 0, rx.getsockname())
    except OSError:  # EINVAL: more than UDP_MAX_SEGMENTS (or no loopback, no offload): the 4.18 figure holds
        return MAX_SEGMENTS
    return big


def groups(layout: list[tuple[int, Any]], most: int = MAX_SEGMENTS) -> list[Group] | None:
    """The sends of a burst of *layout* (``(size, destination)`` per datagram) with ``UDP_SEGMENT``: its datagrams
    grouped by (destination, size), each group's in their order, at most *most* datagrams (:func:`max_segments`)
    and :data:`GSO_BYTES` long, with their size (the segment size of the control message :class:`Layout` gives a
    group of more than one); None when no two datagrams share a destination and a size (then one message per
    datagram is as good)."""
    by: dict[tuple[Any, int], list[int]] = {}
    for i, (n, addr) in enumerate(layout):
        by.setdefault((addr, n), []).append(i)
    if len(by) == len(layout):
        return None
    out: list[Group] = []
    for (addr, n), indices in by.items():
        per = max(1, min(most, GSO_BYTES // max(1, n)))
        for start in range(0, len(indices), per):
            chunk = indices[start:start + per]
            out.append((chunk, addr, n))
    return out


def members_of(grouped: list[Group]) -> list[list[int]]:
    """Each group's datagram indices."""
    return [idx for idx, _, _ in grouped]


class Layout:
    """The ``sendmmsg`` vector of one shape over a send buffer at address *base*: ``msgs`` (``count`` messages)
    and, with the offload, one message per group (``groups``; ``members[j]`` the burst's indices in message j).

    *name* gives each destination's ``struct sockaddr`` (a ctypes buffer the caller keeps alive), None for one
    that is not numeric: then the shape cannot be laid out and :meth:`build` returns None."""

    __slots__ = ("count", "msgs", "iov", "groups", "members", "_ctl")

    def __init__(self, count: int, msgs: Any, iov: Any, grouped: list[Group] | None, members: list[list[int]],
                 ctl: Any) -> None:
        self.count = count  #: messages in ``msgs``: one per datagram, or one per group
        self.msgs = msgs  #: the vector to send
        self.iov = iov
        self.groups = grouped  #: the offload's groups (:func:`groups`), None: one message per datagram
        self.members = members  #: per message, the burst's datagram indices it carries
        self._ctl = ctl  #: the control messages (kept alive with the headers that point at them)

    @classmethod
    def build(cls, sizes: tuple[int, ...], addrs: tuple[Any, ...], base: int, gso: bool,
              name: Callable[[Any], Any]) -> Layout | None:
        names = [name(addr) for addr in addrs]
        if any(n is None for n in names):
            return None
        offsets, off = [], 0
        for n in sizes:
            offsets.append(off)
            off += n
        layout = list(zip(sizes, addrs))
        grouped = groups(layout, max_segments()) if gso else None
        members = [[i] for i in range(len(sizes))] if grouped is None else members_of(grouped)
        count = len(members)
        msgs, iov = (MMsgHdr * count)(), (IoVec * len(sizes))()
        ctl = ctypes.create_string_buffer(count * _CMSG_SPACE) if grouped is not None else None
        at, k = ctypes.addressof(iov), 0
        for j, indices in enumerate(members):
            hdr = msgs[j].msg_hdr
            hdr.msg_iov, hdr.msg_iovlen = at + k * _IOV, len(indices)
            for i in indices:
                iov[k].iov_base, iov[k].iov_len = base + offsets[i], sizes[i]
                k += 1
            first = names[indices[0]]
            hdr.msg_name, hdr.msg_namelen = ctypes.addressof(first), len(first)
            if ctl is not None and len(indices) > 1:
                _CMSG.pack_into(ctl, j * _CMSG_SPACE, _CMSG_LEN, SOL_UDP, UDP_SEGMENT, sizes[indices[0]])
                hdr.msg_control, hdr.msg_controllen = ctypes.addressof(ctl) + j * _CMSG_SPACE, _CMSG_SPACE
        return cls(count, msgs, iov, grouped, members, ctl)


class Shapes:
    """The last :attr:`KEEP` shapes a socket laid out, each with its :class:`Layout` (or None: not numeric)."""

    KEEP = 4

    __slots__ = ("_known",)

    def __init__(self) -> None:
        self._known: dict[tuple[tuple[int, ...], tuple[Any, ...]], Layout | None] = {}

    def get(self, key: tuple[tuple[int, ...], tuple[Any, ...]], make: Callable[[], Layout | None]) -> Layout | None:
        known = self._known
        try:
            return known[key]
        except KeyError:
            pass
        if len(known) >= self.KEEP:
            del known[next(iter(known))]  # the oldest laid out
        made = known[key] = make()
        return made

    def clear(self) -> None:
        """Forget every shape (the send buffer moved, or the offload was refused)."""
        self._known.clear()
