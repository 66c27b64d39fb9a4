"""What a drive is doing and what holds it, read from the model's state (:meth:`mlink_sim.drive.Drive.activity`).

A failed timeline check explains itself from this reading (docs/configuration.md, "When a check fails"): the
ramp in progress and its time parameter, stall prevention (DC bus, current), the torque limit, a fault and since
when, a run command the drive does not take. Reading it changes nothing in the drive.

:data:`PARAM_ROLES` names, per family, the parameter behind each setting the explanation mentions (docs/drive-model.md
sections 3 and 5; the names are those of :mod:`mlink_sim.params`). :func:`ramp_seconds` is the soft starter's
time for a change, in closed form (docs/drive-model.md section 3, "S-curve": ``Δf / a + (start + end) / 2``).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, fields
from typing import Any

from .faults import Fault
from .integrate import IntegratorState
from .settings import DriveSettings, Family

__all__ = ["DriveActivity", "PARAM_ROLES", "REGULATION", "regulation_names", "ramp_seconds", "read_activity"]

#: Setting -> parameter name, per family (docs/drive-model.md sections 3 and 5). ``None``: the drive has no
#: parameter for it (the VS-606V7's decel stall level and speed-agree width are fixed).
PARAM_ROLES: dict[Family, dict[str, str | None]] = {
    Family.A1000: {
        "accel": "C1-01", "decel": "C1-02", "accel2": "C1-03", "decel2": "C1-04", "fast": "C1-09",
        "max_hz": "E1-04", "min_hz": "E1-09", "s_accel_start": "C2-01", "s_accel_end": "C2-02",
        "s_decel_start": "C2-03", "s_decel_end": "C2-04", "stall_accel": "L3-01", "stall_accel_level": "L3-02",
        "stall_decel": "L3-04", "stall_decel_level": None, "run_source": "b1-02", "ref_source": "b1-01",
        "stop_method": "b1-03", "agree_width": "L4-02",
    },
    Family.V7: {
        "accel": "n019", "decel": "n020", "accel2": "n021", "decel2": "n022", "fast": "n022",
        "max_hz": "n011", "min_hz": "n016", "s_accel_start": "n023", "s_accel_end": "n023",
        "s_decel_start": "n023", "s_decel_end": "n023", "stall_accel": "n093", "stall_accel_level": "n093",
        "stall_decel": "n092", "stall_decel_level": None, "run_source": "n003", "ref_source": "n004",
        "stop_method": "n005", "agree_width": None,
    },
}


#: The states in which the drive's own regulation holds its output (:meth:`mlink_sim.drive.Drive.regulation`, one bit
#: each): (bit, name, what it is, the parameters behind it: A1000 / VS-606V7). The A1000's "stall prevention" is the
#: first two: a current limit while accelerating, a DC-bus regulation while decelerating (docs/drive-model.md
#: section 5).
REGULATION: tuple[tuple[int, str, str, str], ...] = (
    (1, "stall-accel", "current limit: stall prevention during acceleration holds the ramp at the stall current",
     "L3-01, L3-02 / n093"),
    (2, "stall-decel", "DC bus regulation: stall prevention during deceleration holds the ramp while the DC bus is at "
     "its stall level", "L3-04 / n092"),
    (4, "torque-limit", "torque limit: the torque held at the network's torque limit, or a torque reference applied",
     "F6-06, d5-01"),
)


def regulation_names(code: int) -> tuple[str, ...]:
    """The names of the :data:`REGULATION` states in *code* (``2`` -> ``("stall-decel",)``)."""
    return tuple(name for bit, name, _, _ in REGULATION if code & bit)


def ramp_seconds(delta_hz: float, time_s: float, max_hz: float, s_start: float = 0.0, s_end: float = 0.0) -> float:
    """Seconds the soft starter takes to change its output by *delta_hz* with the ramp time *time_s* (0 to
    *max_hz*: rate ``a = max_hz / time_s``) and the S-curve times *s_start*/*s_end* (jerk ``a / s``).

    A change large enough to reach ``a`` takes ``Δf / a + (s_start + s_end) / 2`` (docs/drive-model.md, section 3);
    a shorter one peaks below ``a``: ``q = √(2 a Δf / (s_start + s_end))`` and takes ``q (s_start + s_end) / a``."""
    delta = abs(delta_hz)
    if delta == 0.0 or time_s <= 0.0 or max_hz <= 0.0:
        return 0.0
    a = max_hz / time_s
    s = max(s_start, 0.0) + max(s_end, 0.0)
    if delta >= a * s / 2.0:
        return delta / a + s / 2.0
    q = math.sqrt(2.0 * a * delta / s)
    return q * s / a


@dataclass(frozen=True)
class DriveActivity:
    """One reading of what the drive does and why (every field JSON-able; :meth:`from_dict` reads it back).

    Times are the drive's own (``now`` ns of :meth:`mlink_sim.drive.Drive.advance`); frequencies are magnitudes in
    Hz."""

    family: str  #: "a1000" / "v7"
    at_ns: int  #: when the drive was last advanced: the moment this reading describes
    output_on: bool  #: False: baseblock (no output)
    output_hz: float
    target_hz: float  #: where the soft starter heads (0 while stopping)
    reference_hz: float  #: the selected frequency reference
    run_requested: bool  #: exactly one of forward / reverse in the network command
    run_from_network: bool  #: b1-02 = 3 / n003 = 3 (else the network's run command is not taken)
    ref_from_network: bool  #: b1-01 = 3 / n004 = 9
    running: bool  #: the run command is in effect (allowed and requested)
    ramp: str  #: the ramp time in use: "accel", "decel", "accel2", "decel2" or "fast" (keys of PARAM_ROLES)
    ramp_s: float  #: its time: 0 to ``max_hz``
    s_curve_s: tuple[float, float]  #: S-curve at the start and the end of that ramp
    max_hz: float
    aim_since_ns: int  #: when the soft starter's aim (run, direction, target) last changed
    aim_from_hz: float  #: the soft starter's output at that moment
    stall_accel: bool  #: acceleration held: output current at or above the stall level
    stall_decel: bool  #: deceleration held: DC bus at or above the stall level
    torque_limited: bool
    output_current_a: float
    stall_current_a: float  #: acceleration stall level (inf when disabled)
    stall_accel_pct: float  #: … as % of the drive rated current (L3-02 / n093)
    dc_bus_v: float
    stall_bus_v: float  #: deceleration stall level (inf when disabled)
    fault: str | None  #: the fault in effect (display name), e.g. "ov"
    fault_at_ns: int | None  #: when it tripped
    fault_stop: str  #: its stop method (StopMethod name)
    minors: tuple[str, ...]  #: minor faults in effect (display names)
    ope: str | None
    baseblock_input: bool  #: an external baseblock is in
    fast_stop: bool  #: a fast stop is in progress (C1-09 / n022)
    mains: bool
    speed_search: bool
    coast_on_stop: bool  #: b1-03 / n005: the run command off coasts

    def ramp_alone_hz(self) -> float:
        """Where the ramp alone would have the output now, from where and when its aim last changed (linear at
        its rate, the start's S-curve as half its time late). An output short of it was held: stall prevention holds
        the soft starter (:attr:`stall_accel` / :attr:`stall_decel` while the hold is on: it goes on and off every
        few milliseconds around its level), and so does the torque limit (docs/drive-model.md sections 1 and 5)."""
        left = (self.at_ns - self.aim_since_ns) / 1e9 - self.s_curve_s[0] / 2.0
        delta = self.target_hz - self.aim_from_hz
        if self.ramp_s <= 0.0:
            return self.target_hz
        moved = min(abs(delta), max(0.0, left) * self.max_hz / self.ramp_s)
        return self.aim_from_hz + math.copysign(moved, delta)

    @property
    def doing(self) -> str:
        """"faulted", "speed search", "coasting", "stopped", "accelerating", "decelerating", "stopping" (ramping to
        a stop) or "at speed"."""
        if self.fault is not None:
            return "faulted"
        if self.speed_search:
            return "speed search"
        if not self.output_on:
            return "stopped"
        if self.target_hz > self.output_hz + 1e-6:
            return "accelerating"
        if self.output_hz > self.target_hz + 1e-6:
            return "decelerating" if self.running else "stopping"
        return "at speed"

    def as_dict(self) -> dict[str, Any]:
        """JSON-able (infinite levels as None)."""
        out: dict[str, Any] = {}
        for f in fields(self):
            value = getattr(self, f.name)
            out[f.name] = None if isinstance(value, float) and math.isinf(value) else (
                list(value) if isinstance(value, tuple) else value)
        return out

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> DriveActivity:
        """Read back :meth:`as_dict` (a slave's answer); ValueError for anything else."""
        kwargs: dict[str, Any] = {}
        try:
            for f in fields(cls):
                value = data[f.name]
                if f.name in ("stall_current_a", "stall_bus_v") and value is None:
                    value = math.inf
                elif f.name in ("s_curve_s", "minors"):
                    value = tuple(value)
                kwargs[f.name] = value
        except (KeyError, TypeError) as exc:
            raise ValueError(f"not a drive activity: {exc}") from None
        return cls(**kwargs)


def read_activity(s: DriveSettings, x: IntegratorState, *, at_ns: int, run_requested: bool, net: tuple[bool, bool],
                  reference_hz: float, fault: tuple[Fault | None, int, str], minors: frozenset[Fault],
                  ope: str | None, baseblock_input: bool, fast: bool, second: bool,
                  aim: tuple[int, float]) -> DriveActivity:
    """The :class:`DriveActivity` of a drive with settings *s* and integrator state *x* (``Drive.activity``, which
    passes its discrete state: the network's run and reference sources, the fault with its time and stop method,
    a fast stop, the second ramp times selected, when the soft starter's aim last changed and from which output)."""
    out = x.out
    m = x.m if out else 0.0
    mt = x.mt if out else 0.0
    two = "2" if second else ""
    stopping_fast = fast and not x.run
    ramp = "fast" if stopping_fast else (f"accel{two}" if mt > m else f"decel{two}")
    ramp_s = {"fast": s.fast_stop_s, "accel": s.accel_s, "decel": s.decel_s, "accel2": s.accel2_s,
              "decel2": s.decel2_s}[ramp]
    sc = s.s_curve_s
    f, f_at, f_stop = fault
    return DriveActivity(
        family=s.family.value, at_ns=at_ns, output_on=out, output_hz=abs(x.fout) if out else 0.0, target_hz=mt,
        reference_hz=reference_hz, run_requested=run_requested, run_from_network=net[0], ref_from_network=net[1],
        running=x.run, ramp=ramp, ramp_s=ramp_s,
        s_curve_s=(0.0, 0.0) if stopping_fast else ((sc[0], sc[1]) if ramp.startswith("accel") else (sc[2], sc[3])),
        max_hz=s.max_freq_hz, aim_since_ns=aim[0], aim_from_hz=aim[1], stall_accel=out and x.hold_acc,
        stall_decel=out and x.hold_dec, torque_limited=out and x.tlimited, output_current_a=x.I,
        stall_current_a=x.acc_lvl, stall_accel_pct=s.stall_accel_level_pct, dc_bus_v=x.V, stall_bus_v=x.dec_lvl,
        fault=None if f is None else f.display, fault_at_ns=None if f is None else f_at, fault_stop=f_stop,
        minors=tuple(sorted(m_.display for m_ in minors)), ope=ope, baseblock_input=baseblock_input,
        fast_stop=stopping_fast, mains=x.mains, speed_search=x.ss != 0, coast_on_stop=s.coast_on_run_off)
