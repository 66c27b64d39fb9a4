"""The timeline's checks judged from what the master sees (``expect = …``, docs/configuration.md): each one a
function of the step, the station's view, its speed scale and the alarms it raised, so that a check reads the same
on both clocks and in a test on explicit values.

The fault checks, which wait for what they judge, are in :mod:`.faultchecks`.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from ..config import TimelineStep
from ..wire import InvCmdStat, Link, M2Status

__all__ = ["CheckResult", "DRIVE_CHECKS", "StationViews", "judge", "label", "running", "with_stalls"]

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


def running(link: Link | None, status: int) -> bool:
    """The station runs: ML-III INVCMD_STAT FORWARD/REVERSE (SI-ET3 "INVCMD_STAT"), ML-I/II STATUS RUNX."""
    if link is Link.ML3:
        return bool(status & (InvCmdStat.FORWARD | InvCmdStat.REVERSE))
    return bool(status & M2Status.RUNX)


class StationViews:
    """A station's output in Hz and its run state, read from the master's view, for any class with ``view``,
    ``_scales`` (address -> :class:`~.values.SpeedScale`) and ``_links`` (address -> link): the Python API's."""

    _scales: dict[int, Any]
    _links: dict[int, Link | None]

    def view(self, station: int) -> Any:
        raise NotImplementedError

    def output_hz(self, station: int) -> float:
        """Output frequency of *station* in Hz at the drive's resolution (the view's ``output_hz``: 6.27, not
        6.2700000000000005), from the latest INV_CTL response."""
        view = self.view(station)
        hz = view.output_hz
        return float(hz) if hz is not None else self._scales[station].to_hz(view.output_freq)

    def running(self, station: int) -> bool:
        """The station runs (its status's run bits: SI-T3 STATUS RUNX, SI-ET3 INVCMD_STAT FORWARD/REVERSE)."""
        return running(self._links[station], self.view(station).status)


def _agree(link: Link | None, status: int) -> bool:
    return bool(status & (InvCmdStat.AGREE if link is Link.ML3 else M2Status.AGREE))


def label(step: TimelineStep, address: int) -> str:
    """The check's description for one station (a step on all stations names each)."""
    return step.describe if step.station != "all" else step.describe.replace("all stations", f"station {address:02X}H")


def judge(step: TimelineStep, address: int, view: Any, link: Link | None, hz: float,
          alarms_seen: Mapping[str, int]) -> CheckResult:
    """The result of the check *step* for station *address*, whose master's view is *view*, output *hz* (its
    speed scale applied) and raised *alarms_seen* (name -> how often) so far."""
    what = step.expect or ""
    is_running = running(link, view.status)
    if what == "running":
        ok, detail = is_running, f"running={is_running}"
    elif what == "stopped":
        ok, detail = (not is_running and hz < 0.5), f"running={is_running}, output {hz:.2f} Hz"
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
        comm_alarm = link is Link.ML3 and view.comm_alm >= 8
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
        wanted = (step.alarm or "").lower()
        hits = sum(n for name, n in alarms_seen.items()
                   if not wanted or wanted in {x.lower() for x in name.replace("/", " ").split()})
        ok = hits > 0
        seen = ", ".join(f"{k} ×{v}" for k, v in sorted(alarms_seen.items()))
        detail = (f"raised {hits} time(s); " if ok else "never raised; ") + (
            f"alarms seen: {seen}" if seen else "no alarm seen")
    else:  # the config model allows no other check
        ok, detail = False, f"unknown check {what!r}"
    return CheckResult(step.at / 1e9, address, label(step, address), ok, detail)


def with_stalls(check: CheckResult, stalls: Any, t0_ns: int) -> CheckResult:
    """*check*, when it failed, with the host stalls of the three seconds before it named in its detail (*t0_ns*:
    the run clock's time of the timeline's 0 s; *stalls*: the run's ``metrics.stalls.StallLog``)."""
    near = "" if check.ok else stalls.describe_near(t0_ns + int(check.at_s * 1e9), zero_ns=t0_ns)
    return dataclasses.replace(check, detail=f"{check.detail}; {near}") if near else check
