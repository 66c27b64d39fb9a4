"""Timeline checks the drive's settings cannot meet, found before anything runs (``mlink-sim validate``, and ``up`` /
``master`` before they start; docs/configuration.md, "Checks the settings cannot meet").

For every station the timeline's ``run``, ``speed``, ``stop`` and ``set-param`` steps are followed on the soft starter's ramp
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

from ..config import Config, StationConfig, TimelineStep
from ..drive import Drive, DriveCommand, DriveSettings, Family, LoadSpec, hz_to_ref
from ..drive.activity import PARAM_ROLES, ramp_seconds
from ..params import FAMILIES
from .explain import RUN_SOURCE, param_text
from .values import station_values

__all__ = ["timeline_warnings"]

#: Transmission cycles (× COM_TIM) between a step and what a check reads of it: the command goes out in the next
#: cycle, and a check reads the latest response.
_LAG_CYCLES = 2
#: A suggested ramp time leaves this share of the time available to spare (command timing, rounding).
_SPARE = 0.9
#: The drive model's sub-step when it runs a stop ahead (:func:`_model_stop_s`; the runs use 1 ms).
_MODEL_STEP_NS = 2_000_000
#: ... and how far past the check it looks for the end of the stop.
_MODEL_BEYOND_S = 30.0


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
    stops: dict[tuple[object, ...], float | None] = {}  # the model's stops, shared by stations set up alike
    for st in config.station:
        steps = [s for s in sorted(config.timeline, key=lambda s: s.at) if s.station in ("all", st.address)]
        for text in _station(config, st, steps, index, stops):
            out.append(f"{source + ': ' if source else ''}{text}")
    return out


def _label(step: TimelineStep, address: int) -> str:
    return step.describe.replace("all stations", f"station {address:02X}H")


def _station(config: Config, st: StationConfig, steps: list[TimelineStep], index: dict[int, int],
             stops: dict[tuple[object, ...], float | None]) -> list[str]:
    family = Family(st.profile.family)
    table = FAMILIES[family.value]
    values = station_values(st)
    settings = DriveSettings.from_params(family, values)
    roles = PARAM_ROLES[family]
    lag = _LAG_CYCLES * config.network.transmission_cycle * (st.com_tim or 1) / 1e9
    runs = [s for s in steps if s.do == "run"]
    if not runs:
        return []
    out: list[str] = []
    ramp = _Ramp()
    for step in steps:
        at = step.at / 1e9
        if step.do == "set-param":
            param, raw = table.parse_assignment(f"{step.param}={step.value}")
            values[param.name] = raw
            settings = DriveSettings.from_params(family, values)
        elif step.do == "run" and not (settings.run_from_network and settings.ref_from_network):
            return out + _sources(st.address, family, settings, values)  # the drive does not run: nothing to follow
        elif step.do in ("run", "stop") or (step.do == "speed" and ramp.running):
            f_now = _position(ramp, settings, at)
            if step.do in ("run", "speed"):
                hz = min(step.hz or 0.0, settings.max_freq_hz)
                hz = 0.0 if hz < settings.min_freq_hz else hz
                reverse = step.direction == "reverse" if step.do == "run" else ramp.target < 0
                ramp = _Ramp(at, f_now, -hz if reverse else hz, True)
            else:
                ramp = _Ramp(at, 0.0 if settings.coast_on_run_off else f_now, 0.0, False)
        elif step.expect in ("output-hz", "speed-agree", "stopped"):
            if step.expect == "stopped" and not ramp.running and _stall_possible(settings, ramp):
                text = _model_check(at, ramp, values, _Model(family, st.load.model_dump(exclude_none=True), stops),
                                    roles, lag)
            else:
                text = _check(step, at, ramp, settings, family, roles, values, lag)
            if text:
                out.append(f"timeline[{index[id(step)]}] ({_label(step, st.address)}): {text}")
    return out


def _sources(address: int, family: Family, s: DriveSettings, values: dict[str, int]) -> list[str]:
    """The run command or reference the drive does not take from the network, with what to set."""
    run_name, run_value, ref_name, ref_value, source = RUN_SOURCE[family]
    out = []
    if not s.run_from_network:
        out.append(f"station {address:02X}H: the timeline runs it, but {param_text(family, run_name, values)} takes "
                   f"the run command from elsewhere; set {run_name} = {run_value} ({source})")
    if not s.ref_from_network:
        out.append(f"station {address:02X}H: the timeline sets its speed, but {param_text(family, ref_name, values)} "
                   f"takes the reference from elsewhere; set {ref_name} = {ref_value} ({source})")
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



def _stall_possible(s: DriveSettings, ramp: _Ramp) -> bool:
    """A ramp stop from a turning output with deceleration stall prevention on (A1000 L3-04, V7 n092): how long it
    takes is for the drive model to say (the load's energy comes back into the DC bus)."""
    return s.stall_decel and not s.coast_on_run_off and ramp.f0 != 0.0


@dataclass
class _Model:
    """The drive model of one station's family and load, running stops ahead; *stops* is shared by the stations of
    a config (stations set up alike run once)."""

    family: Family
    load: dict[str, object]
    stops: dict[tuple[object, ...], float | None]

    def stop_s(self, values: dict[str, int], f0: float, longest_s: float) -> float | None:
        """Seconds the model takes to stop from a steady *f0* Hz (None: not within *longest_s*)."""
        key = (self.family, tuple(sorted(values.items())), tuple(sorted(self.load.items())), round(f0, 3), longest_s)
        if key not in self.stops:
            settings = DriveSettings.from_params(self.family, values)
            self.stops[key] = _model_stop_s(settings, LoadSpec.from_config(self.load), f0, longest_s)
        return self.stops[key]


def _model_stop_s(s: DriveSettings, load: LoadSpec, f0: float, longest_s: float) -> float | None:
    """Seconds the drive model takes to stop from a steady *f0* Hz with these settings and this load (its own
    equations: stall prevention holds the ramp while the load's energy comes back into the DC bus, docs/drive-model.md
    section 5); None when it has not stopped after *longest_s*."""
    d = Drive(s.family, s, load, substep_ns=_MODEL_STEP_NS)
    up = int((ramp_seconds(f0, s.accel_s, s.max_freq_hz, s.s_curve_s[0], s.s_curve_s[1]) + 2.0) * 1e9)
    d.command(DriveCommand(forward=True, freq_ref_raw=hz_to_ref(s, f0)), 0)
    d.advance(up)
    d.command(DriveCommand(), up)
    t, step = up, 50_000_000
    while d.status.running:
        if t - up > longest_s * 1e9 or d.status.faulted:
            return None
        t += step
        d.advance(t)
    return (t - up) / 1e9


def _model_check(at: float, ramp: _Ramp, values: dict[str, int], model: _Model, roles: dict[str, str | None],
                 lag: float) -> str | None:
    """A ``stopped`` check after a ramp stop that stall prevention may stretch, judged on the drive model: None when
    it stops in time, else when it stops and what would do (a shorter deceleration time where the model stops in
    time with it, else coasting to a stop)."""
    family, f0 = model.family, abs(ramp.f0)
    avail = at - ramp.t - lag
    longest = avail + _MODEL_BEYOND_S
    took = model.stop_s(values, f0, longest)
    if took is not None and took <= avail:
        return None
    s = DriveSettings.from_params(family, values)
    name, stop = roles["decel"] or "", roles["stop_method"] or ""
    param = FAMILIES[family.value].by_name(name)
    fix = f"set {stop} = 1 (coast to stop)"
    room = _SPARE * avail - s.s_curve_s[2] / 2.0 - s.s_curve_s[3] / 2.0
    if room > 0.0:
        raw = param.to_raw(math.floor(room * s.max_freq_hz / f0 / param.scale) * param.scale)
        if 0 < raw < values[name] and (t := model.stop_s({**values, name: raw}, f0, longest)) is not None and t <= avail:
            fix = f"set {name} = {param.format_number(raw)} or less"
    ramp_s = ramp_seconds(f0, s.decel_s, s.max_freq_hz, s.s_curve_s[2], s.s_curve_s[3])
    held = took is None or took > ramp_s + 0.1
    when = f"does not stop within {longest:.1f} s" if took is None else f"stops at {ramp.t + took:.1f} s"
    why = (f"; deceleration stall prevention, {param_text(family, roles['stall_decel'] or '', values)}, holds the "
           "ramp while the load's energy comes back into the DC bus (docs/drive-model.md section 5)") if held else ""
    later = "" if took is None else f", or check at {math.ceil((ramp.t + took + lag) * 10.0) / 10.0:g} s or later"
    return (f"the output {when} on the drive model: {param_text(family, name, values)} per "
            f"{param_text(family, roles['max_hz'] or '', values)} (the ramp, docs/drive-model.md section 3){why}; "
            f"{fix}{later}")
