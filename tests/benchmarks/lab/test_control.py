"""benchmarks.lab.control: the late answers of a query's window against as many background windows between
queries (synthetic read times), its refusals, and one short live run."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

from benchmarks.common import child_env, module_command
from benchmarks.lab import control

MS = 1_000_000


def test_late_answers_in_a_query_s_window_are_the_query_s_and_half_an_interval_later_the_background() -> None:
    every = 500 * MS
    queries = [(1000 * MS, 1002 * MS), (1500 * MS, 1501 * MS)]
    late = sorted([
        999 * MS + 1,      # within BEFORE_NS of the first send: the query's
        1004 * MS,         # within AFTER_NS of its reply
        1005 * MS + 1,     # beyond: neither
        1250 * MS,         # half an interval after the first window: the background
        1503 * MS,         # the second query's
        1754 * MS,         # the second background window (1749 .. 1754 ms)
        1754 * MS + 1,     # just beyond it
    ])
    assert control.attribute(late, queries, every) == (3, 2)
    assert control.attribute([], queries, every) == (0, 0)


def _run(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(module_command("benchmarks.lab.control", *args), capture_output=True, text=True,
                          timeout=120, env=child_env())


def test_wrong_arguments_are_refused_with_exit_2_and_no_traceback() -> None:
    for args in (["--op", "nope"], ["--stations", "63"], ["--queries", "0"], ["--cycles", "1ms", "--every", "5ms"],
                 ["--cycles", "soon"]):
        out = _run(*args)
        assert out.returncode == 2, args
        assert out.stderr.startswith("control: ") and "Traceback" not in out.stderr


def test_a_short_live_run_reports_each_op(tmp_path: Path) -> None:
    out = _run("--stations", "2", "--cycles", "1ms", "--op", "stats,ping", "--queries", "2", "--every", "100ms",
               "--json", str(tmp_path / "c.json"))
    assert out.returncode == 0, out.stderr
    assert " stats " in out.stdout and " ping " in out.stdout and "late answers per query" in out.stdout
    doc = json.loads((tmp_path / "c.json").read_text())
    assert [o["op"] for o in doc["outcomes"]] == ["stats", "ping"]
    assert all(o["queries"] == 2 and o["answers"] > 0 and o["reply_p50_us"] > 0 for o in doc["outcomes"])
