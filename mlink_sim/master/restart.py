"""Running a drive again after a recovery (docs/master.md, "Running again after a recovery").

A lost connection trips bUS and the drive stops by coasting (SI-T3 Table 26, F6-01; SI-T/V7 Table 11); a motor
that still turns when the drive is run again from 0 Hz draws a large current, which is oC. So when a station the
master had running is back at its phase, the master runs it again only when the drive can take it:

* with speed search (``StationPlan.speed_search``: A1000 b3-01 = 1, or a speed-search input), at once, with the
  search input (``StationPlan.search_input``, VS-606V7 n05x = 14/15) on until speed agree;
* else once the motor stands still: |U1-05 motor speed| at or below ``StationPlan.standstill``, read in MON1
  (SEL_MON code 1, SI-T3 Table 18 / SI-ET3 Table 22) on a card whose profile names its motor speed monitor
  (``CardProfile.motor_speed``). The SI-T/V7 has none (its Table 5 code 1 is the output frequency), and a station
  whose plan names no card is not relied on for it: the run is held until the application gives a run command
  again.

The application's latest command is the one resumed. The functions work on the core's per-station state
(``run_held``, ``searching``, ``control``, ``ctl_body``) and report through ``emit``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from typing import Any

from ..wire import M2Status
from ..wire.selections import SEL_MON_TABLES
from .plan import StationPlan
from .types import Event, RunHeld, RunResumed

__all__ = ["motor_code", "begin", "watch", "command"]

Emit = Callable[[Event], None]


def motor_code(plan: StationPlan) -> int:
    """The SEL_MON code that selects the motor speed on the card *plan* names (U1-05 is code 1: SI-T3 Table 18,
    SI-ET3 Table 22); -1 when its card has no such monitor (SI-T/V7 Table 5) or the plan names no card."""
    profile = plan.profile
    if profile is None:
        return -1
    table = SEL_MON_TABLES.get(profile.selections, ())
    return table.index(profile.motor_speed) if profile.motor_speed in table else -1


def _running(st: Any) -> bool:
    return bool(st.control.forward or st.control.reverse)


def sees_motor(st: Any) -> bool:
    """MON1 shows the motor speed: a card that has its monitor with SEL_MON MON1 set to it (the master's default
    41H: MON1 = 1, U1-05 on the A1000 cards)."""
    return bool(st.motor_code >= 0 and st.control.sel_mon & 0x0F == st.motor_code)


def begin(st: Any, emit: Emit) -> None:
    """*st* is back at its phase after a fault: resume with speed search, or hold the run command."""
    if not _running(st):
        return
    plan = st.plan
    if plan.speed_search:
        if plan.search_input:
            st.searching = True
            st.ctl_body = _body(st)
        emit(RunResumed(st.address, "speed search"))
        return
    st.run_held = True
    st.ctl_body = _body(st)
    emit(RunHeld(st.address, "standstill" if sees_motor(st) else "the next run command"))


def watch(st: Any, emit: Emit) -> None:
    """An INV_CTL answer while a restart is pending: release a held run at standstill; end the search input at
    speed agree (SI-T/V7 STATUS bit 9, as SI-T3 Table 20)."""
    running = _running(st)
    if st.run_held:
        mon = st.mon1 - 0x10000 if st.mon1 >= 0x8000 else st.mon1
        if not running or (sees_motor(st) and abs(mon) <= st.plan.standstill):
            st.run_held = False
            st.ctl_body = _body(st)
            if running:
                emit(RunResumed(st.address, "standstill"))
    elif st.searching and (not running or st.status & M2Status.AGREE):
        st.searching = False
        st.ctl_body = _body(st)


def command(st: Any, emit: Emit) -> Any:
    """The INV_CTL body for a new application command while a restart is pending. Still waiting for standstill
    (the motor speed is seen): the new command is the one resumed then. Otherwise the application's command ends
    the hold (a run in it is :class:`RunResumed` "run command") or the search (the run went out all along)."""
    if st.run_held and _running(st) and sees_motor(st):
        return _body(st)
    if _running(st) and st.run_held:  # a search input pending: the run was never held, so nothing resumes
        emit(RunResumed(st.address, "run command"))
    st.run_held = st.searching = False
    return _body(st)


def _body(st: Any) -> Any:
    """The INV_CTL body of *st*'s control as the pending restart shapes it."""
    c = st.control
    if st.run_held:
        c = replace(c, forward=False, reverse=False)
    elif st.searching:
        c = replace(c, multi_inputs=c.multi_inputs | st.plan.search_input)
    return st.codec.inv_ctl(c)
