"""A capture's tap on the batched UDP calls (:mod:`~mlink_sim.aio.mmsg`): what ``--capture`` wraps a socket in.

:func:`tap` gives a :class:`TappedBurstSocket` where ``sendmmsg``/``recvmmsg`` are supported, so a captured run
makes the same system calls as an uncaptured one, else the per-datagram
:class:`~mlink_sim.capture.tap.TappedSocket` (``MLINK_MMSG=0``). Both feed the capture's queue one
``(ts_ns, datagram, src, dst)`` tuple per datagram (:attr:`CaptureWriter.sink
<mlink_sim.capture.CaptureWriter.sink>`); the writer thread does the rest.

A burst of commands is recorded with one clock read (the time ``sendmmsg`` returned) and the destinations the
burst already carries. The answers one ``recvmmsg`` read share its time and take their sources from the
``msg_name`` each message left in the socket's headers, decoded once per source and kept (as ``recvfrom_burst``
does): reading answers with the capture on costs no ``recvfrom`` per datagram (docs/performance.md, "Capture").
"""

from __future__ import annotations

import socket
import time
from collections.abc import Sequence
from typing import Any

from ..capture.tap import Sink, TappedSocket
from . import mmsg
from .mmsg import CAPACITY, BurstSocket

__all__ = ["TappedBurstSocket", "tap"]

_mono = time.monotonic_ns


def tap(capture: Any, sock: socket.socket) -> Any:
    """*sock* recording into *capture* (a :class:`~mlink_sim.capture.CaptureWriter`): the batched calls, tapped,
    where :func:`mmsg.supported <mlink_sim.aio.mmsg.supported>`; else a
    :class:`~mlink_sim.capture.tap.TappedSocket`."""
    if mmsg.supported() and sock.type == socket.SOCK_DGRAM:
        return TappedBurstSocket(sock, capture.sink)
    return TappedSocket(sock, capture.sink)


class TappedBurstSocket(BurstSocket):
    """A :class:`~mlink_sim.aio.mmsg.BurstSocket` that feeds *sink* one ``(ts_ns, datagram, src, dst)`` tuple per
    datagram its calls move (see the module docstring). The per-datagram calls (``sendto``, ``recv``,
    ``recvfrom``) are a :class:`~mlink_sim.capture.tap.TappedSocket`'s."""

    __slots__ = ("_append", "_local", "_namelen", "_slot")

    def __init__(self, sock: socket.socket, sink: Sink, capacity: int = CAPACITY) -> None:
        super().__init__(sock, capacity)
        single = TappedSocket(sock, sink)
        # the same calls, tapped (closures with their own, narrower signatures: recv(bufsize) without flags)
        self.sendto, self.recv, self.recvfrom = single.sendto, single.recv, single.recvfrom  # type: ignore[assignment]
        self._append = sink
        self._local = sock.getsockname()[:2]
        #: bytes of a source address in msg_name (struct sockaddr_in or sockaddr_in6): its cache key
        self._namelen = 16 if sock.family == socket.AF_INET else 28
        self._slot = len(self._rnview) // capacity  #: bytes between two messages' msg_name

    def send_burst(self, items: Sequence[tuple[bytes, Any]]) -> list[tuple[int, OSError]]:
        failures = BurstSocket.send_burst(self, items)
        ts = _mono()
        if failures:  # a datagram that was not sent is not recorded
            lost = {i for i, _ in failures}
            items = [item for i, item in enumerate(items) if i not in lost]
        local, append = self._local, self._append
        for data, addr in items:  # a plain loop: cheaper than zip/extend for the few datagrams of a burst
            append((ts, data, local, addr))
        return failures

    def recv_burst(self, limit: int = CAPACITY) -> list[bytes]:
        got = BurstSocket.recv_burst(self, limit)
        if got:
            ts, names, size, sources, local, append = (_mono(), self._rnview, self._namelen, self._sources,
                                                       self._local, self._append)
            at = 0
            for data in got:  # the source of message i is in its msg_name slot (left there by recvmmsg)
                raw = names[at:at + size].tobytes()
                append((ts, data, sources.get(raw) or self._source(raw), local))
                at += self._slot
        return got

    def recvfrom_burst(self, limit: int = CAPACITY) -> list[tuple[bytes, Any]]:
        got = BurstSocket.recvfrom_burst(self, limit)
        if got:
            ts, local, append = _mono(), self._local, self._append
            for data, addr in got:
                append((ts, data, addr, local))
        return got
