"""Induction motor (V/f, linear slip-torque region) and mechanical load.

Equations (docs/drive-model.md, section "Motor and load"):

* pole pairs ``pp = E2-04 / 2``; synchronous speed ``w_s = 2 pi f / pp`` (rad/s, mechanical)
* rated speed ``w_r = 2 pi (E1-06 - E2-02) / pp``; rated torque ``T_r = E2-11 / w_r``
* flux ratio ``phi = 1`` up to the base frequency E1-06, ``E1-06 / |f|`` above (constant voltage)
* torque ``T = K phi^2 (w_s - w)`` with ``K = T_r / (2 pi E2-02 / pp)``: slip proportional to
  torque, rated slip at rated torque
* current ``I = sqrt((I0 phi)^2 + (I_T (T / T_r) / phi)^2)``, ``I_T = sqrt(E2-01^2 - E2-03^2)``
* mechanics ``J dw/dt = T - T_load(w)``

The load is chosen per station (:class:`LoadSpec`): pure inertia, constant (passive, Coulomb-like)
torque, quadratic fan torque, or viscous friction; every kind may add viscous friction.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Literal

from .settings import DriveSettings

__all__ = ["LoadSpec", "MotorConstants", "vf_voltage", "DEFAULT_STARTING_TIME_S", "DEFAULT_LOAD_PCT"]

LoadKind = Literal["inertia", "constant", "fan", "friction"]


#: Defaults "scaled to the motor" for fields left None (see :meth:`LoadSpec.resolve`).
DEFAULT_STARTING_TIME_S = 0.5  # mechanical starting time of the default inertia
DEFAULT_LOAD_PCT = {"constant": 50.0, "fan": 80.0, "friction": 50.0, "inertia": 0.0}


@dataclass(frozen=True)
class LoadSpec:
    """Mechanical load on the motor shaft (all quantities referred to the motor shaft).

    * ``kind`` -- ``"inertia"``: no load torque; ``"constant"``: passive constant torque
      ``torque_nm`` opposing rotation (holds the shaft at standstill up to ``torque_nm``);
      ``"fan"``: ``torque_nm * (w / w_fan)^2`` opposing rotation, ``torque_nm`` at
      ``rated_speed_rpm``; ``"friction"``: viscous ``viscous_nms * w``.
    * ``inertia_kgm2`` -- total inertia, motor rotor plus load (kg m^2), > 0.  None: scaled to
      the motor, ``J = T_r * 0.5 s / w_r`` (rated torque accelerates it to rated speed in 0.5 s).
    * ``torque_nm`` -- constant torque, or fan torque at ``rated_speed_rpm`` (N m), >= 0.
      None: 50 % (constant) / 80 % (fan) of the motor rated torque.
    * ``viscous_nms`` -- viscous friction coefficient (N m s/rad), >= 0, added for every kind.
      None: 0, except ``"friction"``: 50 % of rated torque at rated speed.
    * ``rated_speed_rpm`` -- fan: speed where ``torque_nm`` applies; None = motor rated speed.

    The drive resolves None fields against its motor (:meth:`resolve`).
    """

    kind: LoadKind = "inertia"
    inertia_kgm2: float | None = None
    torque_nm: float | None = None
    viscous_nms: float | None = None
    rated_speed_rpm: float | None = None

    def __post_init__(self) -> None:
        if self.kind not in ("inertia", "constant", "fan", "friction"):
            raise ValueError(f"unknown load kind {self.kind!r}")
        if self.inertia_kgm2 is not None and not self.inertia_kgm2 > 0.0:
            raise ValueError("inertia_kgm2 must be > 0")
        if (self.torque_nm or 0.0) < 0.0 or (self.viscous_nms or 0.0) < 0.0:
            raise ValueError("torque_nm and viscous_nms must be >= 0")
        if self.rated_speed_rpm is not None and not self.rated_speed_rpm > 0.0:
            raise ValueError("rated_speed_rpm must be > 0")

    @classmethod
    def from_config(cls, cfg: Mapping[str, object]) -> LoadSpec:
        """From a station's ``load`` table: ``kind``, ``inertia`` (kg m^2), ``torque`` (N m),
        ``friction`` (N m s/rad); missing keys are scaled to the motor."""
        def num(key: str) -> float | None:
            v = cfg.get(key)
            return None if v is None else float(v)  # type: ignore[arg-type]
        return cls(str(cfg.get("kind", "inertia")), num("inertia"), num("torque"),  # type: ignore[arg-type]
                   num("friction"), num("rated_speed_rpm"))

    @classmethod
    def for_motor(cls, settings: DriveSettings, kind: LoadKind = "constant", *,
                  load_pct: float = 50.0, starting_time_s: float = DEFAULT_STARTING_TIME_S) -> LoadSpec:
        """A load scaled to the motor of ``settings``.

        ``starting_time_s`` is the mechanical starting time: the time rated torque needs to
        accelerate the inertia to rated speed, ``J = T_r * t / w_r``.  ``load_pct`` is the load
        torque at rated speed in % of rated torque (constant: at any speed; fan: at rated
        speed; friction: ``viscous = load_pct% * T_r / w_r``; inertia: ignored).
        """
        t_r = settings.rated_torque_nm
        w_r = settings.rated_speed_rad_s
        j = t_r * starting_time_s / w_r
        t_l = t_r * load_pct / 100.0
        if kind == "friction":
            return cls("friction", j, 0.0, t_l / w_r)
        if kind == "inertia":
            return cls("inertia", j, 0.0, 0.0)
        return cls(kind, j, t_l, 0.0)

    def resolve(self, settings: DriveSettings) -> LoadSpec:
        """This load with None fields replaced by values scaled to the motor of ``settings``."""
        if None not in (self.inertia_kgm2, self.torque_nm, self.viscous_nms):
            return self
        t_r, w_r = settings.rated_torque_nm, settings.rated_speed_rad_s
        pct = DEFAULT_LOAD_PCT[self.kind] / 100.0
        j = self.inertia_kgm2 if self.inertia_kgm2 is not None else t_r * DEFAULT_STARTING_TIME_S / w_r
        if self.torque_nm is not None:
            tq = self.torque_nm
        else:
            tq = t_r * pct if self.kind in ("constant", "fan") else 0.0
        if self.viscous_nms is not None:
            b = self.viscous_nms
        else:
            b = t_r * pct / w_r if self.kind == "friction" else 0.0
        return LoadSpec(self.kind, j, tq, b, self.rated_speed_rpm)


@dataclass(frozen=True)
class MotorConstants:
    """Per-drive constants derived once from the settings (see module docstring)."""

    pole_pairs: int
    w_per_hz: float  # rad/s (mechanical) per Hz of output frequency
    stiffness: float  # K, N m per rad/s of slip
    rated_torque: float
    rated_speed: float
    i0: float
    i_t_rated: float
    i_rated: float
    r_phase: float
    base_freq: float

    @classmethod
    def from_settings(cls, s: DriveSettings) -> MotorConstants:
        pp = s.pole_pairs
        w_per_hz = 2.0 * math.pi / pp
        slip_w = s.motor_rated_slip_hz * w_per_hz
        t_r = s.rated_torque_nm
        i_t = math.sqrt(max(s.motor_rated_current_a**2 - s.motor_no_load_current_a**2, 1e-9))
        return cls(pp, w_per_hz, t_r / slip_w if slip_w > 0 else 1e9, t_r, s.rated_speed_rad_s,
                   s.motor_no_load_current_a, i_t, s.motor_rated_current_a,
                   s.motor_phase_resistance_ohm, s.base_freq_hz)


def vf_voltage(s: DriveSettings, f_hz: float) -> float:
    """Output voltage of the V/f pattern E1-04..E1-10 (V7 n011..n017) at ``|f_hz|``.

    Straight lines through (E1-09, E1-10), (E1-07, E1-08), (E1-06, E1-05); E1-05 above E1-06.
    """
    f = abs(f_hz)
    if f <= 0.0:
        return 0.0
    if f >= s.base_freq_hz:
        return s.max_voltage_v
    pts = ((0.0, s.min_voltage_v), (s.min_freq_hz, s.min_voltage_v),
           (s.mid_freq_hz, s.mid_voltage_v), (s.base_freq_hz, s.max_voltage_v))
    for (f0, v0), (f1, v1) in zip(pts, pts[1:]):
        if f <= f1:
            return v0 if f1 <= f0 else v0 + (v1 - v0) * (f - f0) / (f1 - f0)
    return s.max_voltage_v
