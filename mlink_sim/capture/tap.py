"""The tap between a UDP socket and a capture: the one place the I/O layer touches capturing.

:class:`TappedSocket` stands in for a non-blocking ``socket.socket`` (``sendto``, ``recv``, ``recvfrom``,
``fileno``, ``getsockname``, ``close``) and calls ``record(ts_ns, datagram, src, dst)`` for every datagram it moves,
stamped with ``time.monotonic_ns()`` as it is sent or read. The master and the slave server wrap their sockets in
it when ``--capture`` is given; otherwise nothing changes on their hot path.

A driver that keeps its own time (a virtual clock) calls ``record`` itself with its simulated timestamps and the
addresses the datagram would carry; the capture does not care where the time comes from.

A socket bound to a wildcard address (``0.0.0.0``, ``::``) has no address of its own: the tap records the address
the kernel would send from to reach each peer (a route lookup with a connected UDP socket, once per peer).
"""

from __future__ import annotations

import socket
import time
from collections.abc import Callable
from typing import Any

__all__ = ["TappedSocket", "Record", "source_address_for"]

#: ``record(ts_ns, datagram, (src_host, src_port), (dst_host, dst_port))``
Record = Callable[[int, bytes, Any, Any], None]

_WILDCARDS = ("0.0.0.0", "::", "")


def source_address_for(peer: Any, port: int) -> tuple[str, int]:
    """``(host, port)`` this machine sends from to reach *peer*: the kernel's route choice, with *port*."""
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
    """A socket that records every datagram it sends or receives (see the module docstring)."""

    __slots__ = ("_sock", "_record", "_local", "_port", "_locals", "fileno", "getsockname", "close", "setsockopt")

    def __init__(self, sock: socket.socket, record: Record) -> None:
        self._sock = sock
        self._record = record
        self.fileno = sock.fileno
        self.getsockname = sock.getsockname
        self.close = sock.close
        self.setsockopt = sock.setsockopt
        host, port = sock.getsockname()[:2]
        self._port = port
        self._local: tuple[str, int] | None = None if host in _WILDCARDS else (host, port)
        self._locals: dict[Any, tuple[str, int]] = {}

    def _local_for(self, peer: Any) -> tuple[str, int]:
        local = self._local
        if local is not None:
            return local
        local = self._locals.get(peer)
        if local is None:
            local = self._locals[peer] = source_address_for(peer, self._port)
        return local

    def sendto(self, data: bytes, addr: Any) -> int:
        n = self._sock.sendto(data, addr)  # raises OSError when not sent: then nothing is recorded
        self._record(time.monotonic_ns(), data, self._local_for(addr), addr)
        return n

    def recvfrom(self, bufsize: int) -> tuple[bytes, Any]:
        data, addr = self._sock.recvfrom(bufsize)
        self._record(time.monotonic_ns(), data, addr, self._local_for(addr))
        return data, addr

    def recv(self, bufsize: int) -> bytes:
        return self.recvfrom(bufsize)[0]
