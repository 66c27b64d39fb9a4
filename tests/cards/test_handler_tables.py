"""The cards' handler tables keyed by command code, the handlers both generations share, and CMD_STAT built in one
place (SI-T3 Tables 5/6, SI-T/V7 Tables 1/2, SI-ET3 Tables 11/12)."""

from __future__ import annotations

import ast
from dataclasses import replace

import pytest
from hypothesis import given
from hypothesis import strategies as st

from .helpers import module_source

from mlink_sim.cards import commands, station_class
from mlink_sim.cards.alarms import Ml3Alarms
from mlink_sim.cards.phases import ML2_MAIN_PHASES, ML3_MAIN_PHASES, ML3_SUB_PHASES, V7_SUB_PHASES, Admit
from mlink_sim.cards.si_et3 import cmd_stat
from mlink_sim.drive import Drive, DriveSettings, Family, LoadSpec
from mlink_sim.profiles import BUILTIN
from mlink_sim.wire import M2Cmd, M3Cmd, ml2, ml3

CARDS = {p.key: station_class(p) for p in BUILTIN}


def _executed(phases) -> set[int]:
    return {code for code, row in phases.items() if Admit.ALLOWED in row}


@pytest.mark.parametrize("card", sorted(CARDS))
def test_every_admitted_command_has_a_handler_si_t3_table_5_si_et3_table_11(card: str) -> None:
    cls = CARDS[card]
    main = ML3_MAIN_PHASES if card == "si-et3" else ML2_MAIN_PHASES
    assert set(cls.handlers) == _executed(main)
    sub = {"si-et3": ML3_SUB_PHASES, "si-t-v7": V7_SUB_PHASES}.get(card)
    if sub is not None:
        assert set(cls.sub_handlers) == _executed(sub)
    else:  # SI-T3 Table 6: NOP, PRM_RD, PRM_WR, ALM_RD, INV_I/O – no CONFIG sub-command
        assert set(cls.sub_handlers) == {M2Cmd.NOP, M2Cmd.PRM_RD, M2Cmd.PRM_WR, M2Cmd.ALM_RD, M2Cmd.INV_IO}


SHARED_MAIN = ("NOP", "PRM_RD", "PRM_WR", "CONFIG", "ALM_CLR", "SYNC_SET")
SHARED_SUB = ("NOP", "PRM_RD", "PRM_WR", "INV_IO")


@pytest.mark.parametrize("name", SHARED_MAIN)
def test_main_handlers_shared_by_both_generations(name: str) -> None:
    et3 = CARDS["si-et3"].handlers[M3Cmd[name]]
    assert CARDS["si-t3"].handlers[M2Cmd[name]] is et3
    assert et3 is getattr(commands, name.lower())
    if name not in ("PRM_RD", "PRM_WR"):  # the SI-T/V7 refuses those as main commands in 32-byte mode
        assert CARDS["si-t-v7"].handlers[M2Cmd[name]] is et3


@pytest.mark.parametrize("name", SHARED_SUB)
def test_sub_handlers_shared_by_both_generations(name: str) -> None:
    handler = getattr(commands, "sub_" + name.lower())
    assert {CARDS[c].sub_handlers[(M3Cmd if c == "si-et3" else M2Cmd)[name]] for c in CARDS} == {handler}


def test_shared_handlers_use_only_the_public_station_operations() -> None:
    """The shared handlers see a station through its public operations, never its private members."""
    tree = ast.parse(module_source(commands))
    private = [f"{node.value.id}.{node.attr}" for node in ast.walk(tree)
               if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name)
               and node.value.id in ("station", "sub", "body") and node.attr.startswith("_")]
    assert private == []


def test_response_of_pairs_each_request_with_the_response_of_its_code() -> None:
    for wire in (ml2, ml3):
        for request, response in ((wire.COMMAND_MAIN, wire.RESPONSE_MAIN), (wire.COMMAND_SUB, wire.RESPONSE_SUB)):
            for code, layout in request.by_code.items():
                assert commands.RESPONSE_OF[layout.cls] is response.by_code[code].cls


#: a drive's status at power-up, for test_cmd_stat_is_the_wire_cmd_stat
_STATUS = Drive(Family.A1000, DriveSettings.from_defaults(Family.A1000), LoadSpec()).status


@given(faulted=st.booleans(), minor=st.booleans(), ready=st.booleans(), clr_cmp=st.booleans(),
       ctrl=st.integers(0, 0xFFFF), cmd_alm=st.integers(0, 0xF), comm_alm=st.integers(0, 0xF),
       handshake=st.booleans())
def test_cmd_stat_is_the_wire_cmd_stat(faulted: bool, minor: bool, ready: bool, clr_cmp: bool, ctrl: int,
                                       cmd_alm: int, comm_alm: int, handshake: bool) -> None:
    """SI-ET3 "Command Status (CMD_STAT)": the cards' builder agrees bit for bit with ``ml3.CmdStat``."""
    # the two DriveStatus fields CMD_STAT reads, on a real DriveStatus (a compiled cmd_stat checks the type)
    status = replace(_STATUS, faulted=faulted, minor_fault=minor)
    alarms = Ml3Alarms()
    alarms.comm_alm, alarms.alm_clr_cmp = comm_alm, clr_cmp
    expected = ml3.CmdStat(d_alm=faulted, d_war=minor, cmdrdy=ready, alm_clr_cmp=clr_cmp and handshake,
                           rcmd_id=ml3.CmdCtrl.from_int(ctrl).cmd_id, cmd_alm=cmd_alm, comm_alm=comm_alm)
    built = cmd_stat(status, alarms, ready, ctrl, cmd_alm, handshake)
    assert built == expected.to_int()
