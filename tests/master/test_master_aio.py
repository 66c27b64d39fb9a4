"""mlink_sim.aio.master.runner.Master over real UDP on 127.0.0.1 (port 0) against in-test responders built from a slave
core. Bounded in time; no fixed ports."""

from __future__ import annotations

import asyncio
import socket
import time

import pytest
from master_fakes import MS, CardSlave

from mlink_sim.aio.master.runner import Master
from mlink_sim.master import NetworkPlan, StationAlarmError, StationPlan, StationState
from mlink_sim.wire import Link

TCYCLE = 4 * MS  # generous: master, timer and responders share one event loop (and the CI machine)


class Responder(asyncio.DatagramProtocol):
    """A UDP slave: every datagram goes through the slave core, the answer goes back to its sender."""

    def __init__(self, slave: CardSlave) -> None:
        self.slave = slave
        self.transport: asyncio.DatagramTransport | None = None

    def connection_made(self, transport) -> None:
        self.transport = transport

    def datagram_received(self, data: bytes, addr) -> None:
        now = time.monotonic_ns()
        resp = self.slave.receive(data, addr, now)
        self.slave.poll(now)
        if resp is not None:
            self.transport.sendto(resp, addr)


async def responder(link: Link, address: int, data_size: int) -> tuple[Responder, asyncio.DatagramTransport]:
    slave = CardSlave(link, address, data_size)  # SI-T3 / SI-ET3 card core
    loop = asyncio.get_running_loop()
    transport, proto = await loop.create_datagram_endpoint(lambda: Responder(slave), local_addr=("127.0.0.1", 0))
    return proto, transport


class Recorder:
    def __init__(self) -> None:
        self.sent = self.rtt = self.late = self.missing = self.cycles = 0

    def record_sent(self, station): self.sent += 1
    def record_rtt(self, station, ns): self.rtt += 1
    def record_late(self, station): self.late += 1
    def record_missing(self, station): self.missing += 1
    def record_cycle_lateness(self, ns, skipped=0): self.cycles += 1


async def loopback_scenario(link: Link, batched: bool = True) -> None:
    plan = NetworkPlan(link, TCYCLE, (StationPlan(0x21, link), StationPlan(0x22, link, sync=False)),
                       request_timeout_ns=5_000_000_000, request_retries=20)
    r1, t1 = await responder(link, 0x21, plan.station(0x21).data_size)
    r2, t2 = await responder(link, 0x22, plan.station(0x22).data_size)
    metrics = Recorder()
    master = await Master.start(plan, {0x21: t1.get_extra_info("sockname"), 0x22: t2.get_extra_info("sockname")},
                                metrics=metrics, batched=batched)
    try:
        await master.bring_up(timeout=5)  # 21H in phase 3, 22H in phase 2 (sync=False)
        assert await master.prm_rd(0x21, 0x0200) == 100
        await master.prm_wr(0x21, 0x0200, 321)
        assert await master.prm_rd(0x21, 0x0200) == 321
        assert await master.prm_rd(0x21, 0x0180, size=4) == bytes([1, 0, 1, 0])  # b1-01, b1-02 defaults
        with pytest.raises(StationAlarmError) as err:
            await master.prm_rd(0x21, 0x7777)
        assert err.value.code == (0x94 if link is Link.ML2 else 9)
        await master.config(0x21, 1)
        if link is Link.ML2:
            assert await master.id_rd(0x21, 0x00, 0, 4) == b"CIMR"  # SI-T3 Table 10
        else:
            assert await master.id_rd(0x21, 0x10, 0, 2) == b"\x20\x00"  # SI-ET3 Table 14
        alarms = await master.alm_rd(0x21, 0)
        assert alarms.alm_rd_mod == 0
        await master.alm_clr(0x21)
        master.set_control(0x21, forward=True, speed_ref=1234)
        await master.wait_until(lambda: master.view(0x21).status != 0, timeout=2)
    finally:
        await master.close(timeout=3)
    assert r1.slave.phase == 1 and r2.slave.phase == 1  # close() disconnected both
    assert metrics.sent > 0 and metrics.rtt > 0 and metrics.cycles > 0
    assert not master.timer.running
    t1.close()
    t2.close()


@pytest.mark.parametrize("link", [Link.ML2, Link.ML3], ids=["ML-II", "ML-III"])
async def test_master_over_udp_loopback(link):
    await asyncio.wait_for(loopback_scenario(link), timeout=20)


def test_master_over_udp_loopback_on_uvloop():
    uvloop = pytest.importorskip("uvloop")

    async def bounded():
        await asyncio.wait_for(loopback_scenario(Link.ML3), timeout=20)

    uvloop.run(bounded())


async def test_absent_slave_is_counted_not_fatal():
    """Nothing listens on the endpoint: ICMP port unreachable may surface as ConnectionRefusedError; the master
    keeps cycling, the station stays OFFLINE, a request times out and close() returns."""

    async def scenario():
        s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        s.bind(("127.0.0.1", 0))
        dead = s.getsockname()
        s.close()
        plan = NetworkPlan(Link.ML2, TCYCLE, (StationPlan(0x21, Link.ML2),))
        master = await Master.start(plan, {0x21: dead})
        try:
            with pytest.raises(TimeoutError, match="bring-up not complete"):
                await master.bring_up(timeout=0.1)
            with pytest.raises(TimeoutError):
                await master.prm_rd(0x21, 0x0200, timeout=0.05)
            assert master.view(0x21).state is StationState.OFFLINE
            assert master.timer.running and master.view(0x21).sent > 10
        finally:
            await master.close()

    await asyncio.wait_for(scenario(), timeout=10)


async def test_start_requires_an_endpoint_per_station():
    plan = NetworkPlan(Link.ML2, TCYCLE, (StationPlan(0x21, Link.ML2),))
    with pytest.raises(ValueError, match="no UDP endpoint for station"):
        await Master.start(plan, {})


async def test_events_feed_network_metrics_with_its_counting_rules():
    """mlink_sim.metrics: late ⊆ answered, missing = never answered. A response that comes after the station's
    next slot (Missing, then Late) counts as answered and late, not missing."""
    from mlink_sim.master import Late, MasterCore, Missing, Rtt
    from mlink_sim.metrics import NetworkMetrics

    plan = NetworkPlan(Link.ML2, TCYCLE, (StationPlan(0x21, Link.ML2),))
    metrics = NetworkMetrics(cycle_ns=TCYCLE)
    master = Master(MasterCore(plan), {0x21: ("127.0.0.1", 9)}, metrics, asyncio.get_running_loop())
    core = master.core
    core.events.extend([Rtt(0x21, 100_000), Missing(0x21, 5), Late(0x21, 5, 2_500_000), Missing(0x21, 7),
                        Missing(0x21, 8)])
    master._pump()
    sm = metrics.station(0x21)
    assert (sm.answered, sm.late, sm.missing) == (2, 1, 1)  # cycle 7 given up; cycle 8 may still be answered
    core.events.append(Late(0x21, 7, 9_000_000))  # too late: cycle 7 already counted missing
    master._pump()
    assert (sm.answered, sm.late, sm.missing) == (2, 1, 1)
    await master.close()
    assert sm.missing == 2  # cycle 8 never answered


@pytest.mark.parametrize("batched", [True, False], ids=["sendmmsg", "sendto"])
async def test_master_over_loopback_with_and_without_batched_calls(batched):
    """The transport with and without sendmmsg/recvmmsg (mlink_sim.aio.transport.mmsg): the same scenario passes either way;
    the socket is a BurstSocket exactly where the calls are supported and asked for (``batched``)."""
    from mlink_sim.aio.transport import mmsg

    if batched and mmsg._calls is None:
        pytest.skip("sendmmsg/recvmmsg not available here")
    plan = NetworkPlan(Link.ML3, TCYCLE, (StationPlan(0x03, Link.ML3),))
    master = await Master.start(plan, {0x03: ("127.0.0.1", 9)}, batched=batched)
    try:
        assert isinstance(master._sock, mmsg.BurstSocket) is batched
        assert asyncio.get_running_loop().remove_reader(master._sock.fileno())  # every answer wakes the reader
    finally:
        await master.close(timeout=0.01)
    await asyncio.wait_for(loopback_scenario(Link.ML3, batched), timeout=20)
