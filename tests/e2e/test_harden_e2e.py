"""Signals, exit codes, input errors, warnings, library use, shipped examples and the live status, met from
outside as a user would: real ``mlink-sim`` processes, loopback, port 0."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from .conftest import MLINK, children_of, run_cli, wait_gone
from .test_cli_e2e import CONFIG

pytestmark = pytest.mark.e2e


def _net(run_at: str, check_at: str) -> str:
    """The two stations of the e2e config, a run step and one check."""
    return CONFIG.split("[[timeline]]")[0] + f"""
[[timeline]]
at = "{run_at}"
do = "run"
hz = 10.0

[[timeline]]
at = "{check_at}"
expect = "running"
"""


#: A check 30 s in: a run long enough to be interrupted.
LONG = _net("0.1s", "30s")


def _write(tmp_path: Path, text: str, name: str = "net.toml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


class _Lines:
    """Reads a pipe in a thread; :meth:`wait_for` blocks until a line contains a text."""

    def __init__(self, pipe: object) -> None:
        self.lines: list[str] = []
        self._cond = threading.Condition()
        self._thread = threading.Thread(target=self._read, args=(pipe,), daemon=True)
        self._thread.start()

    def _read(self, pipe: object) -> None:
        for line in pipe:  # type: ignore[attr-defined]
            with self._cond:
                self.lines.append(line)
                self._cond.notify_all()

    def wait_for(self, text: str, timeout: float) -> bool:
        with self._cond:
            return self._cond.wait_for(lambda: any(text in ln for ln in self.lines), timeout)

    @property
    def text(self) -> str:
        return "".join(self.lines)

    def rest(self, timeout: float = 10.0) -> str:
        """All the text, once the process has exited: waits for the reader to reach the end of the pipe (the
        process may be gone while its last lines are still unread)."""
        self._thread.join(timeout)
        return self.text


def _start_up(args: list[str], **kw: object) -> tuple[subprocess.Popen[str], _Lines, _Lines]:
    proc = subprocess.Popen([*MLINK, "up", *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True, **kw)  # type: ignore[call-overload]
    return proc, _Lines(proc.stdout), _Lines(proc.stderr)


# -- interrupts --------------------------------------------------------------------------------------------------------

@pytest.mark.parametrize(("sig", "code", "group"), [(signal.SIGINT, 130, True), (signal.SIGTERM, 143, False)])
def test_signal_during_up_disconnects_and_exits_128_plus_n(tmp_path: Path, sig: signal.Signals, code: int,
                                                            group: bool) -> None:
    cfg = _write(tmp_path, LONG)
    report, run_dir = tmp_path / "r.json", tmp_path / "run"
    proc, out, err = _start_up([str(cfg), "--no-status", "--log-level", "info", "--report", str(report),
                                "--run-dir", str(run_dir)])
    try:
        assert err.wait_for("network_up", 60), err.text
        kids = children_of(proc.pid)
        assert len(kids) == 2 and all(os.getpgid(k) != proc.pid for k in kids)  # own process groups
        time.sleep(0.5)
        # Ctrl-C at a terminal signals the whole foreground group: here `up`'s own group (its workers are not in it)
        os.killpg(proc.pid, sig) if group else proc.send_signal(sig)
        proc.wait(30)
    finally:
        if proc.poll() is None:
            proc.kill()
    stdout, stderr = out.rest(), err.rest()
    assert proc.returncode == code, stdout + stderr
    assert f"interrupted by {sig.name}" in stdout and "all checks held" not in stdout
    assert "30s all stations: expect running: not run" in stdout
    assert "Traceback" not in stderr
    doc = json.loads(report.read_text())
    assert doc["meta"]["interrupted"] == sig.name
    assert doc["meta"]["not_run"] == ["30s all stations: expect running"]
    logs = "".join(p.read_text() for p in run_dir.glob("worker-*.log"))
    assert logs.count("disconnected") >= 2, logs  # the master DISCONNECTed both stations before they stopped
    assert not wait_gone(kids), "worker processes left behind"


@pytest.mark.parametrize(("sig", "code"), [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_slave_and_master_exit_128_plus_n_on_signals(tmp_path: Path, sig: signal.Signals, code: int) -> None:
    cfg = _write(tmp_path, LONG)
    slave = subprocess.Popen([*MLINK, "slave", "--config", str(cfg), "--ready-json"], stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, text=True)
    try:
        assert slave.stdout is not None
        ready = json.loads(slave.stdout.readline())
        eps = [f"{s['address']:#04x}=127.0.0.1:{s['port']}" for s in ready["stations"]]
        master = subprocess.Popen([*MLINK, "master", str(cfg), "--no-status", "--log-level", "info",
                                   *(a for ep in eps for a in ("--endpoint", ep))],
                                  stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        merr = _Lines(master.stderr)
        mout = _Lines(master.stdout)
        assert merr.wait_for("network_up", 60), merr.text
        master.send_signal(sig)
        assert master.wait(30) == code, mout.rest() + merr.rest()
        assert f"interrupted by {sig.name}" in mout.rest() and "Traceback" not in merr.rest()
        slave.send_signal(sig)
        assert slave.wait(10) == code
        assert slave.stderr is not None and "Traceback" not in slave.stderr.read()
    finally:
        for p in (slave,):
            if p.poll() is None:
                p.kill()


# -- honest verdicts, the report's invariant ---------------------------------------------------------------------------

def test_duration_shorter_than_the_timeline_warns_and_lists_the_steps_not_run(tmp_path: Path) -> None:
    cfg = _write(tmp_path, LONG)
    report = tmp_path / "r.json"
    r = run_cli("up", str(cfg), "--no-status", "--duration", "1.5s", "--report", str(report), timeout=90)
    # a loaded machine may leave a station in alarm after bring-up: then, and only then, the run fails
    assert r.returncode == (1 if "station(s) did not come up" in r.stdout else 0), r.stdout + r.stderr
    assert "warning: --duration 1.5s ends the run before 1 timeline step(s)" in r.stderr
    assert "30s all stations: expect running" in r.stderr
    assert "30s all stations: expect running: not run" in r.stdout
    assert "all checks held" not in r.stdout
    assert "1 timeline step(s) not run (--duration 1.5s ended the run)" in r.stdout
    doc = json.loads(report.read_text())
    assert doc["meta"]["not_run"] == ["30s all stations: expect running"] and doc["meta"]["interrupted"] is None
    # answered + missing <= sent, network-wide and per station, on a real run's report
    for fig in [doc, *doc["station"].values()]:
        assert fig["answered"] + fig["missing"] <= fig["sent"], fig
        assert fig["late"] <= fig["answered"] and fig["rtt"]["count"] == fig["answered"]


def test_report_invariant_and_verdict_on_the_virtual_clock(tmp_path: Path) -> None:
    """The same counting on simulated time, where the outcome does not depend on the machine's load."""
    report = tmp_path / "r.json"
    r = run_cli("up", "quickstart", "--clock", "virtual", "--no-status", "--report", str(report), timeout=120,
                cwd=tmp_path)
    assert r.returncode == 0 and r.stdout.rstrip().endswith("all checks held; report: " + str(report)), r.stdout
    doc = json.loads(report.read_text())
    assert doc["meta"]["interrupted"] is None and doc["meta"]["not_run"] == []
    for fig in [doc, *doc["station"].values()]:
        assert fig["answered"] + fig["missing"] <= fig["sent"], fig


# -- every input checked before anything starts ------------------------------------------------------------------------

@pytest.mark.parametrize(("edit", "expected"), [
    (('card = "si-et3"', 'card = "si-et3"\noptions = { et3_syncmode_tabel19 = false }'),
     "station[1].options: unknown card option 'et3_syncmode_tabel19'; did you mean 'et3_syncmode_table19'?"),
    (('card = "si-et3"', 'card = "si-et3"\noptions = { et3_syncmode_table19 = "yes" }'),
     "station[1].options: card option 'et3_syncmode_table19' expects true or false"),
    (('hz = 10.0', 'hz = 10.0\n\n[[timeline]]\nat = "1s"\ndo = "set-param"\nparam = "QQ-12"\n'
                         'value = 1.0'), "timeline[1].param: unknown parameter 'QQ-12'"),
    (('hz = 10.0', 'hz = 10.0\n\n[[timeline]]\nat = "1s"\ndo = "set-param"\nparam = "C1-01"\n'
                         'value = 99999'), "timeline[1].param: C1-01: 99999.0 s is out of range"),
    (('expect = "running"', 'expect = "alarm"\nalarm = "E55"'), "timeline[1].alarm: expected an alarm name"),
])
def test_config_errors_are_one_line_exit_2_before_anything_starts(tmp_path: Path, edit: tuple[str, str],
                                                                   expected: str) -> None:
    cfg = _write(tmp_path, LONG.replace(*edit))
    for cmd in ("validate", "up") if "options" in expected else ("validate",):
        r = run_cli(cmd, str(cfg), timeout=30)
        assert r.returncode == 2, r.stdout + r.stderr
        assert f"{cfg}: {expected}" in r.stderr and "Traceback" not in r.stderr
        assert len(r.stderr.strip().splitlines()) == 1, r.stderr


def test_command_line_errors_are_one_line_exit_2(tmp_path: Path) -> None:
    cfg = _write(tmp_path, LONG)
    latin1 = tmp_path / "latin1.toml"
    latin1.write_bytes(LONG.replace('name = "e2e"', 'name = "caf\xe9"').encode("latin-1"))
    cases = [
        (["up", str(cfg), "--assert", "station[0x99].late == 0"], "expected a station of the configuration"),
        (["master", str(cfg), "--endpoint", "0x99=127.0.0.1:1"], "--endpoint 99H: not a station of"),
        (["slave", "--config", str(cfg), "--endpoint", "0x99=127.0.0.1:0"], "--endpoint 99H: not a station of"),
        (["slave", "--card", "si-t3", "--station", "0x21", "--link", "ml3"], "--link ML3: si-t3 speaks"),
        (["slave", "--card", "si-et3", "--station", "0x03", "--link", "ml2"], "--link ML2: si-et3 speaks"),
        (["up", str(cfg), "--report", str(tmp_path / "no" / "such" / "r.json")], "does not exist"),
        (["validate", str(latin1)], "not a UTF-8 text file (byte 0xe9"),
        (["up", str(latin1)], "not a UTF-8 text file"),
        (["probe", "127.0.0.1:1", "--station", "0x21", "--timeout", "-1"], "--timeout"),
    ]
    for args, expected in cases:
        t0 = time.monotonic()
        r = run_cli(*args, timeout=30)
        assert r.returncode == 2, (args, r.stdout, r.stderr)
        assert expected in r.stderr and "Traceback" not in r.stderr, (args, r.stderr)
        assert time.monotonic() - t0 < 15, args  # refused before the run, not after it


def test_address_already_in_use_names_the_address(slave) -> None:
    s = slave("--card", "si-t3", "--station", "0x21", "--listen", "127.0.0.1:0")
    r = run_cli("slave", "--card", "si-t3", "--station", "0x21", "--listen", f"127.0.0.1:{s.port}")
    assert r.returncode == 2, r.stderr
    assert f"127.0.0.1:{s.port}" in r.stderr and "in use" in r.stderr and "Traceback" not in r.stderr


# -- quiet as a library ------------------------------------------------------------------------------------------------

LIBRARY_USE = """
import asyncio, sys
from mlink_sim.aio.run.session import NetworkSession
from mlink_sim.config import load_config

async def main(path):
    session = await NetworkSession.open(load_config(path), path)
    try:
        await session.bring_up(20.0)
        session.net.kill_slave(0x21)        # logs a warning, then a worker exit and a restart
        await asyncio.sleep(1.5)
    finally:
        await session.close()

asyncio.run(main(sys.argv[1]))
print("done")
"""


def test_library_use_prints_no_log_lines(tmp_path: Path) -> None:
    cfg = _write(tmp_path, LONG)
    r = subprocess.run([sys.executable, "-c", LIBRARY_USE, str(cfg)], capture_output=True, text=True, timeout=90)
    assert r.returncode == 0, r.stdout + r.stderr
    assert r.stdout == "done\n" and r.stderr == ""
    # the same run with logging configured by the application logs through the standard library
    configured = LIBRARY_USE.replace("import asyncio, sys", "import asyncio, sys, logging\n"
                                     "logging.basicConfig(level=logging.INFO, stream=sys.stderr)")
    r = subprocess.run([sys.executable, "-c", configured, str(cfg)], capture_output=True, text=True, timeout=90)
    assert r.returncode == 0 and r.stdout == "done\n"
    assert "killing_slave" in r.stderr and "mlink_sim" in r.stderr


# -- shipped examples by name, from any folder -------------------------------------------------------------------------

def test_examples_by_name_from_any_folder(tmp_path: Path) -> None:
    r = run_cli("validate", "quickstart", cwd=tmp_path)
    assert r.returncode == 0 and "network 'quickstart', 3 station(s)" in r.stdout, r.stderr
    r = run_cli("validate", "configs/quickstart.toml", cwd=tmp_path)  # the README's path, outside the repository
    assert r.returncode == 0, r.stderr
    r = run_cli("validate", "quickstrat", cwd=tmp_path)
    assert r.returncode == 2 and "shipped examples, usable by name: " in r.stderr and "quickstart" in r.stderr


def test_pytest_marker_takes_a_shipped_example_by_name(tmp_path: Path) -> None:
    (tmp_path / "test_line.py").write_text(
        "import pytest\n\n"
        "@pytest.mark.mlink_network('quickstart')\n"
        "def test_up(mlink_network):\n"
        "    assert len(mlink_network.config.station) == 3\n"
        "    mlink_network.wait(0.3)\n")
    r = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "test_line.py"],
                       cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stdout + r.stderr
    assert "1 passed" in r.stdout


def test_the_wheel_ships_the_examples(tmp_path: Path) -> None:
    repo = Path(__file__).resolve().parents[2]
    r = subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-q", "-w",
                        str(tmp_path), str(repo)], capture_output=True, text=True, timeout=300)
    if r.returncode != 0:
        pytest.skip(f"cannot build a wheel here: {r.stderr.strip()[-200:]}")
    import zipfile

    [wheel] = tmp_path.glob("mlink_sim-*.whl")
    names = zipfile.ZipFile(wheel).namelist()
    shipped = sorted(n.rsplit("/", 1)[1] for n in names if n.startswith("mlink_sim/examples/") and
                     n.endswith(".toml"))
    assert "quickstart.toml" in shipped
    assert shipped == sorted(p.name for p in (repo / "configs").glob("*.toml"))
    assert "LICENSE" in " ".join(names) or any(n.endswith("licenses/LICENSE") for n in names)


# -- the live status ---------------------------------------------------------------------------------------------------

#: A run of 3.5 s.
SHORT = _net("0.5s", "2.5s")


def _run_in_pty(args: list[str], cols: int, rows: int, timeout: float = 90) -> tuple[int, bytes]:
    import fcntl
    import pty
    import struct
    import termios

    pid, fd = pty.fork()
    if pid == 0:  # the child: a terminal of cols × rows
        fcntl.ioctl(0, termios.TIOCSWINSZ, struct.pack("HHHH", rows, cols, 0, 0))
        os.environ.update(COLUMNS=str(cols), LINES=str(rows), TERM="xterm")
        os.execv(sys.executable, [sys.executable, "-m", "mlink_sim", *args])
    out = b""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        try:
            chunk = os.read(fd, 65536)
        except OSError:
            break
        if not chunk:
            break
        out += chunk
    _, status = os.waitpid(pid, 0)
    os.close(fd)
    return os.waitstatus_to_exitcode(status), out


def test_live_status_fits_a_small_terminal_without_piling_frames(tmp_path: Path) -> None:
    pyte = pytest.importorskip("pyte")
    cfg = _write(tmp_path, SHORT.replace('name = "e2e"', 'name = "tinyterm"'))
    cols, rows = 60, 4
    code, out = _run_in_pty(["up", str(cfg)], cols, rows)
    assert code in (0, 1), out.decode(errors="replace")[-2000:]  # the checks' outcome is not the point here
    screen = pyte.HistoryScreen(cols, rows, history=10_000)
    stream = pyte.ByteStream(screen)
    stream.feed(out)
    history = ["".join(ch.data for ch in line.values()) for line in screen.history.top]
    shown = history + list(screen.display)
    frames = [ln for ln in shown if ln.startswith("tinyterm  ")]
    assert len(frames) == 1, "\n".join(shown)  # one frame, redrawn in place; no copies in the scrollback
    assert "/3.5 s" in frames[0] and "p99" in frames[0]
    assert any("== tinyterm: 2 stations" in ln for ln in shown)  # the summary follows the last frame
    assert all(len(ln.rstrip()) <= cols for ln in shown)


def test_status_is_plain_lines_off_a_terminal_and_log_json_keeps_stderr_json(tmp_path: Path) -> None:
    cfg = _write(tmp_path, SHORT)
    r = run_cli("up", str(cfg), "--duration", "2s", "--log-json", "--log-level", "info", timeout=90)
    assert r.returncode in (0, 1), r.stdout + r.stderr  # on a loaded machine a check may fail: not the point here
    assert "\x1b[" not in r.stdout  # no cursor movement when stdout is a pipe
    assert "e2e  2.0/2.0 s  p99 " in r.stdout  # the last frame, as plain lines
    lines = r.stderr.splitlines()
    assert lines, "expected log lines"
    for line in lines:
        json.loads(line)  # every line of stderr is a JSON document
    assert any(json.loads(ln).get("event") == "steps_cut" for ln in lines)  # the --duration notice too
