"""Reference path: ramps referred to E1-04, S-curve, fast stop, direction, multi-step, units.

Expected values come from the parameter definitions (A1000 Technical Manual: C1-01 is the time
from 0 to E1-04; with S-curve the time grows by (C2-01 + C2-02) / 2), not from the model.
"""

from __future__ import annotations

import pytest

from mlink_sim.drive import DriveCommand, Fault, LoadSpec, StopMethod

from .conftest import MS, S, a1000, make_drive, run_until, v7


def _friction_load(settings):
    # a load that always absorbs the small decel energy, so the bus never limits the ramp
    return LoadSpec.for_motor(settings, "friction", load_pct=50.0, starting_time_s=0.05)


def test_ramp_30hz_c1_01_10s_e1_04_60hz_takes_5s():
    s = a1000(C1_01=100, E1_04=600)  # 10.0 s, 60.0 Hz
    d = make_drive(s, _friction_load(s))
    d.command(DriveCommand(forward=True, freq_ref_raw=3000), 0)
    t = run_until(d, 8 * S, pred=lambda d: d.output_frequency_hz >= 30.0 - 1e-9)
    assert t == pytest.approx(5.0 * S, rel=0.01)
    # halfway: 2.5 s -> 15 Hz on a linear ramp
    d2 = make_drive(s, _friction_load(s))
    d2.command(DriveCommand(forward=True, freq_ref_raw=3000), 0)
    d2.advance(int(2.5 * S))
    assert d2.output_frequency_hz == pytest.approx(15.0, rel=0.01)


def test_ramp_time_scales_with_e1_04_not_with_target():
    s = a1000(C1_01=100, E1_04=1200, E1_06=600)  # 10 s to 120 Hz -> 12 Hz/s
    d = make_drive(s, _friction_load(s))
    d.command(DriveCommand(forward=True, freq_ref_raw=3000), 0)
    t = run_until(d, 8 * S, pred=lambda d: d.output_frequency_hz >= 30.0 - 1e-9)
    assert t == pytest.approx(2.5 * S, rel=0.01)


def test_s_curve_c2_01_c2_02_adds_half_their_sum():
    s = a1000(C1_01=100, C2_01=50, C2_02=100)  # 0.5 s at accel start, 1.0 s at accel end
    d = make_drive(s, _friction_load(s))
    d.command(DriveCommand(forward=True, freq_ref_raw=3000), 0)
    d.advance(250 * MS)
    # jerk-limited start: a = 6 Hz/s reached over 0.5 s, f(t) = (6 / 0.5) t^2 / 2
    assert d.output_frequency_hz == pytest.approx(12.0 * 0.25**2 / 2.0, rel=0.03)
    t = run_until(d, 9 * S, pred=lambda d: d.output_frequency_hz >= 30.0 - 1e-6)
    assert t == pytest.approx((5.0 + (0.5 + 1.0) / 2.0) * S, rel=0.01)


def test_s_curve_decel_c2_03_c2_04():
    s = a1000(C1_01=1, C1_02=100, C2_03=40, C2_04=60)
    d = make_drive(s, _friction_load(s))
    d.command(DriveCommand(forward=True, freq_ref_raw=6000), 0)
    d.advance(1 * S)
    assert d.output_frequency_hz == pytest.approx(60.0)
    d.command(DriveCommand(forward=True, freq_ref_raw=3000), 1 * S)
    t = run_until(d, 10 * S, pred=lambda d: d.output_frequency_hz <= 30.0 + 1e-6)
    assert (t - 1 * S) == pytest.approx((5.0 + (0.4 + 0.6) / 2.0) * S, rel=0.01)


def test_decel_c1_02_ramp_to_stop_then_baseblock():
    s = a1000(C1_01=1, C1_02=50)  # 5.0 s from E1-04
    d = make_drive(s, _friction_load(s))
    d.command(DriveCommand(forward=True, freq_ref_raw=6000), 0)
    d.advance(1 * S)
    d.command(DriveCommand(), 1 * S)
    assert d.status.running and not d.status.baseblock
    t = run_until(d, 10 * S, pred=lambda d: d.status.baseblock)
    assert (t - 1 * S) == pytest.approx(5.0 * S, rel=0.01)
    assert not d.status.running


def test_fast_stop_uses_c1_09():
    s = a1000(C1_01=1, C1_02=100, C1_09=20, F6_01=2)  # fast stop 2.0 s from E1-04
    d = make_drive(s, _friction_load(s))
    d.command(DriveCommand(forward=True, freq_ref_raw=6000), 0)
    d.advance(1 * S)
    d.trip(Fault.BUS, s.bus_stop, 1 * S)
    assert s.bus_stop is StopMethod.FAST
    t = run_until(d, 10 * S, pred=lambda d: d.status.baseblock)
    assert (t - 1 * S) == pytest.approx(2.0 * S, rel=0.01)


def test_forward_to_reverse_passes_through_zero():
    s = a1000(C1_01=100, C1_02=100)
    d = make_drive(s, _friction_load(s))
    d.command(DriveCommand(forward=True, freq_ref_raw=3000), 0)
    d.advance(6 * S)
    assert not d.status.reverse
    d.command(DriveCommand(reverse=True, freq_ref_raw=3000), 6 * S)
    d.advance(6 * S + 4900 * MS)
    assert d.output_frequency_hz > 0.0  # still decelerating forward
    t = run_until(d, 20 * S, pred=lambda d: d.output_frequency_hz <= -30.0 + 1e-9)
    assert (t - 6 * S) == pytest.approx(10.0 * S, rel=0.01)
    assert d.status.reverse and d.motor_speed_rpm < 0


def test_speed_agree_within_l4_02_of_reference():
    s = a1000(C1_01=100, L4_02=20)  # 2.0 Hz
    d = make_drive(s, _friction_load(s))
    d.command(DriveCommand(forward=True, freq_ref_raw=3000), 0)
    t = run_until(d, 6 * S, pred=lambda d: d.status.speed_agree)
    assert t == pytest.approx(28.0 / 6.0 * S, rel=0.01)


def test_user_speed_agree_l4_01():
    s = a1000(C1_01=100, L4_01=200, L4_02=20)  # 20.0 Hz +- 2.0 Hz
    d = make_drive(s, _friction_load(s))
    d.command(DriveCommand(forward=True, freq_ref_raw=3000), 0)
    t = run_until(d, 6 * S, pred=lambda d: d.status.user_speed_agree)
    assert t == pytest.approx(18.0 / 6.0 * S, rel=0.01)


def test_zero_speed_below_e1_09():
    s = a1000(C1_01=100, E1_09=15)  # 1.5 Hz
    d = make_drive(s, _friction_load(s))
    assert d.status.zero_speed
    d.command(DriveCommand(forward=True, freq_ref_raw=3000), 0)
    t = run_until(d, 2 * S, pred=lambda d: not d.status.zero_speed)
    assert t == pytest.approx(1.5 / 6.0 * S, abs=2 * MS)


def test_multi_step_f6_07_1_selects_d1_02_with_s5():
    s = a1000(C1_01=1, F6_07=1, d1_02=1500)
    d = make_drive(s, _friction_load(s))
    d.command(DriveCommand(forward=True, freq_ref_raw=3000, multi_inputs=1 << 2), 0)  # S5 = H1-05 = 3
    d.advance(100 * MS)
    assert d.output_frequency_hz == pytest.approx(15.0)
    assert d.monitor("U1-01") == 1500


def test_multi_step_f6_07_0_ignores_inputs():
    s = a1000(C1_01=1, F6_07=0, d1_02=1500)
    d = make_drive(s, _friction_load(s))
    d.command(DriveCommand(forward=True, freq_ref_raw=3000, multi_inputs=1 << 2), 0)
    d.advance(100 * MS)
    assert d.output_frequency_hz == pytest.approx(30.0)


def test_jog_input_uses_d1_17():
    s = a1000(C1_01=1, d1_17=600)
    d = make_drive(s, _friction_load(s))
    d.command(DriveCommand(forward=True, freq_ref_raw=3000, multi_inputs=1 << 4), 0)  # S7 = H1-07 = 6
    d.advance(100 * MS)
    assert d.output_frequency_hz == pytest.approx(6.0)


def test_accel_time_2_input_uses_c1_03():
    s = a1000(C1_01=100, C1_03=50, H1_07=0x07)  # S7: accel/decel time 1 selection
    d = make_drive(s, _friction_load(s))
    d.command(DriveCommand(forward=True, freq_ref_raw=3000, multi_inputs=1 << 4), 0)
    t = run_until(d, 8 * S, pred=lambda d: d.output_frequency_hz >= 30.0 - 1e-9)
    assert t == pytest.approx(2.5 * S, rel=0.01)


@pytest.mark.parametrize(("o1_03", "raw"), [(0, 3000), (1, 5000), (2, 900)])
def test_o1_03_reference_units(o1_03, raw):
    # 0: 0.01 Hz; 1: 0.01 % of E1-04; 2: r/min with E2-04 = 4 poles -> 30 Hz in each case
    s = a1000(C1_01=1, o1_03=o1_03)
    d = make_drive(s, _friction_load(s))
    d.command(DriveCommand(forward=True, freq_ref_raw=raw), 0)
    d.advance(100 * MS)
    assert d.output_frequency_hz == pytest.approx(30.0)
    assert d.monitor("U1-01") == raw
    assert d.monitor("U1-02") == raw


def test_reference_clamped_to_e1_04():
    s = a1000(C1_01=1)
    d = make_drive(s, _friction_load(s))
    d.command(DriveCommand(forward=True, freq_ref_raw=9000), 0)
    d.advance(100 * MS)
    assert d.output_frequency_hz == pytest.approx(60.0)


def test_v7_n019_ramp_referred_to_n011():
    s = v7(n019=100, n011=600)
    d = make_drive(s, _friction_load(s))
    d.command(DriveCommand(forward=True, freq_ref_raw=3000), 0)
    t = run_until(d, 8 * S, pred=lambda d: d.output_frequency_hz >= 30.0 - 1e-9)
    assert t == pytest.approx(5.0 * S, rel=0.01)


def test_v7_n023_s_curve_0_5s():
    s = v7(n019=100, n023=2)  # 0.5 s at both ends
    d = make_drive(s, _friction_load(s))
    d.command(DriveCommand(forward=True, freq_ref_raw=3000), 0)
    t = run_until(d, 8 * S, pred=lambda d: d.output_frequency_hz >= 30.0 - 1e-6)
    assert t == pytest.approx(5.5 * S, rel=0.01)


def test_v7_multi_step_always_enabled_n025_with_s5():
    s = v7(n019=1, n025=2000)
    d = make_drive(s, _friction_load(s))
    d.command(DriveCommand(forward=True, freq_ref_raw=3000, multi_inputs=1 << 2), 0)  # n054 = 6
    d.advance(100 * MS)
    assert d.output_frequency_hz == pytest.approx(20.0)


def test_not_remote_ignores_network_run():
    s = a1000(b1_02=1)
    d = make_drive(s)
    d.command(DriveCommand(forward=True, freq_ref_raw=3000), 0)
    d.advance(1 * S)
    assert not d.status.running and not d.status.remote
    assert d.output_frequency_hz == 0.0
