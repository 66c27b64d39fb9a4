"""scripts/bench_timers.py --arm: what arming a timerfd costs, three figures of three percentiles each, printed and
written as JSON (no timing asserted); a clear refusal of a count below one."""

from __future__ import annotations

import json

import pytest

from mlink_sim.aio.timing.timerfd import timerfd_supported

from .scripts_loader import script_fixture

bench = script_fixture("bench", "bench_timers.py")

pytestmark = pytest.mark.skipif(not timerfd_supported(), reason="no timerfd here")


def test_arm_prints_and_writes_each_case(bench, capsys, tmp_path) -> None:
    out = tmp_path / "arm.json"
    assert bench.main(["--arm", "--arm-calls", "200", "--arm-ahead", "300us", "--json", str(out)]) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    assert lines[0].startswith("# timerfd_settime, µs per call, 200 calls")
    doc = json.loads(out.read_text())
    assert doc["calls"] == 200 and doc["ahead_ns"] == 300_000
    assert list(doc["arm"]) == ["earliest", "behind an earlier one", "getppid"]
    for name, q in doc["arm"].items():
        assert list(q) == ["p50", "p90", "p99"] and 0 < q["p50"] <= q["p90"] <= q["p99"]
        assert any(line.startswith(name) for line in lines[1:])


def test_arm_refuses_no_calls(bench, capsys) -> None:
    with pytest.raises(SystemExit) as exc:
        bench.main(["--arm", "--arm-calls", "0"])
    assert exc.value.code == 2
    assert "--arm-calls must be at least 1" in capsys.readouterr().err
