"""Recovery without operator action: lost cycles, WDT faults, a station that disappears and returns."""

from __future__ import annotations

import pytest
from master_fakes import MS, FakeSlave

from mlink_sim.master import AlarmRaised, Late, Missing, Recovered, StateChanged, StationPlan, StationState
from mlink_sim.wire import Frame, Kind, Link, decode, encode, ml2, ml3

S = StationState
LINKS = [pytest.param(Link.ML1, 2 * MS, id="ML-I"), pytest.param(Link.ML2, MS, id="ML-II"),
         pytest.param(Link.ML3, MS, id="ML-III")]


def up(net_of, link, tcycle, *plans, **options):
    net = net_of(link, tcycle, *(plans or (StationPlan(0x21, link),)), **options)
    net.run_until(net.core.all_at_target, limit=30)
    net.events.clear()
    return net


def drop_commands(net, station, cycles):
    first, last = net.cycle, net.cycle + cycles
    net.fault = lambda d, st, dg, now: None if d == "cmd" and st == station and first <= net.cycle < last else dg


def of(net, kind):
    return [e for e in net.events if isinstance(e, kind)]


@pytest.mark.parametrize(("link", "tcycle"), LINKS)
def test_lost_cycles_reception_alarm_then_alm_clr_and_sync_set(net_of, link, tcycle):
    """SI-T3 Table 22: a second consecutive reception failure is E6 and the slave drops to phase 2
    (SI-ET3: COMM_ALM 9); the master clears it and restores phase 3 by itself. Two lost commands: one
    communications alarm, below F6-26 = 2, so the connection stays."""
    net = up(net_of, link, tcycle)
    slave = net.slaves[0x21]
    drop_commands(net, 0x21, 2)
    net.run(4)
    assert slave.phase == 2  # the slave noticed
    net.run_until(lambda: net.core.state(0x21) is S.PHASE3 and slave.phase == 3, limit=20)
    raised = of(net, AlarmRaised)
    want = ("COMM_ERROR", "alarm") if link is not Link.ML3 else ("NOT_RECEIVED", "comm")
    assert any((e.name, e.source) == want for e in raised)
    states = [e.new for e in of(net, StateChanged)]
    assert states[:3] == [S.ALARM, S.SYNCING, S.PHASE3]
    rec = of(net, Recovered)
    assert len(rec) == 1 and rec[0].station == 0x21 and rec[0].ns > 0
    assert [n for n, _ in slave.log][-10:].count("AlmClr") == 1
    net.run(50)
    assert slave.phase == 3 and net.core.view(0x21).alarm == 0 and net.core.view(0x21).recoveries == 1


@pytest.mark.parametrize("slave_factory", ["card"], indirect=True)
@pytest.mark.parametrize(("link", "tcycle"), LINKS)
def test_master_gets_its_station_back_after_a_connection_loss_and_a_probe(net_of, link, tcycle):
    """The master's commands are lost until the card declares bUS (F6-26 communications alarms,
    SI-T3 Table 28) and releases the connection; a health-check probe's NOP then binds nothing, and the master's
    next command is answered as from phase 1, so it CONNECTs and owns the station again (docs/cards.md)."""
    net = up(net_of, link, tcycle)
    card = net.slaves[0x21].station
    drop_commands(net, 0x21, 6)
    net.run(6)
    assert card.snapshot().connected_source is None
    probe = ml3.M3Command(ml3.Nop(), sub=ml3.Nop()) if link is Link.ML3 else ml2.M2Command(ml2.Nop(), sub=ml2.Nop())
    size = net.core.plan.station(0x21).data_size
    if link is not Link.ML3 and size == 17 or link is Link.ML3 and size == 32:
        probe = type(probe)(probe.body)
    answer = card.receive(encode(Frame(link, Kind.COMMAND, 0x21, 1, 2 * MS, probe)), ("192.0.2.99", 9), net.cycle * tcycle)
    assert answer is not None and card.snapshot().connected_source is None
    net.run_until(lambda: net.core.state(0x21) is S.PHASE3 and card.phase == 3, limit=60)
    assert card.snapshot().connected_source == "master" and card.counters.status_queries == 1
    served = card.counters.rx_ok
    net.run(50)
    assert card.counters.rx_ok == served + 50 and net.core.state(0x21) is S.PHASE3


def test_lost_responses_only_are_missing_but_not_fatal(net_of):
    net = up(net_of, Link.ML2, MS)
    first = net.cycle
    net.fault = lambda d, st, dg, now: None if d == "rsp" and first <= net.cycle < first + 3 else dg
    net.run(10)
    assert len(of(net, Missing)) == 3
    assert net.core.state(0x21) is S.PHASE3 and not of(net, StateChanged)


def test_late_response_is_missing_then_late(net_of):
    net = up(net_of, Link.ML2, MS)
    when = net.cycle
    net.fault = lambda d, st, dg, now: (dg, int(1.5 * MS)) if d == "rsp" and net.cycle == when else dg
    net.run(4)
    (missing,) = of(net, Missing)
    (late,) = of(net, Late)
    assert late.cycle == missing.cycle == when and late.ns > MS
    assert net.core.view(0x21).late == 1 and net.core.state(0x21) is S.PHASE3


@pytest.mark.parametrize(("link", "tcycle"), LINKS)
def test_wdt_fault_e5_is_recovered(net_of, link, tcycle):
    """A command whose WDT count jumps: E5 (SI-T3 Table 23) / COMM_ALM C, phase 3 -> 2; master recovers."""
    net = up(net_of, link, tcycle)
    when = net.cycle

    def bad_wdt(d, st, dg, now):
        if d != "cmd" or net.cycle != when:
            return dg
        f = decode(dg)
        m = f.message
        msg = (ml3.M3Command(m.body, m.wdt ^ 0x50, m.cmd_ctrl, m.sub, m.sub_ctrl) if link is Link.ML3
               else ml2.M2Command(m.body, m.wdt ^ 0x50, m.sub))
        return encode(Frame(f.link, f.kind, f.station, f.cycle, f.tcycle_ns, msg))

    net.fault = bad_wdt
    net.run_until(lambda: of(net, Recovered), limit=20)
    assert net.slaves[0x21].e5 == 1
    # M2Alarm E5H / CommAlm CH, or on the SI-T3 the drive fault E5 (39H, Table 26) that hides E5H (Table 21)
    assert of(net, AlarmRaised)[0].name in ("WDT_ERROR", "E5")
    net.run(30)
    assert net.core.state(0x21) is S.PHASE3 and net.slaves[0x21].phase == 3 and net.slaves[0x21].e5 == 1


@pytest.mark.parametrize(("link", "tcycle"), LINKS)
def test_station_disappears_and_returns_as_a_new_card(net_of, link, tcycle):
    net = up(net_of, link, tcycle, StationPlan(0x21, link), StationPlan(0x22, link))
    net.cut.add(0x22)
    net.run(12)
    assert net.core.state(0x22) is S.OFFLINE
    assert net.core.state(0x21) is S.PHASE3  # the other station is not disturbed
    net.slaves[0x22] = net.make_slave(0x22)  # power cycled: phase 1
    net.cut.clear()
    net.run_until(lambda: net.core.state(0x22) is S.PHASE3, limit=20)
    assert net.slaves[0x22].phase == 3
    assert [n for n, _ in net.slaves[0x22].log][:3] == ["Nop", "Connect", "SyncSet"]
    (rec,) = of(net, Recovered)
    assert rec.station == 0x22 and rec.reason == "silent"
    net.run(30)
    assert net.slaves[0x22].e5 == 0 and net.slaves[0x22].phase == 3
    assert net.slaves[0x21].failures == 0


@pytest.mark.parametrize(("link", "tcycle"), LINKS)
def test_quick_restart_detected_from_phase_error(net_of, link, tcycle):
    """A slave that restarts within a cycle answers INV_CTL with A.95 (SI-T3 "INV_CTL": not in phase 2 or 3) or
    CMD_ALM CH (SI-ET3 Table 9): the master reconnects it."""
    net = up(net_of, link, tcycle)
    net.slaves[0x21] = net.make_slave(0x21)
    net.run_until(lambda: net.core.state(0x21) is S.PHASE3 and net.slaves[0x21].phase == 3, limit=20)
    assert [e.new for e in of(net, StateChanged)][:2] == [S.PHASE1, S.CONNECTING]
    assert of(net, Recovered)[0].reason == "phase 1"


def test_long_outage_slave_kept_its_connection(net_of):
    """Offline, then back while the slave is still in phase 2 with E6 latched: CONNECT is ignored (no alarm),
    SYNC_SET shows E6, ALM_CLR + SYNC_SET restore phase 3."""
    net = up(net_of, Link.ML2, MS)
    net.cut.add(0x21)
    net.run(12)
    assert net.core.state(0x21) is S.OFFLINE and net.slaves[0x21].phase == 2
    net.cut.clear()
    net.run_until(lambda: net.core.state(0x21) is S.PHASE3 and net.slaves[0x21].phase == 3, limit=30)
    assert len(of(net, Recovered)) == 1


class _StickyAlarm(FakeSlave):
    """ALM_CLR does not clear E6 (a fault the card cannot clear); only DISCONNECT does."""

    def _main(self, name, msg):
        if name == "AlmClr":
            return msg.body, True, 0
        return super()._main(name, msg)


@pytest.mark.parametrize("slave_factory", ["fake"], indirect=True)
def test_alarm_that_alm_clr_cannot_clear_escalates_to_disconnect_connect(net_of):
    net = up(net_of, Link.ML2, MS, clear_attempts=2)
    sticky = _StickyAlarm(Link.ML2, 0x21, 32)
    sticky.__dict__.update({k: v for k, v in net.slaves[0x21].__dict__.items()})
    net.slaves[0x21] = sticky
    drop_commands(net, 0x21, 3)
    net.run_until(lambda: of(net, Recovered), limit=60)
    names = [n for n, _ in sticky.log]
    assert names.count("AlmClr") == 2
    assert "Disconnect" in names and names[names.index("Disconnect") + 1] == "Connect"
    assert net.core.state(0x21) is S.PHASE3 and sticky.phase == 3


def test_connect_refused_backs_off_and_reports(net_of):
    """ML-II COM_TIM 2 on an SI-T3 is A.94 (errata (1)): the master waits and retries, and says why."""
    net = net_of(Link.ML2, MS, StationPlan(0x21, Link.ML2, com_tim=2), connect_backoff=5)
    net.run(25)
    view = net.core.view(0x21)
    assert view.state in (S.PHASE1, S.CONNECTING) and not view.at_target
    # A.94, or on the SI-T3 the CyC minor fault (33H) that hides it (Table 27 / Table 21)
    assert "DATA_SETTING_WARNING" in view.last_error or "CYC" in view.last_error
    connects = [n for n, _ in net.slaves[0x21].log].count("Connect")
    assert 2 <= connects <= 4  # one try per back-off period, not one per cycle


def test_bad_fcs_command_is_only_a_warning_on_ml3(net_of):
    # 500 us: one lost command ends well inside the slave's silence tolerance (max(cycle / 2, 1 ms))
    net = up(net_of, Link.ML3, 500_000)
    when = net.cycle
    net.fault = lambda d, st, dg, now: dg[:-1] + bytes([dg[-1] ^ 1]) if d == "cmd" and net.cycle == when else dg
    net.run(10)
    assert [(e.name, e.source) for e in of(net, AlarmRaised)] == [("FCS_WARNING", "comm")]
    assert net.core.state(0x21) is S.PHASE3 and not of(net, StateChanged)


def test_si_t3_table_21_request_answered_under_a_comm_alarm_is_asked_again(net_of):
    """E6 (an alarm) hides the A.94 of a bad PRM_RD; the master does not take that answer as success but asks
    again once it has cleared the alarm, and then gets the A.94."""
    from mlink_sim.master import StationAlarmError

    net = up(net_of, Link.ML2, MS)
    drop_commands(net, 0x21, 3)
    net.run(3)
    req = net.core.request(0x21, ml2.PrmRd(0x7777, 2))
    net.run_until(lambda: req.done, limit=30)
    assert isinstance(req.error, StationAlarmError) and req.error.code == 0x94
    assert req.attempts >= 2 and of(net, Recovered)
