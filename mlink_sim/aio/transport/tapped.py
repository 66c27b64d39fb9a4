"""A capture's tap on the batched UDP calls (:mod:`~mlink_sim.aio.transport.mmsg`): what ``--capture`` wraps a
socket in.

:func:`tap` gives a :class:`TappedBurstSocket` where ``sendmmsg``/``recvmmsg`` are supported, so a captured run
makes the same system calls as an uncaptured one, else the per-datagram
:class:`~mlink_sim.capture.tap.TappedSocket` (``tap(..., batched=False)`` asks for it where both exist). Both feed the
capture's queue one ``(ts_ns, datagram, src, dst)`` tuple per datagram (:attr:`CaptureWriter.sink
<mlink_sim.capture.CaptureWriter.sink>`); the writer thread does the rest.

A burst of commands is recorded with one clock read (the time ``sendmmsg`` returned) and the destinations the
burst already carries. The answers one ``recvmmsg`` read share its time and take their sources from the
``msg_name`` each message left in the socket's headers (the read is ``recvfrom_burst``'s: each source decoded
once and kept): reading answers with the capture on costs no ``recvfrom`` per datagram (docs/performance.md).

Touches: the socket it wraps and the capture's queue.
"""

from __future__ import annotations

import socket
import time
from collections.abc import Sequence
from typing import Any

from ...capture.tap import Sink, TappedSocket
from . import mmsg
from .mmsg import CAPACITY, BurstSocket
from .ports import PeerPort

__all__ = ["TappedBurstSocket", "tap"]

_mono = time.monotonic_ns
_recvfrom_burst = BurstSocket.recvfrom_burst


def tap(capture: Any, sock: socket.socket, *, batched: bool = True) -> PeerPort:
    """*sock* recording into *capture* (a :class:`~mlink_sim.capture.CaptureWriter`): the batched calls, tapped,
    where :func:`mmsg.supported <mlink_sim.aio.transport.mmsg.supported>` and *batched*; else a
    :class:`~mlink_sim.capture.tap.TappedSocket`."""
    if batched and mmsg.supported() and sock.type == socket.SOCK_DGRAM:
        return TappedBurstSocket(sock, capture.sink)
    return TappedSocket(sock, capture.sink)


class TappedBurstSocket(BurstSocket):
    """A :class:`~mlink_sim.aio.transport.mmsg.BurstSocket` that feeds *sink* one ``(ts_ns, datagram, src, dst)`` tuple
    per datagram its calls move (see the module docstring). The per-datagram calls (``sendto``, ``recv``,
    ``recvfrom``) are a :class:`~mlink_sim.capture.tap.TappedSocket`'s."""

    __slots__ = ("_append", "_local")

    def __init__(self, sock: socket.socket, sink: Sink, capacity: int = CAPACITY) -> None:
        super().__init__(sock, capacity)
        single = TappedSocket(sock, sink)
        # the same calls, tapped (closures with their own, narrower signatures: recv(bufsize) without flags)
        self.sendto, self.recv, self.recvfrom = single.sendto, single.recv, single.recvfrom  # type: ignore[assignment]
        self._append = sink
        self._local = sock.getsockname()[:2]

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

    def enable_gro(self) -> bool:
        """Never: a captured socket reads each datagram as the kernel cuts it, so that its per-datagram calls
        (``recv``, ``recvfrom``: the tap's) never see a coalesced buffer."""
        return False

    def recv_burst(self, limit: int = CAPACITY) -> list[bytes]:
        got = _recvfrom_burst(self, limit)  # the same recvmmsg, each datagram with its source (msg_name, cached)
        if len(got) == 1:  # the common case: one answer per read
            data, addr = got[0]
            self._append((_mono(), data, addr, self._local))
            return [data]
        if got:
            self._received(got)
        return [data for data, _ in got]

    def recvfrom_burst(self, limit: int = CAPACITY) -> list[tuple[bytes, Any]]:
        got = _recvfrom_burst(self, limit)
        if got:
            self._received(got)
        return got

    def _received(self, got: list[tuple[bytes, Any]]) -> None:
        """Record the datagrams of one read, with its time."""
        ts, local, append = _mono(), self._local, self._append
        for data, addr in got:
            append((ts, data, addr, local))
