"""The real tshark with the shipped dissector: installed on demand (scripts/ensure-tshark); in CI (``CI=true``)
a tshark that cannot be had fails the tests instead of skipping them."""

from __future__ import annotations

import atexit
import functools
import json
import os
import shutil
import subprocess
import tempfile
from pathlib import Path
from typing import Any

import pytest

from mlink_sim.wireshark.generate import shipped_path

ROOT = Path(__file__).resolve().parents[2]


def _tshark() -> str | None:
    found = shutil.which("tshark")
    if found is None:
        subprocess.run([str(ROOT / "scripts" / "ensure-tshark")], timeout=600, check=False)
        found = shutil.which("tshark")
    return found


@pytest.fixture(scope="session")
def tshark() -> str:
    found = _tshark()
    if found is None:
        reason = "tshark is not installed and scripts/ensure-tshark could not install it (no apt-get or not root)"
        if os.environ.get("CI", "").lower() == "true":
            pytest.fail(f"{reason}; CI must run the dissector tests")
        pytest.skip(reason)
    return found


@functools.cache
def _empty_home() -> str:
    home = tempfile.mkdtemp(prefix="mlink-tshark-home-")
    atexit.register(shutil.rmtree, home, True)
    return home


def tshark_process(args: list[str], **kwargs: Any) -> subprocess.CompletedProcess[Any]:
    """tshark run in an empty home: a dissector installed in the user's ~/.local/lib/wireshark/plugins
    (``mlink-sim wireshark --install``) would register the protocol a second time beside the shipped one
    under test, and tshark refuses that."""
    home = _empty_home()
    env = {**os.environ, "HOME": home, "XDG_CONFIG_HOME": os.path.join(home, ".config")}
    return subprocess.run(args, env=env, **kwargs)


def run_tshark(tshark: str, capture: Path, *args: str) -> str:
    """tshark on *capture* with the shipped dissector, the heuristic tried first (ephemeral ports)."""
    proc = tshark_process([tshark, "-n", "-X", f"lua_script:{shipped_path()}", "-o", "udp.try_heuristic_first:TRUE",
                           "-r", str(capture), *args], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert "Lua: Error" not in proc.stderr and "lua_script" not in proc.stderr, proc.stderr
    return proc.stdout


def tshark_packets(tshark: str, capture: Path) -> list[dict[str, Any]]:
    """The ``mlink`` layer of every packet (``-T json``), None for a packet the dissector did not take."""
    doc = json.loads(run_tshark(tshark, capture, "-T", "json", "-J", "mlink"))
    return [p["_source"]["layers"].get("mlink") for p in doc]
