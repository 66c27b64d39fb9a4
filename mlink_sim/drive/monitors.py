"""Monitors in the drive's raw units: U1/U2/U3 (A1000 family), U-xx (VS-606V7), SEL_MON codes.

Units (A1000 Technical Manual, "U: Monitors"; SI-T3 Table 18; SI-ET3 Table 22; SI-T/V7 Table 5). What each
SEL_MON code selects is the wire's table (:data:`mlink_sim.wire.selections.SEL_MON_TABLES`, re-exported here):

========  ============================  ===================================================
U1-01     frequency reference           o1-03 units
U1-02     output frequency              o1-03 units
U1-03     output current                0.01 A (models up to 2A0040/4A0023) or 0.1 A
U1-04     control method                A1-02 value
U1-05     motor speed                   o1-03 units, signed
U1-06     output voltage reference      0.1 V
U1-07     DC bus voltage                1 V
U1-08     output power                  0.01 kW / 0.1 kW (same split as U1-03), signed
U1-09     torque reference              0.1 % of motor rated torque, signed
U1-10     input terminals S1..S8        bit n-1 = Sn (network S3..S8; S1/S2 not simulated: 0)
U1-11     output terminals              bit0 M1-M2 (H2-01 = 0 during run), bit1 M3-M4
                                        (H2-02 = 1 zero speed), bit2 M5-M6 (H2-03 = 2 speed
                                        agree), bit7 MA-MB-MC fault contact
U1-12     drive status                  bit0 run, 1 zero speed, 2 reverse, 3 fault reset
                                        input, 4 speed agree, 5 ready, 6 minor fault, 7 fault
U1-13..15 analog inputs A1, A2, A3      0.1 %, always 0 (no analog inputs simulated)
U1-16     soft-starter output           0.01 Hz
U2-01     current fault                 SI-T3 Table 26 code (0 = none)
U2-02     previous fault                SI-T3 Table 26 code
U3-01..10 fault history, most recent 1st  SI-T3 Table 26 codes (SI-T3 Table 14 numbering)
========  ============================  ===================================================

VS-606V7: U-01 frequency reference and U-02 output frequency in n035 units, U-03 output current
0.1 A, U-04 output voltage 1 V, U-05 DC bus 1 V, U-06 input terminals (bit n-1 = Sn), U-07 output
terminals (bit0 MA, bit1 P1, bit2 P2 with n057..n059 defaults fault / running / frequency agree),
U-08 torque 0.1 % (vector control n002 = 1 only, else 0 -- SI-T/V7 Table 5), U-09 most recent
fault (Table 10 code), U-11 output power 0.1 kW.

Signed values are returned as Python ints; the card packs them as 16-bit two's complement.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Protocol

from ..wire.selections import SEL_MON_TABLES
from .faults import Fault, fault_code, minor_code
from .settings import DriveSettings, Family, _ref_to_hz
from .status import DriveStatus

__all__ = ["DriveView", "hz_to_ref", "ref_to_hz", "read_monitor", "monitor_reader", "read_sel_mon", "sel_mon_readers",
           "SEL_MON_TABLES", "MONITOR_REGISTERS", "MONITOR_NAMES"]


class _Inputs(Protocol):
    @property
    def multi_inputs(self) -> int: ...


class DriveView(Protocol):
    """What the monitors read of a drive: :class:`mlink_sim.drive.Drive`'s outputs (this module does not import
    it; the drive imports this one)."""

    @property
    def family(self) -> Family: ...
    @property
    def settings(self) -> DriveSettings: ...
    @property
    def status(self) -> DriveStatus: ...
    @property
    def fault_history(self) -> tuple[Fault, ...]: ...
    @property
    def command_in_effect(self) -> _Inputs: ...  # a DriveCommand: its multi-function inputs
    @property
    def frequency_reference_hz(self) -> float: ...
    @property
    def output_frequency_hz(self) -> float: ...
    @property
    def soft_starter_hz(self) -> float: ...
    @property
    def motor_speed_rad_s(self) -> float: ...
    @property
    def output_current_a(self) -> float: ...
    @property
    def output_voltage_v(self) -> float: ...
    @property
    def output_power_kw(self) -> float: ...
    @property
    def dc_bus_v(self) -> float: ...
    @property
    def torque_pct(self) -> float: ...


def hz_to_ref(s: DriveSettings, hz: float) -> int:
    """Hz -> raw frequency units of o1-03 (A1000) / n035 (V7), sign kept."""
    mode = s.ref_mode
    if mode == "hz":
        v = hz / s.ref_unit
    elif mode == "pct" or mode == "user":
        v = hz / s.max_freq_hz * s.ref_full_scale
    else:
        v = hz * 120.0 / s.motor_poles
    return int(math.floor(v + 0.5)) if v >= 0 else -int(math.floor(-v + 0.5))


def ref_to_hz(s: DriveSettings, raw: int) -> float:
    """Raw frequency reference (o1-03 / n035 units) -> Hz (magnitude; direction is the run bits)."""
    return _ref_to_hz(s, raw)


def _r(x: float) -> int:
    return int(math.floor(x + 0.5)) if x >= 0 else -int(math.floor(-x + 0.5))


#: MEMOBUS register -> monitor, for F6-23 / F6-24 (A1000 Technical Manual, MEMOBUS data table:
#: U1-01 is 0040H, consecutive up to U1-12 at 004BH).  Other registers read 0 here; a card
#: may resolve them through the parameter table instead.
MONITOR_REGISTERS: dict[int, str] = {0x40 + i: f"U1-{i + 1:02d}" for i in range(12)}


def _u2(idx: int) -> Callable[[DriveView], int]:
    def read(d: DriveView) -> int:
        cur = d.status.fault
        if idx == 1:
            return fault_code(d.family, cur)
        hist = d.fault_history
        prev = hist[1:2] if cur is not None else hist[0:1]
        return fault_code(d.family, prev[0]) if prev else 0
    return read


def _u3(idx: int) -> Callable[[DriveView], int]:
    def read(d: DriveView) -> int:
        hist = d.fault_history
        return fault_code(d.family, hist[idx - 1]) if idx <= len(hist) else 0
    return read


def _u1_11(d: DriveView) -> int:
    st = d.status
    return int(st.running) | int(st.zero_speed) << 1 | int(st.speed_agree) << 2 | int(st.faulted) << 7


def _u1_12(d: DriveView) -> int:
    st = d.status
    return (int(st.running) | int(st.zero_speed) << 1 | int(st.reverse) << 2
            | int(st.fault_reset_input) << 3 | int(st.speed_agree) << 4 | int(st.ready) << 5
            | int(st.minor_fault) << 6 | int(st.faulted) << 7)


def _v7_u07(d: DriveView) -> int:
    st = d.status
    return int(st.faulted) | int(st.running) << 1 | int(st.speed_agree) << 2


def _zero(d: DriveView) -> int:
    return 0


_TWO_PI = 2.0 * math.pi

_A1000: dict[str, Callable[[DriveView], int]] = {
    "U1-01": lambda d: hz_to_ref(d.settings, d.frequency_reference_hz),
    "U1-02": lambda d: abs(hz_to_ref(d.settings, d.output_frequency_hz)),
    "U1-03": lambda d: _r(d.output_current_a / d.settings.current_unit_a),
    "U1-04": lambda d: d.settings.control_method,
    "U1-05": lambda d: hz_to_ref(d.settings, d.motor_speed_rad_s * d.settings.pole_pairs / _TWO_PI),
    "U1-06": lambda d: _r(d.output_voltage_v * 10.0),
    "U1-07": lambda d: _r(d.dc_bus_v),
    "U1-08": lambda d: _r(d.output_power_kw / d.settings.power_unit_kw),
    "U1-09": lambda d: _r(d.torque_pct * 10.0),
    "U1-10": lambda d: (d.command_in_effect.multi_inputs & 0x3F) << 2,
    "U1-11": _u1_11,
    "U1-12": _u1_12,
    "U1-13": _zero, "U1-14": _zero, "U1-15": _zero,
    "U1-16": lambda d: _r(abs(d.soft_starter_hz) * 100.0),
    "U2-01": _u2(1), "U2-02": _u2(2),
    **{f"U3-{i:02d}": _u3(i) for i in range(1, 11)},
}

_V7: dict[str, Callable[[DriveView], int]] = {
    "U-01": lambda d: hz_to_ref(d.settings, d.frequency_reference_hz),
    "U-02": lambda d: abs(hz_to_ref(d.settings, d.output_frequency_hz)),
    "U-03": lambda d: _r(d.output_current_a * 10.0),
    "U-04": lambda d: _r(d.output_voltage_v),
    "U-05": lambda d: _r(d.dc_bus_v),
    "U-06": lambda d: (d.command_in_effect.multi_inputs & 0x1F) << 2,
    "U-07": _v7_u07,
    "U-08": lambda d: _r(d.torque_pct * 10.0) if d.settings.control_method == 1 else 0,
    "U-09": _u3(1),
    "U-11": lambda d: _r(d.output_power_kw * 10.0),
}

#: Monitor names each family answers (others read 0).
MONITOR_NAMES: dict[Family, tuple[str, ...]] = {Family.A1000: tuple(_A1000), Family.V7: tuple(_V7)}


def monitor_reader(family: Family, name: str) -> Callable[[DriveView], int]:
    """The function :func:`read_monitor` calls for monitor ``name`` of ``family`` (reads 0 for an unknown name):
    a caller that reads the same monitor every cycle resolves it once."""
    return (_V7 if family is Family.V7 else _A1000).get(name, _zero)


def read_monitor(drive: DriveView, name: str) -> int:
    """Monitor ``name`` in raw units (see module docstring); unknown names read 0."""
    fn = (_V7 if drive.family is Family.V7 else _A1000).get(name)
    return fn(drive) if fn is not None else 0


def _alarm(d: DriveView) -> int:
    return fault_code(d.family, d.status.fault)


def _warning(d: DriveView) -> int:
    return minor_code(d.family, d.status.minor)


def _register(which: str) -> Callable[[DriveView], int]:
    def read(d: DriveView) -> int:
        reg = d.settings.f6_23 if which == "F6-23" else d.settings.f6_24
        target = MONITOR_REGISTERS.get(reg)
        return read_monitor(d, target) if target else 0
    return read


def _sel_mon_readers(table: tuple[str, ...], family: dict[str, Callable[[DriveView], int]]
                     ) -> tuple[Callable[[DriveView], int], ...]:
    special = {"": _zero, "ALARM": _alarm, "WARNING": _warning, "F6-23": _register("F6-23"),
               "F6-24": _register("F6-24")}
    return tuple(special.get(name) or family.get(name, _zero) for name in table)


#: (SEL_MON table, family) -> its 16 readers, made on first use (:func:`sel_mon_readers`).
_SEL_MON_READERS: dict[tuple[str, Family], tuple[Callable[[DriveView], int], ...]] = {}


def sel_mon_readers(table: str, family: Family) -> tuple[Callable[[DriveView], int], ...]:
    """The 16 reader functions (call ``reader(drive)``) of the SEL_MON table *table* (its key in
    :data:`SEL_MON_TABLES`, a card profile's ``selections``: "SI-T3", "SI-ET3", "SI-T/V7") on a drive of *family*;
    a table it does not know reads 0."""
    readers = _SEL_MON_READERS.get((table, family))
    if readers is None:
        names = SEL_MON_TABLES.get(table, ("",) * 16)
        readers = _sel_mon_readers(names, _V7 if family is Family.V7 else _A1000)
        _SEL_MON_READERS[(table, family)] = readers
    return readers


def read_sel_mon(drive: DriveView, table: str, code: int) -> int:
    """SEL_MON ``code`` (0..F) of the SEL_MON table *table* ("SI-T3", "SI-ET3", "SI-T/V7")."""
    if not 0 <= code <= 0xF:
        return 0
    return sel_mon_readers(table, drive.family)[code](drive)
