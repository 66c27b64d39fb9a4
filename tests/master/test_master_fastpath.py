"""The master's steady-state INV_CTL fast path (mlink_sim.master.fastpath) sends the same bytes and reaches the same
views and events as the general path, over bring-up, control changes, requests, drive faults and a lossy,
corrupting, delaying network (the cyclic INV_CTL of SI-T3 Table 16 / SI-ET3 Table 21)."""

from __future__ import annotations

import zlib
from collections.abc import Callable
from typing import Any

import pytest
from master_fakes import MS, Net

from mlink_sim import _accel
from mlink_sim.master import StationPlan
from mlink_sim.master.fastpath import CyclicFrames
from mlink_sim.wire import Link, ml2, ml3

CASES = [(Link.ML2, 17), (Link.ML2, 32), (Link.ML3, 32), (Link.ML3, 64)]
IDS = ["ML-II-17B", "ML-II-32B", "ML-III-32B", "ML-III-64B"]
#: Whether the fast path's hits can be counted: a compiled (mypyc) core takes no wrapper object in place of its
#: CyclicFrames, so the count runs on the pure-Python cores (CI's MLINK_PURE=1 pass; tests/test_accel.py pins the
#: compiled cores to them byte for byte). Everything else here runs on both.
COUNTED = _accel.MODE != "compiled"


class _Counting:
    """Wraps a station's CyclicFrames and counts the responses it took."""

    def __init__(self, inner: CyclicFrames) -> None:
        self.inner = inner
        self.hits = 0

    def command(self, *a: Any) -> bytes:
        return self.inner.command(*a)

    def response(self, *a: Any) -> Any:
        r = self.inner.response(*a)
        self.hits += r >= 0
        return r

    @property
    def last(self) -> Any:
        return self.inner.last


def _lossy(direction: str, station: int, datagram: bytes, now: int) -> Any:
    """Deterministic per datagram (same bytes, same fate): ~3 % dropped, ~2 % corrupted, ~2 % a cycle late."""
    h = zlib.crc32(datagram) % 100
    if h < 3:
        return None
    if h < 5:
        return datagram[:20] + bytes([datagram[20] ^ 0x10]) + datagram[21:]
    if h < 7 and direction == "rsp":
        return datagram, 1_200_000
    return datagram


def _pair(net_of: Callable[..., Net], link: Link, size: int) -> tuple[Net, Net, list[bytes], list[bytes]]:
    stations = [StationPlan(a, link, data_size=size) for a in ((0x21, 0x22) if link is not Link.ML3 else (3, 4))]
    nets, sent = [], []
    for fast in (True, False):
        net = net_of(link, MS, *stations)
        net.core.fast_path = fast
        log: list[bytes] = []

        def fault(direction: str, station: int, dg: bytes, now: int, log: list[bytes] = log) -> Any:
            if direction == "cmd":
                log.append(dg)
            return _lossy(direction, station, dg, now) if now > 300 * MS else dg

        net.fault = fault
        nets.append(net)
        sent.append(log)
    if COUNTED:
        for st in nets[0].core._stations:
            st.frames = _Counting(st.frames)  # type: ignore[assignment]
    return nets[0], nets[1], sent[0], sent[1]


def _both(fast: Net, slow: Net, step: Callable[[Net], Any]) -> None:
    for net in (fast, slow):
        step(net)


@pytest.mark.parametrize("link, size", CASES, ids=IDS)
def test_fast_path_matches_general_path_table16_table21(net_of: Callable[..., Net], link: Link, size: int) -> None:
    fast, slow, fast_sent, slow_sent = _pair(net_of, link, size)
    first = fast.core.addresses[0]
    mod = ml3 if link is Link.ML3 else ml2
    _both(fast, slow, lambda n: n.run(200))
    assert all(v.state.value == "phase3" for v in fast.core.views().values())
    _both(fast, slow, lambda n: n.core.set_control(first, forward=True, speed_ref=3000))
    _both(fast, slow, lambda n: n.run(150))
    reqs = [n.core.request(first, mod.PrmRd(0x0200, 2), now=n.cycle * MS) for n in (fast, slow)]
    _both(fast, slow, lambda n: n.run(50))
    _both(fast, slow, lambda n: n.core.set_control(first, forward=True, speed_ref=6000, ef0=True))  # drive fault
    _both(fast, slow, lambda n: n.run(100))
    _both(fast, slow, lambda n: n.core.set_control(first, forward=False, speed_ref=0))
    _both(fast, slow, lambda n: n.run(300))

    assert fast.events == slow.events
    assert fast.core.views() == slow.core.views()
    assert dict(fast.core.drops) == dict(slow.core.drops)
    assert [r.done for r in reqs] == [True, True] and reqs[0].result == reqs[1].result
    assert fast_sent == slow_sent
    if COUNTED:
        hits = sum(st.frames.hits for st in fast.core._stations)
        assert hits > 0.5 * sum(st.responses for st in fast.core._stations)  # the fast path carried the steady state



@pytest.mark.parametrize("link, size", CASES, ids=IDS)
def test_late_answers_to_the_cyclic_inv_ctl_take_the_fast_path_too(net_of: Callable[..., Net], link: Link,
                                                                   size: int) -> None:
    """Every response one and a half cycles late (RTT beyond the cycle, as on an overloaded host): each INV_CTL
    answer arrives after the next slot and is a Late answer to the command counted missing. The fast path takes
    those too, with the same events, views and drops as the general path; the station stays in phase 3."""
    fast, slow, fast_sent, slow_sent = _pair(net_of, link, size)
    _both(fast, slow, lambda n: n.run(200))
    first = fast.core.addresses[0]
    _both(fast, slow, lambda n: n.core.set_control(first, forward=True, speed_ref=3000))

    def late(direction: str, station: int, dg: bytes, now: int) -> Any:
        return (dg, MS + MS // 2) if direction == "rsp" else dg

    for n in (fast, slow):
        n.fault = late
    hits0 = sum(st.frames.hits for st in fast.core._stations) if COUNTED else 0
    late0 = sum(v.late for v in fast.core.views().values())
    _both(fast, slow, lambda n: n.run(200))

    assert fast.events == slow.events
    assert fast.core.views() == slow.core.views()
    assert dict(fast.core.drops) == dict(slow.core.drops)
    assert fast_sent == slow_sent
    views = fast.core.views().values()
    assert all(v.state.value == "phase3" for v in views)
    late_answers = sum(v.late for v in views) - late0
    assert late_answers >= 2 * 190  # nearly every answer of the 200 cycles, both stations
    if COUNTED:
        assert sum(st.frames.hits for st in fast.core._stations) - hits0 >= late_answers
