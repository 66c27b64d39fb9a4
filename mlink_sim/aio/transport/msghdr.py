"""The libc layer of the batched UDP calls (:mod:`mlink_sim.aio.transport.mmsg`, :mod:`mlink_sim.aio.transport.gro`):
``struct iovec``, ``struct msghdr`` and ``struct mmsghdr`` as ctypes structures, and ``sendmmsg(2)`` / ``recvmmsg(2)``
from the C library (:data:`CALLS`, None where they cannot be loaded: not Linux, no libc, a platform ctypes cannot load).
Why ctypes: see :mod:`mlink_sim.aio.transport.mmsg`.

Touches: libc (loaded once); no socket.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import errno
import sys
from typing import Any

__all__ = ["CALLS", "EAGAIN", "HDR_SIZE", "IoVec", "MMsgHdr", "MSG_DONTWAIT", "MsgHdr", "NAME_SIZE"]

MSG_DONTWAIT = 0x40  # <bits/socket.h>, the same on every Linux architecture CPython supports
EAGAIN = (errno.EAGAIN, errno.EWOULDBLOCK)
NAME_SIZE = 128  # sizeof(struct sockaddr_storage)


class IoVec(ctypes.Structure):
    _fields_ = [("iov_base", ctypes.c_void_p), ("iov_len", ctypes.c_size_t)]


class MsgHdr(ctypes.Structure):
    _fields_ = [("msg_name", ctypes.c_void_p), ("msg_namelen", ctypes.c_uint32), ("msg_iov", ctypes.c_void_p),
                ("msg_iovlen", ctypes.c_size_t), ("msg_control", ctypes.c_void_p),
                ("msg_controllen", ctypes.c_size_t), ("msg_flags", ctypes.c_int)]


class MMsgHdr(ctypes.Structure):
    _fields_ = [("msg_hdr", MsgHdr), ("msg_len", ctypes.c_uint)]


HDR_SIZE = ctypes.sizeof(MMsgHdr)


def _load() -> tuple[Any, Any] | None:
    if not sys.platform.startswith("linux"):
        return None
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6", use_errno=True)
        send, recv = libc.sendmmsg, libc.recvmmsg
    except (OSError, AttributeError):
        return None
    # No argtypes: the arguments are Python ints (int), the header arrays themselves or byref() (pointers) and
    # None (NULL), which ctypes passes as they are; argtypes' conversions would add about a microsecond to every
    # call (docs/performance.md, "Batched calls").
    send.restype = recv.restype = ctypes.c_int
    return send, recv


CALLS = _load()
