"""``up --clock virtual --capture``: the master's view on simulated time, fabric addresses, reproducible by seed."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from mlink_sim.capture import read_capture

ROOT = Path(__file__).resolve().parents[2]


def _run(out: Path) -> list[tuple[int, tuple[str, int], tuple[str, int], bytes, tuple[str, ...]]]:
    proc = subprocess.run([sys.executable, "-m", "mlink_sim", "up", str(ROOT / "configs" / "quickstart.toml"),
                           "--clock", "virtual", "--duration", "0.5s", "--no-status", "--capture", str(out)],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert f"capture {out}:" in proc.stderr
    dgs = read_capture(out).datagrams
    t0 = dgs[0].ts_ns
    return [(d.ts_ns - t0, d.src, d.dst, d.data, d.comments) for d in dgs]


def test_virtual_clock_capture_is_the_same_for_the_same_seed(tmp_path: Path) -> None:
    first = _run(tmp_path / "a.pcapng")
    assert first == _run(tmp_path / "b.pcapng")
    assert len(first) > 500
    # commands leave on the cycle instants of simulated time (2 ms), from the master of their link
    commands = [(t, src, dst) for t, src, dst, data, _ in first if data[2] == 1]
    assert all(t % 2_000_000 == 0 for t, _, _ in commands)
    assert {src for _, src, _ in commands} == {("192.0.2.1", 40002), ("192.0.2.1", 40003)}
    assert {dst for _, _, dst in commands} == {("192.0.2.33", 47001), ("192.0.2.34", 47001), ("192.0.2.35", 47001)}
    comments = [c for *_, cs in first for c in cs]
    assert "StateChanged station 23H: old=syncing new=phase3" in comments
    assert "timeline: 0.2s all stations: do run forward 30 Hz" in comments  # the quickstart's first action
