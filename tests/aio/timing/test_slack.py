"""The slack of a cycle (docs/timing.md, "Work beside the cycle"): work beside the cycle runs once the cycle's answers
are in, in the time before the clock's next wake-up, and never waits for ever. No test here times the machine: the
slack's bounds are set far from what a step takes."""

from __future__ import annotations

import asyncio
import time
from types import SimpleNamespace
from typing import Any

from mlink_sim.aio.master.runner import Master, NullMetrics
from mlink_sim.aio.timing.slack import MOST_NEED_NS, AnswersIn, Slack, Step

_S = 1_000_000_000


async def test_a_step_runs_at_once_in_an_open_slack() -> None:
    slack = Slack(max_wait_s=10.0)
    slack.open(time.monotonic_ns() + 10 * _S)
    await asyncio.wait_for(slack.wait(1000), 5.0)
    assert slack.waited_out == 0


async def test_a_step_waits_for_the_slack_to_open() -> None:
    slack = Slack(max_wait_s=10.0)
    waiter = asyncio.ensure_future(slack.wait(1000))
    await asyncio.sleep(0.01)
    assert not waiter.done()
    slack.open(time.monotonic_ns() + 10 * _S)
    await asyncio.wait_for(waiter, 5.0)
    assert slack.waited_out == 0 and slack.opened == 1


async def test_a_waiter_cancelled_in_the_turn_its_slack_opens_is_cancelled() -> None:
    """A sampler stopped at the end of a run, in the turn a cycle's slack opened for it, stops: the cancellation is
    not lost to the slack's opening (the trace's close waits for its task)."""
    slack = Slack(max_wait_s=10.0)

    async def sampler() -> None:
        while True:
            await slack.wait(20 * _S)  # never fits: waits for the next opening each time

    task = asyncio.ensure_future(sampler())
    for _ in range(3):
        await asyncio.sleep(0.01)
        slack.open(time.monotonic_ns() + _S)
    task.cancel()
    slack.open(time.monotonic_ns() + _S)  # the same turn
    done, _ = await asyncio.wait({task}, timeout=5.0)
    assert task in done and task.cancelled()


async def test_a_slack_too_short_for_the_step_is_not_taken() -> None:
    slack = Slack(max_wait_s=10.0)
    slack.open(time.monotonic_ns() + 10 * _S)
    waiter = asyncio.ensure_future(slack.wait(20 * _S))  # longer than what is left
    await asyncio.sleep(0.01)
    assert not waiter.done()
    slack.open(time.monotonic_ns() + 30 * _S)
    await asyncio.wait_for(waiter, 5.0)


async def test_a_step_no_slack_opened_for_runs_all_the_same() -> None:
    """A network whose answers never all come (a station gone): the work beside it is late, never stopped."""
    slack = Slack(max_wait_s=0.01)
    await asyncio.wait_for(slack.wait(), 5.0)
    assert slack.waited_out == 1


async def test_the_virtual_clocks_slack_is_always_open() -> None:
    slack = Slack(always=True, max_wait_s=10.0)
    await asyncio.wait_for(slack.wait(10 * _S), 5.0)


def test_a_step_needs_the_longest_recent_one_decaying_and_bounded() -> None:
    step = Step(need_ns=200_000)
    with step:
        pass
    assert step.need_ns == 200_000 - (200_000 >> 4)  # a shorter step: the need decays
    step.need_ns = 10 * MOST_NEED_NS
    with step:
        pass
    assert step.need_ns == MOST_NEED_NS


def _told() -> tuple[AnswersIn, list[int]]:
    """A master's AnswersIn and the list its hook appends to, once a cycle."""
    core: Any = SimpleNamespace(plan=SimpleNamespace(link=SimpleNamespace(name="ML3")), on_rtt=None)
    loop = asyncio.new_event_loop()
    master = Master(core, {}, NullMetrics(), loop)
    loop.close()  # the master is only asked when its answers are in: its loop never runs
    told: list[int] = []
    master.answers_in.hook = lambda: told.append(1)
    return master.answers_in, told


def test_a_master_says_once_a_cycle_that_its_answers_are_in() -> None:
    answers_in, told = _told()
    answers_in.expect(3)
    answers_in.answered(2)
    assert told == []
    answers_in.answered(1)
    answers_in.answered(1)  # a late answer of another cycle: told once only
    assert told == [1]


def test_a_station_that_stopped_answering_is_not_waited_for() -> None:
    """Cycle 1: two of three answer; from cycle 2 on the silent one is not awaited; once it answers again the master
    waits for it again."""
    answers_in, told = _told()
    answers_in.expect(3)
    answers_in.answered(2)
    assert told == []
    answers_in.expect(3)
    answers_in.answered(2)
    assert told == [1]
    answers_in.expect(3)
    answers_in.answered(3)  # it is back: told after two, then one more came
    assert told == [1, 1]
    answers_in.expect(3)
    answers_in.answered(2)
    assert told == [1, 1]
    answers_in.answered(1)
    assert told == [1, 1, 1]
