"""``--capture`` / ``--capture-max`` on the commands: sizes, and a file that cannot be written is exit 2."""

from __future__ import annotations

from pathlib import Path

import pytest
from click.testing import CliRunner

from mlink_sim.cli.capture_opts import parse_size
from mlink_sim.cli.network import master_cmd, up_cmd
from mlink_sim.cli.slave import slave_cmd


def test_parse_size() -> None:
    assert parse_size("100MB") == 100_000_000
    assert parse_size("512KiB") == 512 * 1024
    assert parse_size("2.5 GB") == 2_500_000_000
    assert parse_size("8192") == 8192
    for bad in ("lots", "10 parsecs", "-5MB", "100"):
        with pytest.raises(ValueError):
            parse_size(bad)


def test_capture_max_is_checked_before_anything_starts(tmp_path: Path) -> None:
    result = CliRunner().invoke(slave_cmd, ["--card", "si-t3", "--station", "0x21", "--capture",
                                            str(tmp_path / "c.pcapng"), "--capture-max", "10"])
    assert result.exit_code == 2 and "at least 4096 bytes" in result.output


@pytest.mark.parametrize("cmd", ["slave", "up", "master"])
def test_unwritable_capture_is_exit_2_in_one_line(tmp_path: Path, cmd: str) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("x")
    target = str(blocker / "c.pcapng")  # a directory that is a file
    config = str(Path(__file__).resolve().parents[1] / "capture" / "one_station.toml")
    args = {"slave": (slave_cmd, ["--card", "si-t3", "--station", "0x21", "--capture", target]),
            "up": (up_cmd, [config, "--capture", target]),
            "master": (master_cmd, [config, "--endpoint", "0x21=127.0.0.1:9", "--capture", target])}[cmd]
    result = CliRunner().invoke(args[0], args[1])
    assert result.exit_code == 2, result.output
    assert f"mlink-sim {cmd}: cannot write the capture {target}" in result.output
    assert "Traceback" not in result.output
