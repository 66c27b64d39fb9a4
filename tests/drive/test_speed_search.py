"""Speed search (A1000 b3 group, VS-606V7 n101/n102 and inputs 14/15) and SEr (SI-T3 Table 26, 3BH).

The scenario: a drive running at 30 Hz trips bUS and coasts (F6-01 = 1); the master
resets the fault and runs the drive again while the motor still turns.  Expected values come from the
parameters and the motor equations (docs/drive-model.md, sections 4 and "Speed search"):

* the sweep falls at E1-04 / b3-03 Hz/s from E1-04, after the b3-05 delay;
* the current at slip s is I = sqrt(E2-03^2 + (I_T s / E2-02)^2), so it drops below b3-02 (% of the drive
  rated current) at s_th = E2-02 sqrt(I_b302^2 - E2-03^2) / I_T: the output resumes at f_rotor + s_th;
* Speed Estimation (b3-24 = 1) resumes at the rotor frequency itself, after b3-05.
"""

from __future__ import annotations

import dataclasses
import math

import pytest

from mlink_sim.drive import Drive, DriveCommand, Fault, LoadSpec, StopMethod, fault_code
from mlink_sim.drive.search import SpeedSearch

from .conftest import MS, S, a1000, make_drive, run_until, v7

RUN30 = DriveCommand(forward=True, freq_ref_raw=3000)
RUN40 = DriveCommand(forward=True, freq_ref_raw=4000)
T_TRIP = 8 * S  # bUS while running at 30 Hz
T_RUN = 9 * S  # the master runs the drive again


def _coasting(settings, load: LoadSpec | None = None, run: DriveCommand = RUN30) -> Drive:
    """Run at 30 Hz (speed search off), trip bUS (coast), reset with RUN off, coast for 1 s, then take
    ``settings`` (CONFIG); the drive is at T_RUN, its event log empty."""
    d = make_drive(dataclasses.replace(settings, search=SpeedSearch()), load)
    d.command(run, 0)
    d.advance(T_TRIP)
    d.trip(Fault.BUS, StopMethod.COAST, T_TRIP)
    d.command(DriveCommand(), T_TRIP + MS)
    assert d.reset_fault(T_TRIP + 2 * MS)
    d.reconfigure(settings, T_RUN)
    assert d.status.baseblock and not d.status.faulted
    d.drain_events()
    return d


def _rotor_hz(d: Drive) -> float:
    return d.motor_speed_rad_s * d.settings.pole_pairs / (2.0 * math.pi)


def _found_slip_hz(s, level_pct: float) -> float:
    i_lvl = level_pct / 100.0 * s.drive_rated_current_a
    i0, ir = s.motor_no_load_current_a, s.motor_rated_current_a
    return s.motor_rated_slip_hz * math.sqrt(i_lvl**2 - i0**2) / math.sqrt(ir**2 - i0**2)


def _found(d: Drive) -> tuple[int, float]:
    ev = [(t, det) for t, kind, det in d.drain_events() if kind == "speed_search" and det.startswith("found")]
    assert ev, "no speed search found the motor"
    t, det = ev[-1]
    return t, float(det.split()[1])


def test_b3_01_0_coasting_motor_run_trips_oc_as_before():
    """Without speed search the output starts at 0 Hz into a motor turning at 30 Hz: oC at once."""
    d = _coasting(a1000())
    assert _rotor_hz(d) == pytest.approx(30.0, abs=0.05)
    d.command(RUN40, T_RUN)
    t = run_until(d, T_RUN + S, MS, lambda x: x.status.faulted)
    assert t is not None and t <= T_RUN + 5 * MS
    assert d.status.fault is Fault.OC


def test_b3_01_1_current_detection_resumes_near_motor_speed_no_oc_and_reaches_reference():
    s = a1000(b3_01=1)  # b3-24 = 0 Current Detection, b3-02 100 %, b3-03 2.0 s, b3-05 0.2 s
    d = _coasting(s)
    f_rotor = _rotor_hz(d)
    d.command(RUN40, T_RUN)
    i_max = 0.0
    t = T_RUN
    while t < T_RUN + 5 * S:
        t += MS
        d.advance(t)
        i_max = max(i_max, d.output_current_a)
        assert not d.status.faulted
        if d.speed_search_active:
            assert d.status.running and not d.status.speed_agree
    t_found, f_found = _found(d)
    s_th = _found_slip_hz(s, 100.0)
    assert f_found == pytest.approx(f_rotor + s_th, abs=0.05)
    sweep_rate = s.max_freq_hz / 2.0  # E1-04 / b3-03
    expect = 0.2 + (s.max_freq_hz - f_found) / sweep_rate
    assert (t_found - T_RUN) / S == pytest.approx(expect, abs=0.003)
    assert i_max <= s.drive_rated_current_a * 1.001 < s.oc_level_pct / 100.0 * s.drive_rated_current_a
    assert d.output_frequency_hz == pytest.approx(40.0)
    assert d.status.speed_agree and not d.speed_search_active
    # from f_found the ramp goes on at E1-04 / C1-01 = 6 Hz/s
    d2 = _coasting(s)
    d2.command(RUN40, T_RUN)
    t40 = run_until(d2, T_RUN + 5 * S, MS, lambda x: not x.speed_search_active and x.output_frequency_hz >= 40.0 - 1e-9)
    assert (t40 - t_found) / S == pytest.approx((40.0 - f_found) / 6.0, abs=0.01)


def test_b3_24_1_speed_estimation_resumes_at_rotor_frequency_after_b3_05():
    s = a1000(b3_01=1, b3_24=1, b3_05=5)  # b3-05 = 0.5 s
    d = _coasting(s)
    f_rotor = _rotor_hz(d)
    d.command(RUN40, T_RUN)
    assert run_until(d, T_RUN + 5 * S, MS, lambda x: x.status.faulted) is None
    t_found, f_found = _found(d)
    assert (t_found - T_RUN) / S == pytest.approx(0.5, abs=0.002)
    assert f_found == pytest.approx(f_rotor, abs=0.01)
    assert d.output_frequency_hz == pytest.approx(40.0)


def test_b3_24_1_speed_estimation_finds_a_motor_turning_the_other_way():
    """Speed Estimation "works both forwards and in reverse": the output starts in the rotor's direction and
    ramps through zero to the commanded one."""
    s = a1000(b3_01=1, b3_24=1)
    d = _coasting(s, run=DriveCommand(reverse=True, freq_ref_raw=3000))
    assert _rotor_hz(d) == pytest.approx(-30.0, abs=0.05)
    d.command(RUN30, T_RUN)
    assert run_until(d, T_RUN + 12 * S, MS, lambda x: x.status.faulted) is None
    _, f_found = _found(d)
    assert f_found == pytest.approx(30.0, abs=0.05)
    assert d.output_frequency_hz == pytest.approx(30.0) and _rotor_hz(d) > 29.0


def test_current_detection_is_unidirectional_sweeps_to_zero_for_reverse_rotation():
    """Current Detection searches in the run direction only: a motor turning the other way is not found and
    the output starts from 0 Hz, as without speed search."""
    s = a1000(b3_01=1)
    d = _coasting(s, run=DriveCommand(reverse=True, freq_ref_raw=3000))
    d.command(RUN30, T_RUN)
    run_until(d, T_RUN + 3 * S, MS, lambda x: not x.speed_search_active)
    _, f_found = _found(d)
    assert f_found == 0.0


@pytest.mark.parametrize("settings, bit, level_pct, start_hz, delay_s", [
    # A1000 H1-05 = 62H External Search Command 2: from the reference, after b3-05 (0.2 s), b3-02 100 %
    (a1000(H1_05=0x62), 2, 100.0, 40.0, 0.2),
    # V7 n055 = 14 search command from maximum frequency: n011, no delay, n101 2.0 s, n102 150 %
    (v7(n055=14), 3, 150.0, 60.0, 0.0),
])
def test_search_command_input(settings, bit, level_pct, start_hz, delay_s):
    """A search-command input on at the run command: no oC; the sweep (60 Hz / 2.0 s) starts at E1-04 / n011
    or at the reference; the output resumes at f_rotor + s_th and reaches the reference."""
    d = _coasting(settings)
    f_rotor = _rotor_hz(d)
    d.command(DriveCommand(forward=True, freq_ref_raw=4000, multi_inputs=1 << bit), T_RUN)
    assert run_until(d, T_RUN + 5 * S, MS, lambda x: x.status.faulted) is None
    t_found, f_found = _found(d)
    assert f_found == pytest.approx(f_rotor + _found_slip_hz(settings, level_pct), abs=0.05)
    assert (t_found - T_RUN) / S == pytest.approx(delay_s + (start_hz - f_found) / 30.0, abs=0.003)
    assert d.output_frequency_hz == pytest.approx(40.0)


def test_ser_after_b3_19_restarts_when_the_current_stays_above_b3_17():
    """b3-02 = 180 % above b3-17 = 150 %: the search ends where the current is 180 %; with a high inertia it
    stays above 150 % for longer than b3-18 = 0.10 s, so the search restarts (after b3-25 = 0.5 s) and ends the
    same way; the (b3-19 + 1)-th restart is SEr ("Too Many Speed Search Restarts", SI-T3 Table 26, 3BH)."""
    for restarts in (3, 1):
        s = a1000(b3_01=1, b3_02=180, b3_17=150, b3_19=restarts)
        load = LoadSpec.for_motor(s, "inertia", starting_time_s=20.0)
        d = _coasting(s, load)
        d.command(DriveCommand(forward=True, freq_ref_raw=6000), T_RUN)
        t = run_until(d, T_RUN + 20 * S, MS, lambda x: x.status.faulted)
        assert t is not None and d.status.fault is Fault.SER
        ev = [det for _, kind, det in d.drain_events() if kind == "speed_search"]
        assert sum(det.startswith("restart") for det in ev) == restarts
        assert sum(det.startswith("found") for det in ev) == restarts + 1
        assert fault_code(s.family, Fault.SER) == 0x3B
        assert d.status.baseblock  # SEr is a fault: output off, motor coasts


def test_no_restart_when_the_current_falls_below_b3_17():
    s = a1000(b3_01=1)  # b3-02 100 % < b3-17 150 %
    d = _coasting(s, LoadSpec.for_motor(s, "inertia", starting_time_s=20.0))
    d.command(DriveCommand(forward=True, freq_ref_raw=6000), T_RUN)
    assert run_until(d, T_RUN + 15 * S, MS, lambda x: x.status.faulted) is None
    assert not any(det.startswith("restart") for _, k, det in d.drain_events() if k == "speed_search")


def test_run_removed_during_the_search_leaves_the_motor_coasting():
    s = a1000(b3_01=1)
    d = _coasting(s)
    d.command(RUN40, T_RUN)
    d.advance(T_RUN + 500 * MS)
    assert d.speed_search_active and not d.status.baseblock
    d.command(DriveCommand(), T_RUN + 500 * MS)
    assert d.status.baseblock and not d.speed_search_active and not d.status.running
    assert _rotor_hz(d) == pytest.approx(30.0, abs=0.05)


def test_v7_without_the_search_input_trips_oc():
    d = _coasting(v7(n055=14))
    d.command(DriveCommand(forward=True, freq_ref_raw=4000), T_RUN)
    assert run_until(d, T_RUN + S, MS, lambda x: x.status.faulted) is not None
    assert d.status.fault is Fault.OC


def test_search_result_nearly_independent_of_call_rate():
    def final(step: int) -> tuple[float, float]:
        d = _coasting(a1000(b3_01=1))
        d.command(RUN40, T_RUN)
        run_until(d, T_RUN + 3 * S, step)
        return d.output_frequency_hz, d.motor_speed_rad_s

    a, b, c = final(MS), final(37 * MS), final(MS)
    assert a == c  # bit-identical repeat
    assert b[0] == pytest.approx(a[0], rel=1e-3) and b[1] == pytest.approx(a[1], rel=1e-3)


def test_settings_from_b3_and_v7_constants():
    ss = a1000(b3_01=1, b3_02=120, b3_03=30, b3_05=4, b3_17=160, b3_18=20, b3_19=5, b3_24=1, b3_25=10).search
    assert (ss.at_start, ss.estimation, ss.current_pct, ss.decel_s, ss.delay_s) == (True, True, 120.0, 3.0, 0.4)
    assert (ss.restart_pct, ss.restart_s, ss.restarts, ss.wait_s) == (160.0, 0.2, 5, 1.0)
    assert not a1000().search.at_start  # b3-01 default 0 (A1-02 = 0/2)
    sv = v7(n101=15, n102=120).search
    assert (sv.at_start, sv.decel_s, sv.current_pct, sv.restart_pct) == (False, 1.5, 120.0, math.inf)
