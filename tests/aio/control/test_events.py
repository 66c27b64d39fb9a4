"""The run's event ring (mlink_sim.aio.control.events): numbered, bounded, read after a number, times from the
timeline's 0 s."""

from __future__ import annotations

from mlink_sim.aio.control.events import RunLog
from mlink_sim.scenario import CheckResult
from mlink_sim.master.types import AlarmRaised, StateChanged, StationState


class Clock:
    def __init__(self) -> None:
        self.ns = 1_000_000_000

    def __call__(self) -> int:
        return self.ns


def test_events_are_numbered_and_read_after_a_number():
    log = RunLog(Clock())
    for i in range(5):
        log.add("action", describe=f"a{i}")
    events, last = log.since(2)
    assert [e["seq"] for e in events] == [3, 4, 5] and last == 5
    assert log.since(5) == ([], 5)  # nothing new: the number stays


def test_at_most_limit_events_per_read_the_rest_with_the_next():
    log = RunLog(Clock())
    for _ in range(10):
        log.add("action")
    first, last = log.since(0, limit=4)
    assert [e["seq"] for e in first] == [1, 2, 3, 4] and last == 4
    assert [e["seq"] for e in log.since(last, limit=4)[0]] == [5, 6, 7, 8]


def test_the_ring_forgets_the_oldest_events():
    log = RunLog(Clock(), capacity=3)
    for _ in range(5):
        log.add("action")
    assert [e["seq"] for e in log.since(0)[0]] == [3, 4, 5]


def test_a_number_from_another_run_reads_from_the_latest():
    log = RunLog(Clock())
    log.add("action")
    assert log.since(99) == ([], 1)


def test_times_count_from_the_timelines_start():
    clock = Clock()
    log = RunLog(clock)
    clock.ns += 500_000_000
    log.add("phase")
    clock.ns += 500_000_000
    log.start()
    clock.ns += 250_000_000
    log.add("action")
    events, _ = log.since(0)
    assert [e["at_s"] for e in events] == [-0.5, 0.25]
    assert log.elapsed_s == 0.25


def test_master_events_become_phase_and_alarm_events():
    """SI-T3 Table 23: E6H COMM_ERROR in the ML-II ALARM byte; SI-ET3 "COMM_ALM": 9H NOT_RECEIVED."""
    clock = Clock()
    log = RunLog(clock)
    log._on_master(clock.ns, StateChanged(0x21, StationState.PHASE2, StationState.PHASE3))
    log._on_master(clock.ns, AlarmRaised(0x21, 0xE6, "COMM_ERROR", "alarm"))
    log._on_master(clock.ns, AlarmRaised(0x23, 0x9, "NOT_RECEIVED", "comm"))
    log._on_master(clock.ns, "station 21H: card SI-T3")  # a capture's text: not an event
    phase, ml2, ml3 = log.since(0)[0]
    assert phase["kind"] == "phase" and phase["state"] == "phase3" and phase["phase"] == 3
    assert (ml2["kind"], ml2["station"], ml2["code"], ml2["name"]) == ("alarm", "0x21", "E6H", "COMM_ERROR")
    assert ml3["code"] == "COMM_ALM 9H"


def test_the_timeline_is_polled_into_steps_and_checks_at_their_own_times():
    class Step:
        def __init__(self, at: int, describe: str) -> None:
            self.at, self.describe = at, describe

    class Scenario:
        steps = [Step(200_000_000, "0.2s run"), Step(3_000_000_000, "3s expect speed-agree")]
        started = 1
        results: list[CheckResult] = []

    clock = Clock()
    log = RunLog(clock)
    log.start()
    scenario = Scenario()
    log.poll(scenario)
    scenario.started = 2
    scenario.results = [CheckResult(3.0, 0x21, "3s station 21H: expect speed-agree", True, "agree")]
    log.poll(scenario)
    log.poll(scenario)  # nothing new: nothing logged twice
    events = log.since(0)[0]
    assert [(e["kind"], e["at_s"]) for e in events] == [("step", 0.2), ("step", 3.0), ("check", 3.0)]
    assert events[2]["station"] == "0x21" and events[2]["ok"] is True
