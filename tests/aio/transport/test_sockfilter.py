"""The kernel's refusal of every source but the listed ones (``mlink_sim.aio.transport.sockfilter``): the socket
filter's program on real loopback sockets (IPv4 hosts, ports and networks, IPv6, an IPv6 socket's IPv4-mapped
datagrams), when a socket is connected instead, and the drop counter."""

from __future__ import annotations

import ipaddress
import socket

import pytest

from mlink_sim.aio.transport import sockfilter
from mlink_sim.aio.transport.sockfilter import Source, program, refuse_others, socket_drops

pytestmark = pytest.mark.skipif(not sockfilter.supported(), reason="socket filters are Linux's")


def _net(text: str) -> ipaddress.IPv4Network | ipaddress.IPv6Network:
    return ipaddress.ip_network(text)


def _receiver(host: str = "127.0.0.1") -> socket.socket:
    sock = socket.socket(socket.AF_INET6 if ":" in host else socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind((host, 0))
    sock.settimeout(0.2)
    return sock


def _sender(host: str) -> socket.socket:
    sock = socket.socket(socket.AF_INET6 if ":" in host else socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind((host, 0))
    return sock


def _arrived(receiver: socket.socket, senders: list[socket.socket]) -> list[int]:
    """The index of each sender whose datagram *receiver* got (each sends to the loopback of its own family)."""
    port = receiver.getsockname()[1]
    for i, s in enumerate(senders):
        s.sendto(bytes([i]), ("::1" if s.family == socket.AF_INET6 else "127.0.0.1", port))
    got = []
    try:
        while True:
            got.append(receiver.recv(16)[0])
    except TimeoutError:
        pass
    return sorted(got)


def test_a_filter_keeps_a_host_s_every_port_one_port_of_another_and_a_network() -> None:
    senders = [_sender(h) for h in ("127.0.0.2", "127.0.0.2", "127.0.0.3", "127.0.0.3", "127.0.9.1", "127.1.0.1")]
    receiver = _receiver()
    try:
        sources = [Source(_net("127.0.0.2/32")), Source(_net("127.0.0.3/32"), senders[2].getsockname()[1]),
                   Source(_net("127.0.9.0/24"))]
        assert refuse_others(receiver, sources) == "filter"
        assert _arrived(receiver, senders) == [0, 1, 2, 4]
        assert socket_drops(receiver) == 2  # 127.0.0.3 from another port, 127.1.0.1
    finally:
        for s in (receiver, *senders):
            s.close()


def test_no_source_drops_everything_and_a_new_filter_replaces_the_old() -> None:
    senders = [_sender("127.0.0.2"), _sender("127.0.0.3")]
    receiver = _receiver()
    try:
        assert refuse_others(receiver, []) == "filter"
        assert _arrived(receiver, senders) == []
        assert refuse_others(receiver, [Source(_net("127.0.0.3/32"))], connect=False) == "filter"
        assert _arrived(receiver, senders) == [1]
    finally:
        for s in (receiver, *senders):
            s.close()


def test_an_ipv6_socket_filters_ipv6_sources_and_its_ipv4_mapped_ones() -> None:
    if not socket.has_ipv6:
        pytest.skip("no IPv6")
    try:
        receiver = _receiver("::")
    except OSError:
        pytest.skip("no IPv6 on this host")
    senders = [_sender("::1"), _sender("::1"), _sender("127.0.0.2"), _sender("127.0.0.3")]
    try:
        sources = [Source(_net("::1/128"), senders[1].getsockname()[1]), Source(_net("127.0.0.2/32"))]
        assert refuse_others(receiver, sources) == "filter"
        assert _arrived(receiver, senders) == [1, 2]
    finally:
        for s in (receiver, *senders):
            s.close()


def test_an_ipv6_network_compares_the_words_its_prefix_covers() -> None:
    """2001:db8:0:1::/64 and fe80::/10: the mask of each 32-bit word (a prefix of 64 covers two, of 10 part of one)."""
    code = program([Source(_net("2001:db8:0:1::/64")), Source(_net("fe80::/10"))])
    words = [k for op, _, _, k in code if op == 0x15]  # the compared values
    assert 0x20010DB8 in words and 0x00000001 in words and 0xFE800000 in words
    assert (0x54, 0, 0, 0xFFC00000) in code  # /10: the first word masked


def test_one_host_and_port_on_a_socket_bound_to_one_address_is_connected() -> None:
    master, stranger = _sender("127.0.0.1"), _sender("127.0.0.1")
    receiver = _receiver()
    try:
        assert refuse_others(receiver, [Source(_net("127.0.0.1/32"), master.getsockname()[1])]) == "connect"
        assert receiver.getpeername() == master.getsockname()
        assert _arrived(receiver, [master, stranger]) == [0]
        receiver.sendto(b"answer", master.getsockname())  # a connected socket still answers with sendto
        assert master.recv(16) == b"answer"
    finally:
        for s in (receiver, master, stranger):
            s.close()


@pytest.mark.parametrize(("bind", "sources", "connect"), [
    ("0.0.0.0", [Source(_net("127.0.0.1/32"), 4000)], True),  # the wildcard: connecting would pin the address
    ("127.0.0.1", [Source(_net("127.0.0.1/32"))], True),  # any port
    ("127.0.0.1", [Source(_net("127.0.0.0/8"), 4000)], True),  # a network
    ("127.0.0.1", [Source(_net("127.0.0.1/32"), 4000), Source(_net("127.0.0.2/32"), 4000)], True),
    ("127.0.0.1", [Source(_net("::1/128"), 4000)], True),  # another family
    ("127.0.0.1", [Source(_net("127.0.0.1/32"), 4000)], False),  # the caller's choice (a name resolved again)
])
def test_every_other_list_gets_a_filter(bind: str, sources: list[Source], connect: bool) -> None:
    receiver = _receiver(bind)
    try:
        assert refuse_others(receiver, sources, connect=connect) == "filter"
        with pytest.raises(OSError):
            receiver.getpeername()
    finally:
        receiver.close()


def test_a_program_the_kernel_would_refuse_is_a_value_error() -> None:
    many = [Source(ipaddress.ip_network(f"10.{i // 256}.{i % 256}.0/24"), 1000 + i) for i in range(1000)]
    with pytest.raises(ValueError, match="more than the kernel's 4096"):
        program(many)
