"""``mlink-sim up --clock virtual``: the quickstart in one process on simulated time; the same seed gives the
same report, byte for byte once the wall-clock metadata (meta.started, meta.host, meta.wall) is left out."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

from mlink_sim.aio.run.virtual_session import WALL_META

ROOT = Path(__file__).resolve().parents[2]
QUICKSTART = ROOT / "configs" / "quickstart.toml"


def _up(*args: str, hashseed: str = "0") -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "PYTHONHASHSEED": hashseed}
    return subprocess.run([sys.executable, "-m", "mlink_sim", "up", *args, "--clock", "virtual", "--no-status"],
                          capture_output=True, text=True, timeout=300, env=env, cwd=ROOT)


def _deterministic_bytes(path: Path) -> bytes:
    """The report file with the wall-clock keys of ``meta`` removed, re-serialised in the file's own key order."""
    report = json.loads(path.read_bytes())
    for key in WALL_META:
        report["meta"].pop(key)
    return json.dumps(report).encode()


def test_quickstart_twice_with_the_same_seed_gives_the_same_report(tmp_path):
    first, second = tmp_path / "a.json", tmp_path / "b.json"
    a = _up(str(QUICKSTART), "--seed", "5", "--report", str(first), hashseed="1")
    b = _up(str(QUICKSTART), "--seed", "5", "--report", str(second), hashseed="2")  # other str hashes too
    assert a.returncode == 0, a.stdout + a.stderr
    assert b.returncode == 0, b.stdout + b.stderr
    assert "all checks held" in a.stdout
    assert "x real time" in a.stdout and "virtual clock (seed 5)" in a.stdout
    assert _deterministic_bytes(first) == _deterministic_bytes(second)
    report = json.loads(first.read_text())
    assert report["meta"]["clock"] == "virtual" and report["meta"]["wall"]["speedup"] > 0
    assert report["meta"]["duration_s"] >= 11.0  # the timeline's end + 1 s, simulated


def test_a_failed_check_exits_1_and_a_bad_model_exits_2(tmp_path):
    text = QUICKSTART.read_text()
    failing = tmp_path / "fail.toml"
    failing.write_text(text.replace("output_hz = 20.0", "output_hz = 45.0"))  # 0x21 runs at 20 Hz then
    result = _up(str(failing), "--duration", "8s")
    assert result.returncode == 1, result.stdout + result.stderr
    assert "FAIL" in result.stdout and "check(s) failed" in result.stdout
    bad = tmp_path / "bad.toml"
    bad.write_text(text.replace('transmission_cycle = "2ms"', 'transmission_cycle = "2ms"\njitter = "1ms"'))
    result = _up(str(bad))
    assert result.returncode == 2
    assert "jitter" in result.stderr and "Traceback" not in result.stderr


def test_no_timeline_runs_the_network_until_duration(tmp_path):
    report = tmp_path / "r.json"
    r = _up("quickstart", "--no-timeline", "--duration", "3s", "--report", str(report))
    assert r.returncode == 0, r.stdout + r.stderr
    assert "run complete (no checks in the timeline, no --assert)" in r.stdout and "FAIL" not in r.stdout
    doc = json.loads(report.read_text())
    assert 2.9 <= doc["meta"]["duration_s"] < 4.0 and doc["meta"]["not_run"] == []
    assert doc["rtt"]["count"] > 0  # the stations answered the whole time
    untimed = _up("quickstart", "--no-timeline")
    assert untimed.returncode == 2 and "add --duration" in untimed.stderr


def test_no_timeline_runs_the_network_until_ctrl_c():
    import signal
    import time

    proc = subprocess.Popen([sys.executable, "-m", "mlink_sim", "up", "quickstart", "--no-timeline", "--no-status",
                             "--no-realtime"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=ROOT)
    try:
        assert proc.stderr is not None
        deadline = time.monotonic() + 60
        for line in proc.stderr:
            if "running until Ctrl-C" in line or time.monotonic() > deadline:
                break
        time.sleep(0.5)
        proc.send_signal(signal.SIGINT)
        out, _ = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == 130, out
    assert "interrupted by SIGINT" in out and "not run" not in out
