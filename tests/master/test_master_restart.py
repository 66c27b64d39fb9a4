"""The master's restart rule (docs/master.md, "Running again after a recovery"), against the real SI-T3 core and
its drive model: after a lost connection trips bUS the motor coasts (SI-T3 Table 26, F6-01), and the master runs
the drive again only when it can take it: at once with speed search (A1000 b3-01), else at standstill, seen in
U1-05 motor speed (MON1 with SEL_MON 1, SI-T3 Table 18). Either way no oC follows the recovery."""

from __future__ import annotations

import pytest
from master_fakes import MS, Net

from mlink_sim.cards import create_card, settings_for
from mlink_sim.drive import LoadSpec
from mlink_sim.master import restart
from mlink_sim.master import MasterCore, NetworkPlan, Recovered, RunHeld, RunResumed, StationPlan, StationState
from mlink_sim.wire import Link

S = StationState
BASE = ["b1-01=3", "b1-02=3", "C1-01=1.0", "C1-02=1.0"]
SEARCH = ["b3-01=1", "b3-24=1"]


class Card:
    def __init__(self, params: list[str], card: str = "si-t3") -> None:
        settings = settings_for(card, 0x21, 32, params, LoadSpec.from_config({"kind": "constant"}))
        self.station = create_card(card, settings=settings, now=0)

    def receive(self, datagram: bytes, source: object, now: int) -> bytes | None:
        return self.station.receive(datagram, source, now)

    def poll(self, now: int) -> None:
        self.station.poll(now)


def running_then_lost(speed_search: bool, card: Card | None = None, **plan: int) -> tuple[Net, Card]:
    card = card or Card(BASE + (SEARCH if speed_search else []))
    station = StationPlan(0x21, Link.ML2, card=card.station.card, speed_search=speed_search, **plan)
    plan = NetworkPlan(Link.ML2, 2 * MS, (station,))
    net = Net(MasterCore(plan), {0x21: card})
    net.run_until(net.core.all_at_target, limit=50)
    net.core.set_control(0x21, forward=True, speed_ref=3000)  # 30.00 Hz (o1-03 = 0: 0.01 Hz)
    net.run_until(lambda: net.core.view(0x21).output_freq >= 2990, limit=1500)
    net.events.clear()
    net.cut.add(0x21)  # the connection is gone for 60 ms: E6, bUS, the drive coasts
    net.run(30)
    net.cut.discard(0x21)
    assert card.station.drive.status.fault is not None  # bUS tripped
    net.run_until(lambda: any(isinstance(e, Recovered) for e in net.events), limit=500)
    return net, card


def of(net, kind):
    return [e for e in net.events if isinstance(e, kind)]


def test_without_speed_search_the_run_waits_for_standstill():
    net, card = running_then_lost(speed_search=False)
    assert [e.until for e in of(net, RunHeld)] == ["standstill"]
    drive = card.station.drive
    held_at_rpm = drive.drive.motor_speed_rpm
    assert held_at_rpm > 100 and not drive.status.running  # still coasting: not run into it
    net.run_until(lambda: of(net, RunResumed), limit=2_000)
    assert of(net, RunResumed)[0].reason == "standstill"
    assert abs(drive.drive.motor_speed_rpm) < 0.02 * 1800  # 2 % of E1-04 (60 Hz, 4 poles)
    net.run_until(lambda: net.core.view(0x21).output_freq >= 2990, limit=2000)
    assert drive.status.fault is None and net.core.state(0x21) is S.PHASE3


def test_with_speed_search_the_run_resumes_at_once_and_catches_the_motor():
    net, card = running_then_lost(speed_search=True)
    assert [e.reason for e in of(net, RunResumed)] == ["speed search"] and not of(net, RunHeld)
    net.run_until(lambda: net.core.view(0x21).output_freq >= 2990, limit=1500)
    assert card.station.drive.status.fault is None


def test_a_new_run_command_while_held_is_the_one_resumed():
    net, card = running_then_lost(speed_search=False)
    net.core.set_control(0x21, forward=False, reverse=True, speed_ref=2000)
    assert not card.station.drive.status.running
    net.run_until(lambda: of(net, RunResumed), limit=2_000)
    net.run_until(lambda: net.core.view(0x21).output_freq >= 1990, limit=2000)
    assert card.station.drive.status.reverse and card.station.drive.status.fault is None


@pytest.mark.parametrize("run", [False, True])
def test_stop_while_held_ends_the_hold(run):
    net, card = running_then_lost(speed_search=False)
    net.core.set_control(0x21, forward=False)
    assert not net.core._station(0x21).run_held
    assert not of(net, RunResumed)


def test_vs606v7_search_input_goes_with_the_run_until_speed_agree():
    """VS-606V7: no search at every start and no motor speed monitor; n056 = 15 makes S7 the speed-search command
    (docs/drive-model.md §10), which the master switches on with the run after a recovery."""
    v7 = Card(["n003=3", "n004=9", "n019=1.0", "n020=1.0", "n056=15"], card="si-t-v7")
    net, card = running_then_lost(True, v7, search_input=1 << 4)  # S7 = multi_inputs bit 4
    assert [e.reason for e in of(net, RunResumed)] == ["speed search"]
    assert net.core._station(0x21).searching
    net.run_until(lambda: not net.core._station(0x21).searching, limit=1500)
    assert card.station.drive.status.fault is None and card.station.drive.status.running


@pytest.mark.parametrize(("speed_search", "events"), [
    (True, [("RunResumed", "speed search")]),  # the run went out at once, with the search input: nothing held
    (False, [("RunHeld", "the next run command"), ("RunResumed", "run command")]),
])
def test_a_run_command_resumes_only_a_held_run(speed_search, events):
    """restart.command: a new run command while only the speed-search input is pending ends the search and
    resumes nothing (no run was held); while a run is held (SI-T/V7: no motor speed monitor) it resumes it."""
    station = StationPlan(0x21, Link.ML2, card="si-t-v7", speed_search=speed_search, search_input=1 << 4)
    core = MasterCore(NetworkPlan(Link.ML2, 2 * MS, (station,)))
    core.set_control(0x21, forward=True, speed_ref=3000)
    st = core._station(0x21)
    restart.begin(st, core._emit)  # back at its phase after a fault
    assert st.searching is speed_search and st.run_held is not speed_search
    core.set_control(0x21, forward=True, speed_ref=2000)
    assert not st.searching and not st.run_held
    got = [(type(e).__name__, getattr(e, "reason", getattr(e, "until", None))) for e in core.drain_events()]
    assert got == events
