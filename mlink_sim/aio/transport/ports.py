"""What the I/O layer needs of a socket, as :class:`typing.Protocol` classes: the master runner, a slave's
endpoint and the proxy hold a socket by what it can do, never by what it is, and ask nothing of it by name at run
time (no ``getattr``).

* :class:`DatagramPort`: one datagram at a time (``sendto``, ``recv``) and the socket's own calls. The master's
  socket is one, whatever stands in for it: a ``socket.socket``, a :class:`~.mmsg.BurstSocket`, a capture's
  :class:`~mlink_sim.capture.tap.TappedSocket` or :class:`~.tapped.TappedBurstSocket`, an
  :class:`~.impaired.ImpairedSocket`, the virtual clock's :class:`~mlink_sim.aio.virtual.fabric.FabricPort`.
* :class:`PeerPort`: also ``recvfrom``, each datagram with its source (a station answers whoever sent the command):
  a slave's :class:`~.udp.BatchEndpoint` reads one.
* :class:`BurstPort`: also the batched calls (one ``sendmmsg`` per burst, one ``recvmmsg`` per read) and the
  coalesced reads (``UDP_GRO``): a :class:`~.mmsg.BurstSocket` and the capture's tap on it.

:func:`bursts` is the one place that asks which a socket is, once, when a holder takes the socket: the cycle then
calls what it holds. mypy checks that each implementation is the port it stands for (the end of this module;
``FabricPort`` in :mod:`mlink_sim.aio.virtual`).

Touches: nothing; the sockets are the callers'.
"""

from __future__ import annotations

import socket
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any, Protocol, runtime_checkable

__all__ = ["DatagramPort", "PeerPort", "BurstPort", "bursts"]


class DatagramPort(Protocol):
    """A non-blocking datagram socket, one datagram at a time: ``sendto`` raises ``OSError`` when it is not sent
    (``BlockingIOError`` for a full send buffer), ``recv`` ``BlockingIOError`` when nothing is waiting."""

    def sendto(self, data: bytes, address: Any, /) -> int: ...

    def recv(self, bufsize: int, /) -> bytes: ...

    def fileno(self) -> int: ...

    def getsockname(self) -> Any: ...

    def close(self) -> None: ...


class PeerPort(DatagramPort, Protocol):
    """A :class:`DatagramPort` that also reads each datagram with its source address."""

    def recvfrom(self, bufsize: int, /) -> tuple[bytes, Any]: ...


@runtime_checkable
class BurstPort(PeerPort, Protocol):
    """A :class:`PeerPort` with the batched calls (:mod:`~mlink_sim.aio.transport.mmsg`): each returns what it did
    and raises nothing for "nothing waiting"."""

    def send_burst(self, items: Sequence[tuple[bytes, Any]], /) -> list[tuple[int, OSError]]:
        """Send every ``(datagram, address)``; the datagrams not sent, by index, with their errors."""
        ...

    def recv_burst(self, limit: int, /) -> list[bytes]:
        """What is waiting, at most *limit* datagrams; [] when none is."""
        ...

    def recvfrom_burst(self, limit: int, /) -> list[tuple[bytes, Any]]:
        """As :meth:`recv_burst`, each datagram with its source."""
        ...

    def enable_gro(self) -> bool:
        """Read a peer's offloaded burst as one buffer, cut again by the reads; False where the socket cannot."""
        ...


def bursts(sock: DatagramPort) -> BurstPort | None:
    """*sock*'s batched calls, or None where it has only the per-datagram ones. Asked once per socket a holder
    takes (a structural check of four methods), never per datagram."""
    return sock if isinstance(sock, BurstPort) else None


if TYPE_CHECKING:  # each implementation is the port it stands for (checked by mypy, never run)
    from ...capture.tap import TappedSocket
    from .impaired import ImpairedSocket
    from .mmsg import BurstSocket
    from .tapped import TappedBurstSocket

    def _ports(plain: socket.socket, burst: BurstSocket, tapped: TappedBurstSocket, single: TappedSocket,
               impaired: ImpairedSocket) -> tuple[PeerPort, BurstPort, BurstPort, PeerPort, DatagramPort]:
        return plain, burst, tapped, single, impaired
