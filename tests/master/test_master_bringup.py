"""Bring-up, scheduling and WDT of the master core against slaves in memory, on explicit time."""

from __future__ import annotations

import pytest
from master_fakes import GENERATION_CASES, GENERATION_IDS, MS

from mlink_sim.master import (
    AlarmRaised,
    MasterCore,
    Missing,
    NetworkPlan,
    StateChanged,
    StationPlan,
    StationState,
)
from mlink_sim.wire import Kind, Link, M2ComMod, M3ComMod, decode, ml2, ml3

S = StationState


def commands(net, station):
    """Names of the main commands the slave received, in order."""
    return [name for name, _ in net.slaves[station].log]


@pytest.mark.parametrize(("link", "tcycle", "com_tim"), GENERATION_CASES, ids=GENERATION_IDS)
def test_bring_up_to_phase3_connect_then_sync_set(net_of, link, tcycle, com_tim):
    net = net_of(link, tcycle, StationPlan(0x21, link, com_tim=com_tim))
    n = net.run_until(net.core.all_at_target, limit=50)
    assert n <= 5
    view = net.core.view(0x21)
    assert view.state is S.PHASE3 and view.phase == 3 and view.at_target
    assert net.slaves[0x21].phase == 3
    assert commands(net, 0x21)[:3] == ["Nop", "Connect", "SyncSet"]
    states = [e.new for e in net.events if isinstance(e, StateChanged)]
    assert states == [S.PHASE1, S.CONNECTING, S.PHASE2, S.SYNCING, S.PHASE3]


@pytest.mark.parametrize(("link", "tcycle", "com_tim"), GENERATION_CASES, ids=GENERATION_IDS)
def test_connect_carries_ver_com_mod_com_tim_and_profile(link, tcycle, com_tim):
    core = MasterCore(NetworkPlan(link, tcycle, (StationPlan(0x21, link, com_tim=com_tim),)))
    core.on_cycle(0, 0)  # NOP probe
    core._by_addr[0x21].state = S.PHASE1  # as if it had answered
    (_, datagram), = core.on_cycle(1, tcycle)
    frame = decode(datagram, kind=Kind.COMMAND)
    body = frame.message.body
    assert body.ver == {Link.ML1: 0x10, Link.ML2: 0x21, Link.ML3: 0x30}[link]
    assert body.com_tim == com_tim
    if link is Link.ML3:
        assert body.profile_type == 0x20
        assert body.com_mod & M3ComMod.SYNCMODE  # default: 1 = synchronous, as the cards read it (docs/cards.md)
    else:
        assert body.com_mod & M2ComMod.SYNCMOD  # SI-T3 "CONNECT": 1 = move to phase 3


def test_si_et3_table_19_syncmode_convention_is_per_station():
    table19 = StationPlan(0x21, Link.ML3, sync=True, et3_syncmode_table19=True)
    ml2_style = StationPlan(0x22, Link.ML3, sync=True)  # the default, as CardOptions
    asynchronous = StationPlan(0x23, Link.ML3, sync=False, et3_syncmode_table19=True)
    assert table19.com_mod & M3ComMod.SYNCMODE == 0
    assert ml2_style.com_mod & M3ComMod.SYNCMODE
    assert asynchronous.com_mod & M3ComMod.SYNCMODE
    assert StationPlan(0x24, Link.ML3, sync=False).com_mod & M3ComMod.SYNCMODE == 0


def test_si_et3_slave_reading_syncmode_the_other_way_still_reaches_phase3(net_of, slave_factory):
    """CONNECT asks for phase 3 by the Table 19 reading; a slave reading the bit the ML-II way lands in phase 2 and
    the master's SYNC_SET brings it to phase 3 anyway."""
    net = net_of(Link.ML3, MS, StationPlan(0x21, Link.ML3, et3_syncmode_table19=True))
    net.slaves[0x21] = slave_factory(MS)(Link.ML3, 0x21, 64, et3_table19=False)
    net.run_until(net.core.all_at_target, limit=20)
    assert net.slaves[0x21].phase == 3


def test_async_station_stops_in_phase2(net_of):
    net = net_of(Link.ML2, MS, StationPlan(0x21, Link.ML2, sync=False))
    net.run_until(net.core.all_at_target, limit=20)
    net.run(10)
    assert net.core.state(0x21) is S.PHASE2
    assert "SyncSet" not in commands(net, 0x21)
    assert net.slaves[0x21].phase == 2


@pytest.mark.parametrize(("link", "tcycle", "com_tim"), GENERATION_CASES, ids=GENERATION_IDS)
def test_wdt_progression_100_cycles_without_e5(net_of, link, tcycle, com_tim):
    net = net_of(link, tcycle, StationPlan(0x21, link, com_tim=com_tim))
    net.run_until(net.core.all_at_target, limit=20)
    net.events.clear()  # (ML-III: the phase-1 NOP probe is answered with CMD_ALM CH, SI-ET3 Table 9)
    wdts = []
    net.fault = lambda d, st, dg, now: (wdts.append(decode(dg).message.wdt) if d == "cmd" else None) or dg
    net.run(100)
    slave = net.slaves[0x21]
    assert slave.e5 == 0 and slave.phase == 3
    counts = [w >> 4 for w in wdts]
    assert all((b - a) % 16 == 1 for a, b in zip(counts, counts[1:]))  # bits 4-7: +1 per communication cycle
    assert len(set(counts)) == 16
    assert not [e for e in net.events if isinstance(e, (Missing, AlarmRaised))]
    assert net.core.view(0x21).state is S.PHASE3


def test_wdt_low_nibble_echoes_slave_rwdt():
    plan = NetworkPlan(Link.ML2, MS, (StationPlan(0x21, Link.ML2, data_size=17),))
    core = MasterCore(plan)
    (_, dg), = core.on_cycle(0, 0)
    cmd = decode(dg)
    from mlink_sim.wire import Frame, encode

    rsp = encode(Frame(Link.ML2, Kind.RESPONSE, 0x21, cmd.cycle, MS, ml2.M2Response(ml2.Nop(), rwdt=0x0B)))
    core.on_response(rsp, 50_000)
    (_, dg), = core.on_cycle(1, MS)
    assert decode(dg).message.wdt & 0x0F == 0x0B
    assert decode(dg).message.wdt >> 4 == 1


def test_com_tim_2_serves_each_station_every_second_cycle_spread(net_of):
    plans = [StationPlan(a, Link.ML3, com_tim=2) for a in (0x03, 0x04, 0x05)] + [StationPlan(0x06, Link.ML3)]
    net = net_of(Link.ML3, 500_000, *plans)
    per_cycle = [[st for st, _ in net.core.on_cycle(k, k * 500_000)] for k in range(6)]
    assert per_cycle == [[0x03, 0x05, 0x06], [0x04, 0x06]] * 3


def test_com_tim_2_not_spread():
    plans = tuple(StationPlan(a, Link.ML3, com_tim=2) for a in (0x03, 0x04))
    core = MasterCore(NetworkPlan(Link.ML3, 500_000, plans, spread=False))
    assert [[st for st, _ in core.on_cycle(k, k * 500_000)] for k in range(4)] == [[3, 4], [], [3, 4], []]


def test_com_tim_2_bring_up_and_wdt_counts_communication_cycles(net_of):
    net = net_of(Link.ML3, 500_000, StationPlan(0x03, Link.ML3, com_tim=2), StationPlan(0x04, Link.ML3, com_tim=2))
    net.run_until(net.core.all_at_target, limit=40)
    net.run(100)
    assert all(s.phase == 3 and s.e5 == 0 and s.failures == 0 for s in net.slaves.values())


def test_skipped_cycles_keep_wdt_in_step_with_cycle_numbers(net_of):
    """The timer may skip cycles; the WDT count follows the communication cycles elapsed (cards/watchdog.py)."""
    net = net_of(Link.ML3, MS, StationPlan(0x21, Link.ML3, et3_syncmode_table19=True))
    net.run_until(net.core.all_at_target, limit=20)
    net.cycle += 3  # three cycles not started: the slave sees a gap (reception failures) but no WDT error
    net.run(20)
    assert net.slaves[0x21].e5 == 0


def test_the_cycle_never_waits_for_an_absent_station(net_of):
    net = net_of(Link.ML2, MS, StationPlan(0x21, Link.ML2), StationPlan(0x22, Link.ML2))
    del net.slaves[0x22]
    net.run_until(lambda: net.core.at_target(0x21), limit=20)
    net.run(20)
    assert net.core.state(0x22) is S.OFFLINE
    missing = [e for e in net.events if isinstance(e, Missing)]
    assert missing and all(e.station == 0x22 for e in missing)
    sent = net.core.view(0x22).sent
    assert sent == net.cycle  # one command per cycle regardless
    assert net.core.view(0x22).missing == sent - 1


def test_ml2_17_byte_and_32_byte_frames(net_of):
    net = net_of(Link.ML2, MS, StationPlan(0x21, Link.ML2, data_size=17), StationPlan(0x22, Link.ML2, subcmd=True))
    net.run_until(net.core.all_at_target, limit=20)
    sizes = {}
    net.fault = lambda d, st, dg, now: sizes.setdefault(st, len(dg)) and dg or dg
    net.run(1)
    assert sizes == {0x21: 12 + 17 + 2, 0x22: 12 + 32 + 2}


def test_inv_ctl_every_cycle_in_phase3_with_control(net_of):
    net = net_of(Link.ML3, MS, StationPlan(0x21, Link.ML3, et3_syncmode_table19=True))
    net.run_until(net.core.all_at_target, limit=20)
    net.core.set_control(0x21, forward=True, speed_ref=6000)
    net.run(5)
    assert commands(net, 0x21)[-5:] == ["InvCtl"] * 5
    view = net.core.view(0x21)
    assert view.status != 0  # INVCMD_STAT from the INV_CTL response (the drive itself ramps on its own time)


def test_control_encoding_ml2_table_16_and_ml3_table_20():
    from mlink_sim.master.codec import Codec
    from mlink_sim.master.types import Control

    c = Control(forward=True, fault_reset=True, ef0=True, ext_bb=True, multi_inputs=0b100001, speed_ref=100)
    b2 = Codec(StationPlan(0x21, Link.ML2)).inv_ctl(c)
    assert isinstance(b2, ml2.InvCtl) and b2.signals == 0x1 | 0x4 | 0x80 | 0x100 | 0x200 | 0x8000
    b3 = Codec(StationPlan(0x21, Link.ML3)).inv_ctl(c)
    assert isinstance(b3, ml3.InvCtl) and b3.invcmd_ctrl == 0x1 | 0x200 | 0x400 | 0x1000 | 0x10000 | 0x200000
    assert b3.sel_mon == 0x41


def test_the_bring_up_window_paces_connect_and_a_waiting_station_is_sent_nothing(net_of):
    """NetworkPlan.bringup_window (docs/master.md, "Bring-up window"): at most that many stations in CONNECTING
    or SYNCING at once. A station in phase 1 whose CONNECT waits gets no command at all meanwhile (a slave in
    phase 1 has no watchdog and no reception monitor: SI-T3 Table 22, SI-ET3 "Communication Phases"), and every
    station still comes up."""
    plans = [StationPlan(a, Link.ML3) for a in range(0x03, 0x0F)]  # 12 stations
    net = net_of(Link.ML3, MS, *plans, bringup_window=3)
    core = net.core
    connects, waited = [], 0
    for _ in range(200):
        if core.all_at_target():
            break
        before = {a: core.state(a) for a in core.addresses}
        sent = _run_cycle(net)
        names = {station: type(decode(d, kind=Kind.COMMAND).message.body).__name__ for station, d in sent}
        connects.append(sum(name == "Connect" for name in names.values()))
        idle = {a for a, st in before.items() if st is S.PHASE1 and a not in names}
        waited += len(idle)
        assert all(core.state(a) is S.PHASE1 for a in idle)  # held back, not dropped
    assert core.all_at_target()
    assert all(s.phase == 3 for s in net.slaves.values())
    # SI-T3 Table 22, phase 1: no reception failure; a station held there for cycles sees none, and no WDT error
    assert all(s.failures == 0 and s.e5 == 0 for s in net.slaves.values())
    assert max(connects) == 3 and sum(connects) == 12  # three at a time, each station once
    assert waited > 0


def test_a_window_as_large_as_the_line_changes_nothing(net_of):
    plans = [StationPlan(a, Link.ML3) for a in range(0x03, 0x0B)]  # 8 stations, the default window 16
    net = net_of(Link.ML3, MS, *plans)
    assert net.run_until(net.core.all_at_target, limit=50) <= 5  # as one station alone (the test above it)


def test_the_bring_up_window_must_hold_a_station():
    with pytest.raises(ValueError, match="bringup_window"):
        NetworkPlan(Link.ML3, MS, (StationPlan(0x03, Link.ML3),), bringup_window=0)


def _run_cycle(net):
    """One cycle of *net*, returning what the master sent in it, ``[(station, datagram), …]``."""
    sent = []

    def record(direction, station, datagram, now):
        if direction == "cmd":
            sent.append((station, datagram))
        return datagram

    net.fault = record
    try:
        net.run(1)
    finally:
        net.fault = None
    return sent
