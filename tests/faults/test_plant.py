"""Drive and plant faults from the model's equations, through the card cores (docs/faults.md, docs/drive-model.md):
the station reports what the drive's protections decide, never a flag."""

from __future__ import annotations

import math

import pytest

from mlink_sim.drive import Drive, DriveCommand, DriveSettings, Family, Fault, LoadSpec
from mlink_sim.faults import FaultError, LoadStep, LockRotor, MainsLoss
from mlink_sim.faults.plant import LOCK_MARGIN, PlantFaults, lock_torque_nm

from .helpers import MS, Bench

S = 1_000_000_000
#: run and reference from the option (SI-T3 Table 4 b1-01/b1-02 = 3; V7 n003 = 3, n004 = 9), quick ramps
FAST = {"si-t3": ("b1-01=3", "b1-02=3", "C1-01=0.5", "C1-02=0.5"),
        "si-et3": ("b1-01=3", "b1-02=3", "C1-01=0.5", "C1-02=0.5"),
        "si-t-v7": ("n003=3", "n004=9", "n019=0.5", "n020=0.5")}


def a1000(**overrides: int) -> DriveSettings:
    """The A1000 table defaults (mlink_sim.params) with raw *overrides* (``L1_02=1``), run from the network."""
    values = {"b1-01": 3, "b1-02": 3, **{k.replace("_", "-"): v for k, v in overrides.items()}}
    return DriveSettings.from_defaults(Family.A1000, values)


def running(card: str = "si-t3", hz: float = 30.0) -> Bench:
    b = Bench(card, params=FAST[card]).up()
    raw = round(hz * 100)  # o1-03 = 0 / n035 = 0: 0.01 Hz
    b.core.set_control(0x21, forward=True, speed_ref=raw)
    b.run_until(lambda: abs(b.card.drive.drive.output_frequency_hz - hz) < 0.01, 2000)
    b.run(200)
    return b


@pytest.mark.parametrize("card", ["si-t3", "si-et3", "si-t-v7"])
def test_mains_loss_while_running_is_uv1_then_a_reset_recovers(card):
    """The bus sags under the motor's power to the Uv1 level (SI-T3 Table 26 02H Uv1, V7 Table 10 UV1); the fault
    stays latched when the mains return (docs/drive-model.md §6) until the operator resets it."""
    b = running(card)
    plants = PlantFaults()
    handle = plants.apply(0x21, b.card, MainsLoss(for_ns=300 * MS), b.now)
    b.run_until(lambda: b.card.drive.status.fault is not None, 2000)
    b.run(3)  # the master sees it in the next answers
    snap = b.card.snapshot()
    assert snap.drive.fault in ("Uv1", "UV1") and snap.drive.dc_bus_v < 200.0
    assert not b.card.drive.status.main_power_on
    assert b.core.view(0x21).fault
    plants.release(0x21, b.card, handle, b.now)
    b.run(5)
    assert b.card.drive.status.main_power_on and b.card.drive.status.fault is not None  # latched
    b.core.set_control(0x21, fault_reset=True)
    b.run(5)
    assert b.card.drive.status.fault is None and not b.core.view(0x21).fault


def test_mains_loss_while_stopped_is_the_uv_minor_fault_and_clears_itself():
    b = Bench("si-t3").up()
    plants = PlantFaults()
    handle = plants.apply(0x21, b.card, MainsLoss(for_ns=S), b.now)
    drive = b.card.drive.drive
    drive.advance(b.now + 30 * S)  # 20 W of control power drain the bus slowly (§5)
    assert drive.status.minor is Fault.UV and drive.status.fault is None
    plants.release(0x21, b.card, handle, b.now + 30 * S)
    assert drive.status.minor is None and drive.status.main_power_on


@pytest.mark.parametrize("card", ["si-t3", "si-t-v7"])
def test_lock_rotor_while_running_trips_oc_within_milliseconds(card):
    """The slip jumps from a rated slip to the whole output frequency: the current passes the oC level (200 % of the
    drive rated current; V7 250 %) in the next sub-step (docs/drive-model.md §6)."""
    b = running(card)
    PlantFaults().apply(0x21, b.card, LockRotor(), b.now)
    start = b.now
    b.run_until(lambda: b.card.drive.status.fault is not None, 20)
    assert b.card.drive.status.fault is Fault.OC
    assert b.now - start <= 2 * MS
    b.run(3)
    assert b.card.drive.drive.motor_speed_rpm == 0.0
    assert b.core.view(0x21).alarm_name == "OC"


def test_locked_rotor_from_standstill_trips_ol1_under_stall_prevention():
    """Started against a jam, the drive's stall prevention during acceleration (L3-01/L3-02 150 %) holds the current
    at 150 % of the drive rated current and oL1 trips on the motor's I²t (docs/drive-model.md §6: θ from cold,
    dθ/dt = ((I/E2-01)² − θ)/τ, trip at 1.21): never oC."""
    s = a1000(L1_02=1)  # 0.1 min: τ = 5.44 × 6 s
    d = Drive(Family.A1000, s, LoadSpec("inertia", inertia_kgm2=0.05))

    class Card:  # what PlantFaults touches of a card core
        drive = type("Link", (), {"drive": d})()

    PlantFaults().apply(0x21, Card(), LockRotor(), 0)
    d.command(DriveCommand(forward=True, freq_ref_raw=3000), 0)
    t = 0
    while d.status.fault is None and t < 120 * S:
        t += 100 * MS
        d.advance(t)
    assert d.status.fault is Fault.OL1
    assert d.motor_speed_rpm == 0.0
    i_ratio = 1.5 * s.drive_rated_current_a / s.motor_rated_current_a
    tau = s.ol1_tau_s
    predicted = tau * math.log(i_ratio**2 / (i_ratio**2 - 1.21))
    assert 0.7 * predicted <= t / S <= 1.3 * predicted + 1.0


def test_lock_torque_is_beyond_what_the_oc_level_allows():
    s = a1000()
    assert lock_torque_nm(s, 1e-6) >= LOCK_MARGIN * s.rated_torque_nm
    w_max = 2 * math.pi * s.max_freq_hz / s.pole_pairs
    assert lock_torque_nm(s, 10.0) * 0.5e-3 >= 10.0 * w_max  # stops even a large inertia within 0.5 ms


def test_load_step_torque_slows_the_motor_by_the_slip_law():
    """T = K (w_s − w) with rated slip E2-02 at rated torque (docs/drive-model.md §4): a step of rated torque on an
    unloaded motor lowers its speed by E2-02 (in electrical Hz), and releasing it brings the speed back."""
    b = running("si-t3")
    drive: Drive = b.card.drive.drive
    s = drive.settings
    before = drive.motor_speed_rpm
    plants = PlantFaults()
    handle = plants.apply(0x21, b.card, LoadStep(torque=s.rated_torque_nm), b.now)
    b.run(1500)
    drop_hz = (before - drive.motor_speed_rpm) / 60.0 * s.pole_pairs
    assert drop_hz == pytest.approx(s.motor_rated_slip_hz, rel=0.05)
    assert not b.core.view(0x21).fault
    plants.release(0x21, b.card, handle, b.now)
    b.run(1500)
    assert drive.motor_speed_rpm == pytest.approx(before, rel=1e-3)


def test_load_step_inertia_adds_to_the_shaft():
    b = running("si-t3")
    drive = b.card.drive.drive
    j0 = drive.load.resolve(drive.settings).inertia_kgm2
    PlantFaults().apply(0x21, b.card, LoadStep(inertia=0.2), b.now)
    assert drive.load.inertia_kgm2 == pytest.approx(j0 + 0.2)


def test_torque_step_on_a_fan_load_is_refused():
    b = Bench("si-t3").up()
    b.card.drive.drive.set_load(LoadSpec("fan"), b.now)
    with pytest.raises(FaultError, match="fan load"):
        PlantFaults().apply(0x21, b.card, LoadStep(torque=1.0), b.now)


def test_a_drive_fault_is_applied_released_and_bad_input_refused_by_kind():
    """A slave's drive fault (aio/slave/faults.py, what its ``fault`` / ``release`` operations do): applied with a
    handle, released by it; a station not here, a fault that is not a drive's, an unknown handle are
    ``OpError``s of their kind, never another exception."""
    from mlink_sim.aio.slave.faults import apply_drive_fault, release_drive_fault
    from mlink_sim.faults import fault_from_fields
    from mlink_sim.operations import OpError

    b = Bench("si-t3").up()
    plants = PlantFaults()
    stations = {0x21: b.card}
    handle = apply_drive_fault(stations, plants, 0x21, fault_from_fields("mains-loss", {"for": "1s"}), b.now)
    assert isinstance(handle, int)
    assert not b.card.drive.drive.status.main_power_on or b.card.drive.drive.dc_bus_v > 0
    release_drive_fault(stations, plants, 0x21, handle, b.now)
    load = fault_from_fields("load", {"torque": 1.0})
    for call, kind, why in [
        (lambda: apply_drive_fault(stations, plants, 0x22, load, b.now), "unknown_station", "not served here"),
        (lambda: apply_drive_fault(stations, plants, 0x21, fault_from_fields("silence", {"for": "1s"}), b.now),
         "bad_request", "not a drive fault"),
        (lambda: release_drive_fault(stations, plants, 0x21, 99, b.now), "bad_request", "no drive fault 99"),
    ]:
        with pytest.raises(OpError) as err:
            call()
        assert err.value.kind == kind and why in str(err.value)
