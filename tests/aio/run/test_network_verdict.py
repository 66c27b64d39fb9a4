"""mlink_sim.aio.run.network: the verdict line and the exit status come from one place, and the live status fits
any terminal."""

from __future__ import annotations

import io
import signal
from types import SimpleNamespace

import pytest

from mlink_sim.aio.run.network import Verdict, cut_by_duration
from mlink_sim.aio.present.status import STATUS_FIELDS, LiveStatus, StatusInfo, WorstP99, fit, render_lines
from mlink_sim.config import parse_config
from mlink_sim.master import StationState
from mlink_sim.metrics import NetworkMetrics

CONFIG = parse_config("""
[network]
name = "unit"
transmission_cycle = "2ms"
[[station]]
address = 0x21
card = "si-t3"
[[station]]
address = 0x22
card = "si-t3"
[[timeline]]
at = "1s"
expect = "running"
[[timeline]]
at = "5s"
expect = "stopped"
""")


def verdict(**kw: object) -> Verdict:
    base = dict(failed_checks=0, failed_asserts=0, unreached=0, not_run=0, checks_not_run=0, held=2, signal=None)
    return Verdict(**{**base, **kw})  # type: ignore[arg-type]


@pytest.mark.parametrize("kw", [
    {"failed_checks": 1}, {"failed_asserts": 1}, {"unreached": 1}, {"signal": signal.SIGINT},
    {"signal": signal.SIGTERM}, {"not_run": 1, "checks_not_run": 1}, {"held": 0},
])
def test_all_checks_held_only_with_exit_0_and_every_check_run(kw: dict[str, object]) -> None:
    v = verdict(**kw)
    assert "all checks held" not in v.line(3_000_000_000)
    if v.exit_code == 0:
        assert kw in ({"not_run": 1, "checks_not_run": 1}, {"held": 0})


def test_exit_status_and_lines() -> None:
    assert verdict().exit_code == 0 and verdict().line(None) == "all checks held"
    assert verdict(signal=signal.SIGINT).exit_code == 130
    assert verdict(signal=signal.SIGTERM, failed_checks=1).exit_code == 143
    assert verdict(signal=signal.SIGINT, not_run=3).line(None) == (
        "interrupted by SIGINT; 3 timeline step(s) not run; 2 check(s) held")
    assert verdict(unreached=1).exit_code == 1
    assert verdict(unreached=1).line(None) == "1 station(s) did not come up; 2 check(s) held"
    assert verdict(not_run=1, checks_not_run=1).line(2_000_000_000) == (
        "1 timeline step(s) not run (--duration 2s ended the run); 2 check(s) held")
    assert verdict(held=0).line(None) == "run complete (no checks in the timeline, no --assert)"


def test_cut_by_duration_lists_the_steps_at_or_after_the_end() -> None:
    assert [s.describe for s in cut_by_duration(CONFIG, 2_000_000_000)] == ["5s all stations: expect stopped"]
    assert cut_by_duration(CONFIG, None) == [] and cut_by_duration(CONFIG, 9_000_000_000) == []


# -- the live status ---------------------------------------------------------------------------------------------

def _view(address: int) -> SimpleNamespace:
    return SimpleNamespace(status=0, fault=False, alarm=0, comm_alm=0, cmd_alm=0, warning=False, alarm_name=None,
                           rtt_ns=250_000, phase=3, state=StationState.PHASE3, output_freq=0)


def _info(metrics: NetworkMetrics, **kw: object) -> StatusInfo:
    net = SimpleNamespace(view=_view)
    scales = {a: SimpleNamespace(to_hz=lambda raw: 0.0) for a in (0x21, 0x22)}
    base = dict(config=CONFIG, net=net, metrics=metrics, scales=scales, elapsed_s=1.25, total_s=6.0,
                step="1s all stations: expect running", p99_ns=1_234_000)
    return StatusInfo(**{**base, **kw})  # type: ignore[arg-type]


def test_header_shows_elapsed_total_p99_missed_stalls_and_the_step() -> None:
    m = NetworkMetrics(2_000_000)
    m.missed = 7
    lines = render_lines(_info(m))
    assert lines[0] == "unit  1.2/6.0 s  p99 1.234ms  missed 7  stalls 0  step 1s all stations: expect running"
    assert len(lines) == 5 and lines[1].startswith("  P1/P2/P3: phase") and " · ok: no alarm · " in lines[1] and lines[2].split() == [
        "ADDR", "CARD", "LINK", "PHASE", "RUN", "OUTPUT", "RTT", "STATE"]
    assert lines[3].split() == ["21H", "SI-T3", "ML2", "P3", "stop", "0.00", "Hz", "0.25", "ms", "ok"]
    assert [label for label, _ in STATUS_FIELDS] == ["", "p99", "missed", "stalls", "step"]
    m.record_stall("master", 5, 23_900_000, 11, True)  # host stalls as they come (metrics/stalls.py)
    assert render_lines(_info(m, total_s=None, p99_ns=None, step=None))[0] == (
        "unit  1.2 s  p99 -  missed 7  stalls 1 (max 23.9ms)  step -")


def test_fit_sums_up_what_does_not_fit() -> None:
    lines = [f"line {i}" for i in range(10)]
    assert fit(lines, 20) == lines
    assert fit(lines, 4) == ["line 0", "line 1", "line 2", "  … 7 more line(s): a taller terminal shows them"]
    assert len(fit(lines, 1)) == 1 and len(fit(lines, 0)) == 1


def test_worst_p99_refreshes_a_few_stations_per_frame() -> None:
    m = NetworkMetrics(2_000_000)
    for st, ns in ((0x21, 100_000), (0x22, 900_000), (0x23, 5_000_000)):
        m.record_rtt(st, ns)
    w = WorstP99(per_step=2)
    first = w.step(m)
    assert first is not None and 899_000 < first < 901_000  # 0x21, 0x22 so far
    assert 4_990_000 < (w.step(m) or 0) < 5_010_000  # 0x23 in the next frame


def test_plain_lines_when_not_a_terminal() -> None:
    out = io.StringIO()
    status = LiveStatus(out)
    status.start()
    status.show(["a", "b"])
    status.stop(["c"])
    assert out.getvalue() == "a\nb\nc\n" and status.interval == 5.0
