"""Faults from the timeline and the plugin (docs/faults.md): config validation with clear messages (exit 2), and
the shipped fault examples passing on the virtual clock, recovery assertable in the report."""

from __future__ import annotations

from pathlib import Path

import pytest
from click.testing import CliRunner

from mlink_sim.aio.run.embed import VirtualNetwork
from mlink_sim.cli.network import up_cmd
from mlink_sim.config import ConfigError, parse_config
from mlink_sim.metrics import check_all, parse_assertion
from mlink_sim.testing.virtual import VirtualRunningNetwork

HEAD = """
[network]
transmission_cycle = "2ms"
[[station]]
address = 0x21
card = "si-t3"
[[station]]
address = 0x22
card = "si-t-v7"
[[station]]
address = 0x23
card = "si-et3"
load = { kind = "fan" }
"""


def step(body: str) -> str:
    return HEAD + '[[timeline]]\nat = "1s"\n' + body + "\n"


@pytest.mark.parametrize(("body", "message"), [
    ('do = "silence"', 'for: required'),
    ('do = "silence"\nfor = "-2ms"', "expected a duration"),
    ('do = "skip-cycles"', "count: required"),
    ('do = "skip-cycles"\ncount = 0', "count: expected a whole number of transmission cycles"),
    ('do = "skip-cycles"\ncount = 2\nfor = "1s"', "for: do = \"skip-cycles\" does not take it (it takes count)"),
    ('do = "freeze-wdt"', "for: required"),
    ('do = "bad-command"', "kind: required, one of 'phase', 'combination', 'data-size'"),
    ('do = "bad-command"\nkind = "size"', "kind: expected one of"),
    ('station = 0x21\ndo = "bad-command"\nkind = "combination"', "subcmd = false"),
    ('station = 0x22\ndo = "bad-command"\nkind = "data-size"\n', None),  # V7 32-byte: sub-commands by default
    ('do = "load"', "give torque"),
    ('do = "load"\ntorque = -1.0', "torque: expected a number of N·m of 0 or more"),
    ('station = 0x23\ndo = "load"\ntorque = 2.0', "fan load"),
    ('station = 0x23\ndo = "load"\ninertia = 0.1', None),
    ('do = "mains-loss"', "for: required"),
    ('do = "lock-rotor"', None),
    ('do = "run"\nhz = 10.0\ncount = 3', "count: 'do = \"run\"' does not take it (it takes hz, direction)"),
    ('expect = "recovered"', "needs within"),
    ('expect = "no-alarm"\nwithin = "5ms"', 'within: only expect = "recovered"'),
    ('expect = "refused"\nalarm = "A.94"', "expected an alarm name"),
])
def test_fault_steps_are_validated_with_clear_messages(body, message):
    if message is None:
        parse_config(step(body))
        return
    with pytest.raises(ConfigError) as exc:
        parse_config(step(body))
    assert message in str(exc.value) and "timeline[0]" in str(exc.value)


def test_a_bad_fault_step_is_exit_2_from_up(tmp_path: Path):
    path = tmp_path / "bad.toml"
    path.write_text(step('do = "skip-cycles"\ncount = -1'))
    result = CliRunner().invoke(up_cmd, [str(path)])
    assert result.exit_code == 2, result.output
    assert "count: expected a whole number" in result.output and "Traceback" not in result.output


def test_run_length_covers_the_faults_and_the_recovery_checks():
    config = parse_config(step('do = "silence"\nfor = "2s"') + '[[timeline]]\nat = "3s"\nexpect = "recovered"\n'
                          'within = "1.5s"\n')
    assert config.run_length_ns == 5_500_000_000


@pytest.mark.parametrize("name", ["faults-station", "faults-master", "faults-drive"])
def test_fault_examples_pass_on_the_virtual_clock(name):
    with VirtualNetwork(name, seed=1) as net:
        results = net.run_timeline()
        report = net.close()
    failed = [f"{r.what}: {r.detail}" for r in results if not r.ok]
    assert not failed, failed
    assert results
    stations = report["station"]
    assert all(s["recovery"]["count"] >= 1 for s in stations.values())
    checks = check_all([parse_assertion("station[*].recovery.max < 500ms"),
                        parse_assertion("station[*].unrecovered == 0")], report)
    assert all(c.ok for c in checks), [c.message for c in checks]


def test_plugin_methods_on_the_virtual_clock():
    with VirtualRunningNetwork("faults-master", seed=2) as net:
        ep = net.skip_cycles(0x21, count=2)
        assert ep.station == 0x21 and ep.what == "skip-cycles count=2"
        net.wait(0.1)
        assert net.fault_episode(0x21).recovery_ns < 50_000_000
        net.bad_command(0x23, "data-size")
        net.wait(0.05)
        assert any("INVALID_DATA" in n for n in net.fault_episode(0x23).notes)
        net.run(0x22, hz=20)
        net.wait(1.5)
        net.mains_loss(0x22, for_="100ms")  # running: Uv1, latched
        net.wait(0.3)
        assert net.view(0x22).alarm_name in ("UV1", "Uv1")
        with pytest.raises(ValueError, match="count: expected a whole number"):
            net.skip_cycles(0x21, count=0)
        net.check("station[0x21].recovery.count >= 1", "station[0x21].injected.skips == 2",
                  "station[0x22].injected.drive_faults == 1")


def test_control_requests_inject_faults_into_a_running_network():
    """``{"op": "fault"}`` / ``{"op": "recovery"}`` on the control endpoint of a running ``up`` (aio/control/faults.py):
    the same faults as the timeline, a repeated request (same ``id``) injected once, bad values refused."""
    import asyncio
    import json

    from mlink_sim.aio.control.endpoint import ControlServer
    from mlink_sim.operations import parse_fault_text

    assert parse_fault_text("load,torque=5,for=1s") == ("load", {"torque": 5, "for": "1s"})
    with VirtualNetwork("faults-master", seed=3) as net:
        server = ControlServer(net.ops.handlers(), "network")

        def ask(**request):
            async def go():
                reply = server.handle(json.dumps(request).encode())
                if isinstance(reply, asyncio.Future):
                    reply = await reply
                return reply
            return net.call(go())

        reply = ask(op="fault", station="0x21", spec="skip-cycles,count=2", id="a")
        assert reply["ok"] and reply["fault"] == {"do": "skip-cycles", "count": 2}
        assert ask(op="fault", station="0x21", spec="skip-cycles,count=2", id="a") == reply
        net.advance(0.1)
        episodes = ask(op="recovery", station="0x21")["episodes"]
        assert episodes["0x21"]["what"] == "skip-cycles count=2" and episodes["0x21"]["recovery_ns"] < 50_000_000
        assert net.report()["station"]["0x21"]["injected"]["skips"] == 2
        bad = ask(op="fault", station="0x21", spec="skip-cycles,count=0")
        assert not bad["ok"] and "count: expected a whole number" in bad["error"]
        unknown = ask(op="fault", station="0x99", spec="silence,for=1s")
        assert not unknown["ok"] and unknown["kind"] == "unknown_station"


def test_mlink_sim_control_fault_checks_the_spec_before_sending():
    from mlink_sim.cli.control import control_cmd

    for spec, why in (("silence", "for: required"), ("warp,for=1s", "do: expected one of"),
                      ("silence,200ms", "expected NAME=VALUE")):
        result = CliRunner().invoke(control_cmd, ["127.0.0.1:9", "fault", "0x21", spec])
        assert result.exit_code == 2 and why in result.output, result.output
