"""One command line: every command spells an address ``ADDR``, an endpoint ``HOST:PORT``, a time ``DURATION``, a
card ``CARD`` and a link as the config does (``ML1|ML2|ML3``, any case); the top-level help gives one whole line per
command and examples; ``examples`` lists and copies the shipped examples."""

from __future__ import annotations

from pathlib import Path

import click
import pytest
from click.testing import CliRunner

from mlink_sim.cli import SHORT_HELP, _register_optional, cli
from mlink_sim.examples import example_names, example_path

_register_optional()

#: option/argument name -> the metavar it must show
ADDRESSES = {"station": "ADDR", "station_text": "ADDR", "stations": "ADDR", "target": "HOST:PORT",
             "listen": "HOST:PORT", "listens": "HOST:PORT", "address": "HOST:PORT", "control": "HOST:PORT"}
DURATIONS = {"duration", "bringup_timeout", "stall_bound", "timeout", "grace"}


def _commands() -> list[tuple[str, click.Command]]:
    out = []
    for name, cmd in sorted(cli.commands.items()):
        out.append((name, cmd))
        if isinstance(cmd, click.Group):
            out += [(f"{name} {sub}", c) for sub, c in sorted(cmd.commands.items())]
    return out


@pytest.mark.parametrize(("name", "cmd"), _commands(), ids=[n for n, _ in _commands()])
def test_every_option_follows_the_metavar_conventions(name: str, cmd: click.Command) -> None:
    ctx = click.Context(cmd, info_name=name)
    for param in cmd.params:
        metavar = param.make_metavar(ctx)
        if param.name in ADDRESSES and name != "decode":
            assert ADDRESSES[param.name] in metavar, (name, param.name, metavar)
        if param.name in DURATIONS:
            assert metavar == "DURATION", (name, param.name, metavar)
        if param.name == "link_name":
            assert metavar == "[ML1|ML2|ML3]", (name, metavar)
        if param.name == "card":
            assert metavar == "CARD", (name, metavar)
        assert metavar != "TEXT" or param.name not in (*ADDRESSES, *DURATIONS), (name, param.name)
        if param.name == "endpoints":
            assert metavar == "ADDR=HOST:PORT"


def test_values_are_spelled_as_in_the_config_in_any_case() -> None:
    runner = CliRunner()
    for link in ("ml1", "ML1", "Ml1"):
        r = runner.invoke(cli, ["probe", "127.0.0.1:9", "--station", "21H", "--link", link, "--frame-size", "64"])
        assert r.exit_code == 2 and "ML1 has no 64-byte frames" in r.output, r.output
    r = runner.invoke(cli, ["slave", "--card", "SI-T3", "--station", "0x21", "--link", "ml3"])
    assert r.exit_code == 2 and "--link ML3: si-t3 speaks" in r.output + (r.stderr or ""), r.output
    r = runner.invoke(cli, ["probe", "127.0.0.1:9", "--station", "fish"])
    assert r.exit_code == 2 and "expected a station address such as 0x21 or 21H" in r.output
    r = runner.invoke(cli, ["up", "quickstart", "--duration", "soon"])
    assert r.exit_code == 2 and "expected a duration such as" in r.output


def test_top_level_help_has_a_whole_line_per_command_and_examples() -> None:
    r = CliRunner().invoke(cli, ["--help"], terminal_width=120)
    assert r.exit_code == 0
    assert set(SHORT_HELP) == set(cli.commands)
    for name, text in SHORT_HELP.items():
        assert f"{name:<10} {text}" in r.output or text in r.output, name
        assert "..." not in text and text.endswith((".", "…)"))
    assert r.output.count("  mlink-sim ") >= 3 and "Examples:" in r.output


def test_up_help_explains_the_status_columns() -> None:
    out = CliRunner().invoke(cli, ["up", "--help"], terminal_width=120).output
    for term in ("P3 connected and synchronous", "ok: no alarm", "stalls: host stalls", "missed: cycles",
                 "--no-timeline", "--no-realtime"):
        assert term in out, term


def test_examples_lists_every_shipped_example_with_its_description() -> None:
    r = CliRunner().invoke(cli, ["examples"])
    assert r.exit_code == 0
    lines = r.output.splitlines()
    assert [line.split()[0] for line in lines] == example_names()
    quick = next(line for line in lines if line.startswith("quickstart"))
    assert "one station of each card behind one master" in quick


def test_examples_copy_writes_once_and_refuses_to_overwrite(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    runner = CliRunner()
    r = runner.invoke(cli, ["examples", "copy", "quickstart", str(tmp_path)])
    target = tmp_path / "quickstart.toml"
    assert r.exit_code == 0 and target.read_bytes() == example_path("quickstart").read_bytes()  # type: ignore[union-attr]
    target.write_text("# mine\n")
    r = runner.invoke(cli, ["examples", "copy", "quickstart", str(target)])
    assert r.exit_code == 2 and "exists; add --force" in r.output and target.read_text() == "# mine\n"
    r = runner.invoke(cli, ["examples", "copy", "quickstart", str(target), "--force"])
    assert r.exit_code == 0 and target.read_bytes() == example_path("quickstart").read_bytes()  # type: ignore[union-attr]
    r = runner.invoke(cli, ["examples", "copy", "nosuch", str(tmp_path / "x.toml")])
    assert r.exit_code == 2 and "no such example" in r.output and "quickstart" in r.output
    monkeypatch.chdir(tmp_path)
    r = runner.invoke(cli, ["examples", "copy", "ml3-62-max"])
    assert r.exit_code == 0 and (tmp_path / "ml3-62-max.toml").is_file()
