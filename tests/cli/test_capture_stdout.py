"""``--capture -``: the pcapng stream on stdout, read by tshark (``tshark -r -``, the shipped dissector) and by
``decode --pcap -`` through a pipe, live while the run goes, everything else the command prints on stderr; a
terminal as stdout refused; a reader that goes away stops the capture, not the run."""

from __future__ import annotations

import os
import re
import subprocess
import sys
import threading
from pathlib import Path

import pytest
from click.testing import CliRunner

from mlink_sim.capture import CaptureWriter
from mlink_sim.cli.decode import decode_cmd
from mlink_sim.wireshark.generate import shipped_path

from tests.capture.timed import write_timed_capture
from tests.wireshark.conftest import tshark_process

MLINK = [sys.executable, "-m", "mlink_sim"]
VIRTUAL = [*MLINK, "up", "quickstart", "--clock", "virtual", "--capture", "-"]


def _summary_count(stderr: str) -> int:
    m = re.search(r"capture to stdout: (\d+) datagrams", stderr)
    assert m, stderr
    return int(m.group(1))


@pytest.mark.e2e
def test_tshark_reads_a_virtual_run_from_stdin(tshark: str) -> None:
    up = subprocess.Popen(VIRTUAL, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    shark = tshark_process([tshark, "-n", "-X", f"lua_script:{shipped_path()}", "-o", "udp.try_heuristic_first:TRUE",
                            "-r", "-", "-Y", "mlink", "-T", "fields", "-e", "mlink.station", "-e", "mlink.cmd.name"],
                           stdin=up.stdout, capture_output=True, text=True, timeout=300)
    assert up.stdout is not None and up.stderr is not None
    up.stdout.close()
    err = up.stderr.read().decode()
    assert up.wait(timeout=60) == 0, err
    assert shark.returncode == 0, shark.stderr
    rows = shark.stdout.splitlines()
    assert len(rows) == _summary_count(err)  # every datagram the run recorded, and nothing else on stdout
    assert {"0x21\tINV_CTL", "0x22\tINV_CTL", "0x23\tINV_CTL", "0x23\tPRM_WR"} <= set(rows)
    assert "all checks held" in err and "== quickstart" in err  # the summary: on stderr


@pytest.mark.e2e
def test_decode_reads_a_run_from_stdin() -> None:
    up = subprocess.Popen(VIRTUAL, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    decode = subprocess.run([*MLINK, "decode", "--pcap", "-", "--stats"], stdin=up.stdout, capture_output=True,
                            text=True, timeout=120)
    assert up.stdout is not None and up.stderr is not None
    up.stdout.close()
    err = up.stderr.read().decode()
    assert up.wait(timeout=60) == 0, err
    assert decode.returncode == 0, decode.stderr
    assert decode.stdout.splitlines()[-1] == f"{_summary_count(err)} datagram(s), 0 rejected"
    assert re.search(r"^21H\s+INV_CTL\s+\d+\s+\d+\s+0\s+0\s", decode.stdout, re.M)


def test_decode_pcap_dash_reads_standard_input(tmp_path: Path) -> None:
    data = write_timed_capture(tmp_path / "timed.pcapng").read_bytes()
    result = CliRunner().invoke(decode_cmd, ["--pcap", "-", "--station", "0x23"], input=data)
    assert result.exit_code == 0, result.output
    assert sum("ML3 cmd 23H" in line for line in result.stdout.splitlines()) == 3
    assert CliRunner().invoke(decode_cmd, ["--pcap", "-"], input=b"nope").exit_code == 2


@pytest.mark.e2e
def test_the_stream_is_live_while_the_run_goes() -> None:
    """On the wall clock the writer sends what came every 250 ms: 64 KB of it (some 700 datagrams) reach the
    reader long before the end of a 4 s run."""
    up = subprocess.Popen([*MLINK, "up", "quickstart", "--capture", "-", "--duration", "4s", "--no-status"],
                          stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    assert up.stdout is not None
    running_at_64k: list[bool] = []

    def read() -> None:
        got = 0
        while True:
            chunk = os.read(up.stdout.fileno(), 1 << 16)  # type: ignore[union-attr]
            if not chunk:
                return
            got += len(chunk)
            if got >= 1 << 16 and not running_at_64k:
                running_at_64k.append(up.poll() is None)

    reader = threading.Thread(target=read)
    reader.start()
    err = up.stderr.read() if up.stderr else b""
    reader.join(timeout=60)
    assert up.wait(timeout=60) == 0, err.decode()
    assert running_at_64k == [True], "the stream came only at the end of the run"


def test_a_terminal_is_not_a_place_for_the_stream(tmp_path: Path) -> None:
    parent, child = os.openpty()
    try:
        proc = subprocess.run(VIRTUAL, stdout=child, stderr=subprocess.PIPE, text=True, timeout=60)
    finally:
        os.close(child)
        os.close(parent)
    assert proc.returncode == 2
    assert proc.stderr.strip() == ("mlink-sim up: --capture - writes a binary pcapng stream: pipe it (| wireshark "
                                   "-k -i -, | tshark -r -, | mlink-sim watch -) or give a file name")


@pytest.mark.e2e
def test_a_reader_that_goes_away_stops_the_capture_not_the_run() -> None:
    up = subprocess.Popen(VIRTUAL, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    assert up.stdout is not None
    up.stdout.read(4096)
    up.stdout.close()  # as `| head -c 4096`
    _, err = up.communicate(timeout=120)
    text = err.decode()
    assert up.returncode == 0, text
    assert "all checks held" in text
    assert "datagrams not recorded (the reader of the stream went away)" in text


def test_the_writer_streams_and_says_when_its_reader_went_away(tmp_path: Path) -> None:
    read_end, write_end = os.pipe()
    got: list[bytes] = []
    reader = threading.Thread(target=lambda: got.append(os.read(read_end, 1 << 20)))
    with CaptureWriter("-", stream=open(write_end, "wb", buffering=0), epoch_offset_ns=0) as w:
        reader.start()
        w.record(1_000, b"\x4d" * 31, ("127.0.0.1", 1), ("127.0.0.1", 2))
        w.record(2_000, b"\x4d" * 31, ("127.0.0.1", 1), ("127.0.0.1", 2))
    reader.join(timeout=10)
    os.close(read_end)
    assert got and got[0][:4] == b"\x0a\x0d\x0d\x0a"  # the section header block first: a pcapng stream
    assert w.stats.datagrams == 2 and w.stats.summary().startswith("capture to stdout: 2 datagrams")
    read_end, write_end = os.pipe()
    os.close(read_end)
    with open(write_end, "wb", buffering=0) as stream:
        w = CaptureWriter("-", stream=stream, epoch_offset_ns=0).start(background=False)
        for i in range(3):
            w.record(i, b"\x4d" * 31, ("127.0.0.1", 1), ("127.0.0.1", 2))
        w.flush()
        stats = w.close()
    assert stats.stopped == "the reader of the stream went away"
    assert "3 datagrams not recorded (the reader of the stream went away)" in stats.summary()
