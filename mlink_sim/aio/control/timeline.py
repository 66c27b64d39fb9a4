"""The driver of a config's timeline (:class:`~mlink_sim.scenario.Timeline`) on a running network: it sleeps to each
step's time on the run's clock, performs each action through the network's operations
(:class:`~.network.NetworkOps`, the handlers every other surface calls), judges each check from the master's view,
waits for the fault checks a cycle at a time without holding the timeline up, and asks the drive why a drive check
failed.

Touches: the loop's clock (sleeps), the network through its operations and views.
"""

from __future__ import annotations

import asyncio
import inspect
from collections.abc import Callable, Coroutine
from typing import Any

from ..._log import get_logger
from ...config import TimelineStep
from ...scenario import DRIVE_CHECKS, CheckResult, Timeline, judge
from ...scenario import faultchecks
from ...scenario.checks import label
from ...scenario.explain import explain

__all__ = ["TimelineRunner", "sleep_until"]

log = get_logger("mlink_sim.scenario")


async def sleep_until(when: float) -> None:
    """Sleep until the loop's time *when* (seconds)."""
    delay = when - asyncio.get_running_loop().time()
    if delay > 0:
        await asyncio.sleep(delay)


class TimelineRunner:
    """Runs *timeline* on *ops*'s network (``ops.handlers()``: the operations, ``ops.session.net``: the views)."""

    def __init__(self, timeline: Timeline, ops: Any) -> None:
        self.timeline = timeline
        self.ops = ops
        self.handlers = ops.handlers()
        self.net = ops.session.net
        self.links = {st.address: st.link for st in timeline.config.station}
        self.tcycle_ns = timeline.config.network.transmission_cycle
        #: called with each action step's description as it begins (a capture's comments: ``--capture``)
        self.note: Callable[[str], None] | None = None
        #: called with each action step as it begins, and with each check's result as it is judged (the trace)
        self.on_action: Callable[[TimelineStep], None] | None = None
        self.on_check: Callable[[CheckResult], None] | None = None
        self._waiting: set[asyncio.Task[None]] = set()  # checks that wait (recovered, refused), explanations
        self._t0 = 0.0

    async def run(self, t0: float) -> None:
        """Execute the steps in order of time; *t0* is the loop time of the timeline's 0 s."""
        self._t0 = t0
        timeline = self.timeline
        timeline.start(round(t0 * 1e9))
        while (deadline := timeline.next_deadline()) is not None:
            await sleep_until(deadline / 1e9)
            for step in timeline.due(deadline):
                if step.do:
                    await self._act(step)
                elif step.expect in ("recovered", "refused"):
                    for address in timeline.targets(step):
                        self._spawn(self._wait_check(step, address))
                else:
                    for address in timeline.targets(step):
                        self._check(step, address)
        if self._waiting:
            await asyncio.gather(*list(self._waiting))

    # -- actions ------------------------------------------------------------------------------------------------

    async def _act(self, step: TimelineStep) -> None:
        log.info("timeline_action", step=step.describe)
        if self.note is not None:
            self.note(f"timeline: {step.describe}")
        if self.on_action is not None:
            self.on_action(step)
        try:
            requests = self.timeline.requests(step)
        except ValueError as exc:  # the config's validation refuses such a step; a network it does not fit
            self.timeline.failed(step, exc)
            return
        outcomes = await asyncio.gather(*(self._perform(r.op, r.args) for r in requests), return_exceptions=True)
        for request, outcome in zip(requests, outcomes):
            if isinstance(outcome, Exception):
                line = self.timeline.failed(step, outcome)
                log.warning("timeline_action_failed", step=step.describe, error=line)
            elif request.op == "set-param" and isinstance(outcome, dict):
                row = outcome["param"]
                self.timeline.entered(request.args["station"], row["name"], int(row["raw"]))

    async def _perform(self, op: str, args: dict[str, Any]) -> Any:
        reply = self.handlers[op](**args)
        return await reply if inspect.isawaitable(reply) else reply

    # -- checks -------------------------------------------------------------------------------------------------

    def _check(self, step: TimelineStep, address: int) -> None:
        view = self.net.view(address)
        hz = self.ops.scales[address].to_hz(view.output_freq)
        result = judge(step, address, view, self.links[address], hz, self.net.alarms_seen(address))
        log.info("timeline_check", what=result.what, ok=result.ok, detail=result.detail)
        self._judged(result)
        if not result.ok and step.expect in DRIVE_CHECKS:
            self._spawn(self._explain(result, address))

    async def _wait_check(self, step: TimelineStep, address: int) -> None:
        """``recovered`` / ``refused``: asked again every transmission cycle until the answer is known."""
        control = self.net.fault_control
        master = self.net.master(address)
        stage = control.stage(address)
        try:
            if step.expect == "recovered":
                episode = stage.latest(address)

                def verdict() -> tuple[bool, str] | None:
                    return faultchecks.recovered(step, address, episode, master.now_ns(), master.view(address))
            else:
                episode = faultchecks.bad_command_episode(stage, address)
                deadline = master.now_ns() + faultchecks.REFUSAL_WAIT_NS

                def verdict() -> tuple[bool, str] | None:
                    last = stage.last_answer(address)
                    answer = last[1] if last is not None and last[0] is episode else None
                    return faultchecks.refused(step, address, episode, answer, master.now_ns(), deadline)

            while (outcome := verdict()) is None:
                await asyncio.sleep(self.tcycle_ns / 1e9)
            ok, detail = outcome
        except Exception as exc:  # noqa: BLE001 - a check that cannot be made fails, it does not stop the run
            ok, detail = False, f"could not check: {exc}"
        result = CheckResult(step.at / 1e9, address, label(step, address), ok, detail)
        log.info("timeline_check", what=result.what, ok=ok, detail=detail)
        self._judged(result)

    def _judged(self, result: CheckResult) -> None:
        self.timeline.record(result)
        if self.on_check is not None:
            self.on_check(result)

    async def _explain(self, result: CheckResult, address: int) -> None:
        """Give the failed *result* its cause: the drive's activity, read now (docs/configuration.md, "When a check
        fails")."""
        try:
            activity = await self.net.drive_activity(address)
        except Exception as exc:  # noqa: BLE001 - an explanation that cannot be had leaves the check as it is
            log.info("check_cause_unread", station=f"{address:#04x}", error=str(exc))
            return
        if activity is None:
            return
        cause = explain(activity, self.timeline.values_of(address), self._t0)
        if self.timeline.explained(result, cause) is not None:
            log.info("timeline_check_cause", what=result.what, cause=cause)

    def _spawn(self, coro: Coroutine[Any, Any, None]) -> None:
        """Run *coro* beside the timeline (not holding it up); :meth:`run` waits for it at the end."""
        task = asyncio.get_running_loop().create_task(coro)
        self._waiting.add(task)
        task.add_done_callback(self._waiting.discard)
