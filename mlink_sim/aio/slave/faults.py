"""Drive faults on the slave side: a slave process's answer to a ``plant`` / ``release`` request of its control
endpoint (docs/faults.md). The drive fault is applied to the card core's drive model in this process, so its effect
reaches the master only through the station's answers, as a real drive's would.

May import the sans-I/O fault specs (:mod:`mlink_sim.faults`) and nothing of the run above it.

Touches: the drive models of this process's card cores, through their plant faults.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from ..._log import get_logger
from ...faults import FaultError, fault_from_fields
from ...faults.plant import PlantFaults
from ...faults.spec import PLANT_FAULTS

__all__ = ["PlantError", "handle_plant_request"]

log = get_logger("mlink_sim.faults")


class PlantError(RuntimeError):
    """A drive fault could not be applied (no slave process to reach, the slave refused or did not answer)."""


def handle_plant_request(request: Mapping[str, Any], stations: Mapping[int, Any], plants: PlantFaults,
                         now: int) -> dict[str, Any]:
    """A slave's answer to ``{"op": "plant", "station": 33, "fault": {"do": "load", "torque": 5}}`` (apply; the
    reply carries a ``handle``) or ``{"op": "release", "station": 33, "handle": 1}``; *stations* maps addresses to
    the card cores of this process. Bad input is an ``ok: false`` reply with the reason, never an exception."""
    address = request.get("station")
    station = stations.get(address) if isinstance(address, int) else None
    if station is None:
        return {"ok": False, "error": f"no station {address!r} in this process"}
    try:
        if request.get("op") == "release":
            handle = request.get("handle")
            # address is an int here: station is None otherwise
            if not isinstance(handle, int) or not plants.release(address, station, handle, now):  # type: ignore[arg-type]
                return {"ok": False, "error": f"no drive fault {handle!r} in force on station {address:02X}H"}
            return {"ok": True}
        fields = dict(request.get("fault") or {})
        fault = fault_from_fields(str(fields.pop("do", "")), fields)
        if fault.action not in PLANT_FAULTS:
            return {"ok": False, "error": f"{fault.action} is not a drive fault ({', '.join(PLANT_FAULTS)})"}
        handle = plants.apply(address, station, fault, now)  # type: ignore[arg-type]
    except FaultError as exc:
        return {"ok": False, "error": str(exc)}
    log.info("drive_fault", station=f"{address:02X}H", fault=fault.describe, handle=handle)
    return {"ok": True, "handle": handle}
