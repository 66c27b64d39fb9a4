"""SEL_REF / SEL_MON of INV_CTL and INV_I/O, per card – each card has its own tables:

* SI-T3 Table 17 (SEL REF) and SI-T3 Table 18 (SEL MON);
* SI-ET3 Table 21 (SEL_REF) and SI-ET3 Table 22 (SEL_MON);
* SI-T/V7 Table 4 (SEL REF: only 4 = terminal outputs; "5 to F Not used. The SI-T/V7 ignores the written
  data") and SI-T/V7 Table 5 (SEL MON: 1 = output frequency, not motor speed; 9, A, D–F not used).

The tables themselves are data in :mod:`mlink_sim.wire.selections` (``SEL_REF_TABLES``, ``SEL_MON_TABLES``), under
the key of the card's profile (``CardProfile.selections``); SEL_REF code → item is read there by the station
(``Station.select_refs``), SEL_MON code → monitor name reaches the card through :meth:`DriveLink.sel_mon_name`. Here the card resolves what only it
knows: E/F read the MEMOBUS register set in F6-23/F6-24 at power-up (any parameter or monitor register, through
the parameter store), 7/8 the drive's fault / minor-fault code (SI-T3 Tables 26/27, SI-T/V7 Tables 10/11), and
U2/U3 the fault history that survives power cycles. Values travel as 16-bit two's complement.

SEL_REF codes are recorded (they show in the station snapshot); the drive model has no analog outputs, PID
or pulse output, so REF values change nothing else. Codes a table marks unused are ignored, as the SI-T/V7
manual says – no alarm.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from .drive_link import DriveLink
    from .paramstore import ParamStore

__all__ = ["sel_mon_value", "sel_mon_enabled"]


def sel_mon_enabled(drive: DriveLink, code: int) -> bool:
    """SI-ET3 INVCMD_STAT bits 24/25 "SEL_MONx enabled": the code selects something on this card."""
    return bool(drive.sel_mon_name(code))


def sel_mon_value(drive: DriveLink, store: ParamStore, registers: Mapping[str, int], code: int) -> int:
    """The 16-bit value SEL_MON *code* selects. *registers*: ``{"F6-23": reg, "F6-24": reg}`` read at power-up."""
    name = drive.sel_mon_name(code)
    if not name:
        return 0
    if name == "ALARM":
        return drive.fault_code(drive.status.fault)
    if name == "WARNING":
        return drive.minor_code(drive.status.minor)
    if name in ("F6-23", "F6-24"):
        reg = registers.get(name, 0)
        word = store.read_register(reg, drive.monitor) if reg else None
        return word or 0
    return drive.monitor(name) & 0xFFFF
