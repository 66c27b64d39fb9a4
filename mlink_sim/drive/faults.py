"""Drive faults and minor faults, and the wire codes the option cards report for them.

Sources (tables as data, transcribed from ``../shared/manuals``):

* SI-T3 Table 26 "Drive Alarm Codes"            -> :data:`SI_T3_FAULT_CODES`
* SI-T3 Table 27 "Drive Minor Fault and Alarm"  -> :data:`SI_T3_MINOR_CODES`
* SI-T/V7 Table 10 "Inverter Alarm Codes"       -> :data:`V7_FAULT_CODES`
* SI-T/V7 Table 11 "Inverter Warning Codes"     -> :data:`V7_WARNING_CODES`

The SI-ET3 manual has no code table of its own for SEL_MON 7/8 ("Inverter Alarm" /
"Inverter Warning", SI-ET3 Table 22); the same A1000-family drive produces them, so the SI-T3
tables are used for SI-ET3 as well (``ET3_FAULT_CODES`` / ``ET3_MINOR_CODES`` are aliases).

A :class:`Fault` member is identified by its operator display name.  The same display name can be a
fault (trip, output shut off) or a minor fault/alarm (operation continues) depending on the drive's
settings (e.g. ``bUS`` with F6-01 = 0..2 is a fault, with F6-01 = 3 a minor fault; SI-T3 section
"Drive-Side Error Codes / Faults").  Each member therefore knows whether it *can* be a fault
(:attr:`Fault.can_trip`: it appears in SI-T3 Table 26 or SI-T/V7 Table 10) and whether it *can* be a
minor fault (:attr:`Fault.can_alarm`: SI-T3 Table 27 or SI-T/V7 Table 11).  Which one it currently
is, is told by where it appears in :class:`mlink_sim.drive.DriveStatus` (``fault`` or ``minor``).

Not transcribed: the range rows of SI-T3 Table 26 whose code/name pairing is ambiguous in the
manual text (CPF11..CPF21 at 8C..96, CPF26..CPF35 at 9B..A4, oFA00..oFA43 at FA..); and the second
``STP`` row of SI-T/V7 Table 11 (41H; both 40H and 41H read "Emergency stop").  Neither the model
nor the cards raise these.
"""

from __future__ import annotations

import enum
from collections.abc import Mapping
from types import MappingProxyType

__all__ = [
    "Fault",
    "SI_T3_FAULT_CODES",
    "SI_T3_MINOR_CODES",
    "ET3_FAULT_CODES",
    "ET3_MINOR_CODES",
    "V7_FAULT_CODES",
    "V7_WARNING_CODES",
    "fault_code",
    "minor_code",
]


class Fault(enum.Enum):
    """Drive fault / minor fault by operator display name (value = display name)."""

    # --- SI-T3 Table 26 (faults) -------------------------------------------------------------
    UV1 = "Uv1"
    UV2 = "Uv2"
    UV3 = "Uv3"
    GF = "GF"
    OC = "oC"
    OV = "ov"
    OH = "oH"
    OH1 = "oH1"
    OL1 = "oL1"
    OL2 = "oL2"
    OL3 = "oL3"
    OL4 = "oL4"
    RR = "rr"
    RH = "rH"
    EF3 = "EF3"
    EF4 = "EF4"
    EF5 = "EF5"
    EF6 = "EF6"
    EF7 = "EF7"
    EF8 = "EF8"
    OS = "oS"
    DEV = "dEv"
    PGO = "PGo"
    PF = "PF"
    LF = "LF"
    OH3 = "oH3"
    OPR = "oPr"
    ERR = "Err"
    OH4 = "oH4"
    CE = "CE"
    BUS = "bUS"
    CF = "CF"
    SVE = "SvE"
    EF0 = "EF0"
    FBL = "FbL"
    UL3 = "UL3"
    UL4 = "UL4"
    OL7 = "oL7"
    DV1 = "dv1"
    DV2 = "dv2"
    DV3 = "dv3"
    DV4 = "dv4"
    LF2 = "LF2"
    STO = "STo"
    PGOH = "PGoH"
    E5 = "E5"
    SER = "SEr"
    FBH = "FbH"
    EF1 = "EF1"
    EF2 = "EF2"
    OL5 = "oL5"
    UL5 = "UL5"
    COF = "CoF"
    DWFL = "dWFL"
    DWF1 = "dWF1"
    VOF = "voF"
    RF = "rF"
    BOL = "boL"
    NSE = "nSE"
    CPF02 = "CPF02"
    CPF03 = "CPF03"
    CPF06 = "CPF06"
    CPF07 = "CPF07"
    CPF08 = "CPF08"
    CPF22 = "CPF22"
    CPF23 = "CPF23"
    CPF24 = "CPF24"
    # --- SI-T3 Table 27 only (minor faults / alarms) -----------------------------------------
    UV = "Uv"
    OH2 = "oH2"
    EF = "EF"
    BB = "bb"
    FAN = "FAn"
    RUN = "rUn"
    CALL = "CALL"
    SE = "SE"
    DNE = "dnE"
    AER = "AEr"
    CYC = "CyC"
    HCA = "HCA"
    LT1 = "LT-1"
    LT2 = "LT-2"
    HBBF = "HbbF"
    HBB = "Hbb"
    TRPC = "TrPC"
    LT3 = "LT-3"
    LT4 = "LT-4"
    DWAL = "dWAL"
    # --- SI-T/V7 Tables 10/11 only ------------------------------------------------------------
    STP = "STP"
    CPF04 = "CPF04"
    CPF05 = "CPF05"
    SER_SEQ = "SEr(V7)"  # V7 Table 11 20H "SEr Sequence input fault" (not the A1000 SEr)

    @property
    def display(self) -> str:
        """Operator display text."""
        return "SEr" if self is Fault.SER_SEQ else self.value

    @property
    def can_trip(self) -> bool:
        """True if the manuals list it as a fault (SI-T3 Table 26 or SI-T/V7 Table 10)."""
        return self in SI_T3_FAULT_CODES or self in V7_FAULT_CODES

    @property
    def can_alarm(self) -> bool:
        """True if the manuals list it as a minor fault/alarm (SI-T3 Table 27 / SI-T/V7 Table 11)."""
        return self in SI_T3_MINOR_CODES or self in V7_WARNING_CODES


F = Fault

#: SI-T3 Table 26 "Drive Alarm Codes" (ALARM byte / SEL_MON 7 / U2, U3 contents), A1000 family.
SI_T3_FAULT_CODES: Mapping[Fault, int] = MappingProxyType({
    F.UV1: 0x02, F.UV2: 0x03, F.UV3: 0x04, F.GF: 0x06, F.OC: 0x07, F.OV: 0x08, F.OH: 0x09,
    F.OH1: 0x0A, F.OL1: 0x0B, F.OL2: 0x0C, F.OL3: 0x0D, F.OL4: 0x0E, F.RR: 0x0F, F.RH: 0x10,
    F.EF3: 0x11, F.EF4: 0x12, F.EF5: 0x13, F.EF6: 0x14, F.EF7: 0x15, F.EF8: 0x16, F.OS: 0x18,
    F.DEV: 0x19, F.PGO: 0x1A, F.PF: 0x1B, F.LF: 0x1C, F.OH3: 0x1D, F.OPR: 0x1E, F.ERR: 0x1F,
    F.OH4: 0x20, F.CE: 0x21, F.BUS: 0x22, F.CF: 0x25, F.SVE: 0x26, F.EF0: 0x27, F.FBL: 0x28,
    F.UL3: 0x29, F.UL4: 0x2A, F.OL7: 0x2B, F.DV1: 0x32, F.DV2: 0x33, F.DV3: 0x34, F.DV4: 0x35,
    F.LF2: 0x36, F.STO: 0x37, F.PGOH: 0x38, F.E5: 0x39, F.SER: 0x3B, F.FBH: 0x41, F.EF1: 0x42,
    F.EF2: 0x43, F.OL5: 0x44, F.UL5: 0x45, F.COF: 0x46, F.DWFL: 0x49, F.DWF1: 0x4A, F.VOF: 0x4D,
    F.RF: 0x4E, F.BOL: 0x4F, F.NSE: 0x52, F.CPF02: 0x83, F.CPF03: 0x84, F.CPF06: 0x87,
    F.CPF07: 0x88, F.CPF08: 0x89, F.CPF22: 0x97, F.CPF23: 0x98, F.CPF24: 0x99,
})

#: SI-T3 Table 27 "Drive Minor Fault and Alarm" (ALARM byte for warnings / SEL_MON 8).
SI_T3_MINOR_CODES: Mapping[Fault, int] = MappingProxyType({
    F.UV: 0x01, F.OV: 0x02, F.OH: 0x03, F.OH2: 0x04, F.OL3: 0x05, F.OL4: 0x06, F.EF: 0x07,
    F.BB: 0x08, F.EF3: 0x09, F.EF4: 0x0A, F.EF5: 0x0B, F.EF6: 0x0C, F.EF7: 0x0D, F.EF8: 0x0E,
    F.FAN: 0x0F, F.OS: 0x10, F.DEV: 0x11, F.PGO: 0x12, F.CE: 0x14, F.BUS: 0x15, F.EF0: 0x1A,
    F.RUN: 0x1B, F.CALL: 0x1D, F.UL3: 0x1E, F.UL4: 0x1F, F.SE: 0x20, F.OH3: 0x22, F.FBL: 0x27,
    F.FBH: 0x28, F.DNE: 0x2A, F.PGOH: 0x2B, F.E5: 0x31, F.AER: 0x32, F.CYC: 0x33, F.HCA: 0x34,
    F.LT1: 0x35, F.LT2: 0x36, F.EF1: 0x39, F.EF2: 0x3A, F.HBBF: 0x3B, F.HBB: 0x3C, F.OL5: 0x3D,
    F.UL5: 0x3E, F.VOF: 0x41, F.TRPC: 0x42, F.LT3: 0x43, F.LT4: 0x44, F.BOL: 0x45, F.DWAL: 0x49,
})

#: SI-ET3: no table of its own; same A1000-family codes (see module docstring).
ET3_FAULT_CODES = SI_T3_FAULT_CODES
ET3_MINOR_CODES = SI_T3_MINOR_CODES

#: SI-T/V7 Table 10 "Inverter Alarm Codes" (VS-606V7 faults).
V7_FAULT_CODES: Mapping[Fault, int] = MappingProxyType({
    F.UV1: 0x02, F.UV2: 0x03, F.GF: 0x06, F.OC: 0x07, F.OV: 0x08, F.OH: 0x09, F.OL1: 0x0B,
    F.OL2: 0x0C, F.OL3: 0x0D, F.RH: 0x10, F.EF3: 0x11, F.EF4: 0x12, F.EF5: 0x13, F.EF6: 0x14,
    F.EF7: 0x15, F.PF: 0x1B, F.LF: 0x1C, F.OPR: 0x1E, F.CE: 0x21, F.BUS: 0xE6, F.E5: 0xE5,
    F.EF0: 0x27, F.UL3: 0x29, F.STP: 0x50, F.EF1: 0x51, F.EF2: 0x52, F.CPF04: 0x84,
    F.CPF05: 0x85, F.CPF07: 0x8C, F.CPF22: 0x93, F.CPF23: 0x94,
})

#: SI-T/V7 Table 11 "Inverter Warning Codes" (VS-606V7 minor faults).
V7_WARNING_CODES: Mapping[Fault, int] = MappingProxyType({
    F.UV: 0x01, F.OV: 0x02, F.OH: 0x03, F.OL3: 0x05, F.EF: 0x07, F.BB: 0x08, F.FAN: 0x0F,
    F.OPR: 0x13, F.CE: 0x14, F.FBL: 0x1C, F.CALL: 0x1D, F.UL3: 0x1E, F.SER_SEQ: 0x20,
    F.OH3: 0x22, F.STP: 0x40,
})

del F


#: The fault and minor fault codes of each drive family (by ``Family`` value): the A1000 family's SI-T3 Tables
#: 26/27 (the SI-ET3 reports the same), the VS-606V7's SI-T/V7 Tables 10/11.
_FAMILY_CODES: Mapping[str, tuple[Mapping[Fault, int], Mapping[Fault, int]]] = MappingProxyType({
    "a1000": (SI_T3_FAULT_CODES, SI_T3_MINOR_CODES),
    "v7": (V7_FAULT_CODES, V7_WARNING_CODES),
})


def fault_code(family: object, fault: Fault | None) -> int:
    """Fault code for the ALARM byte / SEL_MON 7 / U2-U3: 0 when none or not in the table.

    ``family`` is ``Family.A1000``/``"a1000"`` (SI-T3 Table 26, also used for SI-ET3) or
    ``Family.V7``/``"v7"`` (SI-T/V7 Table 10).
    """
    if fault is None:
        return 0
    return _FAMILY_CODES[str(getattr(family, "value", family))][0].get(fault, 0)


def minor_code(family: object, minor: Fault | None) -> int:
    """Minor fault code (SI-T3 Table 27 / SI-T/V7 Table 11); 0 when none or not in the table."""
    if minor is None:
        return 0
    return _FAMILY_CODES[str(getattr(family, "value", family))][1].get(minor, 0)
