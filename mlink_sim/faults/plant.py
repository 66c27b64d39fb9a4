"""Drive and plant faults, applied to a station's drive model on the slave side: sans-I/O, time is
``now`` (ns). Nothing here sets an alarm: each fault changes an input of the model's equations (docs/drive-model.md)
and the drive reacts as they decide.

* ``load`` — the load on the shaft steps: ``torque`` N·m of passive constant torque and/or ``inertia`` kg·m² are
  added to the station's load (§4); removed again by :meth:`PlantFaults.release`.
* ``lock-rotor`` — the shaft jams: a passive load torque ten times what the motor develops at the drive's oC current
  level (so no current the drive allows can turn it), and enough to stop the shaft within half a millisecond.
  Running, the slip jumps to the output frequency and the current past the oC level; from a standstill, stall
  prevention during acceleration (L3-01/L3-02) holds the current at its level and oL1 follows (§6).
* ``mains-loss`` — the rectifier's supply is gone (:meth:`Drive.set_main_power`): the DC bus feeds the motor and the
  control power and sags to Uv1 (running) or the Uv minor fault (stopped) (§5–6); when it returns the bus is charged
  again, a Uv1 fault stays until it is reset, the Uv minor fault clears by itself.

Several faults may overlap on one station; the load is always recomputed from the station's own load and the faults
in force, so releasing one leaves the others.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

from ..drive import LoadSpec
from .spec import FaultError, LoadStep, LockRotor, MainsLoss, PlantFault

__all__ = ["PlantFaults", "lock_torque_nm", "LOCK_MARGIN", "STOP_WITHIN_S"]

#: The lock's torque, in multiples of the motor torque at the drive's oC current level.
LOCK_MARGIN = 10.0
#: A jam stops the shaft within this long (the drive model's sub-step is 1 ms).
STOP_WITHIN_S = 0.5e-3


def lock_torque_nm(settings: Any, inertia_kgm2: float) -> float:
    """The jam's torque: ten times what the motor develops at the oC current level (docs/drive-model.md §4:
    ``I_T = I_T,r T/T_r`` at flux ratio 1; above the base frequency the same current gives less torque), and at
    least enough to stop the shaft from the maximum frequency (E1-04 / n011) within :data:`STOP_WITHIN_S`: a jam is
    a rigid stop, not a brake."""
    i_oc = settings.oc_level_pct * 0.01 * settings.drive_rated_current_a
    i0, i_r = settings.motor_no_load_current_a, settings.motor_rated_current_a
    i_t_rated = math.sqrt(max(i_r * i_r - i0 * i0, 1e-9))
    i_t = math.sqrt(max(i_oc * i_oc - i0 * i0, 0.0))
    beyond_motor = LOCK_MARGIN * settings.rated_torque_nm * max(i_t / i_t_rated, 1.0)
    w_max = 2.0 * math.pi * settings.max_freq_hz / settings.pole_pairs
    return max(beyond_motor, inertia_kgm2 * w_max / STOP_WITHIN_S)


@dataclass
class _Plant:
    base: LoadSpec  #: the station's own load, as configured
    steps: dict[int, LoadStep] = field(default_factory=dict)
    locks: int = 0
    mains_out: int = 0


class PlantFaults:
    """The plant faults in force on the stations of one process, keyed by station address."""

    def __init__(self) -> None:
        self._plants: dict[int, _Plant] = {}
        self._next = 0

    def apply(self, address: int, station: Any, fault: PlantFault, now: int) -> int:
        """Apply *fault* to the drive of *station* (a card core) at *now*; returns a handle for :meth:`release`."""
        drive = station.drive.drive
        plant = self._plants.get(address)
        if plant is None:
            plant = self._plants[address] = _Plant(drive.load)
        self._next += 1
        handle = self._next
        if isinstance(fault, LoadStep):
            if fault.torque and plant.base.kind == "fan":
                raise FaultError("torque: the station has a fan load and the model carries one load-torque law per "
                                 "shaft (docs/drive-model.md §4); step its inertia instead")
            plant.steps[handle] = fault
            self._set_load(drive, plant, now)
        elif isinstance(fault, LockRotor):
            plant.steps[handle] = fault  # type: ignore[assignment]
            plant.locks += 1
            self._set_load(drive, plant, now)
        elif isinstance(fault, MainsLoss):
            plant.steps[handle] = fault  # type: ignore[assignment]
            plant.mains_out += 1
            drive.set_main_power(False, now)
        else:
            raise FaultError(f"not a drive fault: {fault!r}")
        return handle

    def release(self, address: int, station: Any, handle: int, now: int) -> bool:
        """End the fault *handle* of *station* at *now* (False: unknown or already released)."""
        plant = self._plants.get(address)
        if plant is None or handle not in plant.steps:
            return False
        fault = plant.steps.pop(handle)
        drive = station.drive.drive
        if isinstance(fault, MainsLoss):
            plant.mains_out -= 1
            if not plant.mains_out:
                drive.set_main_power(True, now)
            return True
        if isinstance(fault, LockRotor):
            plant.locks -= 1
        self._set_load(drive, plant, now)
        return True

    def forget(self, address: int) -> None:
        """The station was powered up again (a new card core): nothing of the old one's faults is in force."""
        self._plants.pop(address, None)

    @staticmethod
    def _set_load(drive: Any, plant: _Plant, now: int) -> None:
        base = plant.base.resolve(drive.settings)
        inertia = (base.inertia_kgm2 or 0.0) + sum(s.inertia or 0.0 for s in plant.steps.values()
                                                   if isinstance(s, LoadStep))
        torque = sum(s.torque or 0.0 for s in plant.steps.values() if isinstance(s, LoadStep))
        if plant.locks:
            load = LoadSpec("constant", inertia, lock_torque_nm(drive.settings, inertia), base.viscous_nms)
        elif torque:
            own = base.torque_nm if base.kind == "constant" else 0.0
            load = LoadSpec("constant", inertia, (own or 0.0) + torque, base.viscous_nms)
        else:
            load = LoadSpec(base.kind, inertia, base.torque_nm, base.viscous_nms, base.rated_speed_rpm)
        drive.set_load(load, now)
