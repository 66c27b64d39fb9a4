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


def _in_process(path: Path, *, background: bool) -> tuple[list[tuple], int, list[str]]:
    """A virtual-clock quickstart of 1.2 simulated seconds with a capture: (its datagrams relative to the first,
    the datagrams written before the close, the threads that ran the run)."""
    import asyncio
    import threading

    from mlink_sim.aio.virtual.vclock import VirtualEventLoop
    from mlink_sim.aio.run.virtual_session import VirtualSession
    from mlink_sim.capture import CaptureWriter
    from mlink_sim.config import load_config

    quickstart = ROOT / "configs" / "quickstart.toml"
    capture = CaptureWriter(path).start(background=background)

    async def main() -> tuple[int, list[str]]:
        session = await VirtualSession.open(load_config(quickstart), quickstart, seed=3, capture=capture)
        try:
            await session.bring_up(5.0)
            await asyncio.sleep(1.2)  # simulated time
            threads = [t.name for t in threading.enumerate()]
            written = capture.stats.datagrams
            await session.close_masters()
        finally:
            await session.close()
        return written, threads

    loop = VirtualEventLoop()
    try:
        written, threads = loop.run_until_complete(main())
    finally:
        loop.close()
        capture.close()
    dgs = read_capture(path).datagrams
    return [(d.ts_ns - dgs[0].ts_ns, d.src, d.dst, d.data, d.comments) for d in dgs], written, threads


def test_virtual_clock_writes_the_capture_in_place_and_where_it_flushes_changes_nothing(tmp_path: Path) -> None:
    """No writer thread on the virtual clock: the session flushes every 250 ms of simulated time (so the file
    grows during the run), and the file is the one a writer thread makes of the same run."""
    in_place, written, threads = _in_process(tmp_path / "a.pcapng", background=False)
    assert "mlink-capture" not in threads
    assert 1000 < written < len(in_place)  # flushed during the run, the rest at the close
    threaded, _, threads = _in_process(tmp_path / "b.pcapng", background=True)
    assert "mlink-capture" in threads
    assert in_place == threaded
