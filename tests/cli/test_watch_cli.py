"""``mlink-sim watch`` as a user runs it: a pcapng stream on stdin (a real run's ``--capture -`` through a pipe), a
file read to its end or followed, one station; Ctrl-C ends it with 130 and the last screen, the end of the stream
and a closed output with 0, what is not a capture with 2 and one line."""

from __future__ import annotations

import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from tests.capture.timed import write_timed_capture

MLINK = [sys.executable, "-m", "mlink_sim"]


@pytest.fixture(scope="module")
def timed(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_timed_capture(tmp_path_factory.mktemp("timed") / "timed.pcapng")


def _watch(*args: str, stdin: bytes | None = None) -> subprocess.CompletedProcess[str]:
    proc = subprocess.run([*MLINK, "watch", *args], input=stdin, capture_output=True, timeout=60)
    return subprocess.CompletedProcess(proc.args, proc.returncode, proc.stdout.decode(), proc.stderr.decode())


def test_a_stream_on_stdin_to_its_end(timed: Path) -> None:
    result = _watch("-", stdin=timed.read_bytes())
    assert result.returncode == 0, result.stderr
    assert result.stdout.startswith("watch stdin  ")
    lines = result.stdout.splitlines()
    rsp = next(line for line in lines if line.startswith("21H  rsp INV_CTL"))
    assert rsp.split()[3] == "12" and "out=26.40 Hz" in rsp  # COUNT on a wide screen, Hz by the note's units
    assert any(line.startswith("23H  rsp PRM_RD") and "param=C1-02 (0201H) = 1.0 s" in line for line in lines)
    assert result.stderr == ""


def test_a_file_to_its_end_one_station(timed: Path) -> None:
    result = _watch(str(timed), "--no-follow", "--station", "0x23")
    assert result.returncode == 0, result.stderr
    rows = [line for line in result.stdout.splitlines() if line[:3] in ("21H", "23H")]
    assert rows and all(line.startswith("23H") for line in rows)


def test_what_is_not_a_capture_is_exit_2_in_one_line(tmp_path: Path) -> None:
    bad = _watch("-", stdin=b"hello")
    assert bad.returncode == 2 and bad.stderr.strip() == \
        "mlink-sim watch: standard input: not a pcap or pcapng file (magic 68656c6c)"
    assert bad.stdout == ""
    endpoint = _watch("127.0.0.1:47001")
    assert endpoint.returncode == 2 and "watch reads a pcapng stream" in endpoint.stderr
    assert "Traceback" not in bad.stderr + endpoint.stderr


def test_ctrl_c_ends_a_followed_file_with_130_and_its_last_screen(timed: Path) -> None:
    proc = subprocess.Popen([*MLINK, "watch", str(timed)], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)
    time.sleep(2.0)  # it has read the file and waits at its end for more
    proc.send_signal(signal.SIGINT)
    out, err = proc.communicate(timeout=20)
    assert proc.returncode == 130, err
    assert "21H  rsp INV_CTL" in out and "Traceback" not in err


def test_a_closed_output_ends_it_quietly(timed: Path) -> None:
    proc = subprocess.Popen([*MLINK, "watch", str(timed), "--no-follow"], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE)
    assert proc.stdout is not None and proc.stderr is not None
    proc.stdout.close()  # the reader went away before the first screen
    err = proc.stderr.read().decode()
    assert proc.wait(timeout=30) == 0, err
    assert "Traceback" not in err and "Error" not in err


@pytest.mark.e2e
def test_a_running_network_through_a_pipe() -> None:
    """``mlink-sim up quickstart --clock virtual --capture - | mlink-sim watch -``: every station's INV_CTL."""
    up = subprocess.Popen([*MLINK, "up", "quickstart", "--clock", "virtual", "--capture", "-"],
                          stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    watch = subprocess.run([*MLINK, "watch", "-"], stdin=up.stdout, capture_output=True, text=True, timeout=120)
    assert up.stdout is not None and up.stderr is not None
    up.stdout.close()
    up_err = up.stderr.read().decode()
    assert up.wait(timeout=60) == 0, up_err
    assert watch.returncode == 0, watch.stderr
    for station in ("21H", "22H", "23H"):
        line = next(line for line in watch.stdout.splitlines() if line.startswith(f"{station}  rsp INV_CTL"))
        assert int(line.split()[3]) > 5000  # its COUNT: 11 s of 2 ms cycles
    assert "all checks held" in up_err  # the summary went to stderr, the stream alone to the pipe
