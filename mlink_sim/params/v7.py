"""VS-606V7 (VS mini V7) constants and monitors (the inverter behind SI-T/V7), as data.

Sources, in order of precedence:

1. the SI-T/V7 manual (``shared/manuals``): §6 Initial Setup table (n003, n004 ranges and
   defaults), INV_CTL Table 3 (n052…n056 default functions of terminals S3…S7), Table 4
   (n057…n059, setting 18 = data output from communications), Table 5 (U-01, U-08), ALM_RD
   (n178 Fault History) and the n035 / n024 references;
2. where it is silent, the VS-606V7 Technical Manual TOE-S606-12.x and Instruction Manual
   TOE-S606-11.x.  The SI-T/V7 manual gives no register numbers at all; it only says "The
   register number (NO) is the same as the register number that is set and referenced in
   MEMOBUS transfers".  Constants therefore use the inverter's MEMOBUS constant-data mapping
   **register = 0100H + n** (n001 = 0101H … n179 = 01B3H) and monitors the MEMOBUS
   monitor-data registers (0020H block).  A figure not confirmed against a table of those
   manuals carries "(unverified: why)" in ``source``.

Defaults that depend on the inverter assume:

* inverter: CIMR-V7AA21P5 (200 V class, 3-phase, 1.5 kW, rated output current 8.0 A);
* motor: 1.5 kW 4-pole 200 V Yaskawa standard motor (n036, n106…n110 defaults of that rating);
* V/f control (n002 = 0, the default), so n014…n017 take the V/f defaults;
* n035 = 0 (frequency references in 0.01 Hz; the keypad shows 0.1 Hz at 100 Hz and above),
  n018 = 0 (times in 0.1 s), n152 = 0 (MEMOBUS frequency monitors in 0.1 Hz).

There is no separate "speed agree" constant on the V7: the speed-agree window of output
setting 2 is fixed; n095 is the frequency detection level used by output settings 4/5.
U-09 (fault history) and U-10 (software No.) are read through n178/n179.
"""

from __future__ import annotations

from .table import Param, ParamTable

__all__ = ["VS606V7"]

_RULE = "VS-606V7 Technical Manual TOE-S606-12, MEMOBUS constant data register = 0100H + n (SI-T/V7 manual silent)"
_TOE = "VS-606V7 Technical Manual TOE-S606-12 constant list; register: 0100H + n (SI-T/V7 manual silent)"
_SETUP = "SI-T/V7 manual §6 Initial Setup table (range, default); register: " + _RULE
_T3 = "SI-T/V7 Table 3 (default function); register: 0100H + n, range: TOE-S606-12"
_T4 = "SI-T/V7 Table 4 (setting 18 = comm. output); register: 0100H + n, default: TOE-S606-12"
_CAP = "capacity-dependent default for CIMR-V7AA21P5 with a 1.5 kW motor, not confirmed"
_MON = "VS-606V7 Technical Manual TOE-S606-12, MEMOBUS monitor data (SI-T/V7 manual gives no register)"


def _unverified(why: str, base: str = _TOE) -> str:
    return f"{base} (unverified: {why})"


def _n(number: int, title: str, unit: str, scale: float, minimum: int, maximum: int, default: int,
       source: str, **extra: object) -> Param:
    """A constant n<number> (e.g. n003) at MEMOBUS register 0100H + <number>."""
    return Param(f"n{number:03d}", 0x0100 + number, title, unit, scale, minimum, maximum, default,
                 source=source, **extra)  # type: ignore[arg-type]


def _mon(name: str, register: int, title: str, unit: str, scale: float, source: str,
         *, signed: bool = False, radix: int = 10) -> Param:
    lo, hi = (-0x8000, 0x7FFF) if signed else (0, 0xFFFF)
    return Param(name, register, title, unit, scale, lo, hi, 0, read_only=True, signed=signed,
                 source=source, radix=radix)


_HZ = ("0.01 Hz", 0.01)
_FREF_SRC = _unverified("raw unit 0.01 Hz and range 0.00…400.00 Hz assumed for n035 = 0")

# -- n001…n018: initialization, operation mode, V/f pattern -----------------------------------
SETUP = (
    _n(1, "Parameter Write-Prohibit Selection / Parameter Initialization", "", 1, 0, 11, 1,
       _unverified("range not confirmed (6: clear fault history, 8…11: initialize)")),
    _n(2, "Control Mode Selection", "", 1, 0, 1, 0, _TOE),
    _n(3, "Operation Method Selection", "", 1, 0, 3, 0, _SETUP),
    _n(4, "Frequency Reference Selection", "", 1, 0, 9, 0, _SETUP),
    _n(5, "Stopping Method Selection", "", 1, 0, 1, 0, _TOE),
    _n(6, "Reverse Run Prohibit", "", 1, 0, 1, 0, _TOE),
    _n(11, "Maximum Output Frequency", "0.1 Hz", 0.1, 500, 4000, 600, _TOE),
    _n(12, "Maximum Voltage", "0.1 V", 0.1, 1, 2550, 2000, _TOE + "; 200 V class"),
    _n(13, "Maximum Voltage Output Frequency (Base Frequency)", "0.1 Hz", 0.1, 2, 4000, 600, _TOE),
    _n(14, "Mid. Output Frequency", "0.1 Hz", 0.1, 1, 3999, 15, _unverified("V/f default not confirmed")),
    _n(15, "Mid. Output Frequency Voltage", "0.1 V", 0.1, 1, 2550, 120, _unverified("V/f 200 V default not confirmed")),
    _n(16, "Minimum Output Frequency", "0.1 Hz", 0.1, 1, 100, 15, _unverified("V/f default not confirmed")),
    _n(17, "Minimum Output Frequency Voltage", "0.1 V", 0.1, 1, 500, 120,
       _unverified("V/f 200 V default not confirmed")),
    _n(18, "Accel/Decel Time Setting Unit", "", 1, 0, 1, 0, _TOE),
)

# -- n019…n023: acceleration/deceleration ------------------------------------------------------
_TIME_SRC = _unverified("raw 0.1 s over 0.0…6000.0 s assumed; keypad uses 1 s steps above 999.9 s")
ACCEL = (
    _n(19, "Acceleration Time 1", "0.1 s", 0.1, 0, 60000, 100, _TIME_SRC),
    _n(20, "Deceleration Time 1", "0.1 s", 0.1, 0, 60000, 100, _TIME_SRC),
    _n(21, "Acceleration Time 2", "0.1 s", 0.1, 0, 60000, 100, _TIME_SRC),
    _n(22, "Deceleration Time 2", "0.1 s", 0.1, 0, 60000, 100, _TIME_SRC),
    _n(23, "S-curve Acceleration/Deceleration Selection", "", 1, 0, 3, 0, _TOE),
)

# -- n024…n036: references, limits, units, motor current --------------------------------------
REFERENCES = (
    _n(24, "Frequency Reference 1", *_HZ, 0, 40000, 600,
       "named in SI-T/V7 §6 (n004 = 1); " + _FREF_SRC),
    *(_n(k, f"Frequency Reference {k - 23}", *_HZ, 0, 40000, 0, _FREF_SRC) for k in range(25, 32)),
    _n(32, "Jog Frequency", *_HZ, 0, 40000, 600, _FREF_SRC),
    _n(33, "Frequency Reference Upper Limit", "%", 1, 0, 110, 100, _TOE),
    _n(34, "Frequency Reference Lower Limit", "%", 1, 0, 110, 0, _TOE),
    _n(35, "Frequency Reference Setting/Display Unit Selection", "", 1, 0, 3999, 0,
       "named in SI-T/V7 INV_CTL / Table 5 (speed reference units); range/default: " + _TOE),
    _n(36, "Motor Rated Current", "0.1 A", 0.1, 0, 120, 62,
       _unverified("range 0…150 % of 8.0 A; " + _CAP)),
)

# -- n050…n059: multi-function inputs (S1…S7) and outputs --------------------------------------
_IN_RANGE = "range not confirmed"
IO = (
    _n(50, "Multi-function Input Selection 1 (Terminal S1)", "", 1, 1, 34, 1, _unverified(_IN_RANGE)),
    _n(51, "Multi-function Input Selection 2 (Terminal S2)", "", 1, 1, 34, 2, _unverified(_IN_RANGE)),
    _n(52, "Multi-function Input Selection 3 (Terminal S3)", "", 1, 0, 34, 3, _unverified(_IN_RANGE, _T3)),
    _n(53, "Multi-function Input Selection 4 (Terminal S4)", "", 1, 1, 34, 5, _unverified(_IN_RANGE, _T3)),
    _n(54, "Multi-function Input Selection 5 (Terminal S5)", "", 1, 1, 34, 6, _unverified(_IN_RANGE, _T3)),
    _n(55, "Multi-function Input Selection 6 (Terminal S6)", "", 1, 1, 34, 7, _unverified(_IN_RANGE, _T3)),
    _n(56, "Multi-function Input Selection 7 (Terminal S7)", "", 1, 1, 35, 10, _unverified(_IN_RANGE, _T3)),
    _n(57, "Multi-function Output Selection 1 (Terminals MA-MB-MC)", "", 1, 0, 21, 0,
       _unverified("range 0…21 not confirmed", _T4)),
    _n(58, "Multi-function Output Selection 2 (Terminal P1)", "", 1, 0, 21, 1,
       _unverified("range 0…21 not confirmed", _T4)),
    _n(59, "Multi-function Output Selection 3 (Terminal P2)", "", 1, 0, 21, 2,
       _unverified("range 0…21 not confirmed", _T4)),
)

# -- n092…n112: stall prevention, frequency detection, motor constants ------------------------
PROTECTION = (
    _n(92, "Stall Prevention during Deceleration", "", 1, 0, 1, 0, _TOE),
    _n(93, "Stall Prevention Level during Acceleration", "%", 1, 30, 200, 170, _TOE),
    _n(94, "Stall Prevention Level during Running", "%", 1, 30, 200, 160, _TOE),
    _n(95, "Frequency Detection Level", *_HZ, 0, 40000, 0, _unverified("raw unit 0.01 Hz assumed")),
    # Speed search (VS-606V7 TOE-S606-12 constant list): the search runs when a multi-function input set to
    # 14 (search from maximum frequency) or 15 (search from set frequency) is on at the run command.
    _n(101, "Speed Search Deceleration Time", "0.1 s", 0.1, 1, 100, 20,
       _unverified("range 0.1…10.0 s and default 2.0 s not confirmed")),
    _n(102, "Speed Search Operation Level", "%", 1, 0, 200, 150,
       _unverified("% of inverter rated current; range 0…200 % and default 150 % not confirmed")),
    _n(103, "Torque Compensation Gain", "0.1", 0.1, 0, 25, 10, _TOE),
    _n(106, "Motor Rated Slip", "0.1 Hz", 0.1, 0, 200, 26, _unverified(_CAP)),
    _n(107, "Motor Line-to-Neutral Resistance", "0.001 Ω", 0.001, 0, 65500, 1233,
       _unverified("raw unit 0.001 Ω assumed; " + _CAP)),
    _n(108, "Motor Leakage Inductance", "0.01 mH", 0.01, 0, 65500, 1340,
       _unverified("raw unit 0.01 mH assumed; " + _CAP)),
    _n(110, "Motor No-Load Current", "%", 1, 0, 99, 45, _unverified("% of n036; " + _CAP)),
    _n(111, "Slip Compensation Gain", "0.1", 0.1, 0, 25, 0, _TOE + "; V/f default"),
    _n(112, "Slip Compensation Time Constant", "0.1 s", 0.1, 0, 255, 20, _TOE),
)

# -- n120…n127: frequency references 9…16 -------------------------------------------------------
REFERENCES_9_16 = tuple(
    _n(k, f"Frequency Reference {k - 111}", *_HZ, 0, 40000, 0, _FREF_SRC) for k in range(120, 128)
)

# -- n178/n179: display-only constants ----------------------------------------------------------
DISPLAY = (
    _n(178, "Fault History", "", 1, 0, 0xFFFF, 0,
       "SI-T/V7 ALM_RD table (n178 Fault History); register: " + _RULE, read_only=True, radix=16),
    _n(179, "Software Version No.", "", 1, 0, 0xFFFF, 0, _RULE, read_only=True),
)

# -- U-xx monitors (MEMOBUS monitor data; no register confirmed) ------------------------------
_MON_U = _unverified("monitor register not confirmed", _MON)
MONITORS = (
    _mon("U-01", 0x0023, "Frequency Reference", "0.1 Hz", 0.1,
         "named in SI-T/V7 Table 5; " + _unverified("register and 0.1 Hz unit (n152 = 0) not confirmed", _MON)),
    _mon("U-02", 0x0024, "Output Frequency", "0.1 Hz", 0.1,
         _unverified("register and 0.1 Hz unit (n152 = 0) not confirmed", _MON)),
    _mon("U-03", 0x0027, "Output Current", "0.1 A", 0.1, _MON_U),
    _mon("U-04", 0x0028, "Output Voltage", "1 V", 1, _MON_U),
    _mon("U-05", 0x0031, "DC Bus Voltage", "1 V", 1, _MON_U),
    _mon("U-06", 0x002B, "Input Terminal Status", "", 1, _MON_U, radix=16),
    _mon("U-07", 0x002D, "Output Terminal Status", "", 1, _MON_U, radix=16),
    _mon("U-08", 0x0032, "Torque Monitor", "%", 1,
         "named in SI-T/V7 Table 5 (MON value in 0.1 %); "
         + _unverified("register and 1 % register unit not confirmed", _MON), signed=True),
)

VS606V7 = ParamTable("v7", "VS-606V7", (
    *SETUP, *ACCEL, *REFERENCES, *IO, *PROTECTION, *REFERENCES_9_16, *DISPLAY, *MONITORS,
))
