"""Drive fault and minor-fault codes as the cards report them in the MECHATROLINK-II ALARM byte, in SEL_MON 7/8
monitors and in ALM_RD data.

* :class:`SiT3DriveAlarm`   – SI-T3 Table 26 "Drive Alarm Codes" (A1000/GA-class faults)
* :class:`SiT3DriveWarning` – SI-T3 Table 27 "Drive Minor Fault and Alarm"
* :class:`V7InverterAlarm`  – V7 Table 10 "Inverter Alarm Codes"
* :class:`V7InverterWarning`– V7 Table 11 "Inverter Warning Codes"

The SI-ET3 manual has no code table of its own; it reports the drive's codes through U2/U3 monitors, and the cards
use Table 26/27 for SEL_MON 7/8 on SI-ET3 too (documented in docs/cards.md). Member names follow the operator
display (``oL1`` -> ``OL1``); ranges the manual lists as "CPF11 to CPF21" are given by their first code only.
"""

from __future__ import annotations

import enum
from collections.abc import Mapping
from types import MappingProxyType

__all__ = ["FAMILY_CODES", "SiT3DriveAlarm", "SiT3DriveWarning", "V7InverterAlarm", "V7InverterWarning"]


class SiT3DriveAlarm(enum.IntEnum):
    """SI-T3 Table 26 – drive alarm (fault) codes."""

    UV1 = 0x02
    UV2 = 0x03
    UV3 = 0x04
    GF = 0x06
    OC = 0x07
    OV = 0x08
    OH = 0x09
    OH1 = 0x0A
    OL1 = 0x0B
    OL2 = 0x0C
    OL3 = 0x0D
    OL4 = 0x0E
    RR = 0x0F
    RH = 0x10
    EF3 = 0x11
    EF4 = 0x12
    EF5 = 0x13
    EF6 = 0x14
    EF7 = 0x15
    EF8 = 0x16
    OS = 0x18
    DEV = 0x19
    PGO = 0x1A
    PF = 0x1B
    LF = 0x1C
    OH3 = 0x1D
    OPR = 0x1E
    ERR = 0x1F
    OH4 = 0x20
    CE = 0x21
    BUS = 0x22
    CF = 0x25
    SVE = 0x26
    EF0 = 0x27
    FBL = 0x28
    UL3 = 0x29
    UL4 = 0x2A
    OL7 = 0x2B
    DV1 = 0x32
    DV2 = 0x33
    DV3 = 0x34
    DV4 = 0x35
    LF2 = 0x36
    STO = 0x37
    PGOH = 0x38
    E5 = 0x39
    SER = 0x3B
    FBH = 0x41
    EF1 = 0x42
    EF2 = 0x43
    OL5 = 0x44
    UL5 = 0x45
    COF = 0x46
    DWFL = 0x49
    DWF1 = 0x4A
    VOF = 0x4D
    RF = 0x4E
    BOL = 0x4F
    NSE = 0x52
    CPF02 = 0x83
    CPF03 = 0x84
    CPF06 = 0x87
    CPF07 = 0x88
    CPF11 = 0x8C
    CPF22 = 0x97
    CPF23 = 0x98
    CPF24 = 0x99
    CPF26 = 0x9B
    OFA00 = 0xFA


class SiT3DriveWarning(enum.IntEnum):
    """SI-T3 Table 27 – drive minor fault and alarm codes."""

    UV = 0x01
    OV = 0x02
    OH = 0x03
    OH2 = 0x04
    OL3 = 0x05
    OL4 = 0x06
    EF = 0x07
    BB = 0x08
    EF3 = 0x09
    EF4 = 0x0A
    EF5 = 0x0B
    EF6 = 0x0C
    EF7 = 0x0D
    EF8 = 0x0E
    FAN = 0x0F
    OS = 0x10
    DEV = 0x11
    PGO = 0x12
    CE = 0x14
    BUS = 0x15
    EF0 = 0x1A
    RUN = 0x1B
    CALL = 0x1D
    UL3 = 0x1E
    UL4 = 0x1F
    SE = 0x20
    OH3 = 0x22
    FBL = 0x27
    FBH = 0x28
    DNE = 0x2A
    PGOH = 0x2B
    E5 = 0x31
    AER = 0x32
    CYC = 0x33
    HCA = 0x34
    LT1 = 0x35
    LT2 = 0x36
    EF1 = 0x39
    EF2 = 0x3A
    HBBF = 0x3B
    HBB = 0x3C
    OL5 = 0x3D
    UL5 = 0x3E
    VOF = 0x41
    TRPC = 0x42
    LT3 = 0x43
    LT4 = 0x44
    BOL = 0x45
    DWAL = 0x49


class V7InverterAlarm(enum.IntEnum):
    """V7 Table 10 – inverter alarm (fault) codes. Note E5H/E6H share the values of the communication alarms."""

    UV1 = 0x02
    UV2 = 0x03
    GF = 0x06
    OC = 0x07
    OV = 0x08
    OH = 0x09
    OL1 = 0x0B
    OL2 = 0x0C
    OL3 = 0x0D
    RH = 0x10
    EF3 = 0x11
    EF4 = 0x12
    EF5 = 0x13
    EF6 = 0x14
    EF7 = 0x15
    PF = 0x1B
    LF = 0x1C
    OPR = 0x1E
    CE = 0x21
    EF0 = 0x27
    UL3 = 0x29
    STP = 0x50
    EF1 = 0x51
    EF2 = 0x52
    CPF04 = 0x84
    CPF05 = 0x85
    CPF07 = 0x8C
    CPF22 = 0x93
    CPF23 = 0x94
    E5 = 0xE5
    BUS = 0xE6


class V7InverterWarning(enum.IntEnum):
    """V7 Table 11 – inverter warning codes (41H is a second "STP" entry in the manual)."""

    UV = 0x01
    OV = 0x02
    OH = 0x03
    OL3 = 0x05
    EF = 0x07
    BB = 0x08
    FAN = 0x0F
    OPR = 0x13
    CE = 0x14
    FBL = 0x1C
    CALL = 0x1D
    UL3 = 0x1E
    SER = 0x20
    OH3 = 0x22
    STP = 0x40
    STP2 = 0x41


#: The (fault, minor fault) code tables a card reports, by its drive family (``CardProfile.family``): the A1000
#: family's SI-T3 Tables 26/27 (the SI-ET3 reports the same codes), the VS-606V7's V7 Tables 10/11.
FAMILY_CODES: Mapping[str, tuple[type[enum.IntEnum], type[enum.IntEnum]]] = MappingProxyType({
    "a1000": (SiT3DriveAlarm, SiT3DriveWarning),
    "v7": (V7InverterAlarm, V7InverterWarning),
})
