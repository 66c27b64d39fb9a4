"""``mlink-sim compose --stack``: a Docker Swarm stack that means what docs/testbeds.md ("More than one machine")
says – one service per slave worker on the hosts' network, placed by node label, real-time rights, the cheap
probe, the master with every endpoint – and that ``docker stack config -c`` accepts."""

from __future__ import annotations

import os
import shutil
import subprocess
from pathlib import Path

import pytest
import yaml
from click.testing import CliRunner

from mlink_sim.cli.compose import compose_cmd
from mlink_sim.config import load_config, parse_config
from mlink_sim.testbed.placement import plan
from mlink_sim.testbed.stack import DEFAULT_RTPRIO, render_stack, stack_document

REPO = Path(__file__).resolve().parents[2]
QUICKSTART = REPO / "configs" / "quickstart.toml"

TWO_NODES = """
[network]
name = "two"
transmission_cycle = "2ms"

[deploy]
nodes = { plc = "192.0.2.1", rack-b = "192.0.2.2" }
master = { node = "plc", cpus = "1" }

[[deploy.worker]]
stations = [0x21, 0x22]
node = "rack-b"
cpus = [0, 1]

[[station]]
address = 0x21
card = "si-t3"

[[station]]
address = 0x22
card = "si-t3"

[[station]]
address = 0x23
card = "si-et3"
node = "plc"
cpus = "0"
"""


def two_nodes():
    return parse_config(TWO_NODES, "two.toml")


def _command(service):
    return service["command"]


def _after(argv, flag):
    return [argv[i + 1] for i, a in enumerate(argv) if a == flag]


def test_one_service_per_worker_on_the_hosts_network_placed_by_node_label():
    doc = stack_document(two_nodes())
    assert list(doc["services"]) == ["worker-0", "station-23", "master"]
    assert doc["networks"] == {"hostnet": {"external": True, "name": "host"}}
    worker, station, master = (doc["services"][n] for n in ("worker-0", "station-23", "master"))
    assert worker["deploy"]["placement"] == {"constraints": ["node.labels.mlink.node == rack-b"]}
    assert station["deploy"]["placement"] == {"constraints": ["node.labels.mlink.node == plc"]}
    assert master["deploy"]["placement"] == {"constraints": ["node.labels.mlink.node == plc"]}
    for service in (worker, station, master):
        assert service["networks"] == ["hostnet"]
        assert "ports" not in service  # the host's own ports: no routing mesh


def test_a_worker_serves_its_stations_on_ports_of_its_node_and_allows_only_the_masters_address():
    doc = stack_document(two_nodes(), station_port=47100)
    worker = _command(doc["services"]["worker-0"])
    assert worker[:5] == ["slave", "--config", "/config/network.toml", "--only", "0x21,0x22"]
    assert _after(worker, "--endpoint") == ["0x21=0.0.0.0:47100", "0x22=0.0.0.0:47101"]
    assert _after(worker, "--allow-master") == ["192.0.2.1"]  # the master's node, as seen from rack-b
    assert _after(worker, "--cpus") == ["0,1"] and "--realtime" in worker  # pinned: a service has no cpuset
    station = _command(doc["services"]["station-23"])
    assert _after(station, "--endpoint") == ["0x23=0.0.0.0:47102"]
    assert _after(station, "--allow-master") == ["127.0.0.1"]  # beside the master
    master = _command(doc["services"]["master"])
    assert _after(master, "--endpoint") == ["0x21=192.0.2.2:47100", "0x22=192.0.2.2:47101", "0x23=127.0.0.1:47102"]
    assert _after(master, "--cpus") == ["1"] and _after(master, "--report") == ["/reports/report.json"]


def test_every_service_may_ask_for_real_time_and_the_rtprio_ulimit_is_optional():
    doc = stack_document(two_nodes())
    for service in doc["services"].values():
        assert service["cap_add"] == ["SYS_NICE", "IPC_LOCK"] and service["user"] == "0:0"
        assert service["ulimits"] == {"rtprio": DEFAULT_RTPRIO}
    doc = stack_document(two_nodes(), rtprio=0)
    assert all("ulimits" not in s for s in doc["services"].values())
    with pytest.raises(ValueError, match="rtprio"):
        stack_document(two_nodes(), rtprio=100)


def test_workers_are_probed_with_the_cheap_probe_and_the_master_runs_once():
    doc = stack_document(two_nodes())
    test = doc["services"]["worker-0"]["healthcheck"]["test"]
    assert test[:3] == ["CMD", "mlink-health", "127.0.0.1:47001"] and test[3:5] == ["--station", "0x21"]
    master = doc["services"]["master"]
    assert master["deploy"]["restart_policy"] == {"condition": "none"}
    assert master["healthcheck"] == {"disable": True}
    assert _after(master["command"], "--bringup-timeout") == ["60s"]  # no depends_on in a swarm
    assert doc["volumes"] == {"reports": {}}


def test_the_config_is_a_swarm_config_named_after_its_content(tmp_path):
    path = tmp_path / "net.toml"
    path.write_text(QUICKSTART.read_text(encoding="utf-8"), encoding="utf-8")
    config = load_config(path)
    first = yaml.safe_load(render_stack(config, path, tmp_path / "stack.yaml"))
    assert first["configs"]["network"]["file"] == "./net.toml"
    for service in first["services"].values():
        assert service["configs"] == [{"source": "network", "target": "/config/network.toml", "mode": 0o444}]
    path.write_text(path.read_text(encoding="utf-8") + "\n# changed\n", encoding="utf-8")
    second = yaml.safe_load(render_stack(config, path, tmp_path / "stack.yaml"))
    assert first["configs"]["network"]["name"] != second["configs"]["network"]["name"]  # swarm configs are immutable


def test_unplaced_config_runs_everything_on_a_manager_at_loopback():
    config = load_config(QUICKSTART)
    doc = stack_document(config)
    assert [n for n in doc["services"]] == ["station-21", "station-22", "station-23", "master"]
    for service in doc["services"].values():
        assert service["deploy"]["placement"] == {"constraints": ["node.role == manager"]}
    assert all(e.split("=")[1].startswith("127.0.0.1:") for e in _after(doc["services"]["master"]["command"],
                                                                        "--endpoint"))


def test_without_the_master_service_the_header_gives_its_command(tmp_path):
    text = render_stack(load_config(QUICKSTART), QUICKSTART, tmp_path / "s.yaml", master_service=False)
    assert "master" not in yaml.safe_load(text)["services"]
    assert "#   mlink-sim master " in text and "--endpoint 0x21=127.0.0.1:47001" in text


def test_ports_beyond_65535_are_a_clear_error():
    with pytest.raises(ValueError, match="beyond 65535"):
        plan(two_nodes(), 65534)


def test_cli_writes_the_stack_and_refuses_options_that_do_not_apply(tmp_path):
    runner = CliRunner()
    out = tmp_path / "stack.yaml"
    r = runner.invoke(compose_cmd, [str(QUICKSTART), "--stack", "-o", str(out), "--rtprio", "0", "--project", "qs"])
    assert r.exit_code == 0, r.output
    doc = yaml.safe_load(out.read_text(encoding="utf-8"))
    assert doc["configs"]["network"]["name"].startswith("qs-network-")
    assert "--stack --rtprio 0 --project qs" in out.read_text(encoding="utf-8").splitlines()[0]
    for args, message in ((["--stack", "--k8s", "-o", str(tmp_path / "d")], "choose one"),
                          (["--stack", "--start-interval"], "--start-interval does not apply"),
                          (["--rtprio", "0"], "--rtprio does not apply"),
                          (["--k8s"], "give the directory with -o DIR"),
                          (["--stack", "--project", "Bad_Name"], "--project 'Bad_Name'")):
        r = runner.invoke(compose_cmd, [str(QUICKSTART), *args])
        assert r.exit_code == 2 and message in r.output, (args, r.output)


def _docker_stack_config(path: Path) -> subprocess.CompletedProcess[str]:
    docker = shutil.which("docker")
    if docker is None:
        if os.environ.get("CI", "").lower() == "true":
            pytest.fail("the docker CLI is missing in CI (apt-get install -y docker.io)")
        pytest.skip("the docker CLI is not installed (apt-get install -y docker.io)")
    result = subprocess.run([docker, "stack", "config", "-c", str(path)], capture_output=True, text=True, timeout=60)
    if result.returncode != 0 and "unknown command" in (result.stderr + result.stdout):
        if os.environ.get("CI", "").lower() == "true":
            pytest.fail(f"this docker CLI has no `docker stack config`: {result.stderr.strip()}")
        pytest.skip("this docker CLI has no `docker stack config` (Docker CLI 24 or later has)")
    return result


@pytest.mark.parametrize("which", ["quickstart", "two-nodes", "no-master"])
def test_docker_stack_config_accepts_the_file(tmp_path, which):
    """`docker stack config` needs no engine: it reads and checks the file as `docker stack deploy` does."""
    if which == "two-nodes":
        path = tmp_path / "two.toml"
        path.write_text(TWO_NODES, encoding="utf-8")
    else:
        path = QUICKSTART
    out = tmp_path / "stack.yaml"
    out.write_text(render_stack(load_config(path), path, out, master_service=which != "no-master"), encoding="utf-8")
    result = _docker_stack_config(out)
    assert result.returncode == 0, result.stderr
    parsed = yaml.safe_load(result.stdout)
    assert set(parsed["services"]) == set(yaml.safe_load(out.read_text(encoding="utf-8"))["services"])
    assert parsed["networks"]["hostnet"]["name"] == "host"
