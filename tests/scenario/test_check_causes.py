"""A failed check of the drive says what the drive model was doing and why (``CheckResult.cause``, the FAIL line,
``checks[].cause`` in the report; docs/configuration.md "When a check fails"), on the virtual clock and with real
slave processes (their ``{"op": "drive"}`` control request)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

from mlink_sim.scenario.explain import explain
from mlink_sim.drive import Drive, DriveCommand, DriveSettings, Family, LoadSpec
from mlink_sim.drive.monitors import hz_to_ref
from mlink_sim.metrics import REPORT_SCHEMA
from mlink_sim.params import FAMILIES

ROOT = Path(__file__).resolve().parents[3]

#: The two cases a first config on the defaults runs into: 40 Hz expected 2 s after the run with C1-01 = 10 s,
#: and a stop expected while deceleration stall prevention (L3-04 = 1) holds the DC bus of an inertia load.
DEFAULTS = """
[network]
transmission_cycle = "2ms"

[[station]]
address = 0x21
card = "si-t3"
params = { "b1-01" = 3, "b1-02" = 3 }

[[station]]
address = 0x03
card = "si-et3"
params = { "b1-01" = 3, "b1-02" = 3, "C1-01" = 2.0, "C1-02" = 1.0 }

[[timeline]]
at = "0s"
do = "run"
hz = 40.0

[[timeline]]
at = "2s"
station = 0x21
expect = "output-hz"
output_hz = 40.0

[[timeline]]
at = "3.5s"
station = 0x03
do = "stop"

[[timeline]]
at = "6s"
station = 0x03
expect = "stopped"
"""


def _up(config: Path, *args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "mlink_sim", "up", str(config), "--no-status", *args],
                          capture_output=True, text=True, timeout=300, cwd=ROOT, env=dict(os.environ))


def _fail_lines(out: str) -> dict[str, str]:
    return {line.split(":")[0].split("FAIL")[1].strip(): line for line in out.splitlines() if "FAIL" in line}


def test_failed_checks_on_the_defaults_name_the_ramp_and_the_stall_prevention_holding_the_bus(tmp_path):
    config, report = tmp_path / "first.toml", tmp_path / "report.json"
    config.write_text(DEFAULTS)
    run = _up(config, "--clock", "virtual", "--report", str(report))
    assert run.returncode == 1, run.stdout + run.stderr
    fails = _fail_lines(run.stdout)
    accel = fails["2s station 21H"]
    assert "— accelerating at C1-01 = 10.0 s (default) per E1-04 = 60.0 Hz (default): 11.4 of 40 Hz after 2.0 s" in accel
    assert "there at 6.9 s" in accel
    stop = fails["6s station 03H"]
    assert "— stopping at C1-02 = 1.0 s per E1-04 = 60.0 Hz (default)" in stop
    assert "held by deceleration stall prevention, L3-04 = 1 (default): DC bus 375 V, its level 375 V" in stop
    checks = {c["what"]: c for c in json.loads(report.read_text())["checks"]}
    assert checks["6s station 03H: expect stopped"]["cause"] in stop
    assert "cause" in REPORT_SCHEMA["$defs"]["check"]["properties"]


def test_a_failed_check_with_real_slave_processes_reads_the_cause_from_the_slave(tmp_path):
    config = tmp_path / "real.toml"
    config.write_text(DEFAULTS.split("[[station]]\naddress = 0x03")[0] + """
[[timeline]]
at = "0s"
do = "run"
hz = 40.0

[[timeline]]
at = "1s"
expect = "output-hz"
output_hz = 40.0
""")
    run = _up(config, "--no-realtime")
    assert run.returncode == 1, run.stdout + run.stderr
    line = _fail_lines(run.stdout)["1s station 21H"]
    assert "— accelerating at C1-01 = 10.0 s (default) per E1-04 = 60.0 Hz (default)" in line, line


def test_explain_names_a_run_command_the_drive_does_not_take_and_what_to_set():
    s = DriveSettings.from_defaults(Family.A1000)
    d = Drive(Family.A1000, s, LoadSpec())
    d.command(DriveCommand(forward=True, freq_ref_raw=hz_to_ref(s, 40.0)), 0)
    d.advance(1_000_000_000)
    text = explain(d.activity(), FAMILIES["a1000"].defaults(), 0.0)
    assert text.startswith("the drive does not take the network's run command: b1-02 = 1 (default); the run "
                           "command from the option needs b1-02 = 3 (SI-T3 Table 4, SI-ET3 Table 7)")


def test_explain_names_a_fault_and_when_it_came_from_the_timelines_zero():
    s = DriveSettings.from_defaults(Family.V7, {"n003": 3, "n004": 9})
    d = Drive(Family.V7, s, LoadSpec())
    d.command(DriveCommand(external_fault=True), 7_200_000_000)
    assert "alarm EF0 since 5.20 s (coast stop)" in explain(d.activity(), FAMILIES["v7"].defaults(), 2.0)


LIMITS = """
[network]
transmission_cycle = "2ms"

[[station]]
address = 0x21
card = "si-t3"
params = { "b1-01" = 3, "b1-02" = 3, "C1-01" = 2.0, "C1-02" = 0.5, "L3-04" = 0 }

[[station]]
address = 0x22
card = "si-t3"
params = { "b1-01" = 3, "b1-02" = 3, "C1-01" = 0.1 }
load = { kind = "inertia", inertia = 0.5 }

[[station]]
address = 0x23
card = "si-t-v7"
params = { "n003" = 3, "n004" = 9, "n019" = 0.1 }
load = { kind = "inertia", inertia = 0.5 }

[[timeline]]
at = "0s"
do = "run"
hz = 40.0

[[timeline]]
at = "0.5s"
station = 0x22
expect = "output-hz"
output_hz = 40.0

[[timeline]]
at = "0.5s"
station = 0x23
expect = "speed-agree"

[[timeline]]
at = "3s"
station = 0x21
do = "stop"

[[timeline]]
at = "5s"
station = 0x21
expect = "no-alarm"
"""


def test_failed_checks_name_the_current_limit_and_an_ov_trip_with_its_time(tmp_path):
    config = tmp_path / "limits.toml"
    config.write_text(LIMITS)
    run = _up(config, "--clock", "virtual")
    assert run.returncode == 1, run.stdout + run.stderr
    fails = _fail_lines(run.stdout)
    assert ("(the ramp alone: 40.0 Hz); held by acceleration stall prevention, L3-01 = 1 (default): output current "
            in fails["0.5s station 22H"])
    assert "A, its level L3-02 = 150% (default) of the drive's rated current (39.9 A)" in fails["0.5s station 22H"]
    assert ("held by acceleration stall prevention, n093 = 170% (default) of the drive's rated current: output "
            "current" in fails["0.5s station 23H"])
    assert fails["5s station 21H"].endswith("— alarm ov since 3.14 s (coast stop)")


def test_a_cause_names_the_value_a_set_param_step_wrote_not_the_default(tmp_path):
    config = tmp_path / "set.toml"
    config.write_text(DEFAULTS.split("[[station]]\naddress = 0x03")[0] + """
[[timeline]]
at = "0s"
do = "set-param"
param = "C1-01"
value = 8.0

[[timeline]]
at = "0.5s"
do = "run"
hz = 40.0

[[timeline]]
at = "2s"
expect = "output-hz"
output_hz = 40.0
""")
    run = _up(config, "--clock", "virtual")
    assert run.returncode == 1, run.stdout + run.stderr
    assert "— accelerating at C1-01 = 8.0 s per E1-04 = 60.0 Hz (default): " in _fail_lines(run.stdout)["2s station 21H"]
