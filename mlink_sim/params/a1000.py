"""A1000/GA-class drive parameters (the drive behind SI-T3 and SI-ET3), as data.

Sources, in order of precedence:

1. the option manuals in ``shared/manuals`` – SI-T3 Table 4 (F6 ranges/defaults), Tables 8/9
   (C1-01 = 0200H), Table 16 (H1-03…H1-08 defaults), Tables 17/18 (H2/H4, U1 monitors);
   SI-ET3 Table 7 (registers, ranges and defaults of b1-01/b1-02, d5-01 and F6);
2. where they are silent, the A1000 Technical Manual SIEP C710616 27 (Appendix B parameter
   table, Appendix C MEMOBUS/Modbus data table).  Rows cite which in ``source``; a figure not
   confirmed against a table of that manual carries "(unverified: why)".

Defaults that depend on the drive carry these assumptions:

* drive: CIMR-A2A0040 (200 V class), Heavy Duty (C6-01 = 0), rated output current 33 A;
* motor: 7.5 kW, 4-pole, 200 V Yaskawa standard motor (E2-xx defaults of that rating);
* control method: Open Loop Vector (A1-02 = 2, the drive default), so E1-07…E1-10 take the
  OLV defaults;
* o1-03 = 0 (frequency units 0.01 Hz) and C1-10 = 1 (times in 0.1 s): ``unit``/``scale`` of
  d1-xx, U1-01/02/05 and C1-xx assume these defaults; the drive model rescales if changed;
* current units are 0.01 A (models 2A0004…2A0040 display current in 0.01 A).

Monitors U1/U2/U3 follow the settings below.  Card views:

* ``A1000_SI_T3`` – F6-01 limited to 0…3 and F6-20 to 20H…3FH (SI-T3 Table 4);
* ``A1000_SI_ET3`` – F6-20 03H…EFH (SI-ET3 Table 7).

The family table ``A1000`` carries the union of both (F6-01 0…5, F6-20 03H…EFH).
"""

from __future__ import annotations

from .table import Param, ParamTable

__all__ = ["A1000", "A1000_SI_ET3", "A1000_SI_T3"]

_T3_4 = "SI-T3 Table 4"
_ET3_7 = "SI-ET3 Table 7"
_T3_ET3 = "SI-T3 Table 4 (range, default); SI-ET3 Table 7 (register, range, default)"
_A1K = "A1000 Technical Manual SIEP C710616 27, Appendix B parameter table (option manuals silent)"
_OLV = _A1K + "; default for A1-02 = 2 (OLV)"


def _unverified(why: str, base: str = _A1K) -> str:
    return f"{base} (unverified: {why})"


_CAP = "capacity-dependent default for a 7.5 kW 200 V motor on CIMR-A2A0040 HD, not confirmed"

# -- A: initialization ------------------------------------------------------------------------
A1 = (
    Param("A1-02", 0x0102, "Control Method Selection", "", 1, 0, 7, 2, source=_A1K),
    # Named by SI-T3/SI-ET3 (F6-08 description).  Only 0, 1110, 2220, 3330 and 5550 are
    # accepted settings on the drive; the range here is the span.
    Param("A1-03", 0x0103, "Initialize Parameters", "", 1, 0, 5550, 0,
          source=_A1K + "; named in SI-T3 Table 4 / SI-ET3 Table 7 (F6-08 text)"),
)

# -- b1: operation mode selection -------------------------------------------------------------
B1 = (
    Param("b1-01", 0x0180, "Frequency Reference Selection 1", "", 1, 0, 4, 1,
          source="SI-T3 Table 4 (range, default 1); SI-ET3 Table 7 (register 0180H)"),
    Param("b1-02", 0x0181, "Run Command Selection 1", "", 1, 0, 3, 1,
          source="SI-T3 Table 4; SI-ET3 Table 7 (register 0181H, range 0…3, default 1)"),
    Param("b1-03", 0x0182, "Stopping Method Selection", "", 1, 0, 3, 0, source=_A1K),
    Param("b1-04", 0x0183, "Reverse Operation Selection", "", 1, 0, 1, 0, source=_A1K),
)

# -- b3: speed search.  The option manuals only list SEr "Too Many Speed Search Restarts" (SI-T3 Table 26,
# code 3BH).  Registers, ranges and defaults: A1000 Technical Manual, b3 parameter table, not confirmed
# against that table (unverified).  The same b3 group as Yaskawa publishes it for the P1000 / Z1000 / T1000V /
# V1000 / GA700 (b3-01 "Speed Search Selection at Start", b3-02 operation current, b3-03 decel time, b3-05
# delay, b3-24 0 = Current Detection / 1 = Speed Estimation, b3-25 0.0…30.0 s default 0.5 s) agrees with
# every figure below that those manuals show. ------------------------------------------------------------
_B3 = "A1000 Technical Manual SIEP C710616 27, b3 Speed Search table (option manuals silent)"

def _b3(name: str, register: int, title: str, unit: str, scale: float, lo: int, hi: int, default: int,
        figures: str) -> Param:
    return Param(name, register, title, unit, scale, lo, hi, default,
                 source=_unverified("register, range and default not confirmed; " + figures, _B3))


B3 = (
    _b3("b3-01", 0x0191, "Speed Search Selection at Start", "", 1, 0, 1, 0,
        "default 0 for A1-02 = 0/2 (V/f, OLV), 1 for CLV and V/f w/PG"),
    _b3("b3-02", 0x0192, "Speed Search Deactivation Current", "%", 1, 0, 200, 100,
        "% of drive rated current; default 100 % for A1-02 = 2 (OLV), 120 % for V/f"),
    _b3("b3-03", 0x0193, "Speed Search Deceleration Time", "0.1 s", 0.1, 1, 100, 20, "0.1…10.0 s, default 2.0 s"),
    _b3("b3-05", 0x0195, "Speed Search Delay Time", "0.1 s", 0.1, 0, 1000, 2, "0.0…100.0 s, default 0.2 s"),
    _b3("b3-17", 0x01F0, "Speed Search Restart Current Level", "%", 1, 0, 200, 150,
        "% of drive rated current, default 150 %"),
    _b3("b3-18", 0x01F1, "Speed Search Restart Detection Time", "0.01 s", 0.01, 0, 100, 10,
        "0.00…1.00 s, default 0.10 s"),
    _b3("b3-19", 0x01F2, "Number of Speed Search Restarts", "", 1, 0, 10, 3,
        "default 3; exceeding it trips SEr (SI-T3 Table 26, 3BH)"),
    _b3("b3-24", 0x01C0, "Speed Search Method Selection", "", 1, 0, 1, 0,
        "0 = Current Detection, 1 = Speed Estimation, default 0"),
    _b3("b3-25", 0x01C8, "Speed Search Wait Time", "0.1 s", 0.1, 0, 300, 5,
        "0.0…30.0 s, default 0.5 s (as the V1000 TM prints it)"),
)

# -- C1: acceleration/deceleration times (C1-10 = 1: 0.1 s units) ------------------------------
C1 = (
    Param("C1-01", 0x0200, "Acceleration Time 1", "0.1 s", 0.1, 0, 60000, 100,
          source="SI-T3 Tables 8/9 (register 0200H); range/default: " + _A1K),
    Param("C1-02", 0x0201, "Deceleration Time 1", "0.1 s", 0.1, 0, 60000, 100,
          source=_A1K + "; named in SI-T3 Table 4 (F6-01)"),
    Param("C1-03", 0x0202, "Acceleration Time 2", "0.1 s", 0.1, 0, 60000, 100, source=_A1K),
    Param("C1-04", 0x0203, "Deceleration Time 2", "0.1 s", 0.1, 0, 60000, 100, source=_A1K),
    Param("C1-05", 0x0204, "Acceleration Time 3", "0.1 s", 0.1, 0, 60000, 100, source=_A1K),
    Param("C1-06", 0x0205, "Deceleration Time 3", "0.1 s", 0.1, 0, 60000, 100, source=_A1K),
    Param("C1-07", 0x0206, "Acceleration Time 4", "0.1 s", 0.1, 0, 60000, 100, source=_A1K),
    Param("C1-08", 0x0207, "Deceleration Time 4", "0.1 s", 0.1, 0, 60000, 100, source=_A1K),
    Param("C1-09", 0x0208, "Fast Stop Time", "0.1 s", 0.1, 0, 60000, 100,
          source=_A1K + "; named in SI-T3 Table 4 / SI-ET3 Table 7 (Fast Stop)"),
    Param("C1-10", 0x0209, "Accel/Decel Time Setting Units", "", 1, 0, 1, 1, source=_A1K),
)

# -- C2: S-curve characteristics ------------------------------------------------------------
C2 = (
    Param("C2-01", 0x020B, "S-Curve Characteristic at Accel Start", "0.01 s", 0.01, 0, 1000, 20, source=_A1K),
    Param("C2-02", 0x020C, "S-Curve Characteristic at Accel End", "0.01 s", 0.01, 0, 1000, 20, source=_A1K),
    Param("C2-03", 0x020D, "S-Curve Characteristic at Decel Start", "0.01 s", 0.01, 0, 1000, 20, source=_A1K),
    Param("C2-04", 0x020E, "S-Curve Characteristic at Decel End", "0.01 s", 0.01, 0, 1000, 0, source=_A1K),
)

# -- d1: frequency references (o1-03 = 0: 0.01 Hz).  d1-10…d1-17 follow d2-01/d2-02 ----------
# (0289H/028AH), which is why d1-10 starts at 028BH.
_D1_SRC = _A1K + "; d1-01…d1-17 named in SI-T3 Table 4 (b1-01 = 0)"
D1 = tuple(
    Param(f"d1-{i:02d}", reg, f"Frequency Reference {i}", "0.01 Hz", 0.01, 0, 40000, 0, source=_D1_SRC)
    for i, reg in zip(range(1, 17), [*range(0x0280, 0x0289), *range(0x028B, 0x0292)])
) + (
    Param("d1-17", 0x0292, "Jog Frequency Reference", "0.01 Hz", 0.01, 0, 40000, 600, source=_D1_SRC),
)

# d2 registers: Appendix B, B.6 d: References, in the SIEP C710616 41H edition (same register map).
_D2 = "A1000 Technical Manual SIEP C710616 41H, Appendix B parameter table, B.6 (option manuals silent)"
D2 = (
    Param("d2-01", 0x0289, "Frequency Reference Upper Limit", "0.1 %", 0.1, 0, 1100, 1000, source=_D2),
    Param("d2-02", 0x028A, "Frequency Reference Lower Limit", "0.1 %", 0.1, 0, 1100, 0, source=_D2),
)

D5 = (
    Param("d5-01", 0x029A, "Torque Control Selection", "", 1, 0, 1, 0, source=_ET3_7),
)

# -- E1: V/f pattern (200 V class).  There is no E1-02 on the A1000 (motor selection moved
# to L1-01); register 0301H is unused. ---------------------------------------------------------
E1 = (
    Param("E1-01", 0x0300, "Input Voltage Setting", "1 V", 1, 155, 255, 200, source=_A1K + "; 200 V class"),
    Param("E1-03", 0x0302, "V/f Pattern Selection", "", 1, 0, 0xF, 0xF, source=_A1K, radix=16),
    Param("E1-04", 0x0303, "Maximum Output Frequency", "0.1 Hz", 0.1, 400, 4000, 600, source=_A1K),
    Param("E1-05", 0x0304, "Maximum Voltage", "0.1 V", 0.1, 0, 2550, 2000, source=_A1K + "; 200 V class"),
    Param("E1-06", 0x0305, "Base Frequency", "0.1 Hz", 0.1, 0, 4000, 600, source=_A1K),
    Param("E1-07", 0x0306, "Middle Output Frequency", "0.1 Hz", 0.1, 0, 4000, 30, source=_OLV),
    Param("E1-08", 0x0307, "Middle Output Frequency Voltage", "0.1 V", 0.1, 0, 2550, 110,
          source=_unverified("OLV/200 V default not confirmed", _OLV)),
    Param("E1-09", 0x0308, "Minimum Output Frequency", "0.1 Hz", 0.1, 0, 4000, 5,
          source=_unverified("OLV default not confirmed", _OLV)),
    Param("E1-10", 0x0309, "Minimum Output Frequency Voltage", "0.1 V", 0.1, 0, 2550, 20,
          source=_unverified("OLV/200 V default not confirmed", _OLV)),
    Param("E1-11", 0x030A, "Middle Output Frequency 2", "0.1 Hz", 0.1, 0, 4000, 0, source=_A1K),
    Param("E1-12", 0x030B, "Middle Output Frequency Voltage 2", "0.1 V", 0.1, 0, 2550, 0, source=_A1K),
    Param("E1-13", 0x030C, "Base Voltage", "0.1 V", 0.1, 0, 2550, 0, source=_A1K),
)

# -- E2: motor 1 parameters (7.5 kW 4-pole motor on a CIMR-A2A0040, see module docstring) -----
E2 = (
    Param("E2-01", 0x030E, "Motor Rated Current", "0.01 A", 0.01, 330, 6600, 2660,
          source=_unverified("range 10…200 % of 33 A HD rated current; " + _CAP)),
    Param("E2-02", 0x030F, "Motor Rated Slip", "0.01 Hz", 0.01, 0, 2000, 130, source=_unverified(_CAP)),
    Param("E2-03", 0x0310, "Motor No-Load Current", "0.01 A", 0.01, 0, 6599, 800,
          source=_unverified("drive limits it below E2-01; " + _CAP)),
    Param("E2-04", 0x0311, "Number of Motor Poles", "", 1, 2, 48, 4, source=_A1K),
    Param("E2-05", 0x0312, "Motor Line-to-Line Resistance", "0.001 Ω", 0.001, 0, 65000, 230,
          source=_unverified(_CAP)),
    Param("E2-06", 0x0313, "Motor Leakage Inductance", "0.1 %", 0.1, 0, 400, 195, source=_unverified(_CAP)),
    Param("E2-11", 0x0318, "Motor Rated Power", "0.01 kW", 0.01, 0, 65000, 750,
          source=_unverified("register not confirmed; " + _CAP)),
)

# -- F6: communication option card settings ----------------------------------------------------
F6 = (
    Param("F6-01", 0x03A2, "Communications Error Operation Selection", "", 1, 0, 5, 1,
          source=_T3_ET3 + "; family range is the SI-ET3 0…5 (SI-T3: 0…3)"),
    Param("F6-02", 0x03A3, "External Fault from Comm. Option Detection Selection", "", 1, 0, 1, 0, source=_T3_ET3),
    Param("F6-03", 0x03A4, "External Fault from Comm. Option Operation Selection", "", 1, 0, 3, 1, source=_T3_ET3),
    Param("F6-06", 0x03A7, "Torque Reference/Torque Limit Selection from Comm. Option", "", 1, 0, 1, 0,
          source=_ET3_7),
    Param("F6-07", 0x03A8, "NetRef/ComRef Function Selection (Multi-Step Speed Enable)", "", 1, 0, 1, 0,
          source=_T3_ET3),
    Param("F6-08", 0x036A, "Reset Communication Parameters", "", 1, 0, 1, 0, source=_T3_ET3),
    Param("F6-15", 0x0B5F, "Comm. Option Parameters Reload", "", 1, 0, 2, 0,
          source="named in SI-ET3 Table 26 (CyPo); GA700 Technical Manual SIEP C710617 parameter table "
                 "(unverified: GA700-series parameter, absent on A1000; register and range not confirmed)"),
    Param("F6-20", 0x036B, "MECHATROLINK Station Address", "", 1, 0x03, 0xEF, 0x21,
          source="SI-T3 Table 4 (20H…3FH, default 21H); SI-ET3 Table 7 (register 036BH, 03H…EFH, default 21H); "
                 "family range is the union", radix=16),
    Param("F6-21", 0x036C, "MECHATROLINK Frame Size", "", 1, 0, 1, 0,
          source=_T3_ET3 + " (SI-T3 0: 32 byte, 1: 17 byte; SI-ET3 0: 64-byte, 1: 32-byte)"),
    Param("F6-22", 0x036D, "MECHATROLINK Link Speed", "", 1, 0, 1, 0,
          source=_T3_4 + " (range, default; 0: 10 Mbps, 1: 4 Mbps); register: " + _A1K
                 + " (unverified: not confirmed; it fills the gap in the 036BH…036FH run of SI-ET3 Table 7)"),
    Param("F6-23", 0x036E, "MECHATROLINK Monitor Selection (E)", "", 1, 0, 0xFFFF, 0, source=_T3_ET3, radix=16),
    Param("F6-24", 0x036F, "MECHATROLINK Monitor Selection (F)", "", 1, 0, 0xFFFF, 0, source=_T3_ET3, radix=16),
    Param("F6-25", 0x03C9, "Operation Selection at Watchdog Error (E5)", "", 1, 0, 3, 1, source=_T3_ET3),
    Param("F6-26", 0x03CA, "MECHATROLINK bUS Errors Detected", "", 1, 2, 10, 2, source=_T3_ET3),
    Param("F6-54", 0x03C5, "Idle Mode Fault Detection", "", 1, 0, 1, 0,
          source="named in SI-ET3 Table 26 (EF0); " + _unverified("DeviceNet-group parameter; register not confirmed")),
)

# -- H1: multi-function digital inputs (settings are hex, e.g. 24H = External Fault) -----------
_H1_T3 = "SI-T3 Table 16 (default); register/range: " + _A1K
_H1_RANGE = _unverified("range 1…9FH for S1/S2 not confirmed", _A1K)
H1 = (
    Param("H1-01", 0x0438, "Multi-Function Digital Input Terminal S1 Function Selection", "", 1, 0x01, 0x9F, 0x40,
          source=_H1_RANGE, radix=16),
    Param("H1-02", 0x0439, "Multi-Function Digital Input Terminal S2 Function Selection", "", 1, 0x01, 0x9F, 0x41,
          source=_H1_RANGE, radix=16),
    Param("H1-03", 0x0400, "Multi-Function Digital Input Terminal S3 Function Selection", "", 1, 0, 0x9F, 0x24,
          source=_H1_T3, radix=16),
    Param("H1-04", 0x0401, "Multi-Function Digital Input Terminal S4 Function Selection", "", 1, 0, 0x9F, 0x14,
          source=_H1_T3, radix=16),
    Param("H1-05", 0x0402, "Multi-Function Digital Input Terminal S5 Function Selection", "", 1, 0, 0x9F, 0x03,
          source=_H1_T3, radix=16),
    Param("H1-06", 0x0403, "Multi-Function Digital Input Terminal S6 Function Selection", "", 1, 0, 0x9F, 0x04,
          source=_H1_T3, radix=16),
    Param("H1-07", 0x0404, "Multi-Function Digital Input Terminal S7 Function Selection", "", 1, 0, 0x9F, 0x06,
          source=_H1_T3, radix=16),
    # SI-T3 Table 16 prints "(Default = 7: External bb command)"; on the A1000, 7 is
    # Accel/Decel Time Selection 1 and External Baseblock N.O. is 8.  The description wins.
    Param("H1-08", 0x0405, "Multi-Function Digital Input Terminal S8 Function Selection", "", 1, 0, 0x9F, 0x08,
          source="SI-T3 Table 16 names External bb command (its '7' conflicts; A1000 setting 8 = External "
                 "Baseblock N.O.); register/range: " + _A1K, radix=16),
)

# -- H2/H4: outputs named by SI-T3 Table 17 / SI-ET3 Table 21 (SEL_REF) -----------------------
_H2 = "named in SI-T3 Table 17 (H2-0x = F: through mode); " + _unverified("register and range not confirmed")
_H4 = "named in SI-T3 Table 17 / SI-ET3 Table 21 (= 000: set by comm.); " + _unverified("register not confirmed")
H2 = (
    Param("H2-01", 0x040B, "Terminal M1-M2 Function Selection (relay)", "", 1, 0, 0x192, 0x00, source=_H2, radix=16),
    Param("H2-02", 0x040C, "Terminal P1-PC Function Selection (photocoupler)", "", 1, 0, 0x192, 0x01,
          source=_H2, radix=16),
    Param("H2-03", 0x040D, "Terminal P2-PC Function Selection (photocoupler)", "", 1, 0, 0x192, 0x02,
          source=_H2, radix=16),
)
H4 = (
    Param("H4-01", 0x041D, "Multi-Function Analog Output Terminal FM Monitor Selection", "", 1, 0, 999, 102, source=_H4),
    Param("H4-04", 0x0420, "Multi-Function Analog Output Terminal AM Monitor Selection", "", 1, 0, 999, 103, source=_H4),
)

# -- L3: stall prevention (HD levels) / L4: speed agree ---------------------------------------
_L3 = _unverified("registers 048FH…0494H not confirmed")
_L3_HD = _unverified("registers 048FH…0494H not confirmed; 150 % is the HD default, ND is 120 %")
L3 = (
    Param("L3-01", 0x048F, "Stall Prevention Selection during Acceleration", "", 1, 0, 2, 1, source=_L3),
    Param("L3-02", 0x0490, "Stall Prevention Level during Acceleration", "%", 1, 0, 150, 150,
          source=_L3_HD),
    Param("L3-03", 0x0491, "Stall Prevention Limit during Acceleration", "%", 1, 0, 100, 50, source=_L3),
    Param("L3-04", 0x0492, "Stall Prevention Selection during Deceleration", "", 1, 0, 5, 1, source=_L3),
    Param("L3-05", 0x0493, "Stall Prevention Selection during Run", "", 1, 0, 2, 1, source=_L3),
    Param("L3-06", 0x0494, "Stall Prevention Level during Run", "%", 1, 30, 150, 150,
          source=_L3_HD),
)
L4 = (
    Param("L4-01", 0x0499, "Speed Agreement Detection Level", "0.1 Hz", 0.1, 0, 4000, 0,
          source=_unverified("register not confirmed")),
    Param("L4-02", 0x049A, "Speed Agreement Detection Width", "0.1 Hz", 0.1, 0, 200, 20,
          source=_unverified("register not confirmed")),
)

# -- o1: keypad display -------------------------------------------------------------------------
O1 = (
    Param("o1-03", 0x0502, "Digital Operator Display Selection (frequency reference units)", "", 1, 0, 3, 0,
          source=_A1K + "; named in SI-T3 INV_CTL / SI-ET3 INV_CTL (speed reference units)"),
)

# =============================================================================================
# Monitors: U1 (status), U2 (fault trace), U3 (fault history).  Read-only; minimum/maximum are
# the 16-bit wire range (signed where the value can be negative) and default is 0.
#
# * U1: SI-T3 Table 18 / SI-ET3 Table 22 (SEL_MON codes) name U1-01, -05, -07, -09, -10, -11,
#   -13, -14, -15 and give units where stated (0.1 % for U1-09/13/14/15, 1 V for U1-07).
#   Registers: A1000 MEMOBUS/Modbus data table ("0040H to 004AH Used for various monitors U1-",
#   "004BH Drive status (U1-12)").
# * U2/U3: SI-T3 Table 14 / SI-ET3 Tables 16, 17 (ALM_RD) name U2-01/U2-02 and U3-01…U3-10.
#   Registers: same data table ("0080H to 0097H Used for monitors U2-, U3-"); U3-05…U3-10 and
#   U3-15…U3-20 sit in the 0800H block, which also mirrors U3-01…U3-04 and U3-11…U3-14.
# * U2-18 and U2-19 do not exist on the A1000 and are left out.
# =============================================================================================
_MB = "A1000 Technical Manual SIEP C710616 27, Appendix C MEMOBUS/Modbus data table (option manuals silent)"
_SELMON = "SI-T3 Table 18 / SI-ET3 Table 22 (SEL_MON; unit where given); register: " + _MB
_ALM = "SI-T3 Table 14 / SI-ET3 Tables 16, 17 (ALM_RD); register: " + _MB
_U16 = (0, 0xFFFF)
_S16 = (-0x8000, 0x7FFF)


def _unverified_mb(why: str, base: str = _MB) -> str:
    return f"{base} (unverified: {why})"


_IN_U1_BLOCK = "exact register not confirmed; it lies in the 004CH…007EH U1/U4/U5/U6 block of C.9"
_POWER_UNIT = "unit not confirmed; the decimals may depend on drive capacity"


def _mon(name: str, register: int, title: str, unit: str, scale: float, source: str,
         *, signed: bool = False, radix: int = 10, alt: tuple[int, ...] = ()) -> Param:
    lo, hi = _S16 if signed else _U16
    return Param(name, register, title, unit, scale, lo, hi, 0, read_only=True, signed=signed,
                 source=source, radix=radix, alt_registers=alt)


U1 = (
    _mon("U1-01", 0x0040, "Frequency Reference", "0.01 Hz", 0.01, _SELMON),
    _mon("U1-02", 0x0041, "Output Frequency", "0.01 Hz", 0.01, _MB),
    _mon("U1-03", 0x0042, "Output Current", "0.01 A", 0.01, _MB + "; 0.01 A on 2A0004…2A0040"),
    _mon("U1-04", 0x0043, "Control Method", "", 1, _MB),
    _mon("U1-05", 0x0044, "Motor Speed", "0.01 Hz", 0.01, _SELMON, signed=True),
    _mon("U1-06", 0x0045, "Output Voltage Reference", "0.1 V", 0.1, _MB),
    _mon("U1-07", 0x0046, "DC Bus Voltage", "1 V", 1, _SELMON),
    _mon("U1-08", 0x0047, "Output Power", "0.1 kW", 0.1, _unverified_mb(_POWER_UNIT), signed=True),
    _mon("U1-09", 0x0048, "Torque Reference", "0.1 %", 0.1, _SELMON, signed=True),
    _mon("U1-10", 0x0049, "Input Terminal Status", "", 1, _SELMON, radix=16),
    _mon("U1-11", 0x004A, "Output Terminal Status", "", 1, _SELMON, radix=16),
    _mon("U1-12", 0x004B, "Drive Status", "", 1, _MB, radix=16),
    _mon("U1-13", 0x004E, "Terminal A1 Input Level", "0.1 %", 0.1,
         _unverified_mb(_IN_U1_BLOCK, _SELMON), signed=True),
    _mon("U1-14", 0x004F, "Terminal A2 Input Level", "0.1 %", 0.1,
         _unverified_mb(_IN_U1_BLOCK, _SELMON), signed=True),
    _mon("U1-15", 0x0050, "Terminal A3 Input Level", "0.1 %", 0.1,
         _unverified_mb(_IN_U1_BLOCK, _SELMON), signed=True),
    _mon("U1-16", 0x0053, "Output Frequency after Soft Starter", "0.01 Hz", 0.01,
         _unverified_mb(_IN_U1_BLOCK)),
)

_TRACE = _unverified_mb("registers 07E0H…07E2H not confirmed")
U2 = (
    _mon("U2-01", 0x0080, "Current Fault", "", 1, _ALM, radix=16),
    _mon("U2-02", 0x0081, "Previous Fault", "", 1, _ALM, radix=16),
    _mon("U2-03", 0x0082, "Frequency Reference at Previous Fault", "0.01 Hz", 0.01, _MB),
    _mon("U2-04", 0x0083, "Output Frequency at Previous Fault", "0.01 Hz", 0.01, _MB),
    _mon("U2-05", 0x0084, "Output Current at Previous Fault", "0.01 A", 0.01, _MB),
    _mon("U2-06", 0x0085, "Motor Speed at Previous Fault", "0.01 Hz", 0.01, _MB, signed=True),
    _mon("U2-07", 0x0086, "Output Voltage at Previous Fault", "0.1 V", 0.1, _MB),
    _mon("U2-08", 0x0087, "DC Bus Voltage at Previous Fault", "1 V", 1, _MB),
    _mon("U2-09", 0x0088, "Output Power at Previous Fault", "0.1 kW", 0.1, _unverified_mb(_POWER_UNIT),
         signed=True),
    _mon("U2-10", 0x0089, "Torque Reference at Previous Fault", "0.1 %", 0.1, _MB, signed=True),
    _mon("U2-11", 0x008A, "Input Terminal Status at Previous Fault", "", 1, _MB, radix=16),
    _mon("U2-12", 0x008B, "Output Terminal Status at Previous Fault", "", 1, _MB, radix=16),
    _mon("U2-13", 0x008C, "Drive Operation Status at Previous Fault", "", 1, _MB, radix=16),
    _mon("U2-14", 0x008D, "Cumulative Operation Time at Previous Fault", "1 h", 1, _MB),
    _mon("U2-15", 0x07E0, "Soft Starter Speed Reference at Previous Fault", "0.01 %", 0.01, _TRACE),
    _mon("U2-16", 0x07E1, "Motor q-Axis Current at Previous Fault", "0.1 %", 0.1, _TRACE, signed=True),
    _mon("U2-17", 0x07E2, "Motor d-Axis Current at Previous Fault", "0.1 %", 0.1, _TRACE, signed=True),
    _mon("U2-20", 0x008E, "Heatsink Temperature at Previous Fault", "1 °C", 1,
         _unverified_mb("exact register not confirmed; it lies in the 0080H…0097H U2/U3 block of C.9"),
         signed=True),
)

_ORD = ("Most Recent", "2nd Most Recent", "3rd Most Recent", "4th Most Recent", "5th Most Recent",
        "6th Most Recent", "7th Most Recent", "8th Most Recent", "9th Most Recent", "10th Most Recent")
_U3_LOW = _ALM + "; mirrored at 0800H…0803H"
_U3_HIGH = _unverified_mb("0800H-block registers not confirmed", _ALM)
_U3_TIME = "A1000 Technical Manual SIEP C710616 27, Appendix C MEMOBUS/Modbus data table (option manuals silent)"
U3 = tuple(
    _mon(f"U3-{i:02d}", 0x0090 + i - 1, f"{_ORD[i - 1]} Fault", "", 1, _U3_LOW, radix=16, alt=(0x0800 + i - 1,))
    for i in range(1, 5)
) + tuple(
    _mon(f"U3-{i:02d}", 0x0800 + i - 1, f"{_ORD[i - 1]} Fault", "", 1, _U3_HIGH, radix=16)
    for i in range(5, 11)
) + tuple(
    _mon(f"U3-{i:02d}", 0x0094 + i - 11, f"Cumulative Operation Time at {_ORD[i - 11]} Fault", "1 h", 1,
         _unverified_mb("mirror registers 080AH…080DH not confirmed", _U3_TIME), alt=(0x080A + i - 11,))
    for i in range(11, 15)
) + tuple(
    _mon(f"U3-{i:02d}", 0x080E + i - 15, f"Cumulative Operation Time at {_ORD[i - 11]} Fault", "1 h", 1,
         _unverified_mb("0800H-block registers not confirmed", _U3_TIME))
    for i in range(15, 21)
)

MONITORS: tuple[Param, ...] = (*U1, *U2, *U3)

SETTINGS: tuple[Param, ...] = (
    *A1, *B1, *B3, *C1, *C2, *D1, *D2, *D5, *E1, *E2, *F6, *H1, *H2, *H4, *L3, *L4, *O1,
)

A1000 = ParamTable("a1000", "A1000", (*SETTINGS, *MONITORS))

A1000_SI_T3 = A1000.derive(
    "si-t3",
    {
        "F6-01": {"maximum": 3, "source": _T3_4 + " (range 0…3, default 1); register: " + _ET3_7},
        "F6-20": {"minimum": 0x20, "maximum": 0x3F,
                  "source": _T3_4 + " (20H…3FH, default 21H); register: " + _ET3_7},
        "F6-21": {"title": "MECHATROLINK Frame Size (0: 32 byte, 1: 17 byte)"},
    },
)

A1000_SI_ET3 = A1000.derive(
    "si-et3",
    {
        "F6-20": {"source": _ET3_7 + " (register 036BH, 03H…EFH, default 21H)"},
        "F6-21": {"title": "MECHATROLINK Frame Size (0: 64-byte, 1: 32-byte)"},
    },
)
