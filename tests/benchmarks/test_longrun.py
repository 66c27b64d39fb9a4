"""benchmarks.soak --long (benchmarks.longrun): one run sampled from outside, each process's RSS, peak RSS and open
files, the run's counters, the trace's size, and the report checked against its schema at the end."""

from __future__ import annotations

import json
import subprocess

import pytest

from benchmarks import longrun, soak
from benchmarks.common import ROOT, child_env, module_command


def test_the_summary_measures_growth_after_the_first_minute_and_keeps_the_peak() -> None:
    def sample(t: float, rss: int, peak: int) -> dict:
        return {"t_s": t, "processes": [{"pid": 1, "role": "up", "rss_kb": rss, "peak_rss_kb": peak, "open_files": 9}]}

    out = longrun.summarise([sample(30, 50_000, 50_000), sample(60, 60_000, 61_000), sample(3660, 60_500, 62_000)])
    assert out["up"]["rss_kb_first"] == 60_000 and out["up"]["rss_growth_kb_per_h"] == 500.0
    assert out["up"]["peak_rss_kb"] == 62_000


def test_a_counter_that_goes_back_or_memory_that_grows_fails_its_target() -> None:
    result = {"exit": 0, "report": {"valid": True},
              "processes": {"up": {"rss_growth_kb_per_h": 4096.0, "from_s": 60.0, "to_s": 3600.0}},
              "samples": [{"run": {name: 5 for name in longrun._COUNTERS}},
                          {"run": {**{name: 5 for name in longrun._COUNTERS}, "sent": 4}}]}
    failed = longrun.judge(result)
    assert any("up: RSS grew 4096 kB/h" in f for f in failed) and any("sent went back" in f for f in failed)


@pytest.mark.parametrize("argv", [["--long", "0s"], ["--long", "soon"], ["--long", "10s", "--sample", "0s"]])
def test_a_long_run_needs_positive_durations(argv: list[str]) -> None:
    with pytest.raises(SystemExit) as exc:
        soak.main(argv)
    assert exc.value.code == 2


@pytest.mark.e2e
def test_a_short_long_run_samples_every_process_and_checks_the_report(tmp_path) -> None:
    out = tmp_path / "long.json"
    r = subprocess.run(module_command("benchmarks.soak", "configs/quickstart.toml", "--long", "9s", "--sample", "3s",
                                      "--json", str(out), "--", "--no-realtime"),
                       capture_output=True, text=True, cwd=ROOT, env=child_env(), timeout=120)
    assert r.returncode == 0, r.stdout + r.stderr
    doc = json.loads(out.read_text())
    assert doc["report"]["valid"] and doc["exit"] == 0 and len(doc["samples"]) >= 2
    roles = set(doc["processes"])
    assert "up" in roles and any(role.startswith("slave") for role in roles), roles
    assert all(p["peak_rss_kb"] >= p["rss_kb_last"] > 0 and p["open_files_last"] > 0
               for p in doc["processes"].values())
    runs = [s["run"] for s in doc["samples"] if s["run"]]
    assert runs and runs[-1]["sent"] > 0 and doc["samples"][-1]["trace_bytes"] > 0
    assert "peak" in r.stdout


def test_the_default_sample_and_the_documented_duration_parse(monkeypatch) -> None:
    seen = {}
    monkeypatch.setattr(longrun, "main", lambda config, duration, sample, extra, json_path: seen.update(
        config=config, duration=duration, sample=sample) or 0)
    assert soak.main(["--long", "60min"]) == 0
    assert seen == {"config": "configs/ml3-62-max.toml", "duration": 3600.0, "sample": 60.0}
