"""``mlink-sim up quickstart --clock virtual --capture - | tshark -r -``: tshark with the shipped dissector reads a
run's pcapng stream from its standard input, every datagram the run recorded and nothing else."""

from __future__ import annotations

import re
import subprocess
import sys

import pytest

from mlink_sim.wireshark.generate import shipped_path

MLINK = [sys.executable, "-m", "mlink_sim"]
VIRTUAL = [*MLINK, "up", "quickstart", "--clock", "virtual", "--capture", "-"]


def _summary_count(stderr: str) -> int:
    m = re.search(r"capture to stdout: (\d+) datagrams", stderr)
    assert m, stderr
    return int(m.group(1))


@pytest.mark.e2e
def test_tshark_reads_a_virtual_run_from_stdin(tshark: str) -> None:
    up = subprocess.Popen(VIRTUAL, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    shark = subprocess.run([tshark, "-n", "-X", f"lua_script:{shipped_path()}", "-o", "udp.try_heuristic_first:TRUE",
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
