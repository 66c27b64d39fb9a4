"""A fifth card is its module and one profile record (tests/cards/fifth_card.py, registered in the test's process):
``mlink-sim validate`` reads it, ``mlink-sim slave`` serves it (a NOP probe answers) and ``mlink-sim up --clock
virtual`` brings it up and runs it, each by what the record says, without a change to any module of the package
(docs/architecture.md, "Card profiles")."""

from __future__ import annotations

import csv
import json
import signal
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest
from click.testing import CliRunner

from mlink_sim.cards import create_card, settings_for
from mlink_sim.cli import _register_optional, cli, network
from mlink_sim.profiles import CardProfile, lookup

from .fifth_card import registered

_register_optional()

HERE = Path(__file__).resolve().parent
CARD_CLI = HERE / "fifth_card_cli.py"

CONFIG = """
[network]
transmission_cycle = "2ms"

[[station]]
address = 0x22
card = "si-t3-lab"
params = { "b1-01" = 3, "b1-02" = 3, "C1-01" = 1.0, "C1-02" = 1.0 }
{extra}
[[timeline]]
at = "0.1s"
do = "run"
hz = 20.0

[[timeline]]
at = "2s"
expect = "output-hz"
output_hz = 20.0
"""


@pytest.fixture
def card() -> Iterator[CardProfile]:
    with registered() as profile:
        yield profile


def _config(tmp_path: Path, extra: str = "") -> str:
    path = tmp_path / "lab.toml"
    path.write_text(CONFIG.replace("{extra}", extra), encoding="utf-8")
    return str(path)


def test_without_its_record_the_card_is_unknown(tmp_path: Path) -> None:
    result = CliRunner().invoke(cli, ["validate", _config(tmp_path)])
    assert result.exit_code == 2 and "unknown option card 'si-t3-lab'" in result.output, result.output


def test_registered_it_is_looked_up_and_created_in_any_spelling(card: CardProfile) -> None:
    assert lookup("SI-T3/LAB") is card and lookup("sit3lab") is card
    station = create_card("SI-T3/LAB", settings=settings_for("si-t3-lab", 0x22, None, []), now=0)
    assert (station.card, station.label, station.address, station.data_size) == ("si-t3-lab", "SI-T3/LAB", 0x22, 32)
    assert station.snapshot().card == "si-t3-lab"


def test_the_config_schema_and_the_card_option_list_it(card: CardProfile) -> None:
    from mlink_sim.config import StationConfig

    assert "si-t3-lab" in StationConfig.model_json_schema()["properties"]["card"]["enum"]
    assert "si-t3-lab" in CliRunner().invoke(cli, ["slave", "--card", "nope", "--station", "22H"]).output


def test_validate_reads_its_links_and_addresses_from_the_record(card: CardProfile, tmp_path: Path) -> None:
    runner = CliRunner()
    result = runner.invoke(cli, ["validate", _config(tmp_path)])
    assert result.exit_code == 0, result.output
    assert "22H SI-T3/LAB MECHATROLINK-II   32-byte" in result.output
    result = runner.invoke(cli, ["validate", _config(tmp_path, 'link = "ML1"')])
    assert result.exit_code == 2 and "si-t3-lab speaks MECHATROLINK-II, not MECHATROLINK-I" in result.output
    config = Path(_config(tmp_path))
    config.write_text(config.read_text().replace("address = 0x22", "address = 0x30"))
    result = runner.invoke(cli, ["validate", str(config)])
    assert result.exit_code == 2 and "outside si-t3-lab's range 21H–2FH" in result.output, result.output


def test_up_on_the_virtual_clock_brings_it_up_and_runs_it(card: CardProfile, tmp_path: Path,
                                                          monkeypatch: pytest.MonkeyPatch) -> None:
    # in this process, the command's structlog set-up would hold for the tests after it (their caplog): left out
    monkeypatch.setattr(network, "configure_logging", lambda **_: None)
    report, trace = tmp_path / "report.json", tmp_path / "trace.csv"
    result = CliRunner().invoke(cli, ["up", _config(tmp_path), "--clock", "virtual", "--no-status",
                                      "--report", str(report), "--trace", str(trace)])
    assert result.exit_code == 0, result.output
    assert "all checks held" in result.output and "ok   2s station 22H: expect output-hz" in result.output
    assert json.loads(report.read_text())["station"]["0x22"]["answered"] > 0
    rows = list(csv.DictReader(trace.read_text().splitlines()))
    samples = [row for row in rows if row["kind"] == "sample"]
    assert samples and {row["card"] for row in samples} == {"si-t3-lab"}
    assert samples[-1]["phase"] == "3"


def test_a_slave_process_that_registers_it_serves_it(tmp_path: Path) -> None:
    proc = subprocess.Popen([sys.executable, str(CARD_CLI), "slave", "--card", "SI-T3/LAB", "--station", "22H",
                             "--listen", "127.0.0.1:0", "--control", "off", "--ready-json"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert proc.stdout is not None
        line = proc.stdout.readline()
        assert line, proc.stderr.read() if proc.stderr else ""
        ready = json.loads(line)["stations"][0]
        assert (ready["card"], ready["link"], ready["frame_size"]) == ("si-t3-lab", "ML2", 32)
        probe = subprocess.run([sys.executable, "-m", "mlink_sim", "probe", f"127.0.0.1:{ready['port']}",
                                "--station", "22H", "--link", "ML2", "--frame-size", "32"],
                               capture_output=True, text=True, timeout=60)
        assert probe.returncode == 0 and "station 22H at 127.0.0.1:" in probe.stdout, probe.stdout + probe.stderr
    finally:
        proc.send_signal(signal.SIGTERM)
        try:
            proc.wait(10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
    assert proc.returncode == 128 + signal.SIGTERM
    refused = subprocess.run([sys.executable, str(CARD_CLI), "slave", "--card", "si-t3-lab", "--station", "22H",
                              "--link", "ML1"], capture_output=True, text=True, timeout=60)
    assert refused.returncode == 2 and "--link ML1: si-t3-lab speaks MECHATROLINK-II" in refused.stderr, refused.stderr
