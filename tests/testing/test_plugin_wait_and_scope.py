"""The plugin beside pytest-asyncio runs without its deprecation warning (the loop scope is stated, a project's own
setting kept), and a ``wait_until`` that times out names the last value it saw."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]

TEST = """
import pytest

@pytest.mark.mlink_network("quickstart", clock="virtual")
def test_up(mlink_network):
    mlink_network.wait(0.2)
"""


def _pytest(folder: Path, *args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "pytest", "-rw", "-p", "no:cacheprovider",
                           "-W", "error::DeprecationWarning", *args, "test_net.py"],
                          capture_output=True, text=True, timeout=300, cwd=folder)


def test_no_loop_scope_warning_and_the_projects_own_setting_kept(tmp_path: Path) -> None:
    (tmp_path / "test_net.py").write_text(TEST)
    r = _pytest(tmp_path)
    out = r.stdout + r.stderr
    assert r.returncode == 0, out
    assert "is unset" not in out and "DeprecationWarning" not in out and "1 passed" in out
    assert "asyncio_default_fixture_loop_scope=fixture-scope" in out  # pytest-asyncio's header: its own default
    (tmp_path / "pytest.ini").write_text("[pytest]\nasyncio_default_fixture_loop_scope = function\n")
    own = _pytest(tmp_path)
    assert own.returncode == 0 and "asyncio_default_fixture_loop_scope=function" in own.stdout, own.stdout


@pytest.mark.mlink_network("configs/quickstart.toml", clock="virtual", seed=1)
def test_wait_until_names_the_last_value_seen(mlink_network):
    net = mlink_network
    net.run(0x21, hz=30)
    with pytest.raises(TimeoutError, match=r"not met within 0.5 s \(simulated\): last value \d+\.\d+") as err:
        net.wait_until(lambda: round(net.output_hz(0x21), 2), 0.5, until=lambda hz: hz > 29.5)
    assert "last value" in str(err.value)
    with pytest.raises(TimeoutError, match="the condition last returned False"):
        net.wait_until(lambda: net.output_hz(0x21) > 100, 0.2)
    hz = net.wait_until(lambda: net.output_hz(0x21), 5, until=lambda hz: hz > 29.5)
    assert hz > 29.5
