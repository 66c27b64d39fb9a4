"""``Drive.activity()``: what the drive does and what holds it, read without advancing it; ``ramp_seconds``: the
soft starter's time in closed form (docs/drive-model.md sections 3 and 5)."""

from __future__ import annotations

import pytest

from mlink_sim.drive import Drive, DriveCommand, DriveSettings, Family, LoadSpec
from mlink_sim.drive.activity import DriveActivity, ramp_seconds
from mlink_sim.drive.monitors import hz_to_ref

S = 1_000_000_000


def _drive(overrides: dict[str, int], load: str = "inertia") -> tuple[Drive, DriveSettings]:
    s = DriveSettings.from_defaults(Family.A1000, {"b1-01": 3, "b1-02": 3, **overrides})
    return Drive(Family.A1000, s, LoadSpec(kind=load)), s


def test_ramp_seconds_is_delta_over_rate_plus_half_the_s_curves():
    assert ramp_seconds(30.0, 10.0, 60.0) == pytest.approx(5.0)  # docs/drive-model.md: 0 to 30 Hz in 5.0 s
    assert ramp_seconds(40.0, 10.0, 60.0, 0.2, 0.2) == pytest.approx(40 / 6 + 0.2)
    assert ramp_seconds(0.1, 10.0, 60.0, 0.2, 0.2) < 0.2  # too short to reach the rate: peaks below it
    assert ramp_seconds(10.0, 0.0, 60.0) == 0.0


def test_activity_of_a_drive_accelerating_on_c1_01_names_ramp_progress_and_start():
    d, s = _drive({})
    d.command(DriveCommand(forward=True, freq_ref_raw=hz_to_ref(s, 40.0)), 0)
    d.advance(2 * S)
    a = d.activity()
    assert a.doing == "accelerating" and a.ramp == "accel" and a.ramp_s == pytest.approx(10.0)
    assert a.target_hz == pytest.approx(40.0) and 10.0 < a.output_hz < 12.0
    assert a.aim_since_ns == 0 and a.aim_from_hz == 0.0 and a.at_ns == 2 * S
    assert d.now == 2 * S and d.activity() == a  # reading changes nothing
    assert DriveActivity.from_dict(a.as_dict()) == a


def test_activity_names_deceleration_stall_prevention_holding_an_inertia_load():
    d, s = _drive({"C1-01": 20, "C1-02": 10})  # 2.0 s up, 1.0 s down: the inertia feeds the bus (L3-04 = 1)
    d.command(DriveCommand(forward=True, freq_ref_raw=hz_to_ref(s, 40.0)), 0)
    d.command(DriveCommand(), 3 * S)
    d.advance(6 * S)
    a = d.activity()
    assert a.doing == "stopping" and a.ramp == "decel" and a.ramp_alone_hz() < a.output_hz - 10.0
    assert a.dc_bus_v == pytest.approx(a.stall_bus_v, abs=2.0) and a.stall_bus_v == 375.0
    assert a.output_hz > 20.0 and a.aim_since_ns == 3 * S


def test_activity_names_the_fault_and_when_it_tripped():
    d, s = _drive({})
    d.command(DriveCommand(external_fault=True), S)
    a = d.activity()
    assert a.doing == "faulted" and a.fault == "EF0" and a.fault_at_ns == S


def test_activity_says_the_drive_does_not_take_the_networks_run_command():
    s = DriveSettings.from_defaults(Family.A1000)  # b1-02 = 1 (default): run from the terminals
    d = Drive(Family.A1000, s, LoadSpec())
    d.command(DriveCommand(forward=True, freq_ref_raw=hz_to_ref(s, 40.0)), 0)
    d.advance(S)
    a = d.activity()
    assert a.run_requested and not a.run_from_network and not a.running and a.doing == "stopped"
