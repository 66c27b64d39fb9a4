"""Timeline checks the drive's settings cannot meet, found before anything runs (``mlink-sim validate``, and ``up`` /
``master`` before they start; docs/configuration.md, "Checks the settings cannot meet").

For every station the timeline's ``run``, ``stop`` and ``set-param`` steps are followed on the soft starter's ramp
as the drive model defines it (docs/drive-model.md section 3: a rate of ``E1-04 / C1-01`` Hz/s, ``n011 / n019`` on
the VS-606V7, S-curves adding half their times; :func:`~mlink_sim.drive.activity.ramp_seconds`), from the config's
parameters on the drive defaults. An ``output-hz``, ``speed-agree`` or ``stopped`` check due before the ramp can get
there gives one line naming the parameter to change and a value that would do, or the time the check could be
made at. A run command the drive does not take from the network (A1000 b1-02, V7 n003) is named too. The load and
stall prevention are not predicted: a check these settings allow can still fail, and then says why
(:mod:`.explain`).

Touches: nothing (the config only).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from ...config import CARD_FAMILY, Config, StationConfig, TimelineStep
from ...drive import DriveSettings, Family
from ...drive.activity import PARAM_ROLES, ramp_seconds
from ...params import FAMILIES
from .explain import RUN_SOURCE, param_text
from .scenario import station_values

__all__ = ["timeline_warnings"]

#: Transmission cycles (× COM_TIM) between a step and what a check reads of it: the command goes out in the next
#: cycle, and a check reads the latest response.
_LAG_CYCLES = 2
#: A suggested ramp time leaves this share of the time available to spare (command timing, rounding).
_SPARE = 0.9


@dataclass
class _Ramp:
    """The soft starter's ramp since *t* (s): from *f0* toward *target* (signed Hz)."""

    t: float = 0.0
    f0: float = 0.0
    target: float = 0.0
    running: bool = False


def timeline_warnings(config: Config, source: str = "") -> list[str]:
    """One line for each check of *config*'s timeline that the stations' settings cannot meet (see the module
    docstring), prefixed with *source* (the file) when given; empty when there is none."""
    out: list[str] = []
    index = {id(step): i for i, step in enumerate(config.timeline)}
    for st in config.station:
        steps = [s for s in sorted(config.timeline, key=lambda s: s.at) if s.station in ("all", st.address)]
        for text in _station(config, st, steps, index):
            out.append(f"{source + ': ' if source else ''}{text}")
    return out


def _label(step: TimelineStep, address: int) -> str:
    return step.describe.replace("all stations", f"station {address:#04x}")


def _station(config: Config, st: StationConfig, steps: list[TimelineStep], index: dict[int, int]) -> list[str]:
    family = Family(CARD_FAMILY[st.card])
    table = FAMILIES[family.value]
    values = station_values(st)
    settings = DriveSettings.from_params(family, values)
    roles = PARAM_ROLES[family]
    lag = _LAG_CYCLES * config.network.transmission_cycle * (st.com_tim or 1) / 1e9
    runs = [s for s in steps if s.do == "run"]
    if not runs:
        return []
    run_name, run_value, ref_name, ref_value, source = RUN_SOURCE[family]
    out = []
    if not settings.run_from_network:
        out.append(f"station {st.address:#04x}: the timeline runs it, but {param_text(family, run_name, values)} "
                   f"takes the run command from elsewhere; set {run_name} = {run_value} ({source})")
    if not settings.ref_from_network and any(s.speed_hz for s in runs):
        out.append(f"station {st.address:#04x}: the timeline sets its speed, but {param_text(family, ref_name, values)}"
                   f" takes the reference from elsewhere; set {ref_name} = {ref_value} ({source})")
    if out:
        return out
    ramp = _Ramp()
    for step in steps:
        at = step.at / 1e9
        if step.do == "set-param":
            param, raw = table.parse_assignment(f"{step.param}={step.value}")
            values[param.name] = raw
            settings = DriveSettings.from_params(family, values)
        elif step.do in ("run", "stop"):
            f_now = _position(ramp, settings, at)
            if step.do == "run":
                hz = min(step.speed_hz or 0.0, settings.max_freq_hz)
                hz = 0.0 if hz < settings.min_freq_hz else hz
                ramp = _Ramp(at, f_now, -hz if step.direction == "reverse" else hz, True)
            else:
                ramp = _Ramp(at, 0.0 if settings.coast_on_run_off else f_now, 0.0, False)
        elif step.expect in ("output-hz", "speed-agree", "stopped"):
            text = _check(step, at, ramp, settings, family, roles, values, lag)
            if text:
                out.append(f"timeline[{index[id(step)]}] ({_label(step, st.address)}): {text}")
    return out


def _position(ramp: _Ramp, s: DriveSettings, at: float) -> float:
    """Where the ramp is at *at* (signed Hz): linear at its rate, the start's S-curve as half its time late."""
    f, target, left = ramp.f0, ramp.target, at - ramp.t
    if f * target < 0.0:  # through 0 Hz first, at the deceleration rate
        need = ramp_seconds(f, s.decel_s, s.max_freq_hz, s.s_curve_s[2], s.s_curve_s[3])
        if left < need:
            return f - math.copysign(_moved(abs(f), left, s.decel_s, s), f)
        f, left = 0.0, left - need
    accel = abs(target) > abs(f)
    moved = _moved(abs(target - f), left, s.accel_s if accel else s.decel_s, s)
    return f + math.copysign(moved, target - f)


def _moved(delta: float, seconds: float, time_s: float, s: DriveSettings) -> float:
    if time_s <= 0.0:
        return delta
    return min(delta, max(0.0, seconds - s.s_curve_s[0] / 2.0) * s.max_freq_hz / time_s)


def _check(step: TimelineStep, at: float, ramp: _Ramp, s: DriveSettings, family: Family,
           roles: dict[str, str | None], values: dict[str, int], lag: float) -> str | None:
    """Why the check *step* at *at* comes before the ramp can meet it, with what to set; None when it can."""
    if step.expect == "stopped":
        if ramp.running or s.coast_on_run_off or ramp.f0 == 0.0:
            return None
        band, goal, role, corners = 0.0, 0.0, "decel", (s.s_curve_s[2], s.s_curve_s[3])
    else:
        goal = abs(ramp.target)
        if not ramp.running or (step.expect == "output-hz" and abs(goal - (step.output_hz or 0.0)) > step.tolerance_hz):
            return None  # not what the settings decide: the timeline asks for another speed
        band = step.tolerance_hz if step.expect == "output-hz" else s.agree_width_hz
        if ramp.f0 * ramp.target < 0.0:
            return None  # a reversal: not estimated
        accel = goal > abs(ramp.f0)
        role = "accel" if accel else "decel"
        corners = (s.s_curve_s[0], 0.0) if accel else (s.s_curve_s[2], 0.0)
    delta = max(0.0, abs(goal - abs(ramp.f0)) - band)
    if delta == 0.0:
        return None
    time_s = s.accel_s if role == "accel" else s.decel_s
    need = ramp_seconds(delta, time_s, s.max_freq_hz, *corners) + lag
    avail = at - ramp.t
    if need <= avail:
        return None
    name, max_name = roles[role] or "", roles["max_hz"] or ""
    param = FAMILIES[family.value].by_name(name)
    room = _SPARE * (avail - lag) - sum(corners) / 2.0
    fix = ""
    if room > 0.0:
        best = math.floor(room * s.max_freq_hz / delta / param.scale) * param.scale
        if best >= param.scale:
            fix = f"set {name} = {param.format_number(param.to_raw(best))} or less, or "
    later = math.ceil((ramp.t + need) * 10.0) / 10.0
    what = "stops" if step.expect == "stopped" else f"is within {band:g} Hz of {goal:g} Hz"
    return (f"the output {what} at {ramp.t + need:.1f} s at the earliest: {param_text(family, name, values)} per "
            f"{param_text(family, max_name, values)} (the ramp, docs/drive-model.md section 3); {fix}"
            f"check at {later:g} s or later")
