"""Determinism, step-size independence, closed-form steady state, and the params-table integration."""

from __future__ import annotations

import pytest

from mlink_sim.drive import Drive, DriveCommand, DriveSettings, Family, LoadSpec, required_params

from .conftest import MS, S, a1000, make_drive, v7


def _scenario(d: Drive, step: int) -> list[tuple[float, ...]]:
    out = []
    cmds = {0: DriveCommand(forward=True, freq_ref_raw=4500), 6 * S: DriveCommand(reverse=True, freq_ref_raw=2000),
            14 * S: DriveCommand()}
    t = 0
    while t <= 20 * S:
        if t in cmds:
            d.command(cmds[t], t)
        d.advance(t)
        if t % S == 0:
            out.append((d.output_frequency_hz, d.motor_speed_rad_s, d.dc_bus_v, d.output_current_a,
                        d.motor_thermal))
        t += step
    return out


def _fan(s):
    return LoadSpec("fan", inertia_kgm2=0.05, torque_nm=15.0)


def test_same_inputs_same_outputs_bit_for_bit():
    s = a1000(C1_01=50, C1_02=50, C2_01=50, C2_02=50)
    assert _scenario(make_drive(s, _fan(s)), MS) == _scenario(make_drive(s, _fan(s)), MS)


def test_result_nearly_independent_of_call_rate():
    s = a1000(C1_01=50, C1_02=50)
    fine = _scenario(make_drive(s, _fan(s)), MS)
    coarse = _scenario(make_drive(s, _fan(s)), 100 * MS)  # advance() splits into <= 1 ms sub-steps
    for a, b in zip(fine, coarse):
        for x, y in zip(a, b):
            assert x == pytest.approx(y, rel=1e-3, abs=1e-3)


def test_steady_state_is_closed_form_and_matches_stepping():
    s = a1000(C1_01=50)
    load = LoadSpec("constant", inertia_kgm2=0.05, torque_nm=15.0)
    d1, d2 = make_drive(s, load), make_drive(s, load)
    for d in (d1, d2):
        d.command(DriveCommand(forward=True, freq_ref_raw=4000), 0)
        d.advance(6 * S)
    assert d1.is_steady
    d1.advance(3600 * S)  # one call
    for t in range(7 * S, 3600 * S + 1, S):
        d2.advance(t)
    assert d1.motor_thermal == pytest.approx(d2.motor_thermal, rel=1e-9)
    assert d1.motor_speed_rad_s == d2.motor_speed_rad_s


def test_substep_option_changes_resolution_only():
    s = a1000(C1_01=50)
    d1 = make_drive(s, _fan(s))
    d2 = make_drive(s, _fan(s), substep_ns=250_000)
    for d in (d1, d2):
        d.command(DriveCommand(forward=True, freq_ref_raw=4000), 0)
        d.advance(3 * S)
    assert d1.motor_speed_rad_s == pytest.approx(d2.motor_speed_rad_s, rel=1e-3)


def test_load_spec_from_config_scaled_to_motor():
    s = a1000()
    spec = LoadSpec.from_config({"kind": "fan"}).resolve(s)
    assert spec.inertia_kgm2 == pytest.approx(s.rated_torque_nm * 0.5 / s.rated_speed_rad_s)
    assert spec.torque_nm == pytest.approx(0.8 * s.rated_torque_nm)
    spec = LoadSpec.from_config({"kind": "friction", "inertia": 0.2, "friction": 0.01}).resolve(s)
    assert (spec.inertia_kgm2, spec.torque_nm, spec.viscous_nms) == (0.2, 0.0, 0.01)
    with pytest.raises(ValueError):
        LoadSpec("inertia", inertia_kgm2=0.0)


def test_params_table_defaults_build_settings():
    params = pytest.importorskip("mlink_sim.params")
    for fam in (Family.A1000, Family.V7):
        table = params.FAMILIES[fam.value]
        s = DriveSettings.from_defaults(fam)
        assert s.check() is None
        # every name the model reads is a name of the table (a misspelt name would be a KeyError)
        missing = [n for n in required_params(fam) if n not in table.defaults()]
        assert missing == []
    s = DriveSettings.from_defaults(Family.A1000, {"b1-01": 3, "b1-02": 3})
    e2_01 = params.FAMILIES["a1000"].by_name("E2-01")
    assert s.motor_rated_current_a == pytest.approx(e2_01.default * e2_01.scale)
    d = Drive(Family.A1000, s, LoadSpec("fan"))
    d.command(DriveCommand(forward=True, freq_ref_raw=3000), 0)
    d.advance(10 * S)
    assert d.output_frequency_hz == pytest.approx(30.0) and not d.status.faulted


def test_params_table_v7_defaults_run():
    pytest.importorskip("mlink_sim.params")
    s = DriveSettings.from_defaults(Family.V7, {"n003": 3, "n004": 9})
    d = Drive(Family.V7, s, LoadSpec("constant"))
    d.command(DriveCommand(forward=True, freq_ref_raw=3000), 0)
    d.advance(10 * S)
    assert d.output_frequency_hz == pytest.approx(30.0) and not d.status.faulted


def test_v7_settings_units():
    s = v7(n036=140, n110=32, n106=27, n107=386)
    assert s.motor_rated_current_a == pytest.approx(14.0)
    assert s.motor_no_load_current_a == pytest.approx(4.48)
    assert s.motor_rated_slip_hz == pytest.approx(2.7)
    assert s.motor_phase_resistance_ohm == pytest.approx(0.386)
    assert s.ov_level_v == 410.0 and s.oc_level_pct == 250.0
