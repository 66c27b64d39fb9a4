"""Which sources may change a station: the allow list of ``mlink-sim slave --allow-master`` (docs/cards.md, "Who may
change a station").

The protocol has no authentication: a station released by a connection loss takes the next CONNECT, whoever sends
it. The transport knows where each datagram comes from, so a slave told its master's address keeps everyone else
out, in two lines:

* **the kernel** (:meth:`AllowList.sources`, :mod:`mlink_sim.aio.transport.sockfilter`): each station socket takes
  datagrams only from the listed sources (connected to the master, or a socket filter); every other datagram is
  dropped before the slave reads it, so a flood from elsewhere costs the slave nothing;
* **the slave** (:meth:`AllowList.screen`): a datagram from a source ``--allow-master`` does not name that reached
  the slave all the same (one of ``--allow-status``, or where the kernel has no filter) goes to the card's
  ``receive_untrusted`` (a status query is answered read-only, anything else counted in ``foreign_source``); the
  protocol decisions stay the card's.

A rule is ``HOST`` (any port), ``HOST:PORT`` (``[V6]:PORT``) or a network in CIDR notation (``10.0.0.0/24``). A
host name is resolved when the list is (:meth:`AllowList.resolve`, at the server's start and again, at most once a
second, while a name has not resolved or a source no rule names appears: a container's address can come and go).
The decision is taken once per source address and kept (:meth:`AllowList.screen`: one dictionary look-up per
datagram).

Touches: the resolver (``socket.getaddrinfo``) in :meth:`AllowList.resolve`, which the server runs in a worker thread
after the start.
"""

from __future__ import annotations

import ipaddress
import socket
from collections.abc import Iterable
from typing import Any

from ..transport.sockfilter import Source

__all__ = ["AllowList", "parse_rule"]

_MAX_KNOWN = 4096  #: sources whose decision is kept; beyond, each new one is decided again (a flood of addresses)
IPAddress = ipaddress.IPv4Address | ipaddress.IPv6Address
IPNetwork = ipaddress.IPv4Network | ipaddress.IPv6Network


def parse_rule(text: str) -> tuple[str, int | None] | IPNetwork:
    """``HOST``, ``HOST:PORT``, ``[V6]:PORT``, a bare IPv6 address or a CIDR network -> ``(host, port or None)`` or
    the network. ValueError with a one-line reason otherwise."""
    text = text.strip()
    if not text:
        raise ValueError("an empty address; expected HOST, HOST:PORT or a CIDR network such as 10.0.0.0/24")
    if "/" in text:
        try:
            return ipaddress.ip_network(text, strict=False)
        except ValueError:
            raise ValueError(f"{text!r} is not a CIDR network such as 10.0.0.0/24") from None
    host, port = text, None
    if text.startswith("["):
        inner, sep, rest = text[1:].partition("]")
        if not sep or (rest and not rest.startswith(":")):
            raise ValueError(f"{text!r}: expected [IPV6] or [IPV6]:PORT")
        host, port_text = inner, rest[1:] if rest else None
        port = _port(text, port_text) if port_text is not None else None
    elif text.count(":") == 1:
        host, port_text = text.split(":")
        port = _port(text, port_text)
    if not host:
        raise ValueError(f"{text!r}: no host")
    return host, port


def _port(text: str, port_text: str) -> int:
    if not port_text.isdigit() or not 0 < int(port_text) < 65536:
        raise ValueError(f"{text!r}: the port is a number from 1 to 65535")
    return int(port_text)


def _ip(host: str) -> IPAddress | None:
    """*host* as an address (an IPv4-mapped IPv6 address as its IPv4 one), None if it is not a literal."""
    try:
        ip = ipaddress.ip_address(host.partition("%")[0])
    except ValueError:
        return None
    if isinstance(ip, ipaddress.IPv6Address) and ip.ipv4_mapped is not None:
        return ip.ipv4_mapped
    return ip


def _add(hosts: dict[IPAddress, set[int] | None], ip: IPAddress, port: int | None) -> None:
    """Allow *port* (None: any) of *ip* in *hosts*."""
    if ip in hosts and hosts[ip] is None:
        return
    if port is None:
        hosts[ip] = None
    else:
        ports = hosts.setdefault(ip, set())
        assert ports is not None
        ports.add(port)


class _Rules:
    """One list of rules: its literal addresses and networks, and its host names with what they resolved to."""

    def __init__(self, rules: Iterable[str]) -> None:
        self.rules: list[str] = list(rules)
        self.networks: list[IPNetwork] = []
        self.names: list[tuple[str, int | None]] = []  #: host names, resolved by resolve()
        hosts: dict[IPAddress, set[int] | None] = {}  #: address -> ports (None: any)
        for text in self.rules:
            rule = parse_rule(text)
            if isinstance(rule, tuple):
                ip = _ip(rule[0])
                if ip is None:
                    self.names.append(rule)
                else:
                    _add(hosts, ip, rule[1])
            else:
                self.networks.append(rule)
        self._static = hosts
        self.hosts: dict[IPAddress, set[int] | None] = _copy(hosts)
        self.unresolved: list[str] = [name for name, _ in self.names]

    def resolve(self) -> None:
        """Resolve the host names (blocking); a name that does not resolve allows nothing until a later call."""
        hosts, unresolved = _copy(self._static), []
        for name, port in self.names:
            try:
                infos = socket.getaddrinfo(name, None, type=socket.SOCK_DGRAM)
            except OSError:
                unresolved.append(name)
                continue
            for info in infos:
                ip = _ip(str(info[4][0]))
                if ip is not None:
                    _add(hosts, ip, port)
        self.hosts, self.unresolved = hosts, unresolved  # whole objects swapped: the loop's thread reads them

    def sources(self) -> list[Source]:
        """The rules as the kernel's filter takes them (:class:`~mlink_sim.aio.transport.sockfilter.Source`)."""
        out = []
        for ip, ports in self.hosts.items():
            net = ipaddress.ip_network(ip)
            out += [Source(net)] if ports is None else [Source(net, port) for port in sorted(ports)]
        return out + [Source(net) for net in self.networks]


def _copy(hosts: dict[IPAddress, set[int] | None]) -> dict[IPAddress, set[int] | None]:
    return {ip: None if ports is None else set(ports) for ip, ports in hosts.items()}


class AllowList:
    """The sources that may change the stations of one slave process, and those whose status queries are answered
    besides (see the module docstring)."""

    def __init__(self, rules: Iterable[str], status: Iterable[str] = ()) -> None:
        """*rules*: ``--allow-master``; *status*: ``--allow-status``, sources the kernel lets through whose datagrams
        the cards take as untrusted (a status query answered read-only, anything else counted in
        ``foreign_source``)."""
        self._change = _Rules(rules)
        self._status = _Rules(status)
        self.rules: list[str] = self._change.rules
        self.status_rules: list[str] = self._status.rules
        self._known: dict[Any, bool] = {}  #: source address (as the socket gives it) -> allowed
        self.unresolved: list[str] = self._change.unresolved + self._status.unresolved  #: names not found last time
        self.stale = self.named  #: a resolve() is due (a name unresolved, or a source no rule names)

    @property
    def named(self) -> bool:
        """Whether a rule names a host (resolved, and again while it does not resolve or a source no rule names shows
        up); without one the lists never change."""
        return bool(self._change.names or self._status.names)

    def resolve(self) -> None:
        """Resolve the host names of the rules (blocking: the server calls it in a worker thread); a name that does
        not resolve allows nothing until a later call finds it."""
        if not self.named:
            self.stale = False
            return
        self._change.resolve()
        self._status.resolve()
        self.unresolved = self._change.unresolved + self._status.unresolved
        self._known = {}
        self.stale = False

    def sources(self) -> list[Source]:
        """Every source the kernel is to let through to the stations' sockets (:mod:`~mlink_sim.aio.transport.
        sockfilter`): those that may change a station and those whose status queries are answered."""
        out = self._change.sources()
        return out + [s for s in self._status.sources() if s not in out]

    def allows(self, addr: Any) -> bool:
        """Whether the source *addr* (a socket address: ``(host, port, …)``) may change a station."""
        known = self._known.get(addr)
        if known is not None:
            return known
        ok = self._decide(addr)
        if len(self._known) < _MAX_KNOWN:
            self._known[addr] = ok
        if not ok and self.named:
            self.stale = True  # perhaps a name's address changed: resolve again (the server, rate-limited)
        return ok

    def _decide(self, addr: Any) -> bool:
        try:
            ip = _ip(str(addr[0]))
            port = int(addr[1])
        except (TypeError, ValueError, IndexError):
            return False
        if ip is None:
            return False
        hosts = self._change.hosts
        if ip in hosts:
            ports = hosts[ip]
            if ports is None or port in ports:
                return True
        return any(ip in net for net in self._change.networks)

    def screen(self, batch: list[tuple[bytes, Any]]) -> tuple[list[tuple[bytes, Any]], list[tuple[bytes, Any]]]:
        """*batch* split into the datagrams of allowed sources and the others, each in arrival order."""
        known = self._known
        i = 0
        for item in batch:
            ok = known.get(item[1])
            if ok is None:
                ok = self.allows(item[1])
            if not ok:
                break
            i += 1
        else:
            return batch, []  # the common case: the master's commands only, the batch as it is
        allowed, others = batch[:i], [batch[i]]
        for item in batch[i + 1:]:
            ok = known.get(item[1])
            if ok is None:
                ok = self.allows(item[1])
            (allowed if ok else others).append(item)
        return allowed, others

