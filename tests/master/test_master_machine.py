"""The master's state machine as data (mlink_sim/master/machine.py) against docs/master.md, illegal transitions,
choosing a slot's command without side effects, and the verdicts a Reply carries (master/codec.py)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from mlink_sim.master import MasterCore, NetworkPlan, StateChanged, StationPlan, StationState
from mlink_sim.master.codec import Codec
from mlink_sim.master.commands import Cmd, Send, cmd_of, code_of
from mlink_sim.master.machine import SENDS, TRANSITIONS, Ev, IllegalTransition, expects, next_state
from mlink_sim.wire import CmdAlm, Link, M2Alarm, M2Cmd, M2Status, M3Cmd, ml2, ml3

S = StationState
DOC = Path(__file__).resolve().parents[2] / "docs" / "master.md"


def doc_transitions() -> dict[tuple[StationState, Ev], StationState]:
    """The transition table of docs/master.md ("State machine"): | `EVENT` | from, ... | to | when |."""
    out = {}
    for event, sources, target in re.findall(r"^\| `(\w+)` \| ([A-Z0-9, ]+) \| ([A-Z0-9]+) \|", DOC.read_text(),
                                              re.M):
        for source in sources.split(","):
            out[S[source.strip()], Ev[event]] = S[target]
    return out


def test_docs_master_md_table_is_the_machine():
    assert doc_transitions() == dict(TRANSITIONS)


def test_every_event_has_a_transition_and_every_state_a_command():
    assert {ev for _, ev in TRANSITIONS} == set(Ev)
    assert set(SENDS) == set(S)


@pytest.mark.parametrize(("state", "event"), [
    (S.OFFLINE, Ev.CONNECTED), (S.PHASE3, Ev.SYNCED), (S.ALARM, Ev.COMM_ALARM), (S.OFFLINE, Ev.SILENT),
    (S.PHASE3, Ev.ANSWERED), (S.PHASE2, Ev.CLEARED),
])
def test_an_illegal_transition_is_rejected(state, event):
    assert not expects(state, event)
    with pytest.raises(IllegalTransition, match=f"no transition from {state.name} on {event.name}"):
        next_state(state, event)


def core(*stations: StationPlan) -> MasterCore:
    return MasterCore(NetworkPlan(stations[0].link, 2_000_000, stations))


def test_the_core_fires_events_through_the_table_only():
    c = core(StationPlan(0x21, Link.ML2))
    st = c._station(0x21)
    with pytest.raises(IllegalTransition):
        c._fire(st, Ev.SYNCED)  # OFFLINE
    assert st.state is S.OFFLINE and not c.drain_events()
    c._fire(st, Ev.ANSWERED)
    assert c.drain_events() == [StateChanged(0x21, S.OFFLINE, S.PHASE1)]


@pytest.mark.parametrize(("state", "sync", "send"), [
    (S.PHASE1, True, Send.PROBE), (S.CONNECTING, True, Send.CONNECT), (S.PHASE2, True, Send.CYCLIC),
    (S.PHASE2, False, Send.CYCLIC), (S.SYNCING, True, Send.SYNC), (S.ALARM, True, Send.CLEAR),
])
def test_choosing_the_command_changes_no_state(state, sync, send):
    """Only the slot's event (CONNECT_DUE / SYNC_DUE, Slave.due) moves the state; choose_main only reads."""
    c = core(StationPlan(0x21, Link.ML2, sync=sync))
    st = c._station(0x21)
    st.state = state
    assert st.choose_main(0)[0] is send
    assert st.state is state and not c.drain_events()


def test_a_slot_in_phase1_connects_and_in_phase2_synchronises():
    c = core(StationPlan(0x21, Link.ML2))
    st = c._station(0x21)
    st.state = S.PHASE1
    assert st.due(0) is Ev.CONNECT_DUE
    st.hold_until = 10
    assert st.due(0) is None  # backing off after a refused CONNECT
    st.state = S.PHASE2
    assert st.due(10) is Ev.SYNC_DUE
    c.on_cycle(10, 0)
    assert st.state is S.SYNCING and st.outstanding.send is Send.SYNC


def test_command_kinds_by_generation():
    """SI-T3 Table 5 INV_CTL 40H, SI-ET3 Table 11 INV_CTL 50H; the other codes agree."""
    assert cmd_of(Link.ML2, 0x40) is Cmd.INV_CTL is cmd_of(Link.ML3, 0x50)
    assert cmd_of(Link.ML3, 0x40) is None and cmd_of(Link.ML2, 0x77) is None
    assert code_of(Link.ML3, Cmd.INV_IO) == M3Cmd.INV_IO and code_of(Link.ML2, Cmd.INV_IO) == M2Cmd.INV_IO
    assert {k.value for k in Cmd} == {c.name for c in M2Cmd} == {c.name for c in M3Cmd}


# --- Reply verdicts --------------------------------------------------------------------------------------------

ML2 = Codec(StationPlan(0x21, Link.ML2))
ML3 = Codec(StationPlan(0x21, Link.ML3))


def test_si_t3_a95_to_inv_ctl_means_not_connected_but_not_to_prm_wr():
    """SI-T3 INV_CTL/SYNC_SET/ALM_CLR: "If not in phase 2 or 3: Command warning (A.95)"; PRM_WR's A.95 has other
    causes (undervoltage, operator)."""
    warn = int(M2Status.CMDRDY | M2Status.WARNG)
    r = ML2.reply(ml2.M2Response(ml2.InvCtlResponse(), M2Alarm.COMMAND_WARNING, warn), M2Cmd.INV_CTL)
    assert r.not_connected and r.kind is Cmd.INV_CTL
    body = ml2.PrmWr(0x0200, 2, bytes(8))
    r = ML2.reply(ml2.M2Response(body, M2Alarm.COMMAND_WARNING, warn), M2Cmd.PRM_WR)
    assert not r.not_connected and r.error == (0x95, "COMMAND_WARNING")


def test_si_et3_cmd_alm_ch_means_not_connected():
    r = ML3.reply(ml3.M3Response(ml3.Nop(), 0, ml3.CmdStat(cmdrdy=True, cmd_alm=CmdAlm.PHASE_ERROR).to_int()))
    assert r.not_connected and r.phase_error and r.kind is Cmd.NOP


@pytest.mark.parametrize(("cmd_alm", "plan"), [(CmdAlm.INVALID_DATA, True), (CmdAlm.INVALID_DATA_WARNING, True),
                                               (CmdAlm.PHASE_ERROR, False)])
def test_si_et3_connect_refusals(cmd_alm, plan):
    stat = ml3.CmdStat(cmdrdy=True, cmd_alm=cmd_alm).to_int()
    r = ML3.reply(ml3.M3Response(ml3.Connect(0x30, 0, 1, 0x20), 0, stat))
    assert r.connect_refusal == (cmd_alm, CmdAlm(cmd_alm).name) and r.plan_refused is plan


def test_si_t3_a94_and_cyc_refuse_the_plan_a95_does_not():
    body = ml2.Connect(0x21, 2, 2)
    warn = int(M2Status.CMDRDY | M2Status.WARNG)
    assert ML2.reply(ml2.M2Response(body, 0x94, warn)).plan_refused
    assert ML2.reply(ml2.M2Response(body, 0x33, warn)).plan_refused  # CyC, SI-T3 Table 27
    r = ML2.reply(ml2.M2Response(body, 0x95, warn))
    assert r.connect_refusal == (0x95, "COMMAND_WARNING") and not r.plan_refused


def test_si_t3_status_field_note_prm_rd_status_is_not_valid():
    """SI-T3 "STATUS Field": with PRM_RD only CMDRDY is valid; MECHATROLINK-III has no such note."""
    assert not ML2.reply(ml2.M2Response(ml2.PrmRdResponse(0x0200, 2, bytes(8)), 0, 0)).status_valid
    assert ML2.reply(ml2.M2Response(ml2.Nop(), 0, 0)).status_valid
    assert ML3.reply(ml3.M3Response(ml3.Nop(), 0, 0)).status_valid
