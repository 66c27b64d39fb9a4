"""scripts/docker-base, docker-build, docker-testbed, swarm-testbed: usage errors and a missing engine are one line and exit 2,
before anything is built or started (the runs themselves need a Docker engine: .ci/run does them)."""

from __future__ import annotations

import os
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
SCRIPTS = {name: ROOT / "scripts" / name for name in ("docker-base", "docker-build", "docker-testbed", "swarm-testbed")}


@pytest.fixture
def no_engine(tmp_path):
    """A PATH whose `docker` is a CLI without an engine behind it."""
    bin_dir = tmp_path / "bin"
    bin_dir.mkdir()
    fake = bin_dir / "docker"
    fake.write_text("#!/bin/sh\necho 'Cannot connect to the Docker daemon' >&2\nexit 1\n")
    fake.chmod(0o755)
    return {**os.environ, "PATH": f"{bin_dir}{os.pathsep}{os.environ['PATH']}"}


def _run(name: str, *args: str, env: dict[str, str] | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run(["bash", str(SCRIPTS[name]), *args], capture_output=True, text=True, timeout=60, cwd=ROOT,
                          env=env)  # fmt: skip


@pytest.mark.parametrize("name", sorted(SCRIPTS))
def test_help_exits_0(name):
    result = _run(name, "--help")
    assert result.returncode == 0 and name in result.stdout


@pytest.mark.parametrize(
    ("name", "args", "message"),
    [
        ("docker-testbed", [], "missing CONFIG"),
        ("docker-testbed", ["configs/quickstart.toml", "configs/quickstart.toml"], "one CONFIG only"),
        ("docker-testbed", ["configs/quickstart.toml", "--bogus"], "unknown option: --bogus"),
        ("docker-testbed", ["configs/quickstart.toml", "--timeout", "10m"], "whole seconds"),
        ("docker-testbed", ["no/such.toml"], "cannot read no/such.toml"),
        ("swarm-testbed", [], "missing CONFIG"),
        ("swarm-testbed", ["configs/quickstart.toml", "--bogus"], "unknown option: --bogus"),
        ("swarm-testbed", ["configs/quickstart.toml", "--port", "high"], "whole numbers"),
        ("swarm-testbed", ["no/such.toml"], "cannot read no/such.toml"),
        ("swarm-testbed", ["configs/quickstart.toml", "--nodes", "3"], "--nodes is 1 or 2, got 3"),
        ("swarm-testbed", ["configs/quickstart.toml", "--link-delay", "1ms"], "--link-delay and --link-loss need --nodes 2"),
        ("docker-build", ["--bogus"], "unknown option: --bogus"),
        ("docker-base", ["--bogus"], "unknown option: --bogus"),
    ],
)
def test_usage_errors_exit_2_with_one_line(name, args, message):
    result = _run(name, *args)
    assert result.returncode == 2, result.stderr
    assert result.stderr.startswith(f"{name}: ") and message in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1


@pytest.mark.parametrize(("name", "args"), [("docker-testbed", ["configs/quickstart.toml"]), ("docker-build", []),
                                            ("docker-base", []), ("swarm-testbed", ["configs/quickstart.toml"])])  # fmt: skip
def test_without_an_engine_exit_2_and_say_so(no_engine, name, args):
    result = _run(name, *args, env=no_engine)
    assert result.returncode == 2, result.stderr
    assert "no Docker engine answers" in result.stderr


def test_swarm_testbed_refuses_a_config_placed_on_other_nodes(tmp_path):
    """One machine: a config whose stations or master name a node is for a real swarm (docs/testbeds.md)."""
    placed = tmp_path / "placed.toml"
    placed.write_text((ROOT / "configs" / "quickstart.toml").read_text(encoding="utf-8")
                      + '\n[deploy]\nmaster = { node = "plc" }\n', encoding="utf-8")
    result = _run("swarm-testbed", str(placed))
    assert result.returncode == 2, result.stderr
    assert "places its processes on node(s) plc" in result.stderr and len(result.stderr.strip().splitlines()) == 1


def test_swarm_testbed_on_two_nodes_refuses_a_config_placed_on_three(tmp_path):
    """Two nodes: the master's and one other; a config that needs more is refused before anything starts."""
    if os.geteuid() != 0:
        pytest.skip("--nodes 2 needs root (it says so and exits 2 first)")
    placed = tmp_path / "three.toml"
    placed.write_text((ROOT / "configs" / "quickstart.toml").read_text(encoding="utf-8")
                      + '\n[deploy]\nnodes = { a = "192.0.2.1", b = "192.0.2.2", c = "192.0.2.3" }\n'
                      'master = { node = "a" }\n[[deploy.worker]]\nstations = [0x21]\nnode = "b"\n'
                      '[[deploy.worker]]\nstations = [0x22]\nnode = "c"\n', encoding="utf-8")
    result = _run("swarm-testbed", "--nodes", "2", str(placed))
    assert result.returncode == 2, result.stderr
    assert "2 node(s) besides the master's (b, c)" in result.stderr and len(result.stderr.strip().splitlines()) == 1
