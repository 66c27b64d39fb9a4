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
from mlink_sim.wire import Kind, Link, decode, ml2, ml3
from mlink_sim.wire.frame import cycle_of

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


@pytest.mark.parametrize("link, size", CASES, ids=IDS)
def test_an_answer_older_than_one_taken_is_counted_but_shows_nothing(net_of: Callable[..., Net], link: Link,
                                                                     size: int) -> None:
    """Answers that arrive out of order (a worker answers its backlog newest cycle first, docs/cards.md; or the
    network reorders): each even cycle's answer 1.3 ms late, after the next cycle's. Every answer is counted (an RTT
    or a ``Late``), but what a station shows (RWDT, STATUS, output frequency, MON1/MON2) is the newest answer's, never
    an older one that came after it; both paths alike."""
    fast, slow, _, _ = _pair(net_of, link, size)
    _both(fast, slow, lambda n: n.run(200))
    first = fast.core.addresses[0]
    _both(fast, slow, lambda n: n.core.set_control(first, forward=True, speed_ref=6000))
    delivered: dict[int, list[tuple[int, bytes]]] = {}

    def swap(direction: str, station: int, dg: bytes, now: int, net: Net) -> Any:
        if direction != "rsp":
            return dg
        extra = 1_300_000 if cycle_of(dg) % 2 == 0 else 0
        delivered.setdefault(id(net), []).append((now + net.latency + extra, dg))
        return dg, extra

    for n in (fast, slow):
        n.fault = lambda d, st, dg, now, n=n: swap(d, st, dg, now, n)
    responses0 = [v.responses for v in fast.core.views().values()]
    _both(fast, slow, lambda n: n.run(501))

    assert fast.events == slow.events
    assert fast.core.views() == slow.core.views()
    end = fast.cycle * fast.tcycle
    for address, view in fast.core.views().items():
        mine = [(at, dg) for at, dg in delivered[id(fast)] if dg[3] == address and at < end]
        newest = max(mine, key=lambda item: cycle_of(item[1]))[1]
        last = max(mine)[1]  # the last to arrive: an even cycle's, older than the newest
        assert cycle_of(last) < cycle_of(newest)
        answer = decode(newest, kind=Kind.RESPONSE).message
        assert view.rwdt == answer.rwdt != decode(last, kind=Kind.RESPONSE).message.rwdt
        assert (view.output_freq, view.mon1, view.mon2) == (answer.body.output_freq, answer.body.mon1, answer.body.mon2)
        assert view.state.value == "phase3"
    arrived = [sum(1 for at, dg in delivered[id(fast)] if dg[3] == a and at < end) for a in fast.core.addresses]
    assert [v.responses for v in fast.core.views().values()] == [r + n for r, n in zip(responses0, arrived)]



@pytest.mark.parametrize("slave_factory", ["card"], indirect=True)  # the fake slave takes no cycle going back
@pytest.mark.parametrize("link, size", CASES, ids=IDS)
def test_an_older_command_the_slave_took_last_shows_what_it_answered(net_of: Callable[..., Net], link: Link,
                                                                       size: int) -> None:
    """Commands reordered on the way (the impairment ``reorder``): the slave takes cycle k+1, then k. Its answer to
    k is the newer one (its RWDT count one further, cards.watchdog), so the station shows it, and with it the WDT
    fault the reordering caused (SI-T3 Table 24 "WDT count fault in a synchronous frame": ML-II E5H, ML-III COMM_ALM
    CH), on both paths alike; the master then clears it and the station is back in phase 3."""
    fast, slow, _, _ = _pair(net_of, link, size)
    _both(fast, slow, lambda n: n.run(200))
    first = fast.core.addresses[0]
    held = {"n": 0}

    def overtake(direction: str, station: int, dg: bytes, now: int) -> Any:
        if direction == "cmd" and station == first and held["n"] < 2 and cycle_of(dg) % 2 == 0:
            held["n"] += 1
            return dg, MS + MS // 2  # arrives after the next cycle's command
        return dg

    events0 = [len(n.events) for n in (fast, slow)]
    for n in (fast, slow):
        n.fault = overtake
    fast.run(40)
    held["n"] = 0
    slow.run(40)
    for n in (fast, slow):
        n.fault = None
    _both(fast, slow, lambda n: n.run(400))

    assert fast.events == slow.events
    assert fast.core.views() == slow.core.views()
    raised = [e for e in fast.events[events0[0]:] if type(e).__name__ == "AlarmRaised" and e.station == first]
    assert {"WDT_ERROR", "WDT_ERR"} & {e.name for e in raised}, raised
    assert fast.core.view(first).state.value == "phase3"
