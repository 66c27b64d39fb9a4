"""STATUS (MECHATROLINK-II) / INVCMD_STAT (MECHATROLINK-III) bits, oPE on CONFIG, monitors, SEL_MON.

Bit positions: SI-T3 / SI-T/V7 "STATUS Field"; SI-ET3 "INVCMD_STAT".  Monitor units: SI-T3
Table 18, SI-ET3 Table 22, SI-T/V7 Table 5 and the A1000 U1 monitor list.
"""

from __future__ import annotations

import math

import pytest

from mlink_sim.drive import (
    SEL_MON_TABLES,
    DriveCommand,
    DriveSettings,
    Family,
    LoadSpec,
    ml2_status_bits,
    ml3_invcmd_stat_bits,
    required_params,
)

from .conftest import A1000_VALUES, MS, S, V7_VALUES, a1000, make_drive, v7

ALM, WARNG, CMDRDY, BBOFF, PON, RUNX, ZSP, REV, RESET, AGREE, READY, OPE, UVR, REMOTE, SELM = (
    1 << i for i in range(15))


def _running(settings, ref=3000, reverse=False, load=None):
    d = make_drive(settings, load or LoadSpec("constant", inertia_kgm2=0.05, torque_nm=10.0))
    d.command(DriveCommand(forward=not reverse, reverse=reverse, freq_ref_raw=ref), 0)
    d.advance(8 * S)
    return d


def test_ml2_status_stopped():
    d = make_drive(a1000())
    w = ml2_status_bits(d.status)
    assert w == CMDRDY | PON | ZSP | READY | REMOTE


def test_ml2_status_running_forward_at_speed():
    d = _running(a1000(C1_01=50))
    w = ml2_status_bits(d.status)
    assert w == CMDRDY | BBOFF | PON | RUNX | AGREE | READY | REMOTE


def test_ml2_status_running_reverse():
    d = _running(a1000(C1_01=50), reverse=True)
    w = ml2_status_bits(d.status)
    assert w & REV and w & RUNX and d.output_frequency_hz < 0


def test_ml3_invcmd_stat_bits():
    d = _running(a1000(C1_01=50))
    assert ml3_invcmd_stat_bits(d.status) == (1 << 0) | (1 << 2) | (1 << 3) | (1 << 5) | (1 << 6) | (1 << 11)
    d = _running(a1000(C1_01=50), reverse=True)
    assert ml3_invcmd_stat_bits(d.status) & 0b11 == 0b10
    d = make_drive(a1000())
    assert ml3_invcmd_stat_bits(d.status) == (1 << 3) | (1 << 4) | (1 << 6) | (1 << 11)


def test_motor2_bit_from_h1_16h():
    s = a1000(H1_08=0x16)
    d = make_drive(s)
    d.command(DriveCommand(multi_inputs=1 << 5), 0)  # S8
    assert d.status.motor2
    assert ml2_status_bits(d.status) & SELM and ml3_invcmd_stat_bits(d.status) & (1 << 12)
    assert not ml2_status_bits(d.status, bits_e_f=False) & SELM


def test_ope10_on_config_with_inconsistent_e1():
    s = a1000()
    d = _running(s)
    bad = a1000(E1_06=700)  # E1-06 > E1-04
    assert bad.check() == "oPE10"
    d.reconfigure(bad, 8 * S)
    st = d.status
    assert st.ope and st.ope_code == "oPE10" and not st.ready and st.baseblock
    assert ml2_status_bits(st) & OPE and ml3_invcmd_stat_bits(st) & (1 << 7)
    d.advance(9 * S)
    assert not d.status.running
    d.reconfigure(s, 9 * S)
    assert not d.status.ope
    d.advance(15 * S)
    assert d.status.running and d.output_frequency_hz == pytest.approx(30.0)


def test_ope03_duplicate_multi_function_input():
    assert a1000(H1_05=0x14).check() == "oPE03"  # fault reset on S4 and S5
    assert a1000(H1_05=0x24).check() is None  # external faults may repeat
    assert a1000(H1_07=0x09).check() == "oPE03"  # baseblock N.O. (S8) and N.C. (S7)


def test_ope02_no_load_current_not_below_rated():
    assert a1000(E2_03=1400).check() == "oPE02"


def test_v7_ope10():
    assert v7(n013=10, n014=15).check() == "oPE10"
    assert v7().check() is None


def test_missing_parameter_keyerror_names_it():
    values = dict(A1000_VALUES)
    del values["C1-02"]
    with pytest.raises(KeyError, match="C1-02"):
        DriveSettings.from_params(Family.A1000, values)
    values = dict(V7_VALUES)
    del values["n020"]
    with pytest.raises(KeyError, match="n020"):
        DriveSettings.from_params(Family.V7, values)
    assert set(required_params(Family.A1000)) <= set(A1000_VALUES)
    assert set(required_params(Family.V7)) <= set(V7_VALUES)


def test_u1_monitors_at_operating_point():
    s = a1000(C1_01=50)
    t_l = 10.0
    d = _running(s, load=LoadSpec("constant", inertia_kgm2=0.05, torque_nm=t_l))
    rpm = d.motor_speed_rpm
    assert d.monitor("U1-01") == 3000
    assert d.monitor("U1-02") == 3000
    assert d.monitor("U1-03") == round(d.output_current_a / 0.01)
    assert d.monitor("U1-04") == 0
    assert d.monitor("U1-05") == round(rpm * 4 / 120 * 100)  # motor speed in 0.01 Hz (o1-03 = 0)
    assert d.monitor("U1-06") == round((15.0 + 185.0 * 27 / 57) * 10)
    assert d.monitor("U1-07") == round(math.sqrt(2) * 200)
    t_r = 3700 / (2 * math.pi * (60 - 2.73) / 2)
    assert d.monitor("U1-09") == round(1000 * t_l / t_r)
    assert d.monitor("U1-12") == 0b0011_0001  # run, speed agree, ready
    assert d.monitor("U1-13") == d.monitor("U1-14") == d.monitor("U1-15") == 0
    assert d.monitor("U1-16") == 3000
    # slip: speed below output frequency by E2-02 * T / T_r
    assert 3000 - d.monitor("U1-05") == pytest.approx(273 * t_l / t_r, abs=1.0)


def test_u1_10_input_terminals():
    d = make_drive(a1000(H1_03=0x0F))  # S3 through mode, so bit 0 raises no EF3
    d.command(DriveCommand(multi_inputs=0b101), 0)
    assert d.monitor("U1-10") == 0b10100  # S3 and S5


@pytest.mark.parametrize("card", ["SI-T3", "SI-ET3"])
def test_sel_mon_a1000_tables_18_and_22(card):
    d = _running(a1000(C1_01=50))
    table = SEL_MON_TABLES[card]
    assert len(table) == 16
    assert d.sel_mon(card, 0x1) == d.monitor("U1-05")
    assert d.sel_mon(card, 0x2) == d.monitor("U1-09")
    assert d.sel_mon(card, 0x3) == 0  # PG counter: no PG option
    assert d.sel_mon(card, 0x4) == 3000
    assert d.sel_mon(card, 0x6) == 283
    assert d.sel_mon(card, 0x7) == 0 and d.sel_mon(card, 0x8) == 0
    assert d.sel_mon(card, 0x9) == d.monitor("U1-11")
    assert d.sel_mon(card, 0xB) == d.monitor("U1-10")
    for code in (0x5, 0xA, 0xC, 0xD, 0x0):
        assert d.sel_mon(card, code) == 0


def test_sel_mon_e_f_registers_f6_23_f6_24():
    values = dict(A1000_VALUES, **{"F6-23": 0x42, "F6-24": 0x46, "C1-01": 50})
    s = DriveSettings.from_params(Family.A1000, values)
    d = _running(s)
    assert d.sel_mon("SI-T3", 0xE) == d.monitor("U1-03")
    assert d.sel_mon("SI-T3", 0xF) == d.monitor("U1-07")


def test_v7_monitors_and_sel_mon_table_5():
    s = v7(n019=50)
    d = _running(s)
    assert d.sel_mon("SI-T/V7", 1) == 3000  # output frequency, n035 = 0: 0.01 Hz
    assert d.sel_mon("SI-T/V7", 4) == 3000
    assert d.sel_mon("SI-T/V7", 6) == 283
    assert d.sel_mon("SI-T/V7", 2) == 0  # torque: vector control only
    assert d.monitor("U-03") == round(d.output_current_a * 10)
    assert d.monitor("U-05") == 283
    dv = _running(v7(n019=50, n002=1))
    assert dv.sel_mon("SI-T/V7", 2) == round(dv.torque_pct * 10)


def test_inputs_while_steady_do_not_cost_integration():
    d = _running(a1000(C1_01=50))
    assert d.is_steady
    cmd = DriveCommand(forward=True, freq_ref_raw=3000)
    d.command(cmd, 8 * S + MS)
    assert d.is_steady  # identical command: nothing re-derived
