"""The timeline's fault checks (docs/faults.md): ``expect = "recovered"`` with ``within`` and ``expect = "refused"``
with an optional ``alarm``. Both wait, on the run's own clock, for what they judge; neither holds up the timeline.

Touches: nothing but the episodes the masters' fault stages recorded (read only).
"""

from __future__ import annotations

import asyncio
from typing import Any

from ...units import format_ns

__all__ = ["recovered", "refused", "REFUSAL_WAIT_NS"]

#: How long ``refused`` waits for the card's answer to the latest bad command.
REFUSAL_WAIT_NS = 500_000_000


async def recovered(faults: Any, step: Any, address: int, tcycle_ns: int) -> tuple[bool, str]:
    """The station's latest fault begun by the time of *step* has ended and the station was back at its target phase
    with no alarm (:func:`mlink_sim.faults.stage.is_healthy`) within ``step.within`` of that end."""
    master = faults.net.master(address)
    stage = faults.stage(address)
    within = step.within
    episode = stage.latest(address)
    if episode is None:
        return False, f"no fault was injected into station {address:02X}H before this check"
    while True:
        now = master.now_ns()
        if episode.recovered_ns is not None:
            break
        if episode.end_ns is not None and now >= episode.end_ns + within:
            break
        await asyncio.sleep(tcycle_ns / 1e9)
    took = episode.recovery_ns
    what = f"after {episode.what} ended"
    if took is not None and took <= within:
        return True, f"recovered {format_ns(took)} {what} (within {format_ns(within)})"
    view = master.view(address)
    state = (f"state {view.state.value}, phase {view.phase}, alarm {view.alarm_name or 'none'}"
             + (", fault" if view.fault else "") + (f", COMM_ALM {view.comm_alm:X}H" if view.comm_alm else ""))
    if took is not None:
        return False, f"recovered only {format_ns(took)} {what}, more than {format_ns(within)}"
    return False, f"not recovered {format_ns(within)} {what}: {state}"


async def refused(faults: Any, step: Any, address: int, tcycle_ns: int) -> tuple[bool, str]:
    """The card refused the latest bad command injected into it (with ``step.alarm``, when given: a name such as
    ``DATA_SETTING_WARNING`` or a code such as ``94H``)."""
    master = faults.net.master(address)
    stage = faults.stage(address)
    deadline = master.now_ns() + REFUSAL_WAIT_NS
    episode = next((ep for ep in reversed(stage.log.episodes)
                    if ep.station == address and ep.what.startswith("bad-command")), None)
    if episode is None:
        return False, f"no bad command was injected into station {address:02X}H before this check"
    answer = None
    while master.now_ns() < deadline:
        last = stage.last_answer(address)
        if last is not None and last[0] is episode:
            answer = last[1]
            break
        await asyncio.sleep(tcycle_ns / 1e9)
    if answer is None:
        return False, f"no answer to the {episode.what} within {format_ns(REFUSAL_WAIT_NS)}"
    if not answer.refused:
        return False, f"the {episode.what} was accepted"
    want = (step.alarm or "").lower()
    names = {answer.name.lower(), f"{answer.code:x}h", f"{answer.code:02x}h"}
    ok = not want or want in names
    return ok, f"answered {answer.describe()}" + ("" if ok else f", expected {step.alarm}")
