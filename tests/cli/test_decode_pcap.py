"""``mlink-sim decode --pcap``: one line per datagram with relative time and direction, --station, --json."""

from __future__ import annotations

import json
from pathlib import Path

from click.testing import CliRunner

from mlink_sim.cli.decode import decode_cmd

GOLDEN = Path(__file__).resolve().parents[1] / "wireshark" / "golden.pcapng"


def test_one_line_per_datagram_and_exit_1_for_the_bad_fcs_ones() -> None:
    result = CliRunner().invoke(decode_cmd, ["--pcap", str(GOLDEN)])
    assert result.exit_code == 1  # three datagrams of the golden capture carry a bad FCS
    lines = [line for line in result.stdout.splitlines() if not line.lstrip().startswith("#")]
    assert len(lines) == 126
    assert lines[0].startswith("   0.000000  192.0.2.1:40000 -> 192.0.2.33:47001  ML1 cmd 21H cycle 1  NOP(00H)")
    assert lines[3].startswith("   0.003000  192.0.2.33:47001 -> 192.0.2.1:40000  ML1 rsp 21H cycle 2  PRM_RD(01H)")
    assert sum("REJECTED bad FCS" in line for line in lines) == 3
    assert "# ML1 main command" in result.stdout  # the capture's comments
    assert "3 of 126 datagram(s) rejected" in result.stderr


def test_station_filter_and_json_lines() -> None:
    result = CliRunner().invoke(decode_cmd, ["--pcap", str(GOLDEN), "--station", "0x31", "--json"])
    assert result.exit_code == 1
    records = [json.loads(line) for line in result.stdout.splitlines()]
    assert records and all(r["frame"]["station"] == 0x31 for r in records if "frame" in r)
    first = records[0]
    assert first["direction"] == "master->slave" and first["frame"]["link"] == "ML3"
    assert first["frame"]["main"]["command"] == "NOP" and first["comments"] == ["ML3 main command"]
    assert any(r["direction"] == "slave->master" for r in records)
    assert [r["reason"] for r in records if "error" in r] == ["BAD_FCS"]


def test_a_clean_station_exits_0() -> None:
    result = CliRunner().invoke(decode_cmd, ["--pcap", str(GOLDEN), "--station", "0x23"])
    assert result.exit_code == 0, result.output
    assert "sub INV_IO(41H)" in result.stdout


def test_usage_errors(tmp_path: Path) -> None:
    assert CliRunner().invoke(decode_cmd, []).exit_code == 2
    assert CliRunner().invoke(decode_cmd, ["--pcap", str(GOLDEN), "4d"]).exit_code == 2
    assert CliRunner().invoke(decode_cmd, ["--station", "0x21", "4d"]).exit_code == 2
    assert CliRunner().invoke(decode_cmd, ["--pcap", str(GOLDEN), "--station", "zz"]).exit_code == 2
    (tmp_path / "x").write_text("nope")
    result = CliRunner().invoke(decode_cmd, ["--pcap", str(tmp_path / "x")])
    assert result.exit_code == 2 and "not a pcap or pcapng file" in result.output
