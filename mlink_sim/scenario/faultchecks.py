"""The timeline's fault checks (docs/faults.md): ``expect = "recovered"`` with ``within`` and ``expect = "refused"``
with an optional ``alarm``. Both judge what the masters' fault stages recorded, and both may have to wait for it:
each returns its verdict ``(ok, detail)``, or None while it cannot tell yet — the driver asks again a cycle later,
without holding up the timeline.
"""

from __future__ import annotations

from typing import Any

from ..units import format_ns

__all__ = ["recovered", "refused", "bad_command_episode", "REFUSAL_WAIT_NS"]

#: How long ``refused`` waits for the card's answer to the latest bad command.
REFUSAL_WAIT_NS = 500_000_000


def recovered(step: Any, address: int, episode: Any, now_ns: int, view: Any) -> tuple[bool, str] | None:
    """The station's latest fault (*episode*, begun by the time of *step*) has ended and the station was back at
    its target phase with no alarm (:func:`mlink_sim.faults.stage.is_healthy`) within ``step.within`` of that end;
    None until that is known (*now_ns* on the master's clock, *view* the master's view of the station)."""
    within = step.within
    if episode is None:
        return False, f"no fault was injected into station {address:02X}H before this check"
    if episode.recovered_ns is None and not (episode.end_ns is not None and now_ns >= episode.end_ns + within):
        return None
    took = episode.recovery_ns
    what = f"after {episode.what} ended"
    if took is not None and took <= within:
        return True, f"recovered {format_ns(took)} {what} (within {format_ns(within)})"
    if took is not None:
        return False, f"recovered only {format_ns(took)} {what}, more than {format_ns(within)}"
    state = (f"state {view.state.value}, phase {view.phase}, alarm {view.alarm_name or 'none'}"
             + (", fault" if view.fault else "") + (f", COMM_ALM {view.comm_alm:X}H" if view.comm_alm else ""))
    return False, f"not recovered {format_ns(within)} {what}: {state}"


def bad_command_episode(stage: Any, address: int) -> Any:
    """The latest bad command injected into station *address* (a fault stage's episode), or None."""
    return next((ep for ep in reversed(stage.log.episodes)
                 if ep.station == address and ep.what.startswith("bad-command")), None)


def refused(step: Any, address: int, episode: Any, answer: Any, now_ns: int, deadline_ns: int) -> tuple[bool, str] | None:
    """The card refused the bad command *episode* (with ``step.alarm``, when given: a name such as
    ``DATA_SETTING_WARNING`` or a code such as ``94H``); *answer* is the card's answer to it so far (None: none
    yet), None until it came or *deadline_ns* passed."""
    if episode is None:
        return False, f"no bad command was injected into station {address:02X}H before this check"
    if answer is None:
        if now_ns < deadline_ns:
            return None
        return False, f"no answer to the {episode.what} within {format_ns(REFUSAL_WAIT_NS)}"
    if not answer.refused:
        return False, f"the {episode.what} was accepted"
    want = (step.alarm or "").lower()
    names = {answer.name.lower(), f"{answer.code:x}h", f"{answer.code:02x}h"}
    ok = not want or want in names
    return ok, f"answered {answer.describe()}" + ("" if ok else f", expected {step.alarm}")
