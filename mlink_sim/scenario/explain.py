"""Why a drive is where it is: a failed check's ``cause``, in the user's terms (docs/configuration.md, "When a check
fails").

:func:`explain` turns a :class:`~mlink_sim.drive.activity.DriveActivity` (the model's state at the check) into one
sentence that names the parameters behind it, with their values and whether they are the drive's defaults (the
defaults of :mod:`mlink_sim.params`): ``"accelerating at C1-01 = 10.0 s (default) per E1-04 = 60.0 Hz (default): 11.4
of 40 Hz after 2.0 s, there at 6.9 s"``, ``"stopping at C1-02 = 1.0 s per E1-04 = 60.0 Hz (default): 33.9 Hz, from
40.0 Hz after 2.5 s (the ramp alone: 0.0 Hz); held by deceleration stall prevention, L3-04 = 1 (default): DC bus
375 V, its level 375 V; …"``, ``"alarm ov since 5.20 s (coast stop)"``.

Touches: nothing (pure text from values).
"""

from __future__ import annotations

import math
from collections.abc import Mapping

from ..drive.activity import PARAM_ROLES, DriveActivity, ramp_seconds
from ..drive.settings import Family
from ..params import FAMILIES

__all__ = ["explain", "param_text", "RUN_SOURCE"]

#: Per family: (run source, value, reference source, value, where the manuals say so) for running from the network.
RUN_SOURCE = {
    Family.A1000: ("b1-02", 3, "b1-01", 3, "SI-T3 Table 4, SI-ET3 Table 7"),
    Family.V7: ("n003", 3, "n004", 9, "SI-T/V7 §6"),
}


#: An output this far short of where the ramp alone would be is behind it (something held it).
_BEHIND_HZ = 0.5


def param_text(family: Family, name: str, values: Mapping[str, int]) -> str:
    """``"C1-01 = 10.0 s (default)"``: the parameter's value in its unit, and whether it is the drive's default."""
    param = FAMILIES[family.value].by_name(name)
    raw = values.get(name, param.default)
    return f"{name} = {param.format(raw)}" + (" (default)" if raw == param.default else "")


def _hz(value: float) -> str:
    return f"{value:.1f}"


def explain(activity: DriveActivity, values: Mapping[str, int], zero_s: float) -> str:
    """One sentence on what the drive of *activity* does and what holds it. *values* are the station's parameter
    values in effect (raw, by name: the config's and the timeline's ``set-param`` steps on the family defaults);
    *zero_s* is the drive time (s) of the timeline's 0 s, from which the sentence counts."""
    a = activity
    family = Family(a.family)
    roles = PARAM_ROLES[family]
    at = a.at_ns / 1e9 - zero_s
    parts: list[str] = []
    run_name, run_value, ref_name, ref_value, source = RUN_SOURCE[family]
    if a.run_requested and not a.run_from_network:
        parts.append(f"the drive does not take the network's run command: {param_text(family, run_name, values)}; "
                     f"the run command from the option needs {run_name} = {run_value} ({source})")
    if a.running and not a.ref_from_network:
        parts.append(f"the reference is not the network's: {param_text(family, ref_name, values)}; the reference "
                     f"from the option needs {ref_name} = {ref_value} ({source})")
    if a.fault is not None:
        since = "" if a.fault_at_ns is None else f" since {a.fault_at_ns / 1e9 - zero_s:.2f} s"
        parts.append(f"alarm {a.fault}{since} ({a.fault_stop.lower()} stop)")
    if a.ope is not None:
        parts.append(f"{a.ope}: the drive refuses its settings (docs/drive-model.md, section 8)")
    if a.baseblock_input:
        parts.append("external baseblock in: output off")
    if not a.mains:
        parts.append(f"no mains: DC bus {a.dc_bus_v:.0f} V")
    if a.minors:
        parts.append("minor fault " + ", ".join(a.minors))
    doing = a.doing
    if doing == "speed search":
        parts.append(f"speed search running, output {_hz(a.output_hz)} Hz")
    elif doing in ("accelerating", "decelerating", "stopping"):
        parts.append(_ramping(a, family, roles, values, at, zero_s))
    elif doing == "at speed":
        clamp = (f", the reference clamped to {param_text(family, roles['max_hz'] or '', values)}"
                 if a.reference_hz > a.max_hz + 1e-6 else "")
        parts.append(f"at speed: {_hz(a.output_hz)} Hz{clamp}")
    elif doing == "stopped" and a.fault is None and not parts:
        parts.append("stopped: " + ("a run command is in, but the output is off" if a.run_requested
                                    else "no run command"))
    if a.torque_limited:
        parts.append("the torque is at the network's torque limit (F6-06 = 1)")
    return "; ".join(parts)


def _ramping(a: DriveActivity, family: Family, roles: Mapping[str, str | None], values: Mapping[str, int],
             at: float, zero_s: float) -> str:
    """The ramp in progress: its time parameter, how far it got, when it gets there, and what holds it."""
    name = roles[a.ramp] or ""
    verb = "fast stop" if a.fast_stop else a.doing
    since = a.aim_since_ns / 1e9 - zero_s
    full = ramp_seconds(a.target_hz - a.aim_from_hz, a.ramp_s, a.max_hz, *a.s_curve_s)
    where = (f"{_hz(a.output_hz)} of {a.target_hz:g} Hz" if a.target_hz else
             f"{_hz(a.output_hz)} Hz, from {_hz(a.aim_from_hz)} Hz")
    text = (f"{verb} at {param_text(family, name, values)} per {param_text(family, roles['max_hz'] or '', values)}"
            f": {where} after {at - since:.1f} s")
    alone = a.ramp_alone_hz()
    behind = abs(alone - a.aim_from_hz) - abs(a.output_hz - a.aim_from_hz) > _BEHIND_HZ
    if behind:
        text += f" (the ramp alone: {_hz(alone)} Hz)"
    else:
        text += f", there at {since + full:.1f} s"
    accel = a.target_hz > a.output_hz
    if a.stall_accel or (behind and accel and not a.torque_limited and math.isfinite(a.stall_current_a)):
        sel, lvl = roles["stall_accel"] or "", roles["stall_accel_level"] or ""
        if sel != lvl:
            what, level = param_text(family, sel, values), f" {param_text(family, lvl, values)} of the drive's rated current"
        else:
            what, level = f"{param_text(family, sel, values)} of the drive's rated current", ""
        text += (f"; held by acceleration stall prevention, {what}: output current {a.output_current_a:.1f} A, "
                 f"its level{level} ({a.stall_current_a:.1f} A)")
    if a.stall_decel or (behind and not accel and math.isfinite(a.stall_bus_v)):  # the only hold of a decel
        text += (f"; held by deceleration stall prevention, {param_text(family, roles['stall_decel'] or '', values)}"
                 f": DC bus {a.dc_bus_v:.0f} V, its level {a.stall_bus_v:.0f} V; the energy the load gives back "
                 "has nowhere else to go (no braking resistor, docs/drive-model.md section 5): a load with friction "
                 f"or a fan takes it, {roles['stop_method']} = 1 coasts to a stop")
    return text
