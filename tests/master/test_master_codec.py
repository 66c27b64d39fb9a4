"""Reading responses the same way on every generation (mlink_sim/master/codec.py), citing the manual tables."""

from __future__ import annotations

import pytest

from mlink_sim.master import Control, StationPlan
from mlink_sim.master.codec import Codec, compatible
from mlink_sim.wire import Link, M2Status, M2SubStatus, ml2, ml3

ML2 = Codec(StationPlan(0x21, Link.ML2))
V7 = Codec(StationPlan(0x21, Link.ML2, card="SI-T/V7"))
ML3 = Codec(StationPlan(0x21, Link.ML3))


def m2(alarm=0, status=M2Status.CMDRDY, body=None, **kw):
    return ML2.reply(ml2.M2Response(body or ml2.Nop(), alarm, int(status), 0, **kw))


def test_si_t3_table_25_a94_with_warng_is_a_refusal():
    r = m2(0x94, M2Status.CMDRDY | M2Status.WARNG)
    assert r.error == (0x94, "DATA_SETTING_WARNING") and r.comm_alarm is None


def test_si_t3_table_23_e5_e6_are_communication_alarms():
    assert m2(0xE6, M2Status.CMDRDY | M2Status.ALM).comm_alarm == (0xE6, "COMM_ERROR")
    assert m2(0xE5, M2Status.CMDRDY | M2Status.ALM).comm_alarm == (0xE5, "WDT_ERROR")
    assert m2(0x96, M2Status.CMDRDY | M2Status.WARNG).comm_alarm is None  # warning: no action


def test_si_t3_table_26_drive_e5_and_bus_faults_count_as_communication_faults():
    """Table 21: the most recent alarm is shown, so the drive's E5 (39H) / bUS (22H) trip can hide E5H/E6H."""
    assert m2(0x39, M2Status.CMDRDY | M2Status.ALM).comm_alarm == (0x39, "E5")
    assert m2(0x22, M2Status.CMDRDY | M2Status.ALM).comm_alarm == (0x22, "BUS")
    assert m2(0x31, M2Status.CMDRDY | M2Status.WARNG).comm_alarm == (0x31, "E5")  # Table 27 minor fault
    assert m2(0x07, M2Status.CMDRDY | M2Status.ALM).comm_alarm is None  # oC: the operator's business


def test_v7_table_10_cpf23_is_not_a94():
    r = V7.reply(ml2.M2Response(ml2.Nop(), 0x94, int(M2Status.CMDRDY | M2Status.ALM)))
    assert r.error is None
    assert V7.alarm_name(0x94, M2Status.ALM) == "CPF23"
    assert V7.alarm_name(0x94, M2Status.WARNG) == "DATA_SETTING_WARNING"


def test_cmdrdy_busy_and_substatus():
    assert not m2(status=M2Status(0)).ready
    r = m2(0x94, M2Status.CMDRDY | M2Status.WARNG, sub=ml2.Nop(), substatus=int(M2SubStatus.SUBCMDRDY |
                                                                                  M2SubStatus.SUBWARNG))
    assert r.sub_error == (0x94, "DATA_SETTING_WARNING") and r.error is None  # the sub-command was refused


def test_si_et3_cmd_stat_and_sub_stat():
    stat = ml3.CmdStat(cmdrdy=True, cmd_alm=0xC, comm_alm=0x9).to_int()
    r = ML3.reply(ml3.M3Response(ml3.Nop(), 0, stat, ml3.Nop(), ml3.SubStat(False, 9).to_int()))
    assert r.error == (0xC, "PHASE_ERROR") and r.phase_error
    assert r.comm_alarm == (9, "NOT_RECEIVED")
    assert not r.sub_ready and r.sub_error == (9, "INVALID_DATA")
    warn = ML3.reply(ml3.M3Response(ml3.Nop(), 0, ml3.CmdStat(comm_alm=2).to_int()))
    assert warn.comm_alarm is None and warn.comm_alm == 2


def test_si_t3_cyc_hides_a94_on_connect():
    r = m2(0x33, M2Status.CMDRDY | M2Status.WARNG, body=ml2.Connect(0x21, 2, 2))
    assert ML2.connect_refusal(r) == (0x33, "CYC")
    assert V7.connect_refusal(V7.reply(ml2.M2Response(ml2.Connect(0x21, 2, 1), 0, int(M2Status.CMDRDY)))) is None


@pytest.mark.parametrize(("main", "sub", "ok"), [
    ("INV_CTL", "PRM_RD", True), ("PRM_RD", "PRM_RD", False), ("PRM_WR", "ALM_RD", True),
    ("CONFIG", "PRM_WR", False), ("ID_RD", "PRM_WR", True), ("CONNECT", "NOP", True), ("ALM_CLR", "INV_IO", False),
])
def test_si_t3_table_7_si_et3_table_13_combinations(main, sub, ok):
    assert compatible(main, sub) is ok


def test_control_ranges():
    with pytest.raises(ValueError, match="speed_ref"):
        Control(speed_ref=70000)
    with pytest.raises(ValueError, match="torque_ref"):
        Control(torque_ref=40000)
    with pytest.raises(ValueError, match="S3–S8"):
        Control(multi_inputs=0x40)
