"""The tap between a UDP socket and a capture: the one place the I/O layer touches capturing.

:class:`TappedSocket` stands in for a non-blocking ``socket.socket`` (``sendto``, ``recv``, ``recvfrom``,
``fileno``, ``getsockname``, ``close``) and calls ``record(ts_ns, datagram, src, dst)`` for every datagram it moves,
stamped with ``time.monotonic_ns()`` as it is sent or read. The master and the slave server wrap their sockets in
it when ``--capture`` is given; otherwise nothing changes on their hot path.

A driver that keeps its own time (a virtual clock) calls ``record`` itself with its simulated timestamps and the
addresses the datagram would carry; the capture does not care where the time comes from.

Where ``sendmmsg``/``recvmmsg`` are supported, the I/O layer taps its batched calls instead
(:class:`mlink_sim.aio.transport.tapped.TappedBurstSocket`, fed the same tuples): the master, the slaves and the proxy
wrap their sockets with :func:`mlink_sim.aio.transport.tapped.tap`, which falls back to a :class:`TappedSocket`
where there is no ``recvmmsg`` (or the caller asks for the per-datagram calls).

``recv`` needs the datagram's real source address. On a socket that is ``connect()``-ed when it is wrapped, the
kernel delivers only datagrams from its peer, so the source is ``getpeername()`` and a plain ``recv`` suffices. On
an unconnected socket (the master's and the slaves' sockets are: one master socket talks to every station, a
station answers whoever sent the command) ``recv`` is served by ``recvfrom``, about 1 µs more in CPython: the
source is never guessed. A tapped socket must not be connected again to
another peer behind the tap's back (:class:`TappedSocket` has no ``connect``).

A socket bound to a wildcard address (``0.0.0.0``, ``::``) has no address of its own: the writer records the
address the kernel would send from to reach each peer (a route lookup with a connected UDP socket, once per flow,
in the writer thread).
"""

from __future__ import annotations

import socket
import time
from collections.abc import Callable
from typing import Any

__all__ = ["TappedSocket", "Record", "Sink", "source_address_for", "WILDCARDS"]

#: ``record(ts_ns, datagram, (src_host, src_port), (dst_host, dst_port))``
Record = Callable[[int, bytes, Any, Any], None]
#: what a :class:`TappedSocket` feeds: one ``(ts_ns, datagram, src, dst)`` tuple per datagram (``deque.append``)
Sink = Callable[[tuple[int, bytes, Any, Any]], None]

WILDCARDS = ("0.0.0.0", "::", "")
_mono = time.monotonic_ns


def source_address_for(peer: Any, port: int) -> tuple[str, int]:
    """``(host, port)`` the local host sends from to reach *peer*: the kernel's route choice, with *port*."""
    family = socket.AF_INET6 if ":" in str(peer[0]) else socket.AF_INET
    probe = socket.socket(family, socket.SOCK_DGRAM)
    try:
        probe.connect((peer[0], peer[1] or 9))
        return probe.getsockname()[0], port
    except OSError:
        return ("::" if family == socket.AF_INET6 else "0.0.0.0"), port
    finally:
        probe.close()


class TappedSocket:
    """A socket that records every datagram it sends or receives (see the module docstring). *sink* gets one
    ``(ts_ns, datagram, src, dst)`` tuple per datagram; the socket's own address is recorded as bound (a wildcard
    host is resolved later, off the hot path, by the writer).

    ``sendto``, ``recvfrom`` and ``recv`` are closures over the socket's own methods and the sink (no attribute
    look-ups on the hot path): a tapped send costs one clock read, one tuple and one ``deque.append`` more."""

    __slots__ = ("sendto", "recvfrom", "recv", "fileno", "getsockname", "close", "setsockopt")

    def __init__(self, sock: socket.socket, sink: Sink) -> None:
        send, receive, local, mono = sock.sendto, sock.recvfrom, sock.getsockname()[:2], _mono
        try:
            peer = sock.getpeername()  # connected: the kernel delivers only what its peer sends
        except OSError:  # ENOTCONN
            peer = None

        def sendto(data: bytes, addr: Any) -> int:
            n = send(data, addr)  # raises OSError when not sent: then nothing is recorded
            sink((mono(), data, local, addr))
            return n

        def recvfrom(bufsize: int) -> tuple[bytes, Any]:
            data, addr = receive(bufsize)
            sink((mono(), data, addr, local))
            return data, addr

        def recv(bufsize: int) -> bytes:  # recvfrom underneath: the capture needs the real source address
            data, addr = receive(bufsize)
            sink((mono(), data, addr, local))
            return data

        if peer is not None:
            plain = sock.recv

            def recv(bufsize: int) -> bytes:
                data = plain(bufsize)
                sink((mono(), data, peer, local))
                return data

        self.sendto, self.recvfrom, self.recv = sendto, recvfrom, recv
        self.fileno = sock.fileno
        self.getsockname = sock.getsockname
        self.close = sock.close
        self.setsockopt = sock.setsockopt

