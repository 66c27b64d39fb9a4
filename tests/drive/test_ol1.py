"""Motor overload oL1 (I^2 t with a first-order thermal model, docs/drive-model.md):

    d(theta)/dt = ((I / E2-01)^2 - theta) / tau,    trip at theta = 1.21,
    tau = L1-02 / ln(1.25 / (2.25 - 1.21))          (A1000; V7: tau = n038)

so that 150 % current after continuous operation at 100 % (hot start) trips after exactly L1-02
(A1000 Technical Manual, L1-02 "Motor Overload Protection Time": 150 % for L1-02 minutes from a
hot start).  Load currents are produced by load torque: I = sqrt(I0^2 + (I_T T / T_r)^2).
"""

from __future__ import annotations

import math

import pytest

from mlink_sim.drive import DriveCommand, Fault, LoadSpec

from .conftest import MS, S, a1000, make_drive, run_until, v7

P_KW, SLIP, PP, I_RATED, I0 = 3.70, 2.73, 2, 14.0, 4.5
T_RATED = P_KW * 1000 / (2 * math.pi * (60.0 - SLIP) / PP)
I_T = math.sqrt(I_RATED**2 - I0**2)
MIN = 60 * S
TRIP = 1.21


def _torque_for_current(pct: float, i_rated=I_RATED, i0=I0, t_rated=T_RATED) -> float:
    i = pct / 100 * i_rated
    return math.sqrt(i**2 - i0**2) / math.sqrt(i_rated**2 - i0**2) * t_rated


def _load(pct, **kw):
    return LoadSpec("constant", inertia_kgm2=0.05, torque_nm=_torque_for_current(pct, **kw))


def _running(settings, pct, **kw):
    d = make_drive(settings, _load(pct, **kw))
    d.command(DriveCommand(forward=True, freq_ref_raw=4000), 0)
    return d


def test_ol1_150pct_hot_start_trips_at_l1_02_and_not_before():
    s = a1000(L1_02=10, L3_01=0)  # 1.0 min
    d = _running(s, 100)
    d.advance(120 * MIN)  # hot: theta -> 1 (closed form while steady)
    assert d.motor_thermal == pytest.approx(1.0, rel=1e-3)
    t0 = 120 * MIN
    d.set_load(_load(150), t0)
    d.advance(t0 + int(0.99 * MIN))
    assert not d.status.faulted
    t = run_until(d, t0 + 2 * MIN, step=100 * MS, pred=lambda d: d.status.faulted)
    assert (t - t0) / MIN == pytest.approx(1.0, rel=0.01)
    assert d.status.fault is Fault.OL1 and d.status.baseblock
    assert d.monitor("U2-01") == 0x0B


def test_ol1_150pct_cold_start_trip_time():
    s = a1000(L1_02=10)
    d = _running(s, 150)
    tau = 1.0 / math.log(1.25 / (2.25 - TRIP))  # minutes per L1-02 minute
    expected = -tau * math.log(1 - TRIP / 2.25)
    t = run_until(d, 20 * MIN, step=S, pred=lambda d: d.status.faulted)
    assert t / MIN == pytest.approx(expected, rel=0.01)


def test_ol1_does_not_trip_at_105pct_continuous():
    s = a1000(L1_02=10)
    d = _running(s, 105)
    d.advance(600 * MIN)
    assert not d.status.faulted
    assert d.motor_thermal == pytest.approx(1.05**2, rel=1e-3)


def test_ol1_l1_01_0_disables_protection():
    s = a1000(L1_01=0, L1_02=10)
    d = _running(s, 150)
    d.advance(60 * MIN)
    assert not d.status.faulted


def test_ol1_trip_instant_independent_of_polling_step():
    s = a1000(L1_02=10)
    tau_min = 1.0 / math.log(1.25 / (2.25 - TRIP))
    t_trip = -tau_min * math.log(1 - TRIP / 2.25)  # minutes, cold start at 150 %
    d = _running(s, 150)
    t = run_until(d, 20 * MIN, step=MIN, pred=lambda d: d.status.faulted)  # polled once a minute
    assert d.fault_history == (Fault.OL1,)
    assert t == math.ceil(t_trip) * MIN
    # tripped inside the minute at t_trip, then cooled (no current) for the rest of it
    assert d.motor_thermal == pytest.approx(TRIP * math.exp(-(t / MIN - t_trip) / tau_min), rel=5e-3)


def test_v7_ol1_n038_is_the_time_constant():
    s = v7(n038=8, n036=140, n110=32)
    i0 = 14.0 * 0.32
    t_r = s.rated_torque_nm
    d = make_drive(s, LoadSpec("constant", inertia_kgm2=0.05,
                               torque_nm=_torque_for_current(150, 14.0, i0, t_r)))
    d.command(DriveCommand(forward=True, freq_ref_raw=4000), 0)
    t = run_until(d, 30 * MIN, step=S, pred=lambda d: d.status.faulted)
    assert t / MIN == pytest.approx(-8 * math.log(1 - TRIP / 2.25), rel=0.01)
    assert d.status.fault is Fault.OL1
    assert d.sel_mon("SI-T/V7", 7) == 0x0B
