"""Communication phases and command admission: SI-ET3 Tables 9/10/13, SI-T3 §7–§8 and Table 7, SI-T/V7 §5.3."""

from __future__ import annotations

import pytest
from .helpers import Master, alarm, cmd_alm, station, sub_alm

from mlink_sim.cards import CardOptions
from mlink_sim.cards.phases import (
    ML2_COMBINATIONS,
    ML3_COMBINATIONS,
    ML3_MAIN_PHASES,
    V7_COMBINATIONS,
    Admit,
    combination_ok,
)
from mlink_sim.wire import CmdAlm, M2Alarm, M2Cmd, M2Status, M2SubStatus, M3Cmd, SubCmdAlm, ml2, ml3

ML3_BODIES = {
    M3Cmd.NOP: ml3.Nop(),
    M3Cmd.PRM_RD: ml3.PrmRd(0x0200, 2),
    M3Cmd.PRM_WR: ml3.PrmWr(0x0200, 2, (50).to_bytes(2, "little").ljust(8, b"\0")),
    M3Cmd.ID_RD: ml3.IdRd(0x02, 0, 4),
    M3Cmd.CONFIG: ml3.Config(0),
    M3Cmd.ALM_RD: ml3.AlmRd(0, 0),
    M3Cmd.ALM_CLR: ml3.AlmClr(0),
    M3Cmd.SYNC_SET: ml3.SyncSet(),
    M3Cmd.CONNECT: ml3.Connect(0x30, 0x80, 1, 0x20),
    M3Cmd.DISCONNECT: ml3.Disconnect(),
    M3Cmd.INV_CTL: ml3.InvCtl(),
}


TABLE_9 = CardOptions(et3_nop_in_phase1=False)


def _et3_in_phase(phase: int, **kw: object) -> Master:
    m = Master(station("si-et3", **kw))  # type: ignore[arg-type]
    if phase >= 2:
        m.connect(sync=phase == 3)
    assert m.st.phase == phase
    return m


@pytest.mark.parametrize("code", sorted(ML3_BODIES))
@pytest.mark.parametrize("phase", [1, 2, 3])
def test_si_et3_table_9_phase_error_ch(code: int, phase: int) -> None:
    """Table 9 read literally (``et3_nop_in_phase1=False``): ○ executed (CMD_ALM 0), △ ignored (CMD_ALM 0, nothing
    happens), – phase error CMD_ALM CH."""
    m = _et3_in_phase(phase, options=TABLE_9)
    expected = ML3_MAIN_PHASES[code][phase - 1]
    r = m.send(ML3_BODIES[code])
    assert r is not None and r.message.code == code
    if expected is Admit.PHASE_ERROR:
        assert cmd_alm(r) == CmdAlm.PHASE_ERROR
        assert m.st.phase == phase
    else:
        assert cmd_alm(r) == CmdAlm.NORMAL
    if expected is Admit.IGNORED:
        assert m.st.phase == phase  # CONNECT in 2/3, SYNC_SET in 3: no phase change


def test_si_et3_table_9_transitions() -> None:
    """CONNECT -> 2, SYNC_SET 2 -> 3, DISCONNECT -> 1."""
    m = _et3_in_phase(1)
    m.connect(sync=False)
    assert m.st.phase == 2
    m.sync_set()
    assert m.st.phase == 3
    m.send(ml3.Disconnect())
    assert m.st.phase == 1
    m.connect(sync=True)
    assert m.st.phase == 3


def test_si_et3_nop_in_phase_1_follows_the_nop_text_by_default() -> None:
    """SI-ET3 NOP: "The command can be used in all communication phases" – the default (CMD_ALM 0, CMDRDY 1, and
    the NOP sub-command of a 64-byte frame with it); ``et3_nop_in_phase1=False`` keeps Table 9's "–" (CMD_ALM CH)."""
    m = _et3_in_phase(1)
    r = m.nop()
    assert cmd_alm(r) == CmdAlm.NORMAL and r.message.stat.cmdrdy and sub_alm(r) == 0
    assert m.st.snapshot().led_colors["R/E"] == "green" and m.st.phase == 1
    strict = _et3_in_phase(1, options=TABLE_9)
    assert cmd_alm(strict.nop()) == CmdAlm.PHASE_ERROR


def test_si_et3_table_10_sub_command_phase_error_ch() -> None:
    m = _et3_in_phase(1, options=TABLE_9)
    r = m.nop(ml3.PrmRd(0x0200, 2))
    assert sub_alm(r) == SubCmdAlm.PHASE_ERROR
    r = m.nop(ml3.Nop())
    assert sub_alm(r) == SubCmdAlm.PHASE_ERROR  # Table 10: NOP is "–" in phase 1 too
    m.connect()
    r = m.nop(ml3.PrmRd(0x0200, 2))
    assert sub_alm(r) == 0 and r.message.sub.parameter[:2] == (100).to_bytes(2, "little")


def test_si_et3_unsupported_command_cmd_alm_8() -> None:
    from mlink_sim.wire import Unknown

    m = _et3_in_phase(2)
    r = m.send(Unknown(0x30, bytes(ml3.COMMAND_MAIN.size)))
    assert cmd_alm(r) == CmdAlm.UNSUPPORTED_COMMAND and r.message.code == 0x30
    r = m.nop(Unknown(0x40, bytes(ml3.COMMAND_SUB.size)))
    assert sub_alm(r) == SubCmdAlm.UNSUPPORTED_COMMAND


@pytest.mark.parametrize("main", sorted(ML3_COMBINATIONS))
@pytest.mark.parametrize("sub", [M3Cmd.NOP, M3Cmd.PRM_RD, M3Cmd.PRM_WR, M3Cmd.ALM_RD, M3Cmd.INV_IO])
def test_si_et3_table_13_combination_bh(main: int, sub: int) -> None:
    subs = {
        M3Cmd.NOP: ml3.Nop(),
        M3Cmd.PRM_RD: ml3.PrmRd(0x0200, 2),
        M3Cmd.PRM_WR: ml3.PrmWr(0x0201, 2, (70).to_bytes(2, "little").ljust(8, b"\0")),
        M3Cmd.ALM_RD: ml3.AlmRd(0, 0),
        M3Cmd.INV_IO: ml3.InvIo(),
    }
    m = _et3_in_phase(2)
    body = ML3_BODIES[main] if main != M3Cmd.CONNECT else ml3.Connect(0x30, 0x80, 1, 0x20)
    r = m.send(body, subs[sub])
    ok = combination_ok(ML3_COMBINATIONS, main, sub)
    if main == M3Cmd.DISCONNECT:
        assert m.st.phase == 1  # the main command is processed either way
    if ok:
        assert sub_alm(r) == 0
    else:
        assert sub_alm(r) == SubCmdAlm.SUBCMD_COMBINATION
        assert cmd_alm(r) == CmdAlm.SUBCMD_COMBINATION
    if sub == M3Cmd.PRM_WR and not ok:
        assert m.st.store.value("C1-02") == 100  # a rejected sub-command is not executed


def test_si_et3_table_13_cmd_alm_cleared_by_next_normal_command() -> None:
    m = _et3_in_phase(2)
    assert cmd_alm(m.send(ml3.AlmRd(0, 0), ml3.PrmRd(0x200, 2))) == CmdAlm.SUBCMD_COMBINATION
    assert cmd_alm(m.nop()) == CmdAlm.NORMAL


ML2_MAIN = {
    M2Cmd.NOP: ml2.Nop(),
    M2Cmd.PRM_RD: ml2.PrmRd(0x0200, 2),
    M2Cmd.PRM_WR: ml2.PrmWr(0x0200, 2, (50).to_bytes(2, "little").ljust(8, b"\0")),
    M2Cmd.ID_RD: ml2.IdRd(0x00, 0, 8),
    M2Cmd.CONFIG: ml2.Config(0),
    M2Cmd.ALM_RD: ml2.AlmRd(0),
    M2Cmd.ALM_CLR: ml2.AlmClr(0),
    M2Cmd.SYNC_SET: ml2.SyncSet(),
    M2Cmd.DISCONNECT: ml2.Disconnect(),
    M2Cmd.INV_CTL: ml2.InvCtl(),
}


@pytest.mark.parametrize("code", sorted(ML2_MAIN))
def test_si_t3_phase_1_rules_a95(code: int) -> None:
    """SI-T3 §8: "If not in phase 2 or 3: Command warning (A.95)" for PRM_WR, CONFIG, ALM_CLR, SYNC_SET,
    INV_CTL; NOP, PRM_RD, ID_RD "can be used in all phases"; ALM_RD has no phase condition; DISCONNECT in
    phase 1 is answered and ignored."""
    m = Master(station("si-t3"))
    r = m.send(ML2_MAIN[code])
    refused = code in (M2Cmd.PRM_WR, M2Cmd.CONFIG, M2Cmd.ALM_CLR, M2Cmd.SYNC_SET, M2Cmd.INV_CTL)
    if refused:
        assert alarm(r) == M2Alarm.COMMAND_WARNING
        assert r.message.status & M2Status.WARNG
    else:
        assert alarm(r) == 0
    assert m.st.phase == 1
    assert alarm(m.nop()) == 0  # a communications warning is reported once (SI-T3 Table 20: no reset)


def test_si_t3_connect_ignored_in_phase_2_and_3() -> None:
    """SI-T3 CONNECT: "Commands are also ignored in phase 2 (with no alarm)"."""
    m = Master(station("si-t3"))
    m.connect(sync=False)
    r = m.send(ml2.Connect(0x21, 0x82, 1))
    assert alarm(r) == 0 and m.st.phase == 2
    m.sync_set()
    r = m.send(ml2.Connect(0x21, 0x80, 1))
    assert alarm(r) == 0 and m.st.phase == 3


def test_si_t3_phase_transitions_figure_8() -> None:
    m = Master(station("si-t3"))
    m.connect(sync=True)
    assert m.st.phase == 3
    m.send(ml2.Disconnect())
    assert m.st.phase == 1
    m.connect(sync=False)
    assert m.st.phase == 2
    m.sync_set()
    assert m.st.phase == 3


def test_v7_connect_sync_to_phase_3() -> None:
    m = Master(station("si-t-v7"))
    m.connect(sync=True)
    assert m.st.phase == 3


ML2_SUBS = {
    M2Cmd.NOP: ml2.Nop(),
    M2Cmd.PRM_RD: ml2.PrmRd(0x0200, 2),
    M2Cmd.PRM_WR: ml2.PrmWr(0x0201, 2, (70).to_bytes(2, "little").ljust(8, b"\0")),
    M2Cmd.ALM_RD: ml2.AlmRd(0),
    M2Cmd.INV_IO: ml2.InvIo(),
}


@pytest.mark.parametrize("main", sorted(ML2_MAIN))
@pytest.mark.parametrize("sub", sorted(ML2_SUBS))
def test_si_t3_table_7_combination_a95(main: int, sub: int) -> None:
    m = Master(station("si-t3"))
    m.connect()
    r = m.send(ML2_MAIN[main], ML2_SUBS[sub])
    ok = combination_ok(ML2_COMBINATIONS, main, sub)
    if ok:
        assert not r.message.substatus & M2SubStatus.SUBWARNG
    else:
        assert r.message.substatus & M2SubStatus.SUBWARNG
        assert alarm(r) in (M2Alarm.COMMAND_WARNING, M2Alarm.DATA_SETTING_WARNING)
        assert r.message.status & M2Status.WARNG
    if sub == M2Cmd.PRM_WR:
        assert (m.st.store.value("C1-02") == 70) == ok


def test_si_t3_table_7_main_command_processed_on_conflict() -> None:
    """"If a conflict occurs ..., the request for the main command is processed"."""
    m = Master(station("si-t3"))
    m.connect()
    r = m.send(ml2.PrmRd(0x0200, 2), ml2.PrmRd(0x0201, 2))
    assert r.message.body.parameter[:2] == (100).to_bytes(2, "little")
    assert r.message.substatus & M2SubStatus.SUBWARNG and alarm(r) == M2Alarm.COMMAND_WARNING


def test_v7_combination_config_sub_command() -> None:
    """SI-T/V7 §7.2 CONFIG sub-command, combined like PRM_WR (docs/cards.md); SI-T3 has none (A.95)."""
    assert combination_ok(V7_COMBINATIONS, M2Cmd.INV_CTL, M2Cmd.CONFIG)
    assert not combination_ok(V7_COMBINATIONS, M2Cmd.CONFIG, M2Cmd.CONFIG)
    m = Master(station("si-t-v7"))
    m.connect()
    r = m.send(ml2.InvCtl(), ml2.Config(1))
    assert r.message.substatus == M2SubStatus.SUBCMDRDY and alarm(r) == 0
    t3 = Master(station("si-t3"))
    t3.connect()
    r = t3.send(ml2.InvCtl(), ml2.Config(0))
    assert r.message.substatus & M2SubStatus.SUBWARNG and alarm(r) == M2Alarm.COMMAND_WARNING


def test_si_t3_subcommands_unused_after_connect_subcmd_0() -> None:
    m = Master(station("si-t3"))
    m.connect(subcmd=False)
    r = m.send(ml2.InvCtl(), ml2.PrmWr(0x0201, 2, (70).to_bytes(2, "little").ljust(8, b"\0")))
    assert r.message.substatus == M2SubStatus.SUBCMDRDY and m.st.store.value("C1-02") == 100
