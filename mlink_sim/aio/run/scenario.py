"""The timeline of a config: timed actions on the master and checks of what the stations report.

Speeds are given in Hz in the config and converted with the station's own reference units (o1-03 / n035, via the
drive settings), so a scenario reads the same whatever the drive's parameters are.

Touches: the network only through its API (requests, controls, faults); the clock through the sleep it is given.
"""

from __future__ import annotations

import asyncio
from collections.abc import Awaitable, Callable, Coroutine
import dataclasses
from dataclasses import dataclass
from typing import Any, Protocol


from ..._log import get_logger
from ...config import Config, StationConfig, TimelineStep
from ...config.faults import step_fault
from ...faults.spec import FAULT_ACTIONS
from ...drive import DriveSettings, Family
from ...drive.monitors import hz_to_ref, ref_to_hz
from ...params import FAMILIES
from ...wire import InvCmdStat, Link, M2Status
from .explain import explain
from .faultchecks import recovered, refused

__all__ = ["SpeedScale", "CheckResult", "NetworkHandle", "Scenario", "StationControls", "speed_scale",
           "speed_scales"]

log = get_logger("mlink_sim.scenario")


#: Timeline actions on the impairment layer (docs/faults.md): ``station = "all"`` is one fault on every path.
_NETWORK_FAULTS = frozenset({"impair", "heal"})


class SpeedScale:
    """Hz <-> raw speed reference / output frequency of one station (its o1-03 / n035 units)."""

    def __init__(self, settings: Any) -> None:
        self._settings = settings

    def to_raw(self, hz: float) -> int:
        return int(hz_to_ref(self._settings, hz))

    def to_hz(self, raw: int) -> float:
        return float(ref_to_hz(self._settings, raw))


def station_values(st: StationConfig) -> dict[str, int]:
    """The station's parameter set: family defaults with the config's assignments applied (raw values)."""
    table = FAMILIES[st.profile.family]
    values = table.defaults()
    for name, value in st.params.items():
        param, raw = table.parse_assignment(f"{name}={value}")
        values[param.name] = raw
    return values


def drive_settings(st: StationConfig) -> DriveSettings:
    """The station's drive settings as its parameters make them (about a millisecond: not in the cycle)."""
    return DriveSettings.from_params(Family(st.profile.family), station_values(st))


def speed_scale(st: StationConfig) -> SpeedScale:
    return SpeedScale(drive_settings(st))


def restart_profile(st: StationConfig) -> dict[str, Any]:
    """The ``StationPlan`` fields of the master's restart rule (docs/master.md): ``speed_search`` (the drive
    catches a turning motor: A1000 b3-01 = 1, or a speed-search input H1 = 61H/62H, VS-606V7 n05x = 14/15),
    ``search_input`` (the ``Control.multi_inputs`` bits of that input, switched on with the run command) and
    ``standstill`` (2 % of E1-04/n011 in the drive's own frequency units)."""
    settings = drive_settings(st)
    search_input = settings.inputs.search_ref or settings.inputs.search_max
    return {"speed_search": settings.search.at_start or bool(search_input),
            "search_input": 0 if settings.search.at_start else search_input,
            "standstill": max(1, abs(hz_to_ref(settings, 0.02 * settings.max_freq_hz)))}


def speed_scales(config: Config) -> dict[int, SpeedScale]:
    """Every station's :class:`SpeedScale`. Build them before the cycle starts: deriving drive settings costs
    about a millisecond per station, which is too long to spend in the event loop once it keeps time."""
    return {st.address: speed_scale(st) for st in config.station}


#: The checks a failure of which the drive's state explains (``CheckResult.cause``).
DRIVE_CHECKS = frozenset({"running", "stopped", "speed-agree", "output-hz", "no-alarm", "alarm"})


@dataclass(frozen=True)
class CheckResult:
    """Outcome of one ``expect`` step for one station. ``cause``: for a failed check of the drive
    (:data:`DRIVE_CHECKS`), what the drive model was doing at that moment and why (:func:`~.explain.explain`);
    None where it could not be read (the slaves of ``mlink-sim master`` run elsewhere)."""

    at_s: float
    station: int
    what: str
    ok: bool
    detail: str
    cause: str | None = None


def _with_stalls(check: CheckResult, stalls: Any, t0: float) -> CheckResult:
    """*check*, when it failed, with the host stalls of the three seconds before it named in its detail (loop time
    is the monotonic clock)."""
    near = "" if check.ok else stalls.describe_near(int((t0 + check.at_s) * 1e9), zero_ns=int(t0 * 1e9))
    return dataclasses.replace(check, detail=f"{check.detail}; {near}") if near else check


class NetworkHandle(Protocol):
    """What the scenario needs from the running network (implemented in :mod:`mlink_sim.aio.run.network`)."""

    fault_control: Any  #: aio.run.faults.FaultControl (the fault stage of each station, for the recovery checks)
    async def fault(self, station: int, fault: Any) -> Any: ...

    def view(self, station: int) -> Any: ...
    def set_control(self, station: int, **fields: Any) -> None: ...
    def control(self, station: int) -> Any: ...
    async def prm_wr(self, station: int, register: int, value: int, size: int = 2) -> Any: ...
    async def config(self, station: int, mode: int = 0) -> Any: ...
    async def alm_clr(self, station: int) -> Any: ...
    async def disconnect(self, station: int) -> Any: ...
    async def reconnect(self, station: int) -> Any: ...
    def kill_slave(self, station: int) -> bool: ...
    def impair(self, station: int | None, spec: Any) -> None: ...
    def alarms_seen(self, station: int) -> dict[str, int]: ...
    async def drive_activity(self, station: int) -> Any: ...
    def heal(self, station: int | None = None) -> int: ...


class StationControls:
    """Run / stop a station in Hz and read its output in Hz, for any class with ``set_control``, ``view``,
    ``_scales`` (:func:`speed_scales`) and ``_links`` (address -> link): the test harness and the embedding API."""

    _scales: dict[int, SpeedScale]
    _links: dict[int, Link | None]
    set_control: Callable[..., None]
    view: Callable[[int], Any]

    def run(self, station: int, hz: float, direction: str = "forward") -> None:
        """Run *station* at *hz* (converted with its o1-03 / n035 units) in *direction* (forward / reverse)."""
        if direction not in ("forward", "reverse"):
            raise ValueError(f"direction must be 'forward' or 'reverse', got {direction!r}")
        self.set_control(station, forward=direction == "forward", reverse=direction == "reverse",
                         speed_ref=self._scales[station].to_raw(hz))

    def stop_station(self, station: int) -> None:
        """Take the run command away (the drive stops per its stopping method)."""
        self.set_control(station, forward=False, reverse=False)

    def output_hz(self, station: int) -> float:
        """Output frequency of *station* in Hz at the drive's resolution (the view's ``output_hz``: 6.27, not
        6.2700000000000005), from the latest INV_CTL response."""
        view = self.view(station)
        hz = view.output_hz
        return hz if hz is not None else self._scales[station].to_hz(view.output_freq)

    def running(self, station: int) -> bool:
        link = self._links[station]
        return _running(link if link is not None else Link.ML2, self.view(station).status)


def _running(link: Link, status: int) -> bool:
    if link is Link.ML3:
        return bool(status & (InvCmdStat.FORWARD | InvCmdStat.REVERSE))
    return bool(status & M2Status.RUNX)


def _agree(link: Link, status: int) -> bool:
    return bool(status & (InvCmdStat.AGREE if link is Link.ML3 else M2Status.AGREE))


class Scenario:
    """Runs the timeline of *config* against a :class:`NetworkHandle`; collects :class:`CheckResult`s."""

    def __init__(self, config: Config, net: NetworkHandle, scales: dict[int, SpeedScale] | None = None) -> None:
        self.config = config
        self.net = net
        self.results: list[CheckResult] = []
        self.action_errors: list[str] = []
        self.scales = scales if scales is not None else speed_scales(config)
        self.links = {st.address: st.link for st in config.station}
        self.steps: list[TimelineStep] = sorted(config.timeline, key=lambda s: s.at)
        self.started = 0  #: steps begun so far, in order of time (``steps[:started]``)
        self._t0: float | None = None  # the loop time of "0 s", once run() began
        #: called with each action step's description as it begins (a capture's comments: ``--capture``)
        self.note: Callable[[str], None] | None = None
        #: called with each action step as it begins, and with each check's result as it is judged (the trace)
        self.on_action: Callable[[TimelineStep], None] | None = None
        self.on_check: Callable[[CheckResult], None] | None = None
        self._waiting: set[asyncio.Task[None]] = set()  # checks that wait (recovered, refused), explanations
        self._values: dict[int, dict[str, int]] = {}  # values_of(), read when first needed

    @property
    def current(self) -> TimelineStep | None:
        """The step begun last (None before the first)."""
        return self.steps[self.started - 1] if self.started else None

    def not_run(self) -> list[TimelineStep]:
        """The steps that never began (the run ended first: --duration, a signal)."""
        return self.steps[self.started:]

    def _targets(self, step: TimelineStep) -> list[int]:
        return [st.address for st in self.config.station] if step.station == "all" else [step.station]

    def results_naming_stalls(self, stalls: Any) -> list[CheckResult]:
        """The checks so far, each failed one naming the host stalls of the three seconds before it
        (docs/timing.md, "Host stalls"); *stalls* is the run's ``metrics.stalls.StallLog``."""
        t0 = self._t0
        return list(self.results) if t0 is None else [_with_stalls(c, stalls, t0) for c in self.results]

    async def run(self, t0: float, sleep_until: Callable[[float], Awaitable[None]]) -> None:
        """Execute the steps in order of time; *t0* is the loop time of "0 s"."""
        self._t0 = t0
        for step in self.steps:
            await sleep_until(t0 + step.at / 1e9)
            self.started += 1
            if step.do:
                await self._act(step)
            elif step.expect in ("recovered", "refused"):
                for address in self._targets(step):
                    self._spawn(self._wait_check(step, address))
            else:
                for address in self._targets(step):
                    result = self.check(step, address)
                    self._judged(result)
                    if not result.ok and step.expect in DRIVE_CHECKS:
                        self._spawn(self._explain(result, address))
        if self._waiting:
            await asyncio.gather(*list(self._waiting))

    def values_of(self, address: int) -> dict[str, int]:
        """*address*'s parameter values in effect (raw, by name): the config's on the family defaults, then each
        ``set-param`` step's. Built when first needed (a failed check, a set-param step), not for every station when
        the timeline starts: the loop keeps time by then."""
        values = self._values.get(address)
        if values is None:
            values = self._values[address] = station_values(self.config.station_by_address(address))
        return values

    def _spawn(self, coro: Coroutine[Any, Any, None]) -> None:
        """Run *coro* beside the timeline (not holding it up); :meth:`run` waits for it at the end."""
        task = asyncio.get_running_loop().create_task(coro)
        self._waiting.add(task)
        task.add_done_callback(self._waiting.discard)

    async def _explain(self, result: CheckResult, address: int) -> None:
        """Give the failed *result* its cause: the drive's activity, read now (docs/configuration.md, "When a check
        fails")."""
        try:
            activity = await self.net.drive_activity(address)
        except Exception as exc:  # noqa: BLE001 - an explanation that cannot be had leaves the check as it is
            log.info("check_cause_unread", station=f"{address:#04x}", error=str(exc))
            return
        if activity is None or self._t0 is None:
            return
        cause = explain(activity, self.values_of(address), self._t0)
        for i, r in enumerate(self.results):
            if r is result:
                self.results[i] = dataclasses.replace(result, cause=cause or None)
                log.info("timeline_check_cause", what=result.what, cause=cause)
                return

    # -- actions ----------------------------------------------------------------------------------------------

    async def _act(self, step: TimelineStep) -> None:
        log.info("timeline_action", step=step.describe)
        if self.note is not None:
            self.note(f"timeline: {step.describe}")
        if self.on_action is not None:
            self.on_action(step)
        if step.do in _NETWORK_FAULTS:  # one fault on the path of every station, not one per station
            coros = [self._act_network(step)]
        else:
            coros = [self._act_one(step, address) for address in self._targets(step)]
        for outcome in await asyncio.gather(*coros, return_exceptions=True):
            if isinstance(outcome, Exception):
                msg = f"{step.describe}: {outcome}"
                self.action_errors.append(msg)
                log.warning("timeline_action_failed", step=step.describe, error=str(outcome))

    async def _act_network(self, step: TimelineStep) -> None:
        station = None if step.station == "all" else step.station
        if step.do == "impair":
            self.net.impair(station, step.impairment)
        elif step.do == "heal":
            self.net.heal(station)

    async def _act_one(self, step: TimelineStep, address: int) -> None:
        net = self.net
        if step.do == "run":
            raw = self.scales[address].to_raw(step.speed_hz or 0.0)
            net.set_control(address, forward=step.direction == "forward", reverse=step.direction == "reverse",
                            speed_ref=raw)
        elif step.do == "stop":
            net.set_control(address, forward=False, reverse=False)
        elif step.do == "set-param":
            st = self.config.station_by_address(address)
            param, raw = FAMILIES[st.profile.family].parse_assignment(f"{step.param}={step.value}")
            await net.prm_wr(address, param.register, param.encode(raw))
            await net.config(address, 0)
            self.values_of(address)[param.name] = raw
        elif step.do == "fault-reset":
            net.set_control(address, forward=False, reverse=False, fault_reset=True)
            await asyncio.sleep(0.05)
            net.set_control(address, fault_reset=False)
        elif step.do == "alm-clr":
            await net.alm_clr(address)
        elif step.do == "ef0":
            net.set_control(address, ef0=True)
        elif step.do == "disconnect":
            await net.disconnect(address)
        elif step.do == "connect":
            await net.reconnect(address)
        elif step.do == "kill-slave":
            if not net.kill_slave(address):
                raise RuntimeError("kill-slave works only under 'mlink-sim up'")
        elif step.do in FAULT_ACTIONS:
            await net.fault(address, step_fault(step))

    # -- checks -----------------------------------------------------------------------------------------------

    async def _wait_check(self, step: TimelineStep, address: int) -> None:
        """``recovered`` / ``refused``: wait (without holding up the timeline) until the answer is known."""
        check = recovered if step.expect == "recovered" else refused
        try:
            ok, detail = await check(self.net.fault_control, step, address, self.config.network.transmission_cycle)
        except Exception as exc:  # noqa: BLE001 - a check that cannot be made fails, it does not stop the run
            ok, detail = False, f"could not check: {exc}"
        result = CheckResult(step.at / 1e9, address, _label(step, address), ok, detail)
        log.info("timeline_check", what=result.what, ok=ok, detail=detail)
        self._judged(result)

    def _judged(self, result: CheckResult) -> None:
        self.results.append(result)
        if self.on_check is not None:
            self.on_check(result)

    def check(self, step: TimelineStep, address: int) -> CheckResult:
        view = self.net.view(address)
        link = self.links[address] or Link.ML2  # None: not ML3, as ML2 (the config fills it in)
        what = step.expect or ""
        hz = self.scales[address].to_hz(view.output_freq)
        running = _running(link, view.status)
        if what == "running":
            ok, detail = running, f"running={running}"
        elif what == "stopped":
            ok, detail = (not running and hz < 0.5), f"running={running}, output {hz:.2f} Hz"
        elif what == "speed-agree":
            agree = _agree(link, view.status)
            ok, detail = agree, f"speed agree={agree}, output {hz:.2f} Hz"
        elif what == "output-hz":
            target = step.output_hz or 0.0
            ok = abs(hz - target) <= step.tolerance_hz
            detail = f"output {hz:.2f} Hz, expected {target:g} ± {step.tolerance_hz:g} Hz"
        elif what == "phase":
            ok, detail = view.phase == step.phase, f"phase {view.phase}, expected {step.phase}"
        elif what == "no-alarm":
            # Warnings do not count (ML-II STATUS.WARNG codes such as 96; ML-III COMM_ALM 1-3): a run on a busy
            # machine may lose a cycle now and then, which the card reports as a warning, not as an alarm.
            comm_alarm = self.links[address] is Link.ML3 and view.comm_alm >= 8
            ok = not view.fault and not comm_alarm
            detail = (f"alarm {view.alarm_name or 'none'}" + (", fault" if view.fault else "")
                      + (f", COMM_ALM {view.comm_alm:X}H" if view.comm_alm else "")
                      + (", warning" if view.warning else ""))
        elif what == "alarm":
            names = {n.lower() for n in (view.alarm_name or "").replace("/", " ").split()}
            ok = (step.alarm or "").lower() in names if step.alarm else bool(view.fault or view.alarm)
            detail = f"alarm {view.alarm_name or 'none'}"
        elif what == "alarm-seen":
            # a transient alarm too: the master may have cleared it and recovered the station since (docs/faults.md)
            seen = self.net.alarms_seen(address)
            wanted = (step.alarm or "").lower()
            hits = sum(n for name, n in seen.items()
                       if not wanted or wanted in {x.lower() for x in name.replace("/", " ").split()})
            ok = hits > 0
            detail = (f"raised {hits} time(s); " if ok else "never raised; ") + (
                "alarms seen: " + ", ".join(f"{k} ×{v}" for k, v in sorted(seen.items())) if seen else "no alarm seen")
        else:  # pragma: no cover - validated by the config model
            ok, detail = False, f"unknown check {what!r}"
        result = CheckResult(step.at / 1e9, address, _label(step, address), ok, detail)
        log.info("timeline_check", what=result.what, ok=ok, detail=detail)
        return result


def _label(step: TimelineStep, address: int) -> str:
    """The check's description for one station (a step on all stations names each)."""
    return step.describe if step.station != "all" else step.describe.replace("all stations", f"station {address:02X}H")
