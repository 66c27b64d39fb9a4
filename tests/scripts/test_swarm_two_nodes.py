"""scripts/swarm-testbed --nodes 2 interrupted by Ctrl-C once its stack runs on both nodes: it exits 130 and leaves
no swarm, engine, namespace, link, volume, config or file behind.

It needs root, a Docker engine in no swarm and the image (scripts/docker-build), and is skipped with the reason
elsewhere. The suite runs before CI starts an engine, so `.ci/run` runs this file again once its engine is up,
after the two-node run that must pass (docs/testbeds.md, "Two nodes on one machine")."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import time
from pathlib import Path

import pytest

from mlink_sim.testbed.netns import list_links, list_netns

ROOT = Path(__file__).resolve().parents[2]
SCRIPT = ROOT / "scripts" / "swarm-testbed"
IMAGE = "mlink-sim:latest"


def _docker(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(["docker", *args], capture_output=True, text=True, timeout=60)


def _unavailable() -> str | None:
    if os.geteuid() != 0:
        return "needs root (a network namespace, a veth pair, a second Docker engine)"
    for tool in ("docker", "dockerd", "nsenter", "ip"):
        if shutil.which(tool) is None:
            return f"needs {tool} (docker.io, util-linux, iproute2)"
    if _docker("version", "--format", "{{.Server.Version}}").returncode != 0:
        return "no Docker engine answers (.ci/run starts one and runs this file then)"
    if _docker("info", "--format", "{{.Swarm.LocalNodeState}}").stdout.strip() != "inactive":
        return "the engine is in a swarm: the two-node testbed makes one of its own"
    if _docker("image", "inspect", IMAGE).returncode != 0:
        return f"no image {IMAGE} (scripts/docker-build)"
    return None


def _ours(pid: int) -> list[str]:
    """What of the run *pid* is still there."""
    prefix, project = f"mlsw{pid}", f"mlinksw{pid}"
    left = [f"namespace {prefix}"] * (prefix in list_netns()) + [f"link {prefix}h"] * (f"{prefix}h" in list_links())
    label = f"label=com.docker.stack.namespace={project}"
    for kind in ("volume", "container"):
        listing = _docker(kind, "ls", "-q", "--filter", label) if kind == "volume" else _docker("ps", "-aq", "--filter", label)
        left += [f"{kind} {x}" for x in listing.stdout.split()]
    state = _docker("info", "--format", "{{.Swarm.LocalNodeState}}").stdout.strip()
    left += [f"swarm {state}"] * (state != "inactive")
    for proc in Path("/proc").iterdir():
        try:
            argv = (proc / "cmdline").read_bytes().split(b"\0")
        except OSError:
            continue
        if prefix.encode() in argv and any(a.endswith(b"dockerd") for a in argv):
            left.append(f"dockerd {proc.name}")
    left += [f"cgroup {p}" for p in Path("/sys/fs/cgroup").glob(f"*/{prefix}")]
    return left


def test_ctrl_c_on_two_nodes_exits_130_and_leaves_nothing_behind(tmp_path):
    reason = _unavailable()
    if reason:
        pytest.skip(reason)
    log = tmp_path / "stderr.log"
    with log.open("w") as err:
        proc = subprocess.Popen(["bash", str(SCRIPT), "--nodes", "2", "configs/quickstart.toml", "--no-build",
                                 "--report", str(tmp_path / "report.json")], cwd=ROOT, stdout=subprocess.DEVNULL,
                                stderr=err, start_new_session=True)  # fmt: skip
    try:
        end = time.monotonic() + 240
        while "answered a NOP from this host" not in log.read_text() and proc.poll() is None:
            assert time.monotonic() < end, log.read_text()
            time.sleep(0.5)
        assert proc.poll() is None, log.read_text()  # the stations run on the second node; the master runs
        proc.send_signal(signal.SIGINT)
        assert proc.wait(timeout=240) == 130, log.read_text()
    finally:
        if proc.poll() is None:
            proc.kill()
    text = log.read_text()
    assert "signal 2 – tearing the testbed down" in text
    assert _ours(proc.pid) == [], text
    assert "could not remove" not in text and "still in a swarm" not in text, text
