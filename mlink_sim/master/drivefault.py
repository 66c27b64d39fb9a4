"""The drive fault behind MECHATROLINK-III D_ALM (docs/master.md, "Drive faults on MECHATROLINK-III").

An SI-ET3 answer says *that* the drive has a fault (CMD_STAT D_ALM, SI-ET3 §8 "Command Status") but not which:
the code is U2-01 "Current Fault", which ALM_RD with ALM_RD_MOD 0 returns in bytes 8-9 (SI-ET3 Tables 16/17), in
the A1000 numbering of SI-T3 Table 26 (the SI-ET3 manual refers to "the drive manual"). So on a rising D_ALM the
master reads it once, for the view (``alarm``, ``alarm_name``) and an :class:`~.types.AlarmRaised`; on a falling
one the view is cleared (:class:`~.types.AlarmCleared`). On MECHATROLINK-II the code travels in every answer
(ALARM byte) and nothing here is needed.

The read also decides what a recovery does with a fault the lost connection caused. bUS and E5 "can appear as an
alarm or as a fault" (SI-ET3 §11 "Faults", Table 26): with F6-01 / F6-25 at their defaults they are faults, the
drive coasts, and "Drive faults and alarms cannot be reset while the Drive RUN command is ON" (SI-T3 "ALM_CLR";
the SI-ET3 runs on the same drive), so the ALM_CLR round of the recovery clears COMM_ALM and leaves the drive
faulted. The master then takes the same way as on the SI-T3, whose ALARM byte shows bUS (22H) or E5 (39H):
DISCONNECT (the drive's control command cleared and a fault reset, SI-T3 "DISCONNECT") and CONNECT again. Any
other fault is the operator's, as on MECHATROLINK-II.
"""

from __future__ import annotations

from typing import Any, Final

from ..wire import M3Cmd, ml3
from ..wire.drive_codes import SiT3DriveAlarm
from .commands import Cmd
from .types import Request

__all__ = ["CONNECTION_FAULTS", "read_request", "code_of", "name_of"]

#: Faults a lost connection leaves behind (SI-ET3 §11 "Faults": bUS Option Communication Error, E5 MECHATROLINK
#: Watchdog Timer Error), as U2-01 gives them (SI-T3 Table 26: bUS 22H, E5 39H).
CONNECTION_FAULTS: Final = frozenset({int(SiT3DriveAlarm.BUS), int(SiT3DriveAlarm.E5)})

_MOD_PRESENT: Final = 0  # ALM_RD_MOD 0: present fault U2-01, then U2-02 (SI-ET3 Table 17)


def read_request(station: int, deadline_ns: int) -> Request:
    """The ALM_RD (05H, ALM_RD_MOD 0) request that reads U2-01 of *station*."""
    return Request(station, ml3.AlmRd(_MOD_PRESENT), False, "ALM_RD", int(M3Cmd.ALM_RD), deadline_ns, Cmd.ALM_RD)


def code_of(req: Request) -> int | None:
    """U2-01 from a completed :func:`read_request`, or None when the read failed (refused, timed out)."""
    body: Any = req.result
    if req.error is not None or type(body) is not ml3.AlmRdResponse or body.alm_rd_mod != _MOD_PRESENT:
        return None
    return int.from_bytes(body.alm_data[0:2], "little")


def name_of(code: int) -> str:
    """The fault's name in SI-T3 Table 26 (e.g. ``BUS``, ``OC``), or its code in hex."""
    try:
        return SiT3DriveAlarm(code).name
    except ValueError:
        return f"{code:02X}H"
