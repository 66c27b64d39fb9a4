"""Stopping per cause (F6-01 bUS, F6-25 E5, F6-03/F6-02 EF0), fault records, reset rules, codes.

Codes are SI-T3 Table 26 (faults) / Table 27 (minor faults) and SI-T/V7 Table 10 / Table 11.
"""

from __future__ import annotations

import pytest

from mlink_sim.drive import (
    SI_T3_FAULT_CODES,
    SI_T3_MINOR_CODES,
    V7_FAULT_CODES,
    V7_WARNING_CODES,
    DriveCommand,
    Fault,
    LoadSpec,
    StopMethod,
    fault_code,
    minor_code,
    ml2_status_bits,
)

from .conftest import MS, S, a1000, make_drive, run_until, v7

RUN = DriveCommand(forward=True, freq_ref_raw=6000)


def _at_speed(settings, load=None):
    load = load or LoadSpec.for_motor(settings, "friction", load_pct=50.0, starting_time_s=0.05)
    d = make_drive(settings, load)
    d.command(RUN, 0)
    d.advance(1 * S)
    assert d.output_frequency_hz == pytest.approx(60.0)
    return d


def test_si_t3_table_26_27_codes_sample():
    assert SI_T3_FAULT_CODES[Fault.BUS] == 0x22 and SI_T3_MINOR_CODES[Fault.BUS] == 0x15
    assert SI_T3_FAULT_CODES[Fault.E5] == 0x39 and SI_T3_MINOR_CODES[Fault.E5] == 0x31
    assert SI_T3_FAULT_CODES[Fault.EF0] == 0x27 and SI_T3_MINOR_CODES[Fault.EF0] == 0x1A
    assert SI_T3_FAULT_CODES[Fault.OV] == 0x08 and SI_T3_MINOR_CODES[Fault.OV] == 0x02
    assert SI_T3_FAULT_CODES[Fault.OC] == 0x07 and SI_T3_FAULT_CODES[Fault.OL1] == 0x0B
    assert SI_T3_MINOR_CODES[Fault.CYC] == 0x33 and SI_T3_MINOR_CODES[Fault.AER] == 0x32
    assert Fault.BUS.can_trip and Fault.BUS.can_alarm
    assert Fault.OC.can_trip and not Fault.OC.can_alarm
    assert Fault.BB.can_alarm and not Fault.BB.can_trip


def test_si_t_v7_table_10_11_codes_sample():
    assert V7_FAULT_CODES[Fault.BUS] == 0xE6 and V7_FAULT_CODES[Fault.E5] == 0xE5
    assert V7_FAULT_CODES[Fault.EF0] == 0x27 and V7_FAULT_CODES[Fault.STP] == 0x50
    assert V7_WARNING_CODES[Fault.BB] == 0x08 and V7_WARNING_CODES[Fault.SER_SEQ] == 0x20
    assert Fault.SER_SEQ.display == "SEr"
    assert fault_code("v7", Fault.OC) == 0x07 and minor_code("v7", Fault.UV) == 0x01
    # codes are unique within each table
    for table in (SI_T3_FAULT_CODES, SI_T3_MINOR_CODES, V7_FAULT_CODES, V7_WARNING_CODES):
        assert len(set(table.values())) == len(table)


@pytest.mark.parametrize(("f6_01", "stop_s"), [(0, 10.0), (2, 2.0)])
def test_bus_f6_01_ramp_or_fast_stop(f6_01, stop_s):
    s = a1000(C1_01=1, C1_02=100, C1_09=20, F6_01=f6_01)
    d = _at_speed(s)
    d.trip(Fault.BUS, s.bus_stop, 1 * S)
    st = d.status
    assert st.faulted and st.fault is Fault.BUS and st.running and not st.baseblock
    t = run_until(d, 20 * S, pred=lambda d: d.status.baseblock)
    assert (t - 1 * S) / S == pytest.approx(stop_s, rel=0.01)
    assert d.monitor("U2-01") == 0x22 and d.sel_mon("SI-T3", 7) == 0x22


def test_bus_f6_01_coast_cuts_output_immediately():
    s = a1000(C1_01=1, F6_01=1)
    d = _at_speed(s)
    w0 = d.motor_speed_rad_s
    d.trip(Fault.BUS, s.bus_stop, 1 * S)
    st = d.status
    assert st.baseblock and not st.running and st.fault is Fault.BUS
    d.advance(1 * S + 10 * MS)
    assert 0 < d.motor_speed_rad_s < w0  # the load slows the motor


def test_bus_f6_01_alarm_only_keeps_running_with_minor_fault():
    s = a1000(C1_01=1, F6_01=3)
    d = _at_speed(s)
    d.trip(Fault.BUS, s.bus_stop, 1 * S)
    d.advance(2 * S)
    st = d.status
    assert not st.faulted and st.minor is Fault.BUS and st.running
    assert d.output_frequency_hz == pytest.approx(60.0)
    assert d.sel_mon("SI-T3", 8) == 0x15
    assert d.fault_history == ()  # minor faults are not recorded
    d.clear_minor(Fault.BUS, 2 * S)
    assert not d.status.minor_fault


def test_bus_f6_01_5_alarm_and_ramp_to_stop():
    s = a1000(C1_01=1, C1_02=20, F6_01=5)
    d = _at_speed(s)
    d.trip(Fault.BUS, s.bus_stop, 1 * S)
    t = run_until(d, 5 * S, pred=lambda d: d.status.baseblock)
    assert (t - 1 * S) / S == pytest.approx(2.0, rel=0.01)
    assert not d.status.faulted and d.status.minor is Fault.BUS


def test_e5_follows_f6_25():
    s = a1000(C1_01=1, F6_25=1, F6_01=3)
    d = _at_speed(s)
    d.trip(Fault.E5, s.e5_stop, 1 * S)
    assert d.status.fault is Fault.E5 and d.status.baseblock
    assert d.monitor("U2-01") == 0x39


def test_ef0_f6_03_ramp_from_network_bit():
    s = a1000(C1_01=1, C1_02=50, F6_03=0)
    d = _at_speed(s)
    d.command(DriveCommand(forward=True, freq_ref_raw=6000, external_fault=True), 1 * S)
    assert d.status.fault is Fault.EF0 and d.status.running
    t = run_until(d, 10 * S, pred=lambda d: d.status.baseblock)
    assert (t - 1 * S) / S == pytest.approx(5.0, rel=0.01)


def test_ef0_f6_02_1_detected_during_run_only():
    s = a1000(C1_01=1, F6_02=1)
    d = make_drive(s)
    d.command(DriveCommand(external_fault=True), 0)
    assert not d.status.faulted
    d.command(DriveCommand(forward=True, freq_ref_raw=3000, external_fault=True), 1 * S)
    assert d.status.fault is Fault.EF0
    s0 = a1000(F6_02=0)
    d0 = make_drive(s0)
    d0.command(DriveCommand(external_fault=True), 0)
    assert d0.status.fault is Fault.EF0


def test_ef0_alarm_only_clears_with_input():
    s = a1000(C1_01=1, F6_03=3)
    d = _at_speed(s)
    d.command(DriveCommand(forward=True, freq_ref_raw=6000, external_fault=True), 1 * S)
    assert d.status.minor is Fault.EF0 and d.status.running
    d.command(RUN, 2 * S)
    assert not d.status.minor_fault


def test_fault_reset_refused_while_run_on_and_accepted_after():
    s = a1000(C1_01=1, F6_01=1)
    d = _at_speed(s)
    d.trip(Fault.BUS, StopMethod.COAST, 1 * S)
    assert d.reset_fault(1 * S) is False
    assert d.status.fault is Fault.BUS
    d.command(DriveCommand(), 2 * S)
    assert d.reset_fault(2 * S) is True
    st = d.status
    assert not st.faulted and st.ready
    assert d.monitor("U2-01") == 0 and d.monitor("U2-02") == 0x22
    assert d.monitor("U3-01") == 0x22


def test_fault_reset_bit_rising_edge_and_reset_status_bit():
    s = a1000(C1_01=1, F6_01=1)
    d = _at_speed(s)
    d.trip(Fault.BUS, StopMethod.COAST, 1 * S)
    d.command(DriveCommand(), 2 * S)
    assert ml2_status_bits(d.status) & 1  # ALM
    d.command(DriveCommand(fault_reset=True), 3 * S)
    st = d.status
    assert not st.faulted and st.fault_reset_input
    assert ml2_status_bits(st) & (1 << 8)  # RESET
    d.command(DriveCommand(), 4 * S)
    assert not d.status.fault_reset_input


def test_alarm_not_reported_while_fault_reset_input_on():
    s = a1000(C1_01=1, F6_01=1)
    d = _at_speed(s)
    d.command(DriveCommand(forward=True, freq_ref_raw=6000, fault_reset=True), 1 * S)
    d.trip(Fault.BUS, StopMethod.COAST, 1 * S)
    st = d.status
    assert st.faulted and st.fault_reset_input
    assert not ml2_status_bits(st) & 1  # SI-T3 Table 16 note <2>


def test_ef0_fault_cannot_be_reset_while_input_on():
    s = a1000(F6_03=1)
    d = make_drive(s)
    d.command(DriveCommand(external_fault=True), 0)
    assert d.reset_fault(1 * S) is False
    d.command(DriveCommand(), 2 * S)
    assert d.reset_fault(2 * S) is True


def test_fault_history_u3_and_clear():
    s = a1000(F6_01=1, F6_25=1)
    d = make_drive(s)
    for i, f in enumerate((Fault.BUS, Fault.E5, Fault.BUS)):
        d.trip(f, StopMethod.COAST, i * S)
        assert d.reset_fault(i * S)
    assert d.fault_history == (Fault.BUS, Fault.E5, Fault.BUS)
    assert [d.monitor(f"U3-{i:02d}") for i in (1, 2, 3, 4)] == [0x22, 0x39, 0x22, 0]
    d.command(DriveCommand(fault_history_clear=True), 5 * S)
    assert d.fault_history == () and d.monitor("U3-01") == 0


def test_ef3_from_multi_function_input_h1_03_24h_coasts():
    s = a1000(C1_01=1)  # H1-03 = 24H: EF3, N.O., always detected, coast
    d = _at_speed(s)
    d.command(DriveCommand(forward=True, freq_ref_raw=6000, multi_inputs=1), 1 * S)
    st = d.status
    assert st.fault is Fault.EF3 and st.baseblock
    assert d.monitor("U2-01") == 0x11


def test_external_baseblock_minor_bb():
    s = a1000(C1_01=1)
    d = _at_speed(s)
    d.command(DriveCommand(forward=True, freq_ref_raw=6000, external_baseblock=True), 1 * S)
    st = d.status
    assert st.baseblock and st.minor is Fault.BB and not st.faulted
    assert d.sel_mon("SI-T3", 8) == 0x08


def test_forward_and_reverse_together_ef_after_half_a_second():
    s = a1000(C1_01=1)
    d = make_drive(s)
    d.command(DriveCommand(forward=True, reverse=True, freq_ref_raw=3000), 0)
    d.advance(499 * MS)
    assert not d.status.minor_fault and not d.status.running
    d.advance(500 * MS)
    assert d.status.minor is Fault.EF
    d.command(DriveCommand(forward=True, freq_ref_raw=3000), 1 * S)
    assert not d.status.minor_fault


def test_card_minor_cyc_and_lowest_code_wins():
    s = a1000(F6_01=3)
    d = make_drive(s)
    d.trip(Fault.CYC, StopMethod.ALARM_ONLY, 0)
    d.trip(Fault.BUS, StopMethod.ALARM_ONLY, 0)
    assert d.status.minor is Fault.BUS  # 15H < 33H (SI-T3 "warning with the lowest code")
    assert d.status.minors == {Fault.BUS, Fault.CYC}


def test_v7_bus_e5_ef0_are_faults_coasting():
    s = v7(n019=1)
    d = _at_speed(s)
    d.trip(Fault.BUS, s.bus_stop, 1 * S)
    assert d.status.fault is Fault.BUS and d.status.baseblock
    assert d.sel_mon("SI-T/V7", 7) == 0xE6
    assert d.monitor("U-09") == 0xE6


def test_events_for_the_card_to_log():
    s = a1000(F6_01=1)
    d = make_drive(s)
    d.trip(Fault.BUS, StopMethod.COAST, 5 * MS)
    d.reset_fault(7 * MS)
    assert d.drain_events() == [(5 * MS, "fault", "bUS COAST"), (7 * MS, "fault_reset", "bUS")]
    assert d.drain_events() == []
