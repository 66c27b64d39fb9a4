"""``mlink-sim validate`` warns (exit 0) where a timeline check comes before the drive's ramp can meet it, naming the
parameter and a value that would do; ``up`` prints the same before it starts; the shipped examples and the first
scenario of docs/configuration.md (with the value the warning names) hold (docs/configuration.md, "Checks the
settings cannot meet")."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from mlink_sim.scenario.expectations import timeline_warnings
from mlink_sim.config import load_config, parse_config
from mlink_sim.examples import example_names

ROOT = Path(__file__).resolve().parents[2]
DOC = ROOT / "docs" / "configuration.md"


def _cli(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "mlink_sim", *args], capture_output=True, text=True, timeout=300,
                          cwd=ROOT, env=dict(os.environ))


def _docs_first_scenario() -> str:
    section = DOC.read_text(encoding="utf-8").split("## Your first scenario", 1)[1]
    return re.search(r"```toml\n(.*?)```", section, re.S).group(1)  # type: ignore[union-attr]


CONFIG = """
[network]
transmission_cycle = "2ms"

[[station]]
address = 0x22
card = "si-t-v7"
params = { "n003" = 3, "n004" = 9 }
load = { kind = "fan" }

[[timeline]]
at = "0s"
do = "run"
hz = 40.0

[[timeline]]
at = "2s"
expect = "speed-agree"

[[timeline]]
at = "8s"
do = "stop"

[[timeline]]
at = "10s"
expect = "stopped"
"""


def test_v7_warnings_name_n019_and_n020_with_values_that_would_do():
    lines = timeline_warnings(parse_config(CONFIG), "v7.toml")
    assert len(lines) == 2, lines
    assert lines[0].startswith("v7.toml: timeline[1] (2s station 22H: expect speed-agree): the output is within 2 Hz"
                               " of 40 Hz at 6.3 s at the earliest: n019 = 10.0 s (default) per n011 = 60.0 Hz "
                               "(default)")
    assert "set n019 = 2.8 or less, or check at 6.4 s or later" in lines[0]
    assert ("(10s station 22H: expect stopped): the output stops at 14.7 s on the drive model: n020 = 10.0 s "
            "(default) per n011 = 60.0 Hz (default)") in lines[1]
    assert "set n020 = 2.6 or less, or check at 14.8 s or later" in lines[1]


def test_a_stop_stall_prevention_stretches_on_an_inertia_load_names_coasting_and_coasting_holds(tmp_path):
    config = tmp_path / "inertia.toml"
    config.write_text(CONFIG.replace('card = "si-t-v7"\nparams = { "n003" = 3, "n004" = 9 }\nload = { kind = "fan" }',
                                     'card = "si-t3"\nparams = { "b1-01" = 3, "b1-02" = 3, "C1-01" = 1.0, '
                                     '"C1-02" = 1.0 }'))
    lines = timeline_warnings(load_config(config))
    assert len(lines) == 1, lines
    assert ": the output stops at 2" in lines[0] and "on the drive model: C1-02 = 1.0 s per E1-04" in lines[0]
    assert ("deceleration stall prevention, L3-04 = 1 (default), holds the ramp while the load's energy comes back "
            "into the DC bus (docs/drive-model.md section 5); set b1-03 = 1 (coast to stop), or check at") in lines[0]
    config.write_text(config.read_text().replace('"C1-02" = 1.0 }', '"C1-02" = 1.0, "b1-03" = 1 }'))
    assert timeline_warnings(load_config(config)) == []
    run = _cli("up", str(config), "--clock", "virtual", "--no-status")
    assert run.returncode == 0 and "all checks held" in run.stdout, run.stdout + run.stderr


def test_the_value_a_warning_names_for_a_v7_holds_on_the_virtual_clock(tmp_path):
    config = tmp_path / "v7.toml"
    config.write_text(CONFIG.replace('"n004" = 9 }', '"n004" = 9, "n019" = 2.8, "n020" = 2.6 }'))
    assert timeline_warnings(load_config(config)) == []
    run = _cli("up", str(config), "--clock", "virtual", "--no-status")
    assert run.returncode == 0 and "all checks held" in run.stdout, run.stdout + run.stderr


def test_a_run_the_drive_does_not_take_from_the_network_names_b1_02_and_b1_01():
    text = CONFIG.replace('card = "si-t-v7"\nparams = { "n003" = 3, "n004" = 9 }', 'card = "si-t3"')
    lines = timeline_warnings(parse_config(text))
    assert lines == [
        "station 22H: the timeline runs it, but b1-02 = 1 (default) takes the run command from elsewhere; set "
        "b1-02 = 3 (SI-T3 Table 4, SI-ET3 Table 7)",
        "station 22H: the timeline sets its speed, but b1-01 = 1 (default) takes the reference from elsewhere; set "
        "b1-01 = 3 (SI-T3 Table 4, SI-ET3 Table 7)"]


@pytest.mark.parametrize("name", example_names())
def test_the_shipped_examples_give_no_warning(name):
    assert timeline_warnings(load_config(name)) == []


def test_validate_and_up_warn_on_the_docs_first_scenario_and_its_fix_holds(tmp_path):
    config = tmp_path / "first.toml"
    config.write_text(_docs_first_scenario())
    validate = _cli("validate", str(config))
    assert validate.returncode == 0, validate.stdout + validate.stderr
    warnings = [line for line in validate.stdout.splitlines() if line.startswith("warning: ")]
    assert len(warnings) == 1 and "set C1-01 = 2.5 or less" in warnings[0], validate.stdout
    run = _cli("up", str(config), "--clock", "virtual", "--no-status")
    assert run.returncode == 1 and run.stderr.count(warnings[0]) == 1, run.stdout + run.stderr
    assert "— accelerating at C1-01 = 10.0 s (default)" in run.stdout
    value = re.search(r"set C1-01 = ([0-9.]+) or less", warnings[0]).group(1)  # type: ignore[union-attr]
    config.write_text(config.read_text().replace('"b1-02" = 3 }', f'"b1-02" = 3, "C1-01" = {value} }}'))
    assert not [line for line in _cli("validate", str(config)).stdout.splitlines() if line.startswith("warning")]
    fixed = _cli("up", str(config), "--clock", "virtual", "--no-status")
    assert fixed.returncode == 0 and "all checks held" in fixed.stdout, fixed.stdout + fixed.stderr


def test_a_set_param_step_before_the_run_that_sets_b1_02_counts():
    text = CONFIG.replace('card = "si-t-v7"\nparams = { "n003" = 3, "n004" = 9 }', 'card = "si-t3"\nparams = { "b1-01" = 3 }')
    text = text.replace('[[timeline]]\nat = "0s"\ndo = "run"', '[[timeline]]\nat = "0s"\ndo = "set-param"\nparam = "b1-02"\n'
                        'value = 3\n\n[[timeline]]\nat = "0.1s"\ndo = "run"')
    assert not [w for w in timeline_warnings(parse_config(text)) if "from elsewhere" in w]
