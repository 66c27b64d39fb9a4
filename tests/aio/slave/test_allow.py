"""The allow list of ``mlink-sim slave --allow-master`` (HOST, HOST:PORT, CIDR) and the control endpoints' token."""

from __future__ import annotations

import ipaddress

import pytest

from mlink_sim.aio.slave.allow import AllowList, parse_rule
from mlink_sim.aio.transport.sockfilter import Source
from mlink_sim.aio.control.token import ControlToken, is_loopback


def test_host_allows_every_port_host_port_one_cidr_a_network() -> None:
    allow = AllowList(["192.0.2.1", "192.0.2.2:5000", "10.1.0.0/16", "[2001:db8::1]:7"])
    assert allow.allows(("192.0.2.1", 1)) and allow.allows(("192.0.2.1", 65535))
    assert allow.allows(("192.0.2.2", 5000)) and not allow.allows(("192.0.2.2", 5001))
    assert allow.allows(("10.1.200.3", 9)) and not allow.allows(("10.2.0.1", 9))
    assert allow.allows(("2001:db8::1", 7, 0, 0)) and not allow.allows(("2001:db8::1", 8, 0, 0))
    assert allow.allows(("::ffff:192.0.2.1", 3, 0, 0))  # a dual-stack socket's view of an IPv4 source
    assert not allow.allows(("192.0.2.3", 5000)) and not allow.allows("not an address")


def test_screen_splits_a_read_and_keeps_the_batch_when_every_source_is_allowed() -> None:
    allow = AllowList(["127.0.0.1:4000"])
    batch = [(b"a", ("127.0.0.1", 4000)), (b"b", ("127.0.0.1", 4000))]
    kept, others = allow.screen(batch)
    assert kept is batch and others == []
    mixed = [(b"a", ("127.0.0.1", 4000)), (b"x", ("127.0.0.1", 4001)), (b"b", ("127.0.0.1", 4000))]
    assert allow.screen(mixed) == ([mixed[0], mixed[2]], [mixed[1]])


def test_the_kernel_is_given_every_source_of_both_lists() -> None:
    """``AllowList.sources``: the rules that may change a station and the status sources, as the kernel's filter
    takes them (a host as a /32 with each of its ports, or any); a status source changes nothing."""
    allow = AllowList(["192.0.2.2:5000", "192.0.2.2:5001", "10.1.0.0/16"], status=["127.0.0.1", "192.0.2.2:5000"])
    assert allow.sources() == [Source(ipaddress.ip_network("192.0.2.2/32"), 5000),
                               Source(ipaddress.ip_network("192.0.2.2/32"), 5001),
                               Source(ipaddress.ip_network("10.1.0.0/16")), Source(ipaddress.ip_network("127.0.0.1/32"))]
    assert not allow.allows(("127.0.0.1", 4000)) and not allow.named


def test_a_status_source_s_host_name_is_resolved_too() -> None:
    allow = AllowList(["192.0.2.1"], status=["localhost"])
    assert allow.named and allow.stale
    allow.resolve()
    assert Source(ipaddress.ip_network("127.0.0.1/32")) in allow.sources()
    assert not allow.allows(("127.0.0.1", 4000)) and allow.unresolved == []


def test_a_host_name_allows_its_addresses_once_resolved() -> None:
    allow = AllowList(["localhost:4000"])
    assert allow.stale and not allow.allows(("127.0.0.1", 4000))  # not resolved yet: nothing
    allow.resolve()
    assert not allow.stale and allow.allows(("127.0.0.1", 4000)) and not allow.allows(("127.0.0.1", 4001))


@pytest.mark.parametrize("bad", ["", "host:0", "host:99999", "host:x", "10.0.0.0/33", "[::1", "[::1]x"])
def test_bad_rules_are_one_line_errors(bad: str) -> None:
    with pytest.raises(ValueError) as err:
        parse_rule(bad)
    assert "\n" not in str(err.value)


def test_the_token_is_checked_on_every_request_and_refusals_are_counted() -> None:
    token = ControlToken("t0k")
    assert token.admits({"op": "stats", "token": "t0k"})
    assert not token.admits({"op": "stats"}) and not token.admits({"op": "stats", "token": "t0"})
    assert not token.admits(None) and not token.admits({"token": 7})
    assert token.refused == 4
    assert ControlToken().admits(None)  # no token: every request


@pytest.mark.parametrize(("host", "loopback"), [("127.0.0.1", True), ("127.3.0.1", True), ("::1", True),
                                                ("localhost", True), ("0.0.0.0", False), ("::", False),
                                                ("192.0.2.1", False), ("example.org", False)])
def test_loopback_hosts(host: str, loopback: bool) -> None:
    assert is_loopback(host) is loopback
