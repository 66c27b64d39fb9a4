"""benchmarks.web: one short run of the quickstart with the page closed and open (a smoke test of the run and its
output; the figures themselves are the benchmark's, not the test's)."""

from __future__ import annotations

import json
import subprocess

import pytest

from benchmarks.common import ROOT, child_env, module_command

pytestmark = pytest.mark.e2e


def test_a_short_run_measures_every_arm_of_the_quickstart(tmp_path) -> None:
    out = tmp_path / "web.json"
    r = subprocess.run(module_command("benchmarks.web", "--networks", "quickstart", "--duration", "1s", "--trace",
                                      "--json", str(out)), capture_output=True, text=True, timeout=180, cwd=ROOT,
                       env=child_env())
    assert r.returncode == 0, r.stdout + r.stderr
    assert "page closed" in r.stdout and "page open" in r.stdout and "traced" in r.stdout
    (network,) = json.loads(out.read_text())["networks"]
    closed, opened, traced = network["arms"]
    assert (network["stations"], closed["arm"], opened["arm"], traced["arm"]) == (3, "closed", "open", "trace")
    assert closed["answers"] > 0 and opened["answers"] > 0 and traced["answers"] > 0
    assert opened["status_per_s"] > 0 and closed["status_per_s"] is None
    assert [v["arm"] for v in network["verdicts"]] == ["closed", "open", "trace"]


def test_an_unknown_network_is_a_usage_error() -> None:
    r = subprocess.run(module_command("benchmarks.web", "--networks", "nope"), capture_output=True, text=True,
                       timeout=60, cwd=ROOT, env=child_env())
    assert r.returncode == 2 and "--networks" in r.stderr
