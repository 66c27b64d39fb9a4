"""Alarm reporting: SI-T3 Tables 19–21, SI-T/V7 Table 6 and §8.1; SI-ET3 CMD_STAT (D_ALM, D_WAR, CMD_ALM,
COMM_ALM, RCMD_ID, CMDRDY) and SUB_STAT."""

from __future__ import annotations

from mlink_sim.cards.alarms import Ml2Alarms
from mlink_sim.wire import CmdAlm, M2Alarm, M2Status, ml2, ml3

from .helpers import Master, alarm, cmd_alm, station

EXT_BB = 0x8000  # operation signal F: external baseblock -> drive warning bb (08H)
EF0 = 0x0100  # operation signal 8: external fault EF0 -> drive alarm (27H)


def _bits(frame) -> tuple[bool, bool]:  # type: ignore[no-untyped-def]
    s = frame.message.status
    return bool(s & M2Status.WARNG), bool(s & M2Status.ALM)


def test_v7_table_6_alarm_priority() -> None:
    """Table 6: Warning/Warning -> smaller code, WARNG 1 ALM 0; Warning/Alarm and Alarm/Warning -> the alarm,
    WARNG 1 ALM 1; Alarm/Alarm -> the most recent alarm, WARNG 0 ALM 1."""
    m = Master(station("si-t-v7"))
    m.connect()
    # warning, warning: bb (08H) stays, A.94 (94H) arrives -> 08H
    r = m.send(ml2.InvCtl(signals=EXT_BB), ml2.PrmRd(0x0200, 3))
    assert alarm(r) == 0x08 and _bits(r) == (True, False)
    # warning, alarm: EF0 fault (V7 Table 10 27H) while bb is on
    r = m.send(ml2.InvCtl(signals=EXT_BB | EF0))
    assert alarm(r) == 0x27 and _bits(r) == (True, True)
    # alarm, warning: A.94 after the fault -> still the alarm
    r = m.send(ml2.InvCtl(signals=EXT_BB | EF0), ml2.PrmRd(0x0200, 5))
    assert alarm(r) == 0x27 and _bits(r) == (True, True)
    # alarm, alarm: a communications alarm E6 after the fault -> E6 (the most recent), no warning left
    m.send(ml2.InvCtl(signals=EF0))
    m.tick(2)
    r = m.send(ml2.InvCtl(signals=EF0))  # the gap is a first failure (96) and a consecutive one (E6)
    assert alarm(r) == M2Alarm.COMM_ERROR and _bits(r) == (True, True)
    # the V7 lost the connection at that first communications alarm (bUS, §8.1): a NOP reads the status as it stands
    r = m.nop()
    assert alarm(r) == M2Alarm.COMM_ERROR and _bits(r) == (False, True)


def test_si_t3_table_21_response_data_for_consecutive_alarms() -> None:
    m = Master(station("si-t3"))
    m.connect()
    m.tick(2)
    r = m.nop()  # E6
    assert alarm(r) == M2Alarm.COMM_ERROR
    r = m.send(ml2.InvCtl(signals=EF0))  # drive alarm EF0 (Table 26 27H) is the most recent
    assert alarm(r) == 0x27 and _bits(r) == (False, True)
    r = m.send(ml2.InvCtl(signals=EF0), ml2.PrmRd(0x0200, 7))
    assert alarm(r) == 0x27 and _bits(r) == (True, True)


def test_si_t3_table_20_communications_warning_needs_no_reset() -> None:
    m = Master(station("si-t3"))
    r = m.send(ml2.PrmRd(0x0200, 3))
    assert alarm(r) == M2Alarm.DATA_SETTING_WARNING and _bits(r) == (True, False)
    assert alarm(m.nop()) == 0


def test_si_t3_table_16_errors_not_reported_while_fault_reset_is_on() -> None:
    m = Master(station("si-t3"))
    m.connect()
    assert alarm(m.send(ml2.InvCtl(signals=EF0))) == 0x27
    r = m.send(ml2.InvCtl(signals=0x0200))  # fault reset held
    assert alarm(r) == 0 and not r.message.status & M2Status.ALM
    assert m.st.snapshot().drive.fault is None


def test_ml2_alarms_lowest_warning_code_unit() -> None:
    a = Ml2Alarms({"F": 0x27}, {"m": 0x20})
    a.warning(0x95)
    a.warning(0x94)
    assert a.report(None, None, False) == (0x94, False, True)
    a.reported()
    assert a.report(None, "m", False) == (0x20, False, True)
    a.alarm(0xE6)
    a.observe("F")
    assert a.report("F", None, False) == (0x27, True, False)
    a.alarm(0xE5)
    assert a.report("F", None, False) == (0xE5, True, False)


def test_si_et3_cmd_stat_d_alm_d_war_cmdrdy_rcmd_id() -> None:
    m = Master(station("si-et3"))
    m.connect()
    r = m.nop(cmd_ctrl=0x80)  # CMD_ID = 2
    stat = r.message.stat
    assert stat.rcmd_id == 2 and stat.cmdrdy and not stat.d_alm and not stat.d_war
    r = m.send(ml3.InvCtl(invcmd_ctrl=0x1000), cmd_ctrl=0x40)  # external baseblock: drive warning
    assert r.message.stat.d_war and r.message.stat.rcmd_id == 1
    r = m.send(ml3.InvCtl(invcmd_ctrl=0x0400))  # EF0: drive alarm
    assert r.message.stat.d_alm
    assert m.st.snapshot().led_colors["R/E"] == "red"


def test_si_et3_cmd_alm_cleared_by_next_normal_command() -> None:
    m = Master(station("si-et3"))
    m.connect()
    assert cmd_alm(m.send(ml3.PrmRd(0x0200, 3))) == CmdAlm.INVALID_DATA
    assert m.st.snapshot().led_colors["R/E"] == "red"  # Table 4: command error
    assert cmd_alm(m.nop()) == 0
    assert m.st.snapshot().led_colors["R/E"] == "green"


def test_alm_clr_cannot_reset_a_drive_fault_while_run_is_on() -> None:
    """SI-T3 ALM_CLR note: "Drive faults and alarms cannot be reset while the Drive RUN command is ON"."""
    m = Master(station("si-t3", params=("b1-01=3", "b1-02=3")))
    m.connect()
    m.send(ml2.InvCtl(signals=1 | EF0, speed_ref=1000))
    m.send(ml2.InvCtl(signals=1, speed_ref=1000))
    r = m.send(ml2.AlmClr(0))
    assert alarm(r) == 0x27 and m.st.snapshot().drive.fault == "EF0"
    m.send(ml2.InvCtl(signals=0))
    r = m.send(ml2.AlmClr(0))
    assert alarm(r) == 0 and m.st.snapshot().drive.fault is None


def test_si_et3_alm_clr_cannot_reset_a_drive_fault_while_run_is_on() -> None:
    """The same drive under the SI-ET3 (ALM_CLR_MOD 0 "Clears the status of present faults and alarms"): D_ALM
    stays while INVCMD_CTRL forward (Table 20 bit 0) is on, and clears once the run is off. The master's recovery
    of a bUS left by a lost connection relies on it (mlink_sim.master.drivefault)."""
    m = Master(station("si-et3", params=("b1-01=3", "b1-02=3")))
    m.connect()
    m.send(ml3.InvCtl(invcmd_ctrl=0x0001 | 0x0400, speed_ref=1000))  # forward + EF0 (Table 20 bit 10)
    m.send(ml3.InvCtl(invcmd_ctrl=0x0001, speed_ref=1000))
    r = m.send(ml3.AlmClr(0))
    assert r.message.stat.d_alm and m.st.snapshot().drive.fault == "EF0"
    m.send(ml3.InvCtl(invcmd_ctrl=0))
    r = m.send(ml3.AlmClr(0))
    assert not r.message.stat.d_alm and m.st.snapshot().drive.fault is None


def test_alm_clr_mod_other_than_0_is_a94() -> None:
    m = Master(station("si-t3"))
    m.connect()
    assert alarm(m.send(ml2.AlmClr(1))) == M2Alarm.DATA_SETTING_WARNING
    m3 = Master(station("si-et3"))
    m3.connect()
    assert cmd_alm(m3.send(ml3.AlmClr(2))) == CmdAlm.INVALID_DATA
