"""UDP datagram endpoints and event-loop setup. Moves bytes; decides nothing.

Touches: UDP sockets and the event loop they are watched by (readers, signal handlers).
"""

from __future__ import annotations

import asyncio
import socket
import time
from collections.abc import Callable, Sequence
from typing import Any

from ..._log import get_logger
from . import mmsg, sockfilter
from .ports import BurstPort, DatagramPort, PeerPort, bursts
from ..timing.arrival import ArrivalPoll

__all__ = ["new_event_loop", "stop_on_signals", "DatagramEndpoint", "open_endpoint", "BatchEndpoint", "open_batch_endpoint", "loop_name",
           "resolve", "bind_address_for", "bound_socket", "close_watched", "BindError"]

log = get_logger("mlink_sim.aio.transport.udp")
_mono = time.monotonic_ns


def new_event_loop() -> asyncio.AbstractEventLoop:
    """A uvloop loop where uvloop is installed, else the default asyncio loop."""
    try:
        import uvloop
    except ImportError:  # pragma: no cover - uvloop is a dependency on Linux/macOS
        return asyncio.new_event_loop()
    return uvloop.new_event_loop()


def stop_on_signals(loop: asyncio.AbstractEventLoop) -> tuple[asyncio.Event, list[int]]:
    """SIGINT and SIGTERM set the returned event (a server's orderly stop); the list gets each signal caught
    (exit status 128 + its number)."""
    import signal

    stop = asyncio.Event()
    caught: list[int] = []

    def on_signal(sig: signal.Signals) -> None:
        caught.append(sig)
        stop.set()

    for sig in (signal.SIGINT, signal.SIGTERM):
        loop.add_signal_handler(sig, on_signal, sig)
    return stop, caught


def loop_name(loop: asyncio.AbstractEventLoop) -> str:
    return "uvloop" if type(loop).__module__.startswith("uvloop") else "asyncio"


class DatagramEndpoint(asyncio.DatagramProtocol):
    """Hands every datagram with its source address to ``on_datagram(data, addr)``.

    Socket errors (e.g. ICMP port unreachable when a peer is gone) are counted in :attr:`errors` and never raised.
    """

    def __init__(self, on_datagram: Callable[[bytes, Any], None]) -> None:
        self.on_datagram = on_datagram
        self.transport: asyncio.DatagramTransport | None = None
        self.errors = 0
        self.closed = asyncio.get_event_loop().create_future()

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        self.transport = transport  # type: ignore[assignment]

    def datagram_received(self, data: bytes, addr: Any) -> None:
        self.on_datagram(data, addr)

    def error_received(self, exc: Exception) -> None:
        self.errors += 1

    def connection_lost(self, exc: Exception | None) -> None:
        if not self.closed.done():
            self.closed.set_result(None)

    def sendto(self, data: bytes, addr: Any) -> None:
        if self.transport is not None:
            self.transport.sendto(data, addr)

    @property
    def local_address(self) -> tuple[str, int]:
        assert self.transport is not None
        sockname = self.transport.get_extra_info("sockname")
        return sockname[0], sockname[1]

    def close(self) -> None:
        if self.transport is not None:
            self.transport.close()


def bound_socket(host: str, port: int, rcvbuf: int = 1 << 20) -> socket.socket:
    """A non-blocking UDP socket bound to *host*:*port* (0 = any free port), receive buffer *rcvbuf* (best effort).
    Raises OSError (the socket is closed then)."""
    sock = socket.socket(socket.AF_INET6 if ":" in host else socket.AF_INET, socket.SOCK_DGRAM)
    try:
        if rcvbuf:
            try:
                sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, rcvbuf)
            except OSError:  # pragma: no cover - best effort
                pass
        try:
            sock.bind((host, port))
        except OSError as exc:
            raise BindError(exc, host, port) from None
        sock.setblocking(False)
    except BaseException:
        sock.close()
        raise
    return sock


class BindError(OSError):
    """A UDP socket that could not be bound; ``str()`` and :attr:`address` name the address
    (``Address already in use: 127.0.0.1:47001``)."""

    def __init__(self, cause: OSError, host: str, port: int) -> None:
        self.address = f"[{host}]:{port}" if ":" in host else f"{host}:{port}"
        reason = cause.strerror or str(cause)
        super().__init__(cause.errno, f"{reason}: {self.address}")


def close_watched(loop: asyncio.AbstractEventLoop, sock: DatagramPort) -> None:
    """Stop watching *sock* (``loop.add_reader``) and close it; a loop already closed is fine."""
    try:
        loop.remove_reader(sock.fileno())
    except (RuntimeError, ValueError, OSError):
        pass  # loop already closed: its selector no longer holds the fd
    sock.close()


async def open_endpoint(
    on_datagram: Callable[[bytes, Any], None], host: str = "127.0.0.1", port: int = 0, *, rcvbuf: int = 1 << 20
) -> DatagramEndpoint:
    """Bind a UDP socket on *host*:*port* (0 = any free port) and return its endpoint."""
    loop = asyncio.get_running_loop()
    sock = bound_socket(host, port, rcvbuf)
    _, protocol = await loop.create_datagram_endpoint(lambda: DatagramEndpoint(on_datagram), sock=sock)
    return protocol


class BatchEndpoint:
    """A non-blocking UDP socket watched with ``loop.add_reader``: each wake-up reads every datagram waiting (at most
    *burst*) and hands them over at once, ``on_batch([(data, addr), …])``, so the receiver can see that it fell
    behind (a slave keeps only the newest command per source, see :mod:`mlink_sim.aio.slave.server`). On a
    :class:`~mlink_sim.aio.transport.mmsg.BurstSocket` a wake-up reads them with one ``recvmmsg`` (and a second only
    when the first filled all its slots), else with one ``recvfrom`` per datagram and one more that finds none.

    ``sendto`` never raises: a full send buffer or an ICMP error reported on the socket is counted in
    :attr:`errors`, like :class:`DatagramEndpoint`."""

    def __init__(self, sock: PeerPort, on_batch: Callable[[list[tuple[bytes, Any]]], None], burst: int,
                 raw: socket.socket | None = None) -> None:
        """*raw*: the ``socket.socket`` under *sock* (the kernel's settings: :meth:`refuse_others`); None: *sock*."""
        self._sock: PeerPort | None = sock  #: a socket.socket, a BurstSocket (recvmmsg) or a capture's tap
        self._raw = raw if raw is not None else sock if isinstance(sock, socket.socket) else None
        self._bursts: BurstPort | None = bursts(sock)  #: its batched calls, where it has them
        self._on_batch = on_batch
        self._burst = burst
        self.errors = 0
        self.poll: ArrivalPoll | None = None  #: the arrival poll, once :meth:`poll_arrivals` set one
        self._loop = asyncio.get_running_loop()
        self._loop.add_reader(sock.fileno(), self._on_readable)

    def poll_arrivals(self, setting: tuple[int, int | None] | None) -> bool:
        """Read the bursts in a short busy-poll around the time each is due (:class:`~mlink_sim.aio.timing.arrival.
        ArrivalPoll`, *setting* from :func:`~mlink_sim.config.units.parse_arrival_poll`); True if one was set."""
        if self.poll is None and self._sock is not None:
            self.poll = ArrivalPoll.create(self._loop, self._read, setting)
        return self.poll is not None

    def read_pending(self) -> None:
        """Hand over what is waiting now (at most *burst*), as the reader callback does."""
        self._read()

    def _on_readable(self) -> None:
        self._read()

    def _read(self) -> bool:
        """One read of what is waiting, handed over; True if there was any."""
        sock = self._sock
        if sock is None:
            return False
        bursts = self._bursts
        if bursts is not None:  # recvmmsg (mlink_sim.aio.transport.mmsg): one system call for what is waiting
            batch = [item for got in mmsg.drain(bursts.recvfrom_burst, self._burst, self._count_error)
                     for item in got]
        else:
            recvfrom = sock.recvfrom
            batch = []
            for _ in range(self._burst):
                try:
                    batch.append(recvfrom(4096))
                except BlockingIOError:
                    break
                except OSError:  # e.g. ConnectionRefusedError after an ICMP port unreachable
                    self.errors += 1
        if not batch:
            return False
        poll = self.poll
        if poll is not None:
            poll.arrived(_mono())
        self._on_batch(batch)
        return True

    def _count_error(self, exc: OSError) -> None:  # e.g. ConnectionRefusedError after an ICMP port unreachable
        self.errors += 1

    def sendto(self, data: bytes, addr: Any) -> None:
        sock = self._sock
        if sock is not None:
            try:
                sock.sendto(data, addr)
            except OSError:
                self.errors += 1

    def send_burst(self, items: list[tuple[bytes, Any]]) -> None:
        """Send every ``(data, addr)``: in one ``sendmmsg`` or offloaded ``sendmsg`` on a
        :class:`~mlink_sim.aio.transport.mmsg.BurstSocket`, else one ``sendto`` each; never raises (a datagram not sent
        counts in :attr:`errors`)."""
        if self._sock is None:
            return
        bursts = self._bursts
        if bursts is not None:
            self.errors += len(bursts.send_burst(items))
            return
        for data, addr in items:
            self.sendto(data, addr)

    def enable_gro(self) -> bool:
        """Read a peer's offloaded bursts as one buffer each
        (:meth:`mlink_sim.aio.transport.mmsg.BurstSocket.enable_gro`);
        False where the socket cannot."""
        return self._sock is not None and self._bursts is not None and self._bursts.enable_gro()

    def refuse_others(self, sources: Sequence[sockfilter.Source], *, connect: bool = True) -> str | None:
        """Have the kernel drop every datagram from a source none of *sources* names
        (:func:`~mlink_sim.aio.transport.sockfilter.refuse_others`): ``"connect"``, ``"filter"``, or None where it
        cannot (no such socket, no such kernel); OSError or ValueError when the kernel refuses the filter."""
        if self._raw is None or not sockfilter.supported():
            return None
        return sockfilter.refuse_others(self._raw, sources, connect=connect)

    def socket_drops(self) -> int | None:
        """The datagrams the kernel dropped at this socket (:func:`~mlink_sim.aio.transport.sockfilter.socket_drops`:
        refused by its filter, or the receive buffer full), None where it does not say."""
        return None if self._raw is None or self._sock is None else sockfilter.socket_drops(self._raw)

    @property
    def local_address(self) -> tuple[str, int]:
        assert self._sock is not None
        sockname = self._sock.getsockname()
        return sockname[0], sockname[1]

    def close(self) -> None:
        poll, self.poll = self.poll, None
        if poll is not None:
            poll.close()
        sock, self._sock, self._bursts, self._raw = self._sock, None, None, None
        if sock is not None:
            close_watched(self._loop, sock)


async def open_batch_endpoint(on_batch: Callable[[list[tuple[bytes, Any]]], None], host: str = "127.0.0.1",
                              port: int = 0, *, rcvbuf: int = 1 << 20, burst: int = 64,
                              wrap: Callable[[socket.socket], PeerPort] | None = None,
                              batched: bool = True) -> BatchEndpoint:
    """Bind a UDP socket on *host*:*port* (0 = any free port) and read it in batches (:class:`BatchEndpoint`).
    *wrap*: wraps the socket (a capture's tap, :func:`mlink_sim.aio.transport.tapped.tap`).
    *batched*: read with ``recvmmsg`` (:mod:`mlink_sim.aio.transport.mmsg`) where it is supported; False: never (the
    tests compare both paths that way)."""
    plain = bound_socket(host, port, rcvbuf)
    sock: PeerPort = plain
    if wrap is not None:
        sock = wrap(plain)
    elif batched and mmsg.supported():
        sock = mmsg.BurstSocket(plain)
    try:
        return BatchEndpoint(sock, on_batch, burst, raw=plain)
    except BaseException:
        sock.close()
        raise


async def resolve(host: str, port: int) -> tuple[str, int]:
    """Resolve *host* once (compose service names, ``localhost``) to a numeric address for ``sendto``.

    Raises OSError with the resolver's message when the name does not resolve."""
    loop = asyncio.get_running_loop()
    infos = await loop.getaddrinfo(host, port, type=socket.SOCK_DGRAM)
    infos.sort(key=lambda info: info[0] != socket.AF_INET)  # IPv4 first: the master socket is IPv4 by default
    return str(infos[0][4][0]), port


def bind_address_for(targets: list[tuple[str, int]]) -> tuple[str, int]:
    """Where a client socket should bind to reach every target: any IPv4 (or IPv6) address, any port.

    A socket bound to 127.0.0.1 cannot send to another host or namespace (EINVAL), so bind the wildcard."""
    return ("::", 0) if targets and all(":" in h for h, _ in targets) else ("0.0.0.0", 0)
