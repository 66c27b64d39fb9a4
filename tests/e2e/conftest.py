"""End-to-end helpers: run the real ``mlink-sim`` console script in subprocesses, on loopback, port 0."""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from mlink_sim.testing import run_beyond_the_bound

MLINK = [sys.executable, "-m", "mlink_sim"]


def run_cli(*args: str, timeout: float = 60.0, cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run([*MLINK, *args], capture_output=True, text=True, timeout=timeout, cwd=cwd)


def lines_until(stream, pattern: str, timeout: float = 20.0) -> tuple[list[str], re.Match[str]]:
    """Read *stream* line by line until one matches *pattern* (a process's notice: "control: 127.0.0.1:PORT")."""
    seen, end = [], time.monotonic() + timeout
    while time.monotonic() < end:
        line = stream.readline()
        if not line:
            break
        seen.append(line)
        m = re.search(pattern, line)
        if m:
            return seen, m
    raise AssertionError(f"no {pattern!r} in {seen!r}")


def assert_held(r: subprocess.CompletedProcess[str]) -> None:
    """A real-clock run held every check: exit 0 and "all checks held". When every failed check names a host
    stall beyond the bound the host-stall policy absorbs (docs/ci.md), the run says nothing about mlink-sim and
    the test is skipped, naming them; any other failure fails."""
    if r.returncode == 1 and (reason := run_beyond_the_bound(r.stdout)):
        pytest.skip(reason)
    assert r.returncode == 0, r.stdout + r.stderr[-2000:]
    assert "all checks held" in r.stdout, r.stdout


class SlaveProc:
    """A ``mlink-sim slave`` process; ``.ready`` is its JSON ready line."""

    def __init__(self, *args: str) -> None:
        self.proc = subprocess.Popen([*MLINK, "slave", "--ready-json", *args], stdout=subprocess.PIPE,
                                     stderr=subprocess.PIPE, text=True)
        assert self.proc.stdout is not None
        line = self.proc.stdout.readline()
        if not line:
            err = self.proc.stderr.read() if self.proc.stderr else ""
            raise RuntimeError(f"slave did not start: {err}")
        self.ready = json.loads(line)

    @property
    def port(self) -> int:
        return self.ready["stations"][0]["port"]

    def stop(self) -> int:
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
            try:
                self.proc.wait(5)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        return self.proc.returncode


@pytest.fixture
def slave() -> Iterator[type[SlaveProc]]:
    started: list[SlaveProc] = []

    class Tracked(SlaveProc):
        def __init__(self, *args: str) -> None:
            super().__init__(*args)
            started.append(self)

    yield Tracked
    for s in started:
        s.stop()


def children_of(pid: int) -> list[int]:
    """PIDs whose parent is *pid* (Linux /proc)."""
    out = []
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            stat = Path(f"/proc/{entry}/stat").read_text()
        except OSError:
            continue
        if int(stat.rsplit(")", 1)[1].split()[1]) == pid:
            out.append(int(entry))
    return out


def wait_gone(pids: list[int], timeout: float = 5.0) -> list[int]:
    end = time.monotonic() + timeout
    alive = pids
    while alive and time.monotonic() < end:
        alive = [p for p in alive if Path(f"/proc/{p}").exists() and "Z" not in _state(p)]
        time.sleep(0.05)
    return alive


def _state(pid: int) -> str:
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return "X"
