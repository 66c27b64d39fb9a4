"""Drive settings in engineering units (SI), built from raw parameter values by name.

:meth:`DriveSettings.from_params` takes the values a card's parameter table holds, in the drive's
own units (0.01 Hz, 0.1 s, 0.1 %, 0.01 A ...), keyed by name (``"C1-01"`` for the A1000 family,
``"n019"`` for the VS-606V7) and converts them once.  A name the model needs that is missing raises
``KeyError`` naming the parameter.  :meth:`DriveSettings.check` returns the oPE code a real drive
would show for inconsistent settings.

Units and defaults of the A1000 parameters: YASKAWA AC Drive A1000 Technical Manual (SIEP C710616 27)
and the SI-T3 / SI-ET3 manuals (Table 4 / Table 7 for b1-01, b1-02, F6-xx, d5-01).  VS-606V7
constants: VS-606V7 Instruction Manual (TOE-S606-11) and SI-T/V7 manual section 6 (n003, n004).
Figures the option manuals do not give are listed, with their source, in docs/drive-model.md.
"""

from __future__ import annotations

import enum
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Final, NamedTuple

from .faults import Fault
from .search import SpeedSearch, a1000_search, v7_search

__all__ = [
    "OPTIONAL_DEFAULTS",
    "Family",
    "StopMethod",
    "ExtFaultInput",
    "InputMap",
    "DriveSettings",
    "required_params",
]


class Family(enum.Enum):
    """Drive family behind the option card."""

    A1000 = "a1000"  # A1000/GA-class behind SI-T3 and SI-ET3
    V7 = "v7"  # VS-606V7 behind SI-T/V7


class StopMethod(enum.IntEnum):
    """Stop on a fault cause; setting values of F6-01 / F6-03 / F6-25 (SI-T3 Table 4, SI-ET3 Table 7)."""

    RAMP = 0  # decelerate to stop with C1-02
    COAST = 1  # output off, the load slows the motor
    FAST = 2  # decelerate to stop with C1-09
    ALARM_ONLY = 3  # minor fault, operation continues
    ALARM_RUN_D1_04 = 4  # F6-01 = 4 (SI-ET3 Table 7): minor fault, run at d1-04
    ALARM_RAMP = 5  # F6-01 = 5 (SI-ET3 Table 7): minor fault, ramp to stop


class ExtFaultInput(NamedTuple):
    """A multi-function input set to an external fault (A1000 H1 = 20H..2FH, V7 n05x = 3/4)."""

    mask: int  # bit in DriveCommand.multi_inputs
    fault: Fault  # EF3..EF8 by terminal
    normally_closed: bool
    run_only: bool
    stop: StopMethod


@dataclass(frozen=True)
class InputMap:
    """Multi-function input functions decoded to bit masks of ``DriveCommand.multi_inputs``.

    Bit k of ``multi_inputs`` is terminal S(k+3): SI-T3 Table 16 bits 2..7, SI-ET3 Table 20 bits
    16..21 and SI-T/V7 Table 3 bits 2..6, each shifted down to bit 0.
    """

    multi_step: tuple[int, int, int, int] = (0, 0, 0, 0)
    jog: int = 0
    accel_decel_2: int = 0
    baseblock_no: int = 0
    baseblock_nc: int = 0
    fault_reset: int = 0
    fast_stop_no: int = 0
    fast_stop_nc: int = 0
    motor2: int = 0
    search_max: int = 0  # speed search from the maximum frequency (H1 = 61H, n05x = 14)
    search_ref: int = 0  # speed search from the frequency reference (H1 = 62H, n05x = 15)
    ext_faults: tuple[ExtFaultInput, ...] = ()
    duplicated: bool = False  # same function on two inputs -> oPE03

    @staticmethod
    def decode_a1000(settings: tuple[int, ...]) -> InputMap:
        """Decode H1-03..H1-08 (A1000 Technical Manual, H1 multi-function input settings, hex)."""
        found: dict[str, int] = {}
        ext: list[ExtFaultInput] = []
        dup = False
        for k, value in enumerate(settings):
            mask = 1 << k
            if 0x20 <= value <= 0x2F:
                n = value & 0x0F
                ext.append(ExtFaultInput(mask, _EF_BY_TERMINAL[k + 3], bool(n & 1), bool(n & 2),
                                         (StopMethod.RAMP, StopMethod.COAST, StopMethod.FAST,
                                          StopMethod.ALARM_ONLY)[n >> 2]))
                continue
            name = _A1000_H1.get(value)
            if name is None:
                continue
            dup |= name in found
            found[name] = found.get(name, 0) | mask
        dup |= bool(found.get("bb_no") and found.get("bb_nc"))
        dup |= bool(found.get("fs_no") and found.get("fs_nc"))
        return InputMap._build(found, tuple(ext), dup)

    @staticmethod
    def decode_v7(settings: tuple[int, ...]) -> InputMap:
        """Decode n052..n056 (terminals S3..S7; VS-606V7 Instruction Manual, n050..n056)."""
        found: dict[str, int] = {}
        ext: list[ExtFaultInput] = []
        dup = False
        seen: set[int] = set()
        for k, value in enumerate(settings):
            mask = 1 << k
            dup |= value in seen and value not in (3, 4)
            seen.add(value)
            if value in (3, 4):
                ext.append(ExtFaultInput(mask, _EF_BY_TERMINAL[k + 3], value == 4, False,
                                         StopMethod.COAST))
            elif value in (19, 20, 21, 22):  # emergency stop: fault/alarm, N.O./N.C.
                ext.append(ExtFaultInput(mask, Fault.STP, value in (21, 22), False,
                                         StopMethod.FAST if value in (19, 21) else StopMethod.ALARM_RAMP))
            else:
                name = _V7_N05X.get(value)
                if name is not None:
                    found[name] = found.get(name, 0) | mask
        return InputMap._build(found, tuple(ext), dup)

    @staticmethod
    def _build(found: dict[str, int], ext: tuple[ExtFaultInput, ...], dup: bool) -> InputMap:
        g = found.get
        return InputMap(
            multi_step=(g("ms1", 0), g("ms2", 0), g("ms3", 0), g("ms4", 0)),
            jog=g("jog", 0), accel_decel_2=g("acc2", 0), baseblock_no=g("bb_no", 0),
            baseblock_nc=g("bb_nc", 0), fault_reset=g("reset", 0), fast_stop_no=g("fs_no", 0),
            fast_stop_nc=g("fs_nc", 0), motor2=g("motor2", 0), search_max=g("ss_max", 0),
            search_ref=g("ss_ref", 0), ext_faults=ext, duplicated=dup)


_EF_BY_TERMINAL = {3: Fault.EF3, 4: Fault.EF4, 5: Fault.EF5, 6: Fault.EF6, 7: Fault.EF7, 8: Fault.EF8}
# A1000 H1-xx setting values (hex) -> function
_A1000_H1 = {0x03: "ms1", 0x04: "ms2", 0x05: "ms3", 0x32: "ms4", 0x06: "jog", 0x07: "acc2",
             0x08: "bb_no", 0x09: "bb_nc", 0x14: "reset", 0x15: "fs_no", 0x17: "fs_nc",
             0x16: "motor2", 0x61: "ss_max", 0x62: "ss_ref"}
# VS-606V7 n050..n056 setting values -> function
_V7_N05X = {5: "reset", 6: "ms1", 7: "ms2", 8: "ms3", 9: "ms4", 10: "jog", 11: "acc2",
            12: "bb_no", 13: "bb_nc", 14: "ss_max", 15: "ss_ref"}

_A1000_REQUIRED = (
    ("A1-02", "b1-01", "b1-02", "b1-03", "C1-01", "C1-02", "C1-03", "C1-04", "C1-09",
     "C2-01", "C2-02", "C2-03", "C2-04")
    + tuple(f"d1-{i:02d}" for i in range(1, 18))
    + ("d5-01", "E1-01", "E1-04", "E1-05", "E1-06", "E1-07", "E1-08", "E1-09", "E1-10",
       "E2-01", "E2-02", "E2-03", "E2-04", "E2-05", "E2-11",
       "F6-01", "F6-02", "F6-03", "F6-06", "F6-07", "F6-25")
    + tuple(f"H1-{i:02d}" for i in range(3, 9))
    + ("L3-01", "L3-02", "L3-04", "L4-01", "L4-02", "o1-03")
)
_V7_REQUIRED = (
    ("n002", "n003", "n004", "n005", "n011", "n012", "n013", "n014", "n015", "n016", "n017",
     "n019", "n020", "n021", "n022", "n023")
    + tuple(f"n{i:03d}" for i in range(24, 33))
    + ("n035", "n036")
    + tuple(f"n{i:03d}" for i in range(52, 57))
    + ("n092", "n093", "n106", "n107", "n110")
)


#: Parameters read when present, else the drive's factory default (source in the comment).
OPTIONAL_DEFAULTS: dict[Family, dict[str, int]] = {
    Family.A1000: {
        "C1-10": 1,  # accel/decel time unit: 1 = 0.1 s (A1000 Technical Manual, C1-10 default)
        "L1-01": 1,  # motor overload: 1 = general-purpose motor (A1000 TM, L1-01 default)
        "L1-02": 10,  # motor overload time 1.0 min (A1000 TM, L1-02 default)
        "F6-23": 0, "F6-24": 0,  # SEL_MON E/F registers (SI-T3 Table 4 default 0)
        # speed search b3 (A1000 TM b3 table; A1-02 = 2 defaults as in mlink_sim.params): off, 100 %, 2.0 s,
        # 0.2 s, restart at 150 % for 0.10 s, 3 restarts, Current Detection, 0.5 s between restarts
        "b3-01": 0, "b3-02": 100, "b3-03": 20, "b3-05": 2, "b3-17": 150, "b3-18": 10, "b3-19": 3,
        "b3-24": 0, "b3-25": 5,
    },
    Family.V7: {
        "n018": 0,  # accel/decel time unit: 0 = 0.1 s (VS-606V7 manual, n018 default)
        "n037": 0,  # electronic thermal: 0 = general-purpose motor (VS-606V7, n037 default)
        "n038": 8,  # electronic thermal time constant 8 min (VS-606V7, n038 default)
        "n095": 0,  # frequency detection level 0.00 Hz (VS-606V7, n095 default)
        "n101": 20, "n102": 150,  # speed search decel time 2.0 s, operation level 150 % (VS-606V7 TOE-S606-12)
    },
}


def required_params(family: Family) -> tuple[str, ...]:
    """Names :meth:`DriveSettings.from_params` always reads; more are read when present
    (:data:`OPTIONAL_DEFAULTS`, L2-05/L3-17, o1-10 when o1-03 = 3, n120..n127 with multi-step 4)."""
    return _A1000_REQUIRED if family is Family.A1000 else _V7_REQUIRED


def _get(values: Mapping[str, int], name: str) -> int:
    try:
        return int(values[name])
    except KeyError:
        raise KeyError(f"drive parameter {name} missing from the parameter values") from None


@dataclass(frozen=True)
class DriveSettings:
    """Everything the model needs, in SI units.  Build with :meth:`from_params`."""

    family: Family
    # reference path -------------------------------------------------------------------------
    ref_mode: str  # "hz" (0.01 Hz), "pct" (% of fmax), "rpm", "user" (user value at fmax)
    ref_unit: float  # Hz per raw unit ("hz"), % per unit ("pct") ...; see monitors.hz_to_ref
    ref_full_scale: float  # raw value at max frequency for "pct"/"user"
    max_freq_hz: float  # E1-04 / n011
    max_voltage_v: float  # E1-05 / n012
    base_freq_hz: float  # E1-06 / n013
    mid_freq_hz: float  # E1-07 / n014
    mid_voltage_v: float  # E1-08 / n015
    min_freq_hz: float  # E1-09 / n016
    min_voltage_v: float  # E1-10 / n017
    accel_s: float  # C1-01 / n019, 0 -> max frequency
    decel_s: float  # C1-02 / n020
    accel2_s: float  # C1-03 / n021
    decel2_s: float  # C1-04 / n022
    fast_stop_s: float  # C1-09 / (V7: n022, decel time 2)
    s_curve_s: tuple[float, float, float, float]  # C2-01..C2-04 / n023 (accel start/end, decel start/end)
    step_refs_hz: tuple[float, ...]  # d1-01..d1-16 / n024..n031(,n120..n127)
    jog_hz: float  # d1-17 / n032
    multi_step_enabled: bool  # F6-07 (V7: always, SI-T3 Table 4 "Same as V7")
    ref_from_network: bool  # b1-01 = 3 / n004 = 9
    local_ref_hz: float  # reference when not from the network: d1-01 (b1-01 = 0) / n024 (n004 = 0, 1)
    run_from_network: bool  # b1-02 = 3 / n003 = 3
    coast_on_run_off: bool  # b1-03 = 1 / n005 = 1
    control_method: int  # A1-02 / n002 (reported in U1-04; the motor model is V/f)
    # motor ---------------------------------------------------------------------------------
    motor_rated_current_a: float  # E2-01 / n036
    motor_rated_slip_hz: float  # E2-02 / n106
    motor_no_load_current_a: float  # E2-03 / n110 x n036
    motor_poles: int  # E2-04 / (V7: n035 when 2..39, else 4)
    motor_phase_resistance_ohm: float  # E2-05 / 2 (line-to-line) / n107 (line-to-neutral)
    motor_rated_power_kw: float  # E2-11 / (V7: estimated, see from_params)
    # torque ---------------------------------------------------------------------------------
    torque_control: bool  # d5-01 = 1
    torque_from_network: bool  # F6-06 = 1
    # protections ----------------------------------------------------------------------------
    input_voltage_v: float  # E1-01 / V7 class
    ov_level_v: float
    uv_level_v: float
    stall_decel_level_v: float
    stall_accel: bool  # L3-01 != 0 / n093 < 200
    stall_accel_level_pct: float  # L3-02 / n093, % of drive rated current
    stall_decel: bool  # L3-04 != 0 / n092 = 0
    stall_decel_intelligent: bool  # L3-04 = 2: also raise the frequency to the rotor speed
    oc_level_pct: float  # % of drive rated current
    drive_rated_current_a: float
    ol1_enabled: bool  # L1-01 != 0 / n037 != 2
    ol1_tau_s: float  # thermal time constant (see docs/drive-model.md)
    # status ---------------------------------------------------------------------------------
    agree_level_hz: float  # L4-01 / n095
    agree_width_hz: float  # L4-02 / 2.0 Hz fixed on V7
    # stopping per cause --------------------------------------------------------------------
    bus_stop: StopMethod  # F6-01
    e5_stop: StopMethod  # F6-25
    ef0_stop: StopMethod  # F6-03
    ef0_run_only: bool  # F6-02 = 1
    # inputs ---------------------------------------------------------------------------------
    inputs: InputMap = field(default_factory=InputMap)
    # electrical figures not in the parameter tables ------------------------------------------
    current_unit_a: float = 0.01  # U1-03 / E2-01 unit
    power_unit_kw: float = 0.01  # U1-08 unit
    bus_capacitance_f: float = 1.2e-3
    control_power_w: float = 20.0
    f6_23: int = 0  # MEMOBUS register of SEL_MON E (F6-23)
    f6_24: int = 0  # MEMOBUS register of SEL_MON F (F6-24)
    search: SpeedSearch = field(default_factory=SpeedSearch)  # b3 group / n101, n102
    # raw values kept for check() --------------------------------------------------------------
    _ope_inputs: tuple[float, ...] = ()

    # ----------------------------------------------------------------------------------------
    @property
    def pole_pairs(self) -> int:
        return max(1, self.motor_poles // 2)

    @property
    def nominal_bus_v(self) -> float:
        """Nominal DC bus: sqrt(2) x input voltage (diode rectifier, no load)."""
        return math.sqrt(2.0) * self.input_voltage_v

    @property
    def rated_speed_rad_s(self) -> float:
        return 2.0 * math.pi * (self.base_freq_hz - self.motor_rated_slip_hz) / self.pole_pairs

    @property
    def rated_torque_nm(self) -> float:
        return self.motor_rated_power_kw * 1000.0 / self.rated_speed_rad_s

    @classmethod
    def from_params(
        cls,
        family: Family,
        values: Mapping[str, int],
        *,
        current_unit_a: float | None = None,
        drive_rated_current_a: float | None = None,
        bus_capacitance_f: float | None = None,
        control_power_w: float = 20.0,
        motor_rated_power_kw: float | None = None,
        motor_poles: int | None = None,
        input_voltage_v: float | None = None,
    ) -> DriveSettings:
        """Convert raw parameter values (drive units, by name) to settings.

        ``current_unit_a``: unit of E2-01/E2-03/U1-03 on the A1000 (0.01 A up to models 2A0040 /
        4A0023, 0.1 A above; A1000 Technical Manual).  ``drive_rated_current_a`` defaults to the
        motor rated current.  ``bus_capacitance_f`` defaults to 600 uF per motor kW (200 V class;
        a quarter of that for 400 V) -- an assumption, the manuals give no figure.  V7 only:
        ``motor_rated_power_kw`` (default estimated from n036/n110/n012, see docs), ``motor_poles``
        (default from n035 when 2..39, else 4), ``input_voltage_v`` (default 200 or 400 by n012).
        """
        if family in OPTIONAL_DEFAULTS:
            values = {**OPTIONAL_DEFAULTS[family], **values}
        if family is Family.A1000:
            return _from_a1000(values, current_unit_a, drive_rated_current_a, bus_capacitance_f,
                               control_power_w)
        if family is Family.V7:
            return _from_v7(values, drive_rated_current_a, bus_capacitance_f, control_power_w,
                            motor_rated_power_kw, motor_poles, input_voltage_v)
        raise ValueError(f"unknown drive family {family!r}")

    @classmethod
    def from_defaults(cls, family: Family, overrides: Mapping[str, int] | None = None,
                      **kwargs: float) -> DriveSettings:
        """Convenience: defaults of ``mlink_sim.params.FAMILIES[family]`` updated by ``overrides``.

        Needs the ``mlink_sim.params`` package (ImportError otherwise).
        """
        from mlink_sim.params import FAMILIES

        table = FAMILIES[family.value]
        values = dict(table.defaults())
        if overrides:
            values.update(overrides)
        if family is Family.A1000 and "current_unit_a" not in kwargs:
            try:
                kwargs["current_unit_a"] = float(table.by_name("E2-01").scale)
            except Exception:  # noqa: BLE001 - keep the documented default
                pass
        return cls.from_params(family, values, **kwargs)  # type: ignore[arg-type]

    def check(self) -> str | None:
        """oPE code for inconsistent settings, or None.

        A1000 (A1000 Technical Manual, "oPE codes"): oPE10 "V/f Data Setting Error" unless
        E1-04 >= E1-06 >= E1-07 >= E1-09; oPE03 "Multi-Function Input Selection Error" when a
        function is on two inputs (external faults 20H..2FH excepted) or N.O./N.C. pairs of
        baseblock or fast stop are both set; oPE02 "Parameter Range Setting Error" when
        E2-03 >= E2-01 (no-load current must be below rated current) or a value is outside the
        range the model accepts (E1-04 40.0..400.0 Hz, E2-04 even 2..48).
        VS-606V7 (Instruction Manual, "OPE" errors): OPE10 unless n011 >= n013 > n014 >= n016;
        OPE03 for a duplicated n05x setting; OPE02 for n110 >= 100 %.
        """
        fmax, fbase, fmid, fmin, i_rated, i0, poles, dup = self._ope_inputs
        if dup:
            return "oPE03"
        if self.family is Family.A1000:
            if not (fmax >= fbase >= fmid >= fmin):
                return "oPE10"
            if i0 >= i_rated or not (40.0 <= fmax <= 400.0) or poles < 2 or poles > 48 or poles % 2:
                return "oPE02"
        else:
            if not (fmax >= fbase > fmid >= fmin):
                return "oPE10"
            if i0 >= i_rated:
                return "oPE02"
        return None


def _s_curve_ok(x: float) -> float:
    return max(0.0, x)


def _voltage_class(v_in: float) -> tuple[float, float, float]:
    """(ov level, default uv level, default stall-prevention level) for the voltage class."""
    if v_in <= 255.0:
        return 410.0, 190.0, 375.0
    return 820.0, 380.0, 750.0


def _from_a1000(values: Mapping[str, int], current_unit_a: float | None,
                drive_rated_current_a: float | None, bus_capacitance_f: float | None,
                control_power_w: float) -> DriveSettings:
    g = lambda name: _get(values, name)  # noqa: E731
    ref_mode, ref_unit, ref_fs = _a1000_ref_units(values)
    fmax = g("E1-04") * 0.1
    poles = g("E2-04")
    cu = current_unit_a if current_unit_a is not None else 0.01
    t_unit = 0.1 if g("C1-10") == 1 else 0.01  # C1-10: 1 -> 0.1 s (default)
    settings_tmp = _RefUnits(ref_mode=ref_mode, ref_unit=ref_unit, ref_full_scale=ref_fs,
                             max_freq_hz=fmax, motor_poles=poles)
    to_hz = lambda raw: _ref_to_hz(settings_tmp, raw)  # noqa: E731
    i_rated = g("E2-01") * cu
    i0 = g("E2-03") * cu
    v_in = float(g("E1-01"))
    ov, uv_default, stall_default = _voltage_class(v_in)
    p_kw = g("E2-11") * 0.01
    inputs = InputMap.decode_a1000(tuple(g(f"H1-{i:02d}") for i in range(3, 9)))
    i_drive = drive_rated_current_a if drive_rated_current_a is not None else i_rated
    if bus_capacitance_f is None:
        bus_capacitance_f = BUS_UF_PER_KW * 1e-6 * max(p_kw, 0.1) * (1.0 if v_in <= 255.0 else 0.25)
    l1_02_min = g("L1-02") * 0.1
    fbase, fmid, fmin = g("E1-06") * 0.1, g("E1-07") * 0.1, g("E1-09") * 0.1
    return DriveSettings(
        family=Family.A1000, ref_mode=ref_mode, ref_unit=ref_unit, ref_full_scale=ref_fs,
        max_freq_hz=fmax, max_voltage_v=g("E1-05") * 0.1, base_freq_hz=fbase,
        mid_freq_hz=fmid, mid_voltage_v=g("E1-08") * 0.1, min_freq_hz=fmin,
        min_voltage_v=g("E1-10") * 0.1,
        accel_s=g("C1-01") * t_unit, decel_s=g("C1-02") * t_unit, accel2_s=g("C1-03") * t_unit,
        decel2_s=g("C1-04") * t_unit, fast_stop_s=g("C1-09") * t_unit,
        s_curve_s=tuple(_s_curve_ok(g(f"C2-0{i}") * 0.01) for i in range(1, 5)),  # type: ignore[arg-type]
        step_refs_hz=tuple(to_hz(g(f"d1-{i:02d}")) for i in range(1, 17)),
        jog_hz=to_hz(g("d1-17")), multi_step_enabled=g("F6-07") == 1,
        ref_from_network=g("b1-01") == 3, run_from_network=g("b1-02") == 3,
        local_ref_hz=to_hz(g("d1-01")) if g("b1-01") == 0 else 0.0,
        coast_on_run_off=g("b1-03") in (1, 3), control_method=g("A1-02"),
        motor_rated_current_a=i_rated, motor_rated_slip_hz=g("E2-02") * 0.01,
        motor_no_load_current_a=i0, motor_poles=poles,
        motor_phase_resistance_ohm=g("E2-05") * 0.001 / 2.0, motor_rated_power_kw=p_kw,
        torque_control=g("d5-01") == 1, torque_from_network=g("F6-06") == 1,
        input_voltage_v=v_in, ov_level_v=ov,
        uv_level_v=float(values.get("L2-05", uv_default)),
        stall_decel_level_v=float(values.get("L3-17", stall_default)),
        stall_accel=g("L3-01") != 0, stall_accel_level_pct=float(g("L3-02")),
        stall_decel=g("L3-04") != 0, stall_decel_intelligent=g("L3-04") == 2, oc_level_pct=200.0, drive_rated_current_a=i_drive,
        ol1_enabled=g("L1-01") != 0, ol1_tau_s=OL1_TAU_PER_TRIP_TIME * l1_02_min * 60.0,
        agree_level_hz=g("L4-01") * 0.1, agree_width_hz=g("L4-02") * 0.1,
        bus_stop=_stop(g("F6-01")), e5_stop=_stop(g("F6-25")), ef0_stop=_stop(g("F6-03")),
        ef0_run_only=g("F6-02") == 1, inputs=inputs, current_unit_a=cu,
        power_unit_kw=0.01 if cu <= 0.01 else 0.1, bus_capacitance_f=bus_capacitance_f,
        control_power_w=control_power_w, f6_23=g("F6-23"), f6_24=g("F6-24"), search=a1000_search(g),
        _ope_inputs=(fmax, fbase, fmid, fmin, i_rated, i0, poles, inputs.duplicated),
    )


def _from_v7(values: Mapping[str, int], drive_rated_current_a: float | None,
             bus_capacitance_f: float | None, control_power_w: float,
             motor_rated_power_kw: float | None, motor_poles: int | None,
             input_voltage_v: float | None) -> DriveSettings:
    g = lambda name: _get(values, name)  # noqa: E731
    n035 = g("n035")
    fmax = g("n011") * 0.1
    if motor_poles is None:
        motor_poles = n035 if 2 <= n035 <= 39 else 4
    ref_mode, ref_unit, ref_fs = _v7_ref_units(n035)
    tmp = _RefUnits(ref_mode=ref_mode, ref_unit=ref_unit, ref_full_scale=ref_fs, max_freq_hz=fmax,
                    motor_poles=motor_poles)
    to_hz = lambda raw: _ref_to_hz(tmp, raw)  # noqa: E731
    t_unit = 0.01 if g("n018") == 1 else 0.1  # n018: 0 -> 0.1 s (default)
    s = (0.0, 0.2, 0.5, 1.0)[min(max(g("n023"), 0), 3)]  # n023: S-curve 0 / 0.2 / 0.5 / 1.0 s
    inputs = InputMap.decode_v7(tuple(g(f"n{i:03d}") for i in range(52, 57)))
    refs = [to_hz(g(f"n{i:03d}")) for i in range(24, 32)]
    if inputs.multi_step[3]:  # multi-step 4 assigned: references 9..16 (n120..n127) needed
        refs += [to_hz(g(f"n{i:03d}")) for i in range(120, 128)]
    else:
        refs += [0.0] * 8
    i_rated = g("n036") * 0.1
    i0 = i_rated * g("n110") * 0.01
    vmax = g("n012") * 0.1
    v_in = input_voltage_v if input_voltage_v is not None else (200.0 if vmax <= 255.0 else 400.0)
    ov, _, stall_default = _voltage_class(v_in)
    uv = 200.0 if v_in <= 255.0 else 400.0  # VS-606V7: UV1 approx. 200 V / 400 V DC (3-phase)
    slip = g("n106") * 0.1
    fbase = g("n013") * 0.1
    if motor_rated_power_kw is None:  # P = sqrt(3) V I_T (1 - s) eta, eta = 0.85 (assumption)
        i_t = math.sqrt(max(i_rated**2 - i0**2, 0.0))
        s_pu = slip / fbase if fbase > 0 else 0.0
        motor_rated_power_kw = math.sqrt(3.0) * vmax * i_t * (1.0 - s_pu) * 0.85 / 1000.0
    if bus_capacitance_f is None:
        bus_capacitance_f = (BUS_UF_PER_KW * 1e-6 * max(motor_rated_power_kw, 0.1)
                             * (1.0 if v_in <= 255.0 else 0.25))
    n093 = g("n093")
    fmid, fmin = g("n014") * 0.1, g("n016") * 0.1
    fault_stop = StopMethod.COAST  # SI-T/V7 Table 10 lists BUS, E5, EF0 as faults: output off
    return DriveSettings(
        family=Family.V7, ref_mode=ref_mode, ref_unit=ref_unit, ref_full_scale=ref_fs,
        max_freq_hz=fmax, max_voltage_v=vmax, base_freq_hz=fbase, mid_freq_hz=fmid,
        mid_voltage_v=g("n015") * 0.1, min_freq_hz=fmin, min_voltage_v=g("n017") * 0.1,
        accel_s=g("n019") * t_unit, decel_s=g("n020") * t_unit, accel2_s=g("n021") * t_unit,
        decel2_s=g("n022") * t_unit, fast_stop_s=g("n022") * t_unit, s_curve_s=(s, s, s, s),
        step_refs_hz=tuple(refs), jog_hz=to_hz(g("n032")), multi_step_enabled=True,
        ref_from_network=g("n004") == 9, run_from_network=g("n003") == 3,
        local_ref_hz=refs[0] if g("n004") in (0, 1) else 0.0,
        coast_on_run_off=g("n005") == 1, control_method=g("n002"),
        motor_rated_current_a=i_rated, motor_rated_slip_hz=slip, motor_no_load_current_a=i0,
        motor_poles=motor_poles, motor_phase_resistance_ohm=g("n107") * 0.001,
        motor_rated_power_kw=motor_rated_power_kw, torque_control=False,
        torque_from_network=False, input_voltage_v=v_in, ov_level_v=ov, uv_level_v=uv,
        stall_decel_level_v=stall_default, stall_accel=n093 < 200,
        stall_accel_level_pct=float(n093), stall_decel=g("n092") == 0,
        stall_decel_intelligent=False, oc_level_pct=250.0,
        drive_rated_current_a=drive_rated_current_a if drive_rated_current_a is not None else i_rated,
        ol1_enabled=g("n037") != 2 and i_rated > 0, ol1_tau_s=g("n038") * 60.0,
        agree_level_hz=g("n095") * 0.01, agree_width_hz=2.0,
        bus_stop=fault_stop, e5_stop=fault_stop, ef0_stop=fault_stop, ef0_run_only=False,
        inputs=inputs, current_unit_a=0.1, power_unit_kw=0.1,
        bus_capacitance_f=bus_capacitance_f, control_power_w=control_power_w, search=v7_search(g),
        _ope_inputs=(fmax, fbase, fmid, fmin, i_rated, i0, motor_poles, inputs.duplicated),
    )


#: Default DC-bus capacitance per kW of motor rating, 200 V class (a quarter at 400 V, same
#: stored energy).  An assumption: the manuals give no figure (docs/drive-model.md).
BUS_UF_PER_KW = 600.0

#: oL1 thermal time constant per L1-02 trip time.  Model: d(theta)/dt = (i^2 - theta)/tau with
#: i = I / E2-01, trip at theta >= OL1_TRIP_LEVEL.  Hot start at 100 % (theta = 1) then 150 %:
#: theta(t) = 2.25 - 1.25 exp(-t/tau) reaches 1.21 at t = L1-02 (A1000: "150 % for L1-02 after
#: continuous operation at rated current").  tau = L1-02 / ln(1.25 / (2.25 - 1.21)).
OL1_TRIP_LEVEL: Final = 1.21  # Final: the compiled integrator uses it as a constant, not a lookup
OL1_TAU_PER_TRIP_TIME = 1.0 / math.log(1.25 / (2.25 - OL1_TRIP_LEVEL))


def _stop(raw: int) -> StopMethod:
    try:
        return StopMethod(raw)
    except ValueError:
        return StopMethod.COAST  # out of range: the drive default (F6-01/F6-03/F6-25 default 1)


def _a1000_ref_units(values: Mapping[str, int]) -> tuple[str, float, float]:
    """o1-03: 0 = 0.01 Hz, 1 = 0.01 %, 2 = r/min (E2-04 poles), 3 = user units (o1-10 at fmax)."""
    o1_03 = _get(values, "o1-03")
    if o1_03 == 1:
        return "pct", 0.01, 10000.0
    if o1_03 == 2:
        return "rpm", 1.0, 0.0
    if o1_03 == 3:
        return "user", 1.0, float(_get(values, "o1-10"))
    return "hz", 0.01, 0.0


def _v7_ref_units(n035: int) -> tuple[str, float, float]:
    """n035: 0 = 0.01 Hz, 1 = 0.1 %, 2..39 = r/min (n035 = poles), 40..3999 = user (value at fmax
    in the lower three digits)."""
    if n035 == 1:
        return "pct", 0.1, 1000.0
    if 2 <= n035 <= 39:
        return "rpm", 1.0, 0.0
    if 40 <= n035 <= 3999:
        return "user", 1.0, float(n035 % 1000 or 1000)
    return "hz", 0.01, 0.0


class _RefUnits(NamedTuple):
    """The reference units while the settings are being built (the step references are converted then)."""

    ref_mode: str
    ref_unit: float
    ref_full_scale: float
    max_freq_hz: float
    motor_poles: int


def _ref_to_hz(s: _RefUnits | DriveSettings, raw: int) -> float:
    """Raw reference (o1-03 / n035 units) -> Hz; sign ignored (direction comes from the run bits)."""
    mode = s.ref_mode
    r = abs(int(raw))
    if mode == "hz":
        return r * s.ref_unit
    if mode == "pct" or mode == "user":
        fs = s.ref_full_scale
        return r / fs * s.max_freq_hz if fs else 0.0
    return r * s.motor_poles / 120.0
