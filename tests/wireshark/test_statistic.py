"""The dissector's exchange fields and its response-time statistic (``tshark -z mlink,srt``) under the real tshark,
on the capture of known timing that ``decode --stats`` is checked against: the same figures."""

from __future__ import annotations

from pathlib import Path

import pytest

from mlink_sim.capture import CaptureFile
from mlink_sim.capture.stats import capture_stats
from mlink_sim.wireshark.generate import shipped_path

from tests.capture.timed import write_timed_capture
from .conftest import run_tshark, tshark_process


@pytest.fixture(scope="module")
def timed(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_timed_capture(tmp_path_factory.mktemp("timed") / "timed.pcapng")


def _rows(text: str) -> dict[str, list[str]]:
    """The statistic's lines by their first two words (``21H INV_CTL``) or, for the station lines, the first."""
    rows: dict[str, list[str]] = {}
    gaps = False
    for line in text.splitlines():
        words = line.split()
        if not words or words[0].startswith("="):
            continue
        if words[0] == "station":
            gaps = words[1] == "gap"
            continue
        if words[0].endswith("H"):
            rows[words[0] if gaps else f"{words[0]} {words[1]}"] = words[1:] if gaps else words[2:]
    return rows


def test_the_statistic_gives_the_figures_decode_gives(tshark: str, timed: Path) -> None:
    out = run_tshark(tshark, timed, "-q", "-z", "mlink,srt")
    assert "MECHATROLINK response times (mlink-sim), ms" in out
    rows = _rows(out)
    stats = capture_stats(CaptureFile(timed))
    for station, per in stats["stations"].items():
        for command, c in per.items():
            cmd, rsp, lost, late, t_min, avg, p50, p99, t_max = rows[f"{station} {command}"]
            assert (int(cmd), int(rsp), int(lost), int(late)) == (c["cmd"], c["rsp"], c["lost"], c["late"])
            rt = c["response_ns"]
            for shown, key in ((t_min, "min"), (p50, "p50"), (p99, "p99"), (t_max, "max")):
                assert float(shown) == pytest.approx(rt[key] / 1e6, abs=0.0005), (station, command, key)
    assert float(rows["21H INV_CTL"][5]) == pytest.approx(sum([100 + 10 * i for i in (0, 1, 2, 4, 5, 7, 8, 9)]
                                                              + [2500, 200, 200]) / 11 / 1000, abs=0.0005)
    for station, t in stats["timing"].items():
        g_min, _, g_p50, g_p99, g_max, fcs, seq = rows[station]
        assert [float(g_min), float(g_p50), float(g_p99), float(g_max)] == pytest.approx(
            [t["gap_ns"][k] / 1e6 for k in ("min", "p50", "p99", "max")], abs=0.0005)
        assert (int(fcs), int(seq)) == (t["fcs_errors"], t["sequence_errors"])


def test_the_statistic_takes_a_filter(tshark: str, timed: Path) -> None:
    rows = _rows(run_tshark(tshark, timed, "-q", "-z", "mlink,srt,mlink.station==0x23"))
    assert set(rows) == {"23H PRM_RD", "23H"}


def _fields(tshark: str, capture: Path, *fields: str, two_pass: bool = False) -> list[list[str]]:
    args = ["-2"] if two_pass else []
    out = run_tshark(tshark, capture, *args, "-T", "fields", *(a for f in fields for a in ("-e", f)))
    return [line.split("\t") for line in out.splitlines()]


def test_the_exchange_fields(tshark: str, timed: Path) -> None:
    rows = _fields(tshark, timed, "frame.number", "mlink.station", "mlink.kind", "mlink.cycle", "mlink.time",
                   "mlink.late", "mlink.gap", "mlink.speed_ref.hz", "mlink.output_freq.hz", "mlink.response_to")
    by = {(r[1], r[2], r[3]): r for r in rows if r[1]}
    answer2 = by[("0x21", "0x02", "2")]
    assert float(answer2[4]) == pytest.approx(110e-6, abs=1e-9) and answer2[5] == "0"
    assert float(answer2[8]) == pytest.approx(400 * 0.006)  # output frequency by the note's 0.006 Hz counts
    assert answer2[9] == by[("0x21", "0x01", "2")][0]
    late = by[("0x21", "0x02", "7")]
    assert float(late[4]) == pytest.approx(2.5e-3, abs=1e-9) and late[5] == "1"
    command2 = by[("0x21", "0x01", "2")]
    assert float(command2[6]) == pytest.approx(2e-3, abs=1e-9) and float(command2[7]) == pytest.approx(3.0)
    assert by[("0x23", "0x01", "100")][7] == ""  # a PRM_RD has no speed
    second = _fields(tshark, timed, "mlink.station", "mlink.kind", "mlink.cycle", "mlink.response_in", two_pass=True)
    responses_in = {(r[0], r[2]): r[3] for r in second if r[0] and r[1] == "0x01"}
    assert responses_in[("0x21", "2")] != "" and responses_in[("0x21", "4")] == ""  # cycle 4 never answered


def test_default_units_are_said_in_the_item(tshark: str, tmp_path: Path) -> None:
    from mlink_sim.capture import CaptureWriter
    from mlink_sim.wire import Frame, Kind, Link, encode, ml3

    path = tmp_path / "bare.pcapng"
    with CaptureWriter(path, epoch_offset_ns=0) as w:
        w.record(0, encode(Frame(Link.ML3, Kind.COMMAND, 0x23, 1, 2_000_000, ml3.M3Command(ml3.InvCtl(speed_ref=3000)))),
                 ("192.0.2.1", 1), ("192.0.2.35", 47001))
    proc = tshark_process([tshark, "-n", "-X", f"lua_script:{shipped_path()}", "-r", str(path), "-V"],
                          capture_output=True, text=True, timeout=120)
    assert "Speed reference: 30.00 Hz (0.01 Hz per count, default: o1-03 = 0 / n035 = 0)" in proc.stdout
