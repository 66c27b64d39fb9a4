"""``mlink-sim decode`` in the user's terms: parameters by name with their values in units where the card is known
(``--card``, the capture's card notes, the link), INVCMD_STAT bits by name; ``decode --pcap`` filtered by
station (its notes included, other stations' left out), command and time, and counted with ``--stats``."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
from click.testing import CliRunner

from mlink_sim.cli.decode import decode_cmd
from mlink_sim.wire import Frame, Kind, Link, encode, ml2, ml3

# n020 (VS-606V7 deceleration time 1, register 0100H + 20) = 1.0 s: 10 counts of 0.1 s
V7_PRM_WR = encode(Frame(Link.ML2, Kind.COMMAND, 0x22, 1, 2_000_000,
                         ml2.M2Command(ml2.PrmWr(0x0114, 2, bytes([10]) + bytes(7)), wdt=0x10))).hex()
# C1-01 (A1000, 0200H: SI-ET3 §9 PRM_RD example) = 1.0 s on MECHATROLINK-III: the SI-ET3 is the only ML-III card
ET3_PRM_WR = encode(Frame(Link.ML3, Kind.COMMAND, 0x04, 1, 2_000_000,
                          ml3.M3Command(ml3.PrmWr(0x0200, 2, bytes([10]) + bytes(7)), 0x10, 0, None, 0))).hex()


def run(*args: str):
    return CliRunner().invoke(decode_cmd, list(args))


def test_one_datagram_names_the_parameter_where_the_card_is_known() -> None:
    assert "PRM_WR(02H) C1-01 (0200H) = 1.0 s" in run(ET3_PRM_WR).stdout  # ML-III: SI-ET3, A1000 table
    assert "PRM_WR(02H) no=0x114 size=2 data=0a00" in run(V7_PRM_WR).stdout  # ML-II: SI-T3 or SI-T/V7?
    assert "PRM_WR(02H) n020 (0114H) = 1.0 s" in run("--card", "si-t-v7", V7_PRM_WR).stdout
    assert "n020 (0114H) = 1.0 s" in run("--card", "22H=SI-T/V7", V7_PRM_WR).stdout
    assert "no=0x114" in run("--card", "0x21=si-t-v7", V7_PRM_WR).stdout  # another station's card


def test_json_gains_the_parameter_fields() -> None:
    frame = json.loads(run("--json", ET3_PRM_WR).stdout)
    param = frame["main"]["param"]
    assert (param["name"], param["register"], param["value"], param["unit"], param["raw"]) == (
        "C1-01", 0x0200, 1.0, "s", 10)
    assert frame["main"]["no"] == 0x0200  # the raw fields stay


def test_a_bad_card_is_a_usage_error() -> None:
    result = run("--card", "si-x9", ET3_PRM_WR)
    assert result.exit_code == 2 and "unknown option card 'si-x9'" in result.output


@pytest.fixture(scope="module")
def capture(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The quickstart on the virtual clock to just after its set-param steps (3.3 s), recorded (its master
    writes the card notes)."""
    path = tmp_path_factory.mktemp("cap") / "quickstart.pcapng"
    done = subprocess.run([sys.executable, "-m", "mlink_sim", "up", "quickstart", "--clock", "virtual", "--no-status",
                           "--duration", "3.4s",
                           "--capture", str(path)], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    return path


def test_pcap_names_parameters_by_the_captures_card_notes(capture: Path) -> None:
    out = run("--pcap", str(capture)).stdout
    assert "# station 22H: card SI-T/V7 (MECHATROLINK-II, 32-byte)" in out
    assert "sub PRM_WR(02H) n020 (0114H) = 1.0 s" in out  # the quickstart's set-param n020=1.0 on 22H
    assert "PRM_WR(02H) C1-02 (0201H) = 1.0 s" in out  # and C1-02=1.0 on 23H
    assert "invcmd_stat=FORWARD|" in out  # SI-ET3 INVCMD_STAT bits by name


def test_station_filter_keeps_its_notes_and_leaves_out_the_others(capture: Path) -> None:
    out = run("--pcap", str(capture), "--station", "22H", "--to", "10ms").stdout
    assert "# station 22H: card SI-T/V7" in out  # recorded on a datagram of 21H
    assert "station 21H" not in out and "station 23H" not in out and "0x23" not in out
    frames = [line for line in out.splitlines() if "->" in line]
    assert frames and all(" 22H cycle " in line for line in frames)
    assert run("--pcap", str(capture), "--station", "0x22", "--to", "10ms").stdout == out


def test_command_filter_and_time_range(capture: Path) -> None:
    out = run("--pcap", str(capture), "--command", "prm_wr", "--command", "CONFIG").stdout
    frames = [line for line in out.splitlines() if "->" in line]
    assert len(frames) == 8  # PRM_WR + CONFIG to 22H and 23H, each answered
    assert all("PRM_WR" in line or "CONFIG" in line for line in frames)
    window = run("--pcap", str(capture), "--from", "1s", "--to", "1.01s").stdout
    times = [float(line.split()[0]) for line in window.splitlines() if "->" in line]
    assert times and 1.0 <= min(times) and max(times) <= 1.01


def test_stats_counts_per_station_and_command(capture: Path) -> None:
    result = run("--pcap", str(capture), "--stats", "--json")
    stats = json.loads(result.stdout)
    assert stats["rejected"] == 0 and set(stats["stations"]) == {"21H", "22H", "23H"}
    assert stats["stations"]["22H"]["sub PRM_WR"] == {"cmd": 1, "rsp": 1}
    inv = stats["stations"]["21H"]["INV_CTL"]
    assert inv["cmd"] > 1500 and inv["rsp"] == inv["cmd"]
    text = run("--pcap", str(capture), "--stats", "--station", "0x23").stdout
    assert text.splitlines()[0].split()[:4] == ["station", "command", "commands", "responses"]
    assert "23H      PRM_WR                   1         1" in text and "22H" not in text


@pytest.mark.parametrize("args", [
    ["--command", "FLY"], ["--from", "soon"], ["--from", "2s", "--to", "1s"], ["--station", "zz"],
])
def test_bad_filters_are_usage_errors(capture: Path, args: list[str]) -> None:
    assert run("--pcap", str(capture), *args).exit_code == 2


@pytest.mark.parametrize("args", [["--stats"], ["--command", "NOP"], ["--from", "1s"]])
def test_pcap_options_without_pcap_are_usage_errors(args: list[str]) -> None:
    assert run(*args, ET3_PRM_WR).exit_code == 2
