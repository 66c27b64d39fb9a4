"""Sources refused by the kernel: a station socket that takes datagrams from a few sources only (a slave's
``--allow-master``, docs/cards.md "Who may change a station") asks the kernel to drop every other datagram before it
is queued, so that a flood from elsewhere costs the slave process no read, no look-up and no CPU.

Two ways, each where it holds:

* **connect()**: a UDP socket connected to one address and port receives nothing from any other source (the
  kernel's socket look-up matches the connected peer). :func:`refuse_others` connects only when the list is one
  address with one port, of the socket's family, and the socket is bound to one address: connecting a socket bound
  to the wildcard would also pin its local address to the route towards the peer, and a master that sends to
  another address of the host would no longer reach it. A datagram from anyone else finds no socket: the host
  counts it (``UdpNoPorts``, ``nstat -az UdpNoPorts``) and answers an ICMP port unreachable, at the kernel's rate
  limit (``net.ipv4.icmp_msgs_per_sec``).
* **a classic BPF socket filter** (``SO_ATTACH_FILTER``, the kernel's ``Documentation/networking/filter.rst``) for
  every other list: hosts with any port, hosts with some ports, networks in CIDR notation, IPv4 and IPv6 (an IPv6
  socket's IPv4-mapped datagrams carry an IPv4 header, so the program reads the IP version first). The program
  compares the IP source (``SKF_NET_OFF``: offsets from the network header) and the UDP source port (offset 0: a UDP
  socket's filter sees the datagram from its UDP header on) and keeps the datagram or drops it; a dropped one counts
  in the socket's drops (:func:`socket_drops`, ``SO_MEMINFO``; the ``drops`` column of ``/proc/net/udp``). A filter
  is replaced as a whole by the next (a host name resolved again), with no moment without one.

Why by hand: the socket module has no call for ``SO_ATTACH_FILTER`` (its ``struct sock_fprog`` holds a pointer,
built here with ctypes), and the libraries that compile filters (libpcap through scapy, bcc) compile tcpdump
expressions for raw sockets, need a C library or root, and would add a dependency for some twenty instructions.

Touches: the socket it is given (``setsockopt``, ``connect``, ``getsockopt``).
"""

from __future__ import annotations

import ctypes
import ipaddress
import socket
import struct
import sys
from collections.abc import Sequence
from dataclasses import dataclass

__all__ = ["Source", "Instruction", "MAX_INSTRUCTIONS", "program", "refuse_others", "socket_drops", "supported"]

IPNetwork = ipaddress.IPv4Network | ipaddress.IPv6Network

#: From the kernel's headers (include/uapi/asm-generic/socket.h, include/uapi/linux/filter.h): the socket options and
#: the classic BPF opcodes used here.
SO_ATTACH_FILTER = 26
SO_MEMINFO = 55  #: nine u32 counters; SK_MEMINFO_DROPS (index 8) counts the datagrams dropped at the socket
_SK_MEMINFO_DROPS = 8
MAX_INSTRUCTIONS = 4096  #: BPF_MAXINSNS: the longest program the kernel takes
_SKF_NET_OFF = -0x100000  #: loads at this offset and above read the network (IP) header
_LD_B_ABS, _LD_H_ABS, _LD_W_ABS = 0x30, 0x28, 0x20  #: BPF_LD | BPF_ABS | BPF_B / BPF_H / BPF_W
_AND_K = 0x54  #: BPF_ALU | BPF_AND | BPF_K
_JA = 0x05  #: BPF_JMP | BPF_JA (a 32-bit offset)
_JEQ_K = 0x15  #: BPF_JMP | BPF_JEQ | BPF_K (8-bit offsets if true / false)
_RET_K = 0x06  #: BPF_RET | BPF_K: the bytes to keep, 0 drops the datagram
_KEEP, _DROP = 0xFFFFFFFF, 0
_IPV4_SOURCE, _IPV6_SOURCE = 12, 8  #: the source address's offset in the IPv4 / IPv6 header
_UDP_SOURCE_PORT = 0


Instruction = tuple[int, int, int, int]  #: (code, jump if true, jump if false, k): one ``struct sock_filter``


@dataclass(frozen=True)
class Source:
    """A source the socket takes: every address of *network* (a host is a /32 or /128), from *port* (None: any)."""

    network: IPNetwork
    port: int | None = None


def supported() -> bool:
    """True where the kernel has socket filters of this form (Linux)."""
    return sys.platform.startswith("linux")


def _mask_words(network: IPNetwork) -> list[tuple[int, int, int]]:
    """(word index, mask, masked value) of each 32-bit word of *network*'s address its prefix covers."""
    width = network.max_prefixlen
    value, prefix = int(network.network_address), network.prefixlen
    words = []
    for i in range(width // 32):
        bits = min(max(prefix - 32 * i, 0), 32)
        if bits:
            mask = (0xFFFFFFFF << (32 - bits)) & 0xFFFFFFFF
            words.append((i, mask, (value >> (width - 32 * (i + 1))) & mask))
    return words


def _rule(source: Source, offset: int) -> list[Instruction]:
    """Keep a datagram from *source*, else fall through to the next rule (the jumps stay inside the rule)."""
    body: list[tuple[int, int, int, int | None]] = []  #: jump-if-false = None: to the end of the rule
    for index, mask, value in _mask_words(source.network):
        body.append((_LD_W_ABS, 0, 0, _SKF_NET_OFF + offset + 4 * index))
        if mask != 0xFFFFFFFF:
            body.append((_AND_K, 0, 0, mask))
        body.append((_JEQ_K, 0, -1, value))
    if source.port is not None:
        body += [(_LD_H_ABS, 0, 0, _UDP_SOURCE_PORT), (_JEQ_K, 0, -1, source.port)]
    body.append((_RET_K, 0, 0, _KEEP))
    end = len(body)
    return [(code, jt, end - i - 1 if jf == -1 else jf, k or 0) for i, (code, jt, jf, k) in enumerate(body)]


def program(sources: Sequence[Source]) -> list[Instruction]:
    """The filter that keeps the datagrams of *sources* and drops every other (none: drops all). ValueError when it
    would be longer than the kernel takes (:data:`MAX_INSTRUCTIONS`)."""
    v4 = [ins for s in sources if s.network.version == 4 for ins in _rule(s, _IPV4_SOURCE)] + [(_RET_K, 0, 0, _DROP)]
    v6 = [ins for s in sources if s.network.version == 6 for ins in _rule(s, _IPV6_SOURCE)] + [(_RET_K, 0, 0, _DROP)]
    head: list[Instruction] = [
        (_LD_B_ABS, 0, 0, _SKF_NET_OFF),  # the IP version, the high nibble of the first byte
        (_AND_K, 0, 0, 0xF0),
        (_JEQ_K, 0, 1, 0x40),
        (_JA, 0, 0, 3),  # IPv4: the first block
        (_JEQ_K, 0, 1, 0x60),
        (_JA, 0, 0, 1 + len(v4)),  # IPv6: the second block
        (_RET_K, 0, 0, _DROP),
    ]
    out = [(code, jt, jf, k & 0xFFFFFFFF) for code, jt, jf, k in head + v4 + v6]  # k is a u32 (negative offsets too)
    if len(out) > MAX_INSTRUCTIONS:
        raise ValueError(f"{len(sources)} sources need {len(out)} filter instructions, more than the kernel's "
                         f"{MAX_INSTRUCTIONS}")
    return out


def _attach(sock: socket.socket, instructions: Sequence[Instruction]) -> None:
    code = b"".join(struct.pack("HBBI", *ins) for ins in instructions)
    buffer = ctypes.create_string_buffer(code, len(code))
    fprog = struct.pack("HP", len(instructions), ctypes.addressof(buffer))  # struct sock_fprog {len; *filter}
    sock.setsockopt(socket.SOL_SOCKET, SO_ATTACH_FILTER, fprog)  # the kernel copies the program: buffer may go


def _peer(sock: socket.socket, sources: Sequence[Source]) -> tuple[str, int] | None:
    """The one peer *sock* may be connected to for *sources*, or None (see the module docstring)."""
    if len(sources) != 1:
        return None
    source = sources[0]
    net = source.network
    if source.port is None or net.prefixlen != net.max_prefixlen:
        return None
    local = sock.getsockname()
    if net.version != (6 if sock.family == socket.AF_INET6 else 4) or ipaddress.ip_address(local[0]).is_unspecified:
        return None
    return str(net.network_address), source.port


def refuse_others(sock: socket.socket, sources: Sequence[Source], *, connect: bool = True) -> str:
    """Have the kernel drop every datagram to *sock* that comes from none of *sources*: ``"connect"`` when *sock*
    was connected to its one source (only with *connect*: a socket is connected once and stays so), ``"filter"``
    when a socket filter does it. OSError or ValueError (:func:`program`) when the kernel refuses both; the socket
    is then as it was."""
    peer = _peer(sock, sources) if connect else None
    if peer is not None:
        sock.connect(peer)
        return "connect"
    _attach(sock, program(sources))
    return "filter"


def socket_drops(sock: socket.socket) -> int | None:
    """The datagrams the kernel dropped at *sock* since it was created (its filter's refusals and those that found
    the receive buffer full), or None where the kernel does not say."""
    try:
        info = sock.getsockopt(socket.SOL_SOCKET, SO_MEMINFO, 4 * (_SK_MEMINFO_DROPS + 1))
    except OSError:
        return None
    if len(info) < 4 * (_SK_MEMINFO_DROPS + 1):
        return None
    return int(struct.unpack_from("I", info, 4 * _SK_MEMINFO_DROPS)[0])
