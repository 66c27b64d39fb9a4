"""Shared fixtures: representative raw parameter sets (drive units, by name).

Values: a 200 V class drive with a 3.7 kW 4-pole motor.  Motor data are the A1000 defaults for a
3.7 kW motor as listed in the A1000 Technical Manual's capacity-dependent defaults table (E2-01
14.00 A, E2-02 2.73 Hz, E2-03 4.50 A, E2-05 0.771 ohm); the remaining settings are the A1000
defaults with b1-01 = b1-02 = 3 (SI-T3 Table 4), A1-02 = 0 (V/f) and the S-curve off unless a test
sets it.  The authoritative default table is ``mlink_sim.params`` (tests/drive/test_params_integration).
"""

from __future__ import annotations

import pytest

from mlink_sim.drive import Drive, DriveSettings, Family, LoadSpec

MS = 1_000_000
S = 1_000_000_000

A1000_VALUES: dict[str, int] = {
    "A1-02": 0, "b1-01": 3, "b1-02": 3, "b1-03": 0,
    "C1-01": 100, "C1-02": 100, "C1-03": 100, "C1-04": 100, "C1-09": 100,
    "C2-01": 0, "C2-02": 0, "C2-03": 0, "C2-04": 0,
    **{f"d1-{i:02d}": 0 for i in range(1, 17)}, "d1-17": 600,
    "d5-01": 0,
    "E1-01": 200, "E1-04": 600, "E1-05": 2000, "E1-06": 600, "E1-07": 30, "E1-08": 150,
    "E1-09": 15, "E1-10": 90,
    "E2-01": 1400, "E2-02": 273, "E2-03": 450, "E2-04": 4, "E2-05": 771, "E2-11": 370,
    "F6-01": 1, "F6-02": 0, "F6-03": 1, "F6-06": 0, "F6-07": 0, "F6-25": 1,
    "H1-03": 0x24, "H1-04": 0x14, "H1-05": 0x03, "H1-06": 0x04, "H1-07": 0x06, "H1-08": 0x08,
    "L1-01": 1, "L1-02": 10, "L3-01": 1, "L3-02": 150, "L3-04": 1, "L4-01": 0, "L4-02": 20,
    "o1-03": 0,
}

V7_VALUES: dict[str, int] = {
    "n002": 0, "n003": 3, "n004": 9, "n005": 0,
    "n011": 600, "n012": 2000, "n013": 600, "n014": 15, "n015": 120, "n016": 15, "n017": 120,
    "n019": 100, "n020": 100, "n021": 100, "n022": 100, "n023": 0,
    **{f"n{i:03d}": 0 for i in range(24, 32)}, "n032": 600,
    "n035": 0, "n036": 140, "n037": 0, "n038": 8,
    "n052": 3, "n053": 5, "n054": 6, "n055": 7, "n056": 10,
    "n092": 0, "n093": 170, "n106": 27, "n107": 386, "n110": 32,
}


def a1000(**overrides: int) -> DriveSettings:
    values = dict(A1000_VALUES)
    values.update({k.replace("_", "-"): v for k, v in overrides.items()})
    return DriveSettings.from_params(Family.A1000, values)


def v7(**overrides: int) -> DriveSettings:
    values = dict(V7_VALUES)
    values.update(overrides)
    return DriveSettings.from_params(Family.V7, values)


def make_drive(settings: DriveSettings, load: LoadSpec | None = None, **kw: object) -> Drive:
    if load is None:
        load = LoadSpec.for_motor(settings, "inertia")
    return Drive(settings.family, settings, load, **kw)  # type: ignore[arg-type]


def run_until(drive: Drive, t_end: int, step: int = MS, pred=None) -> int | None:
    """Advance in ``step`` increments until t_end; return the first time pred(drive) held."""
    t = drive.now
    while t < t_end:
        t = min(t + step, t_end)
        drive.advance(t)
        if pred is not None and pred(drive):
            return t
    return None


@pytest.fixture
def a1000_settings() -> DriveSettings:
    return a1000()
