"""Motor and load against physics: slip at rated torque, current, coast-down laws, torque control.

Expected values are computed here from the motor nameplate (E2-xx) and Newton's law, not read
from the model: rated torque T_r = P / w_r with w_r = 2 pi (f_base - s_r) / pp.
"""

from __future__ import annotations

import math

import pytest

from mlink_sim.drive import DriveCommand, LoadSpec

from .conftest import MS, S, a1000, make_drive

P_KW, F_BASE, SLIP, POLES, I_RATED, I_NOLOAD = 3.70, 60.0, 2.73, 4, 14.0, 4.5
PP = POLES // 2
W_RATED = 2 * math.pi * (F_BASE - SLIP) / PP
T_RATED = P_KW * 1000 / W_RATED


def _slip_hz(d) -> float:
    return d.output_frequency_hz - d.motor_speed_rpm * POLES / 120.0


@pytest.mark.parametrize("f_ref", [30.0, 50.0, 60.0])
def test_slip_at_rated_torque_equals_e2_02(f_ref):
    s = a1000(C1_01=50)
    load = LoadSpec("constant", inertia_kgm2=0.05, torque_nm=T_RATED)
    d = make_drive(s, load)
    d.command(DriveCommand(forward=True, freq_ref_raw=int(f_ref * 100)), 0)
    d.advance(10 * S)
    assert not d.status.faulted
    assert _slip_hz(d) == pytest.approx(SLIP, rel=0.02)
    # rated torque draws rated current: I^2 = I0^2 + I_T^2 by the definition of E2-01/E2-03
    assert d.output_current_a == pytest.approx(I_RATED, rel=0.02)
    assert d.monitor("U1-09") == pytest.approx(1000, abs=20)  # 100.0 %


def test_slip_proportional_to_torque():
    s = a1000(C1_01=50)
    d = make_drive(s, LoadSpec("constant", inertia_kgm2=0.05, torque_nm=0.5 * T_RATED))
    d.command(DriveCommand(forward=True, freq_ref_raw=4000), 0)
    d.advance(10 * S)
    assert _slip_hz(d) == pytest.approx(0.5 * SLIP, rel=0.02)


def test_slip_above_base_frequency_scales_with_f_squared():
    # constant voltage above E1-06: flux ~ f_base / f, torque per slip ~ (f_base / f)^2
    s = a1000(C1_01=100, E1_04=1200)
    d = make_drive(s, LoadSpec("constant", inertia_kgm2=0.05, torque_nm=0.5 * T_RATED))
    d.command(DriveCommand(forward=True, freq_ref_raw=9000), 0)
    d.advance(12 * S)
    assert _slip_hz(d) == pytest.approx(0.5 * SLIP * (90.0 / 60.0) ** 2, rel=0.02)


def test_no_load_current_is_e2_03_and_voltage_follows_vf():
    s = a1000(C1_01=50)
    d = make_drive(s, LoadSpec("inertia", inertia_kgm2=0.05))
    d.command(DriveCommand(forward=True, freq_ref_raw=6000), 0)
    d.advance(8 * S)
    assert d.output_current_a == pytest.approx(I_NOLOAD, rel=0.01)
    assert d.output_voltage_v == pytest.approx(200.0)  # E1-05 at E1-06
    d = make_drive(s, LoadSpec("inertia", inertia_kgm2=0.05))
    d.command(DriveCommand(forward=True, freq_ref_raw=3000), 0)
    d.advance(8 * S)
    # linear between (E1-07 3 Hz, 15 V) and (E1-06 60 Hz, 200 V)
    assert d.output_voltage_v == pytest.approx(15.0 + (200.0 - 15.0) * (30 - 3) / (60 - 3), rel=1e-3)


def test_output_power_is_airgap_plus_copper_loss():
    s = a1000(C1_01=50)
    d = make_drive(s, LoadSpec("constant", inertia_kgm2=0.05, torque_nm=T_RATED))
    d.command(DriveCommand(forward=True, freq_ref_raw=6000), 0)
    d.advance(10 * S)
    w_sync = 2 * math.pi * 60.0 / PP
    r_phase = 0.771 / 2
    expected_kw = (T_RATED * w_sync + 3 * I_RATED**2 * r_phase) / 1000
    assert d.output_power_kw == pytest.approx(expected_kw, rel=0.02)
    assert d.monitor("U1-08") == pytest.approx(expected_kw / 0.01, rel=0.02)


def _run_then_coast(load, f_ref_raw=5000):
    s = a1000(C1_01=50, b1_03=1)  # b1-03 = 1: coast to stop
    d = make_drive(s, load)
    d.command(DriveCommand(forward=True, freq_ref_raw=f_ref_raw), 0)
    d.advance(10 * S)
    w0 = d.motor_speed_rad_s
    d.command(DriveCommand(), 10 * S)
    assert d.status.baseblock
    return d, w0


def test_coast_down_viscous_friction_follows_exponential():
    J, B = 0.08, 0.02
    d, w0 = _run_then_coast(LoadSpec("friction", inertia_kgm2=J, viscous_nms=B))
    for t_s in (0.5, 2.0, 5.0, 10.0):
        d.advance(10 * S + int(t_s * S))
        assert d.motor_speed_rad_s == pytest.approx(w0 * math.exp(-B * t_s / J), rel=0.005)


def test_coast_down_constant_torque_is_linear_and_stops():
    J, TL = 0.08, 0.3 * T_RATED
    d, w0 = _run_then_coast(LoadSpec("constant", inertia_kgm2=J, torque_nm=TL))
    t_stop = J * w0 / TL
    d.advance(10 * S + int(0.5 * t_stop * S))
    assert d.motor_speed_rad_s == pytest.approx(0.5 * w0, rel=0.005)
    d.advance(10 * S + int(1.01 * t_stop * S))
    assert d.motor_speed_rad_s == 0.0
    d.advance(20 * S + int(t_stop * S))
    assert d.motor_speed_rad_s == 0.0  # held by the passive load


def test_coast_down_fan_follows_hyperbola():
    J, TF = 0.08, 0.8 * T_RATED  # T = TF (w / w_rated)^2
    d, w0 = _run_then_coast(LoadSpec("fan", inertia_kgm2=J, torque_nm=TF))
    k = TF / W_RATED**2
    for t_s in (0.5, 2.0, 5.0):
        d.advance(10 * S + int(t_s * S))
        assert d.motor_speed_rad_s == pytest.approx(w0 / (1 + k * w0 * t_s / J), rel=0.01)


def test_pure_inertia_keeps_coasting():
    d, w0 = _run_then_coast(LoadSpec("inertia", inertia_kgm2=0.08))
    d.advance(60 * S)
    assert d.motor_speed_rad_s == pytest.approx(w0)


def test_torque_control_d5_01_accelerates_inertia_at_t_over_j():
    J = 0.1
    s = a1000(C1_01=1, d5_01=1, F6_06=1)
    d = make_drive(s, LoadSpec("inertia", inertia_kgm2=J))
    d.command(DriveCommand(forward=True, freq_ref_raw=3000, torque_ref_raw=500), 0)  # 50.0 %
    d.advance(200 * MS)
    alpha = 0.5 * T_RATED / J
    assert d.motor_speed_rad_s == pytest.approx(alpha * 0.2, rel=0.01)
    assert d.status.torque_limited
    assert d.torque_pct == pytest.approx(50.0, rel=1e-6)
    # speed limit = frequency reference (30 Hz): settles at synchronous speed, no load
    d.advance(3 * S)
    assert d.motor_speed_rpm == pytest.approx(900.0, rel=0.002)
    assert not d.status.torque_limited


def test_torque_control_negative_reference_reverses():
    J = 0.1
    s = a1000(C1_01=1, d5_01=1, F6_06=1)
    d = make_drive(s, LoadSpec("inertia", inertia_kgm2=J))
    d.command(DriveCommand(forward=True, freq_ref_raw=3000, torque_ref_raw=-300), 0)
    d.advance(100 * MS)
    assert d.motor_speed_rad_s == pytest.approx(-0.3 * T_RATED / J * 0.1, rel=0.01)


def test_torque_limit_f6_06_caps_motor_torque():
    s = a1000(C1_01=50, F6_06=1)  # d5-01 = 0: the network value is a torque limit
    d = make_drive(s, LoadSpec("constant", inertia_kgm2=0.1, torque_nm=0.3 * T_RATED))
    d.command(DriveCommand(forward=True, freq_ref_raw=3000, torque_limit_raw=1500), 0)
    d.advance(8 * S)
    assert not d.status.torque_limited
    d.set_load(LoadSpec("constant", inertia_kgm2=0.1, torque_nm=0.8 * T_RATED), 8 * S)
    d.command(DriveCommand(forward=True, freq_ref_raw=3000, torque_limit_raw=500), 8 * S)
    w0 = d.motor_speed_rad_s
    d.advance(8 * S + 100 * MS)
    assert d.status.torque_limited
    assert d.torque_pct == pytest.approx(50.0, rel=1e-6)
    # J dw/dt = 0.5 T_r - 0.8 T_r
    assert d.motor_speed_rad_s == pytest.approx(w0 - 0.3 * T_RATED / 0.1 * 0.1, rel=0.01)
