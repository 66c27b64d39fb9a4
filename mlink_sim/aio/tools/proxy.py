"""``mlink-sim proxy``: an impairing UDP proxy between any master and any slaves (docs/faults.md, "The proxy").

Each *link* listens on a HOST:PORT for the master and forwards to one slave's HOST:PORT from a socket of its own;
the slave's answers go back to the master that last sent. Every datagram goes through the shared
:class:`~mlink_sim.impair.ImpairmentLayer` (the station is the envelope's byte 3) while it has a fault; without
one, a datagram is forwarded as it was read. Delayed datagrams wait in a
:class:`~mlink_sim.aio.transport.impaired.DelayLine`. The proxy understands nothing else of the protocol: it works with
any master, the user's own included.

Touches: its UDP sockets (one per link and direction), a capture when given.
"""

from __future__ import annotations

import asyncio
import socket
import time
from collections import Counter
from dataclasses import dataclass, field
from typing import Any

from ..._log import get_logger
from ...impair import Direction, ImpairmentLayer
from ..transport.impaired import DelayLine
from ..transport.ports import DatagramPort, PeerPort
from ..transport.tapped import tap
from ..transport.udp import bind_address_for, bound_socket, close_watched, resolve

__all__ = ["ImpairingProxy", "ProxyLink"]

log = get_logger("mlink_sim.proxy")
_mono = time.monotonic_ns
_BURST = 256  # datagrams read per wake-up at most


@dataclass
class ProxyLink:
    """One listening address and the slave it forwards to."""

    listen: tuple[str, int]
    to: tuple[str, int]
    down: PeerPort | None = None  #: the master's side (bound to *listen*)
    up: PeerPort | None = None  #: towards the slave
    master: Any = None  #: where the last command came from: the answers go there
    counts: Counter[str] = field(default_factory=Counter)


class ImpairingProxy:
    """Proxies *links* (``[(listen, to), …]``) through *layer*; ``await start()``, ``close()``. *capture*: a
    :class:`~mlink_sim.capture.CaptureWriter`, every socket tapped (what the proxy received and sent)."""

    def __init__(self, links: list[tuple[tuple[str, int], tuple[str, int]]], layer: ImpairmentLayer, *,
                 capture: Any = None) -> None:
        self.links = [ProxyLink(listen, to) for listen, to in links]
        self.impairments = layer
        self.capture = capture
        self._loop: asyncio.AbstractEventLoop | None = None
        self._line: DelayLine | None = None

    # -- the control endpoint's target (aio/control/endpoint.py) ----------------------------------------------------------
    def impair(self, station: int | None, spec: Any, name: str | None = None) -> str:
        """Start *spec* on *station* (None: every station's path); its name (*name*, or a made one)."""
        return self.impairments.impair(spec, station, _mono(), name=name)

    def heal(self, station: int | None = None, name: str | None = None) -> list[str]:
        """End the impairments of *station* (None: all), or the one called *name*; the names that ended."""
        return self.impairments.heal(station, _mono(), name=name)

    def now_ns(self) -> int:
        return _mono()

    # -- life cycle ---------------------------------------------------------------------------------------------
    async def start(self) -> None:
        """Resolve the slaves, bind every socket (OSError: nothing is left open)."""
        loop = self._loop = asyncio.get_running_loop()
        try:
            for link in self.links:
                link.to = await resolve(*link.to)
                down = link.down = self._wrap(bound_socket(*link.listen))
                link.listen = down.getsockname()[:2]
                up = link.up = self._wrap(bound_socket(*bind_address_for([link.to])))
                loop.add_reader(down.fileno(), self._from_master, link)
                loop.add_reader(up.fileno(), self._from_slave, link)
            self._line = DelayLine(loop, self._due)
        except BaseException:
            self.close()
            raise
        for link in self.links:
            log.info("proxy_ready", listen=f"{link.listen[0]}:{link.listen[1]}", to=f"{link.to[0]}:{link.to[1]}")

    def _wrap(self, sock: socket.socket) -> PeerPort:
        return sock if self.capture is None else tap(self.capture, sock)

    def close(self) -> None:
        if self._line is not None:
            self._line.close()
            self._line = None
        for link in self.links:
            for sock in (link.down, link.up):
                if sock is not None and self._loop is not None:
                    close_watched(self._loop, sock)
                elif sock is not None:
                    sock.close()
            link.down = link.up = None

    def totals(self) -> Counter[str]:
        out: Counter[str] = Counter()
        for link in self.links:
            out.update(link.counts)
        return out

    # -- datagrams ----------------------------------------------------------------------------------------------
    def _from_master(self, link: ProxyLink) -> None:
        down, up = link.down, link.up
        if down is None or up is None:
            return  # closed
        for data, addr in self._read(down, link):
            link.master = addr
            link.counts["to_station"] += 1
            self._forward(link, data, Direction.TO_STATION, up, link.to)

    def _from_slave(self, link: ProxyLink) -> None:
        down, up = link.down, link.up
        if down is None or up is None:
            return  # closed
        for data, _addr in self._read(up, link):
            link.counts["to_master"] += 1
            if link.master is None:
                link.counts["no_master"] += 1  # an answer before any command: nowhere to send it
                continue
            self._forward(link, data, Direction.TO_MASTER, down, link.master)

    def _read(self, sock: PeerPort, link: ProxyLink) -> list[tuple[bytes, Any]]:
        out = []
        for _ in range(_BURST):
            try:
                out.append(sock.recvfrom(4096))
            except BlockingIOError:
                break
            except OSError:  # e.g. ICMP port unreachable from a slave that is not there (yet)
                link.counts["errors"] += 1
        return out

    def _forward(self, link: ProxyLink, data: bytes, direction: Direction, sock: DatagramPort, addr: Any) -> None:
        layer = self.impairments
        if not layer.active:
            self._send(link, sock, data, addr)
            return
        now = _mono()
        for delay, out in layer.process(data, direction, data[3] if len(data) > 3 else -1, now):
            if delay <= 0:
                self._send(link, sock, out, addr)
            elif self._line is not None:
                self._line.push(now + delay, (link, sock, out, addr))

    def _send(self, link: ProxyLink, sock: DatagramPort, data: bytes, addr: Any) -> None:
        try:
            sock.sendto(data, addr)
        except OSError:
            link.counts["errors"] += 1

    def _due(self, now: int) -> None:
        if self._line is None:
            return
        for link, sock, data, addr in self._line.pop_due(now):
            if link.down is not None:
                self._send(link, sock, data, addr)
        self.impairments.expire(now)
