"""Drive faults on the slave side (docs/faults.md): a drive fault applied to a card core's drive model in the process
that hosts the station, so that its effect reaches the master only through the station's answers, as a real drive's
would. A slave's ``fault`` / ``release`` operations (:mod:`mlink_sim.aio.control.slave`) and the virtual clock's
card cores use these two functions.

May import the sans-I/O fault specs (:mod:`mlink_sim.faults`) and nothing of the run above it.

Touches: the drive models of this process's card cores, through their plant faults.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from ..._log import get_logger
from ...faults import FaultError, FaultSpec
from ...faults.plant import PlantFaults
from ...faults.spec import PLANT_FAULTS
from ...operations import OpError, station_name

__all__ = ["PlantError", "apply_drive_fault", "release_drive_fault"]

log = get_logger("mlink_sim.faults")


class PlantError(RuntimeError):
    """A drive fault could not be applied (no slave process to reach, the slave refused or did not answer)."""


def _station(stations: Mapping[int, Any], address: int) -> Any:
    station = stations.get(address)
    if station is None:
        known = ", ".join(station_name(a) for a in stations) or "none"
        raise OpError("unknown_station", f"station {station_name(address)} is not served here (stations: {known})")
    return station


def apply_drive_fault(stations: Mapping[int, Any], plants: PlantFaults, address: int, fault: FaultSpec,
                      now: int) -> int:
    """Apply the drive fault *fault* to station *address* (a card core of *stations*) at *now*; its handle for
    :func:`release_drive_fault`. ``OpError``: no such station here, or not a drive fault."""
    station = _station(stations, address)
    if fault.action not in PLANT_FAULTS:
        raise OpError("bad_request", f"fault: {fault.action} is not a drive fault ({', '.join(PLANT_FAULTS)}): the "
                                     "station and master faults are the network's (up/master --control)")
    try:
        handle = plants.apply(address, station, fault, now)  # type: ignore[arg-type]
    except FaultError as exc:
        raise OpError("bad_request", f"fault: {exc}") from None
    log.info("drive_fault", station=station_name(address), fault=fault.describe, handle=handle)
    return handle


def release_drive_fault(stations: Mapping[int, Any], plants: PlantFaults, address: int, handle: int,
                        now: int) -> None:
    """End the drive fault *handle* of station *address* at *now*; ``OpError`` when there is none."""
    station = _station(stations, address)
    if not plants.release(address, station, handle, now):
        raise OpError("bad_request", f"release: no drive fault {handle} in force on station "
                                       f"{station_name(address)}")
    log.info("drive_fault_released", station=station_name(address), handle=handle)
