"""Reading a peer's offloaded bursts as coalesced buffers (``UDP_GRO``; :mod:`mlink_sim.aio.transport.mmsg`,
"Segmentation offload"): one ``recvmmsg`` for up to :data:`SLOTS` buffers, each cut into its datagrams by one
``struct`` call.

A socket with ``UDP_GRO`` gets the datagrams a peer sent in one offloaded burst as one buffer, with the segment
size in a control message. :class:`CoalescedReads` holds the read slots of one such socket: per slot a buffer of
:data:`SLOT` bytes (a coalesced buffer is one UDP datagram, at most 65,535 bytes), room for the source address and
room for the control message (``struct cmsghdr``: ``cmsg_len``, a ``size_t``, then ``cmsg_level`` and ``cmsg_type``,
two ints; the segment size is an int at ``CMSG_LEN(0)``). One call reads a burst and learns that nothing more
waits, where a ``recvmsg`` per buffer needs a second call that fails with ``EAGAIN`` (4 µs in a running network,
docs/cards.md, "Performance: the cyclic path").

Touches: the socket it is given (reads only), libc through ctypes.
"""

from __future__ import annotations

import ctypes
import errno
import os
import socket
import struct
from collections.abc import Callable
from itertools import repeat
from typing import Any

from .msghdr import CALLS, EAGAIN, MSG_DONTWAIT, NAME_SIZE, IoVec, MMsgHdr

__all__ = ["CONTROL", "SLOT", "SLOTS", "SOL_UDP", "UDP_GRO", "CoalescedReads"]

SOL_UDP = 17  # <linux/udp.h>: UDP_GRO (Linux 5.0) at level SOL_UDP
UDP_GRO = 104
CONTROL = socket.CMSG_SPACE(4)  #: one control message: the segment size
SLOTS = 4  #: coalesced buffers per recvmmsg
SLOT = 65536  #: bytes per slot
_KIND = struct.Struct("=ii")
_KIND_AT = ctypes.sizeof(ctypes.c_size_t)
_INT = struct.Struct("=i")
_DATA_AT = socket.CMSG_LEN(0)


def _cutter(size: int, count: int) -> struct.Struct:
    """The ``struct`` that cuts a coalesced buffer into *count* datagrams of *size* bytes in one call, several
    times cheaper than slicing it (docs/performance.md, "Batched calls"). Made once per shape and kept (at most 256 shapes: a
    peer's segment size is its own choice)."""
    cut = _CUTTERS.get((size, count))
    if cut is None:
        if len(_CUTTERS) >= 256:
            _CUTTERS.clear()
        cut = _CUTTERS[(size, count)] = struct.Struct(f"{size}s" * count)
    return cut


_CUTTERS: dict[tuple[int, int], struct.Struct] = {}


class CoalescedReads:
    """The read slots of one ``UDP_GRO`` socket (its file descriptor *fd*; see the module docstring)."""

    def __init__(self, fd: int) -> None:
        if CALLS is None:
            raise OSError(errno.ENOSYS, "recvmmsg is not available on this platform")
        self._fd = fd
        self._buf = ctypes.create_string_buffer(SLOTS * SLOT)
        self._view = memoryview(self._buf).cast("B")
        self._names = ctypes.create_string_buffer(SLOTS * NAME_SIZE)
        self._names_view = memoryview(self._names).cast("B")
        self._ctl = ctypes.create_string_buffer(SLOTS * CONTROL)
        self._msgs = (MMsgHdr * SLOTS)()
        self._iov = (IoVec * SLOTS)()  # kept alive with the headers that point into it
        buf, names, ctl, iov = (ctypes.addressof(self._buf), ctypes.addressof(self._names),
                                ctypes.addressof(self._ctl), ctypes.addressof(self._iov))
        for i in range(SLOTS):
            self._iov[i].iov_base, self._iov[i].iov_len = buf + i * SLOT, SLOT
            hdr = self._msgs[i].msg_hdr
            hdr.msg_iov, hdr.msg_iovlen = iov + i * ctypes.sizeof(IoVec), 1
            hdr.msg_name, hdr.msg_namelen = names + i * NAME_SIZE, NAME_SIZE
            hdr.msg_control, hdr.msg_controllen = ctl + i * CONTROL, CONTROL

    def read(self, limit: int, out: list[tuple[bytes, Any]], known: Callable[[bytes], Any],
             source: Callable[[bytes], Any]) -> None:
        """Append to *out* what is waiting, ``(datagram, source address)``, until it holds *limit* datagrams or
        nothing more waits. One ``recvmmsg`` takes up to :data:`SLOTS` buffers, never more buffers than datagrams
        are still wanted, and a buffer's segments are never cut off (so *out* may end up longer than *limit*).
        *known(raw)* is the address of a ``struct sockaddr`` seen before (or None), *source(raw)* decodes a new one.
        Raises OSError for a socket error (what was read before it is in *out*)."""
        call, fd, msgs = CALLS[1], self._fd, self._msgs  # type: ignore[index]
        view, names, ctl = self._view, self._names_view, self._ctl
        while len(out) < limit:
            want = min(SLOTS, limit - len(out))
            n = call(fd, msgs, want, MSG_DONTWAIT, None)
            if n < 0:
                e = ctypes.get_errno()
                if e in EAGAIN:
                    return
                if e == errno.EINTR:
                    continue
                raise OSError(e, os.strerror(e))
            for i in range(n):
                msg = msgs[i]
                size, hdr = msg.msg_len, msg.msg_hdr
                raw = names[i * NAME_SIZE:i * NAME_SIZE + hdr.msg_namelen].tobytes()
                hdr.msg_namelen = NAME_SIZE
                addr = known(raw)
                if addr is None:
                    addr = source(raw)
                seg = size
                if hdr.msg_controllen >= _DATA_AT + 4:  # the kernel's UDP_GRO message: the segment size
                    at = i * CONTROL
                    if _KIND.unpack_from(ctl, at + _KIND_AT) == (SOL_UDP, UDP_GRO):
                        seg = _INT.unpack_from(ctl, at + _DATA_AT)[0]
                hdr.msg_controllen = CONTROL
                at = i * SLOT
                if 0 < seg < size:
                    count, rest = divmod(size, seg)
                    out += zip(_cutter(seg, count).unpack_from(view, at), repeat(addr, count))
                    if rest:
                        out.append((view[at + size - rest:at + size].tobytes(), addr))
                else:
                    out.append((view[at:at + size].tobytes(), addr))
            if n < want:
                return
