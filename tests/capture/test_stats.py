"""``decode --pcap FILE --stats``: the figures of a capture of known timing (``timed.py``) – response times, cycle
gaps, lost and late answers, FCS and sequence errors, INV_CTL in Hz by the units the card note names or the
default – as the user reads them, in text and JSON."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from click.testing import CliRunner

from mlink_sim.capture import CaptureFile
from mlink_sim.capture.stats import capture_stats, percentile, summary
from mlink_sim.capture.text import Selection
from mlink_sim.cli.decode import decode_cmd

from .timed import CYCLE, RT_21, write_timed_capture


@pytest.fixture(scope="module")
def timed(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_timed_capture(tmp_path_factory.mktemp("timed") / "timed.pcapng")


def test_nearest_rank_percentiles() -> None:
    values = list(range(1, 101))
    assert percentile(values, 50) == 50 and percentile(values, 99) == 99 and percentile(values, 100) == 100
    assert percentile([7], 99) == 7
    assert summary([]) is None
    assert summary([30, 10, 20]) == {"count": 3, "min": 10, "p50": 20, "p99": 30, "max": 30}


def test_the_figures_of_a_capture_of_known_timing(timed: Path) -> None:
    stats = capture_stats(CaptureFile(timed))
    assert stats["datagrams"] == 30 and stats["rejected"] == 1
    inv = stats["stations"]["21H"]["INV_CTL"]
    assert (inv["cmd"], inv["rsp"], inv["lost"], inv["late"]) == (12, 12, 1, 1)  # cycle 4 lost, cycle 7 late
    assert inv["response_ns"] == {"count": 11, "min": RT_21[0], "p50": RT_21[5], "p99": RT_21[-1], "max": 2_500_000}
    assert RT_21[0] == 100_000 and RT_21[5] == 170_000
    t21 = stats["timing"]["21H"]
    assert t21["gap_ns"] == {"count": 11, "min": CYCLE, "p50": CYCLE, "p99": CYCLE, "max": CYCLE}
    assert (t21["fcs_errors"], t21["sequence_errors"], t21["rejected"]) == (1, 2, 0)  # repeated cycle, duplicate
    assert t21["speed_ref"] == {"min": 0, "max": 5500, "last": 5500}
    assert t21["output_freq"] == {"min": 0, "max": 4400, "last": 4400}
    prm = stats["stations"]["23H"]["PRM_RD"]
    assert (prm["cmd"], prm["rsp"], prm["lost"], prm["late"]) == (3, 2, 0, 0)  # its last: the capture's end
    assert prm["response_ns"]["min"] == prm["response_ns"]["max"] == 150_000
    assert stats["timing"]["23H"]["gap_ns"]["p50"] == 4_000_000 and stats["timing"]["23H"]["speed_ref"] is None


def test_the_filters_apply(timed: Path) -> None:
    only = capture_stats(CaptureFile(timed), Selection(station=0x23))
    assert set(only["stations"]) == {"23H"} and only["datagrams"] == 5
    early = capture_stats(CaptureFile(timed), Selection(to_ns=5_000_000))
    assert early["stations"]["21H"]["INV_CTL"]["cmd"] == 3


def test_the_text_a_user_reads(timed: Path) -> None:
    result = CliRunner().invoke(decode_cmd, ["--pcap", str(timed), "--stats"])
    assert result.exit_code == 0, result.output
    lines = result.stdout.splitlines()
    assert lines[0].split() == ["station", "command", "commands", "responses", "lost", "late", "rt", "min", "p50",
                                "p99", "max"]
    assert lines[1].split() == ["21H", "INV_CTL", "12", "12", "1", "1", "100us", "170us", "2.5ms", "2.5ms"]
    assert lines[2].split() == ["23H", "PRM_RD", "3", "2", "0", "0", "150us", "150us", "150us", "150us"]
    gaps = next(line for line in lines if line.startswith("21H      ML2"))
    assert gaps.split() == ["21H", "ML2", "2ms", "2ms", "2ms", "2ms", "1", "2", "0"]
    hz = next(line for line in lines if line.startswith("21H") and "Hz per count" in line)
    assert "0.00…33.00, last 33.00" in hz and "0.00…26.40, last 26.40" in hz  # 5500 and 4400 counts × 0.006 Hz
    assert hz.endswith("0.006 Hz per count, the capture's note")
    assert lines[-1] == "30 datagram(s), 1 rejected"


def test_json_gives_hz_and_says_where_the_units_come_from(timed: Path) -> None:
    stats = json.loads(CliRunner().invoke(decode_cmd, ["--pcap", str(timed), "--stats", "--json"]).stdout)
    t21, t23 = stats["timing"]["21H"], stats["timing"]["23H"]
    assert t21["hz_per_count"] == 0.006 and t21["units"] == "the capture's note"
    assert t21["speed_ref_hz"] == {"min": 0.0, "max": 33.0, "last": 33.0}
    assert t23["hz_per_count"] == 0.01 and t23["units"] == "default of SI-ET3 (o1-03 = 0)"  # its note names none
    assert t23["speed_ref_hz"] is None
    assert stats["stations"]["21H"]["INV_CTL"]["response_ns"]["p99"] == 2_500_000


def test_a_station_without_a_card_note_says_its_units_are_a_default(tmp_path: Path) -> None:
    from mlink_sim.capture import CaptureWriter
    from mlink_sim.wire import Frame, Kind, Link, encode, ml2

    path = tmp_path / "bare.pcapng"
    with CaptureWriter(path, epoch_offset_ns=0) as w:
        w.record(0, encode(Frame(Link.ML2, Kind.COMMAND, 0x21, 1, CYCLE, ml2.M2Command(ml2.InvCtl(speed_ref=3000)))),
                 ("192.0.2.1", 1), ("192.0.2.33", 2))
    out = CliRunner().invoke(decode_cmd, ["--pcap", str(path), "--stats"]).stdout
    line = next(line for line in out.splitlines() if "Hz per count" in line)
    assert "30.00…30.00, last 30.00" in line and line.endswith("default (o1-03 = 0 / n035 = 0)")
