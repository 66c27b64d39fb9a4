"""The scenario engine on explicit time (mlink_sim.scenario): which steps are due, what each action asks of the
network (an operation of the table with its arguments), the checks judged from a view — no clock, no loop."""

from __future__ import annotations

from types import SimpleNamespace

from mlink_sim.config import parse_config
from mlink_sim.scenario import Timeline, judge
from mlink_sim.scenario import faultchecks
from mlink_sim.wire import InvCmdStat, Link, M2Status

CONFIG = """
[network]
transmission_cycle = "2ms"
[[station]]
address = 0x21
card = "si-t3"
[[station]]
address = 0x23
card = "si-et3"
[[timeline]]
at = "0.2s"
do = "run"
hz = 30
[[timeline]]
at = "1s"
station = 0x21
do = "set-param"
param = "C1-01"
value = 1.5
[[timeline]]
at = "1s"
do = "impair"
loss = "5%"
for = "300ms"
[[timeline]]
at = "2s"
station = 0x23
do = "silence"
for = "200ms"
[[timeline]]
at = "3s"
expect = "output-hz"
output_hz = 30
[[timeline]]
at = "4s"
station = 0x23
expect = "recovered"
within = "50ms"
"""


def test_steps_come_due_at_their_times_and_each_action_is_an_operation() -> None:
    timeline = Timeline(parse_config(CONFIG))
    assert timeline.next_deadline() is None  # not started
    timeline.start(1_000_000_000)
    assert timeline.next_deadline() == 1_200_000_000
    assert timeline.due(1_199_999_999) == []
    run, = timeline.due(1_200_000_000)
    assert [(r.op, r.args) for r in timeline.requests(run)] == [
        ("run", {"station": 0x21, "hz": 30.0, "direction": "forward"}),
        ("run", {"station": 0x23, "hz": 30.0, "direction": "forward"})]  # one request per station
    set_param, impair = timeline.due(2_000_000_000)  # two steps at one time, in the config's order
    assert [(r.op, r.args) for r in timeline.requests(set_param)] == [
        ("set-param", {"station": 0x21, "param": "C1-01", "value": 1.5, "eeprom": False})]
    (request,) = timeline.requests(impair)  # one impairment for every station's path
    assert request.op == "impair" and request.args["station"] is None and request.args["loss"] == "5%"
    assert request.args["for_"] == "300000000ns" and request.args["direction"] == "both"
    silence, = timeline.due(3_000_000_000)
    (fault,) = timeline.requests(silence)
    assert fault.op == "fault" and fault.args["station"] == 0x23 and fault.args["do"] == "silence"
    assert timeline.current is silence and [s.expect for s in timeline.not_run()] == ["output-hz", "recovered"]
    timeline.entered(0x21, "C1-01", 15)
    assert timeline.values_of(0x21)["C1-01"] == 15


def test_a_check_is_judged_from_the_view_it_is_given() -> None:
    timeline = Timeline(parse_config(CONFIG))
    step = timeline.steps[4]
    running = SimpleNamespace(status=int(M2Status.RUNX | M2Status.AGREE), phase=3)
    ok = judge(step, 0x21, running, Link.ML2, 30.1, {})
    assert ok.ok and ok.what == "3s station 21H: expect output-hz 30±0.5 Hz" and "output 30.10 Hz" in ok.detail
    slow = judge(step, 0x23, SimpleNamespace(status=int(InvCmdStat.FORWARD), phase=3), Link.ML3, 12.0, {})
    assert not slow.ok and slow.at_s == 3.0
    timeline.record(slow)
    explained = timeline.explained(slow, "accelerating at C1-01 = 10.0 s (default)")
    assert explained is not None and timeline.results == [explained] and explained.cause.startswith("accelerating")


def test_a_recovery_check_waits_until_it_can_tell() -> None:
    step = Timeline(parse_config(CONFIG)).steps[5]
    view = SimpleNamespace(state=SimpleNamespace(value="alarm"), phase=2, alarm_name="E5", fault=False, comm_alm=0)
    episode = SimpleNamespace(what="silence for=200ms", end_ns=2_200_000_000, recovered_ns=None, recovery_ns=None)
    assert faultchecks.recovered(step, 0x23, episode, 2_230_000_000, view) is None  # within the 50 ms: wait
    ok, detail = faultchecks.recovered(step, 0x23, episode, 2_250_000_000, view)
    assert not ok and detail.startswith("not recovered 50ms after silence for=200ms ended: state alarm, phase 2")
    done = SimpleNamespace(**{**vars(episode), "recovered_ns": 2_212_000_000, "recovery_ns": 12_000_000})
    assert faultchecks.recovered(step, 0x23, done, 2_212_000_000, view) == (
        True, "recovered 12ms after silence for=200ms ended (within 50ms)")
    assert faultchecks.recovered(step, 0x23, None, 0, view) == (
        False, "no fault was injected into station 23H before this check")
