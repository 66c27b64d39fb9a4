"""mlink_sim.testing.stalls: a run whose every failed check names a host stall beyond the bound (docs/ci.md)."""

from __future__ import annotations

from mlink_sim.metrics.stalls import StallLog
from mlink_sim.testing import beyond_the_bound, run_beyond_the_bound

MS = 1_000_000


def _near(*stalls_ms: float) -> str:
    log = StallLog("absorb", 100 * MS)
    log.reset(0)
    for i, ms in enumerate(stalls_ms):
        log.record("master", (1_000 + 100 * i) * MS, int(ms * MS), 65, False)
    return log.describe_near(2_000 * MS)


def test_every_failed_check_after_a_stall_beyond_the_bound():
    failed = [f"2s station 21H: expect output-hz: output 0.00 Hz; {_near(12.6, 130.5)}",
              f"2s station 23H: expect output-hz: output 0.00 Hz; {_near(130.5)}"]
    reason = beyond_the_bound(failed, 100 * MS)
    assert reason is not None and reason.startswith("the host stalled beyond the 100 ms bound")
    assert "station 21H" in reason and "station 23H" in reason


def test_one_failure_without_such_a_stall_is_a_failure():
    assert beyond_the_bound([f"a: {_near(130.5)}", f"b: {_near(99.0)}"], 100 * MS) is None
    assert beyond_the_bound(["c: alarm none, fault"], 100 * MS) is None
    assert beyond_the_bound([], 100 * MS) is None
    assert beyond_the_bound([f"a: {_near(130.5)}"], 0) is None  # strict: no bound, nothing is excused


SUMMARY = """== e2e: 2 stations, 2ms cycle, 4.5 s ==
rtt p50 86.78us  p99 379.1us  max 5.505ms  (4373 responses); missed cycles 65, missing responses 0, late 0
host stalls 3, longest 130.5ms, 73 cycles delayed: 8 run late, 65 lost (policy absorbs up to 100ms)
  FAIL 2s station 21H: expect output-hz 20±0.5 Hz: output 0.00 Hz, expected 20 ± 0.5 Hz; {near}
  ok   3.5s station 21H: expect stopped: running=False, output 0.00 Hz
1 check(s) failed; 1 check(s) held
"""


def test_the_cli_output():
    assert run_beyond_the_bound(SUMMARY.format(near=_near(130.5))) is not None
    assert run_beyond_the_bound(SUMMARY.format(near=_near(60.0))) is None
    assert run_beyond_the_bound(SUMMARY.replace("policy absorbs up to 100ms", "policy strict")
                                .format(near=_near(130.5))) is None
    assert run_beyond_the_bound(SUMMARY.replace("up to 100ms", "up to 200ms").format(near=_near(130.5))) is None
    assert run_beyond_the_bound("all checks held") is None
