"""benchmarks.reply: every command of a card's round in a NOP stream (the round against the card core, and one short
run of a standalone slave beside the echo: a smoke test of the run and its output; the figures are the benchmark's,
not the test's)."""

from __future__ import annotations

import json
import subprocess

import pytest

from benchmarks.common import ROOT, child_env, module_command
from benchmarks.reply import CASES, _ADDRESS, _Templates, round_of
from mlink_sim.cards import create_card, settings_for
from mlink_sim.wire import Kind, decode
from mlink_sim.wire.frame import CYCLE_AT, patch_seal


@pytest.mark.parametrize("name", list(CASES))
def test_every_command_of_a_round_is_taken_in_its_phase(name: str) -> None:
    """Two rounds against the card core, a NOP between two commands: CONNECT brings the card up, SYNC_SET to phase 3,
    DISCONNECT back to phase 1; no command of the second round is refused for its phase or its data (SI-ET3 CMD_ALM,
    SI-T3 ALARM A.94/A.95), but the SI-T/V7's main PRM_RD/PRM_WR in 32-byte mode (sub-commands only, §7.1)."""
    case = CASES[name]
    st = create_card(case.card, settings=settings_for(case.card, _ADDRESS[case.card], case.size, []), now=0)
    kinds = round_of(case)
    tpl = _Templates(case, kinds)
    refused, k, now, echo = [], 0, 0, 0
    for rnd in range(2):
        for i, kind in enumerate(kinds):
            for body, what in ((tpl.nop, "NOP"), (tpl.kinds[i], kind.name)):
                k += 1
                now += case.cycle_ns
                answer = st.receive(patch_seal(body, CYCLE_AT, k, tpl.wdt_at, (k & 0xF) << 4 | echo), ("m", 1), now)
                st.finish()
                assert answer is not None, what
                echo = answer[tpl.rwdt_at] & 0xF
                msg = decode(answer, kind=Kind.RESPONSE).message
                bad = (msg.stat.cmd_alm or (msg.substat is not None and msg.substat.subcmd_alm)
                       if case.card == "si-et3" else msg.alarm)
                if bad and rnd == 1:
                    refused.append(what)
            if kind.name == "SYNC_SET":
                assert st.phase == 3
    assert st.phase == 1
    assert refused == (["PRM_RD", "PRM_WR"] if name == "si-t-v7:32" else [])


@pytest.mark.e2e
def test_a_short_run_measures_the_echo_and_the_slave(tmp_path) -> None:
    out = tmp_path / "reply.json"
    r = subprocess.run(module_command("benchmarks.reply", "--cases", "si-t3:17", "--duration", "1s", "--every", "4",
                                      "--realtime", "off", "--json", str(out)),
                       capture_output=True, text=True, timeout=180, cwd=ROOT, env=child_env())
    assert r.returncode == 0, r.stdout + r.stderr
    (result,) = json.loads(out.read_text())["results"]
    assert (result["case"], result["cycle_ns"], result["realtime"]) == ("si-t3:17", 500_000, False)
    assert result["echo"]["NOP"]["sent"] > 0
    assert {"NOP", "CONNECT", "DISCONNECT", "CONFIG(EEPROM)"} <= set(result["slave"])
    assert all(f["sent"] > 0 for f in result["slave"].values())
    assert "si-t3:17 at 500us" in r.stdout


def test_an_unknown_case_is_a_usage_error() -> None:
    r = subprocess.run(module_command("benchmarks.reply", "--cases", "si-t3:64"), capture_output=True, text=True,
                       timeout=60, cwd=ROOT, env=child_env())
    assert r.returncode == 2 and "unknown case" in r.stderr
