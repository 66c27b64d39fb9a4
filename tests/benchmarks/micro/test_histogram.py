"""benchmarks.micro.histogram: its figures on small sizes (no timing asserted), and a clear refusal of bad sizes."""

from __future__ import annotations

import json


from benchmarks.micro import histogram


def test_rtt_like_values_centre_near_200_us() -> None:
    values = sorted(histogram.rtt_like(2001))
    assert 150_000 < values[1000] < 260_000


def test_a_short_run_prints_every_figure_and_one_json_line(capsys) -> None:
    assert histogram.main(["--stations", "4", "--values", "400", "--repeat", "1", "--calls", "2000"]) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    doc = json.loads(lines[-1])
    assert set(doc["recording_ns"]) == {"record", "record_over_4", "record_rtt", "record_sent",
                                        "record_cycle_lateness"}
    assert set(doc["report_ms"]) == {"copy", "summary", "merged", "to_pairs"}
    assert all(v >= 0 for v in (*doc["recording_ns"].values(), *doc["report_ms"].values()))
    assert doc["stations"] == 4 and doc["values"] == 400 and lines[0] == f"cores: {doc['cores']}"


def test_bad_sizes_exit_2_with_a_message(capsys) -> None:
    for bad in (["--stations", "0"], ["--calls", "-1"]):
        assert histogram.main(bad) == 2
        assert "must be ≥ 1" in capsys.readouterr().err
