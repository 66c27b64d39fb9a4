"""benchmarks.micro.capture: its verdict (met, not met, void on a drifting machine) and one virtual run's figures
(no timing asserted)."""

from __future__ import annotations

from benchmarks.micro import capture


def _virtual(added_us: float, drift: float) -> dict:
    return {"run_added_us_per_datagram": {"median": added_us}, "drift": drift}


def test_the_verdict_judges_the_headline_then_the_virtual_run_unless_the_machine_drifted():
    target = capture.TARGET_US
    assert capture.verdict(target, None) == "met"
    assert capture.verdict(target + 0.01, None) == "not met"
    assert capture.verdict(1.0, _virtual(target, 1.0)) == "met"
    assert capture.verdict(1.0, _virtual(target + 0.01, 1.0)) == "not met"
    assert capture.verdict(1.0, _virtual(0.5, capture.DRIFT + 0.01)) == "void"  # neither a pass nor a fail
    assert capture.verdict(target + 1, _virtual(0.5, capture.DRIFT + 0.01)) == "not met"


def test_a_virtual_run_reports_its_own_cpu_and_the_capture_s_datagrams(tmp_path):
    own, datagrams, writer_us, run = capture._up(["--clock", "virtual", "--duration", "0.5s"], True, tmp_path / "q.pcapng")
    assert (tmp_path / "q.pcapng").stat().st_size > 0
    assert datagrams > 100 and writer_us >= 0
    assert run is not None and 0 < run < own  # the run alone, without the process's start-up
    own, datagrams, _, run = capture._up(["--clock", "virtual", "--duration", "0.5s"], False, None)
    assert datagrams == 0 and run is not None
