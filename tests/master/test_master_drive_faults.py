"""The drive fault behind MECHATROLINK-III D_ALM (mlink_sim.master.drivefault; docs/master.md, "Drive faults on
MECHATROLINK-III"), against the real SI-ET3 core and its drive model.

An SI-ET3 answer carries D_ALM but no code; the master reads U2-01 with ALM_RD ALM_RD_MOD 0 (SI-ET3 Tables 16/17)
for the view. After a connection loss the drive is left in bUS (SI-ET3 §11 Table 26, F6-01 default: coast), which
the recovery's ALM_CLR cannot reset while RUN is on (SI-T3 "ALM_CLR"): the master resets it with DISCONNECT +
CONNECT, as the SI-T3's ALARM byte (bUS 22H) makes it do on MECHATROLINK-II, and runs the drive again. Any other
fault is the operator's.
"""

from __future__ import annotations

import pytest
from master_fakes import MS, Net

from mlink_sim.cards import create_card, settings_for
from mlink_sim.drive import LoadSpec
from mlink_sim.drive.faults import Fault
from mlink_sim.master import (
    AlarmCleared,
    AlarmRaised,
    MasterCore,
    NetworkPlan,
    Recovered,
    RunHeld,
    RunResumed,
    StationPlan,
    StationState,
)
from mlink_sim.master.drivefault import CONNECTION_FAULTS, name_of
from mlink_sim.wire import Link, decode, Kind

S = StationState
BASE = ["b1-01=3", "b1-02=3", "C1-01=1.0", "C1-02=1.0"]  # run and reference from the option: bUS is detected
SEARCH = ["b3-01=1", "b3-24=1"]
BUS, EF0, E5 = 0x22, 0x27, 0x39  # SI-T3 Table 26, the numbering U2-01 gives on the SI-ET3


class Et3:
    """The SI-ET3 core, logging the main commands it receives."""

    def __init__(self, params: list[str]) -> None:
        settings = settings_for("si-et3", 0x21, 64, params, LoadSpec.from_config({"kind": "constant"}))
        self.station = create_card("si-et3", settings=settings, now=0)
        self.log: list[str] = []

    def receive(self, datagram: bytes, source: object, now: int) -> bytes | None:
        self.log.append(type(decode(datagram, kind=Kind.COMMAND).message.body).__name__)
        return self.station.receive(datagram, source, now)

    def poll(self, now: int) -> None:
        self.station.poll(now)


def running(params: list[str], *, speed_search: bool) -> tuple[Net, Et3]:
    card = Et3(params)
    station = StationPlan(0x21, Link.ML3, data_size=64, card="si-et3", speed_search=speed_search)
    net = Net(MasterCore(NetworkPlan(Link.ML3, 2 * MS, (station,))), {0x21: card})
    net.run_until(net.core.all_at_target, limit=50)
    net.core.set_control(0x21, forward=True, speed_ref=3000)  # 30.00 Hz (o1-03 = 0: 0.01 Hz)
    net.run_until(lambda: net.core.view(0x21).output_freq >= 2990, limit=1500)
    net.events.clear()
    card.log.clear()
    return net, card


def lose_the_connection(net: Net, card: Et3) -> None:
    net.cut.add(0x21)  # gone for 60 ms: COMM_ALM, bUS after F6-26 of them, the station released, the drive coasts
    net.run(30)
    net.cut.discard(0x21)
    assert card.station.drive.status.fault is Fault.BUS and card.station.snapshot().connected_source is None


def of(net: Net, kind: type) -> list:
    return [e for e in net.events if isinstance(e, kind)]


@pytest.mark.parametrize("speed_search", [True, False])
def test_bus_left_by_a_connection_loss_is_reset_and_the_drive_runs_again(speed_search):
    net, card = running(BASE + (SEARCH if speed_search else []), speed_search=speed_search)
    lose_the_connection(net, card)
    net.run_until(lambda: of(net, Recovered), limit=500)
    drive = card.station.drive
    # back in phase 3 with the drive reset: CONNECT, SYNC_SET, ALM_CLR (RUN still on: bUS stays), ALM_RD reads
    # U2-01 = bUS, then DISCONNECT (command cleared, fault reset) and CONNECT again
    assert drive.status.fault is None and net.core.state(0x21) is S.PHASE3
    assert ("AlmRd", "Disconnect") == tuple(n for n in card.log if n in ("AlmRd", "Disconnect"))[:2]
    assert [(e.code, e.name, e.source) for e in of(net, AlarmRaised) if e.source == "alarm"] == [(BUS, "BUS", "alarm")]
    assert any(e.source == "alarm" for e in of(net, AlarmCleared))
    assert len(of(net, Recovered)) == 1 and net.core.view(0x21).recoveries == 1
    assert net.core.view(0x21).alarm == 0 and net.core.view(0x21).alarm_name is None
    if speed_search:
        assert [e.reason for e in of(net, RunResumed)] == ["speed search"]
    else:
        assert [e.until for e in of(net, RunHeld)] == ["standstill"]
        net.run_until(lambda: of(net, RunResumed), limit=2_000)
    net.run_until(lambda: net.core.view(0x21).output_freq >= 2990, limit=2_000)
    assert drive.status.fault is None and drive.status.running


def test_d_alm_is_named_from_u2_01_and_cleared_with_the_fault():
    """SI-ET3 Table 20 EF0 from the master: D_ALM, which ALM_RD names (EF0, SI-T3 Table 26 27H); the operator's
    fault reset clears it, and the view with it."""
    net, card = running(BASE, speed_search=False)
    net.core.set_control(0x21, ef0=True)  # EF0, and no run
    net.run_until(lambda: net.core.view(0x21).alarm_name is not None, limit=50)
    view = net.core.view(0x21)
    assert view.fault and (view.alarm, view.alarm_name) == (EF0, "EF0")
    assert [(e.code, e.name) for e in of(net, AlarmRaised) if e.source == "alarm"] == [(EF0, "EF0")]
    assert card.log.count("AlmRd") == 1
    net.core.set_control(0x21, fault_reset=True)
    net.run_until(lambda: not net.core.view(0x21).fault, limit=50)
    assert net.core.view(0x21).alarm == 0 and net.core.view(0x21).alarm_name is None
    assert any(e.source == "alarm" for e in of(net, AlarmCleared))
    assert not of(net, Recovered)  # nothing was lost: no recovery


def test_another_fault_after_a_connection_loss_is_left_to_the_operator():
    """The drive was already in EF0 (its cause still input) when the connection went: the recovery brings the
    station back, names the fault, and does not reset it (it is not bUS / E5)."""
    net, card = running(BASE, speed_search=False)
    net.core.set_control(0x21, ef0=True)
    net.run_until(lambda: net.core.view(0x21).alarm_name == "EF0", limit=50)
    net.events.clear()
    card.log.clear()
    net.cut.add(0x21)
    net.run(30)
    net.cut.discard(0x21)
    net.run_until(lambda: of(net, Recovered), limit=500)
    net.run(50)
    assert "Disconnect" not in card.log
    assert net.core.state(0x21) is S.PHASE3 and card.station.drive.status.fault is Fault.EF0
    assert (net.core.view(0x21).alarm_name, net.core.view(0x21).fault) == ("EF0", True)


def test_e5_left_by_a_frozen_watchdog_is_reset_and_the_drive_runs_again():
    """The master's WDT count frozen for 8 cycles (its bits 4-7, which must advance every cycle): the SI-ET3
    detects a watchdog timer fault in phase 3 and moves to phase 2 ("Phase 3: Synchronous communications"); the
    drive trips E5 (SI-ET3 Table 26 "MECHATROLINK Watchdog Timer Error", F6-25 default 1: coast). The master names it
    from U2-01 (39H, SI-T3 Table 26) and resets it as it does bUS: DISCONNECT + CONNECT, then runs the drive
    again."""
    from mlink_sim.faults import frames

    net, card = running(BASE, speed_search=False)
    net.fault = lambda direction, station, dg, now: frames.set_wdt_count(dg, 3) if direction == "cmd" else dg
    net.run(8)
    net.fault = None
    net.run_until(lambda: of(net, Recovered), limit=500)
    assert (E5, "E5", "alarm") in [(e.code, e.name, e.source) for e in of(net, AlarmRaised)]
    assert "Disconnect" in card.log and card.log.index("AlmRd") < card.log.index("Disconnect")
    assert net.core.state(0x21) is S.PHASE3 and card.station.drive.status.fault is None
    assert len(of(net, Recovered)) == 1 and net.core.view(0x21).alarm_name is None
    net.run_until(lambda: of(net, RunResumed), limit=2_000)  # no speed search: from standstill
    net.run_until(lambda: net.core.view(0x21).output_freq >= 2990, limit=2_000)
    assert card.station.drive.status.fault is None and card.station.drive.status.running


def test_the_connection_faults_are_bus_and_e5():
    assert {name_of(c) for c in CONNECTION_FAULTS} == {"BUS", "E5"}
    assert name_of(0xFE) == "FEH"
