"""The shell a page's commands run in, as a reader runs them: one working folder per page (``configs/`` in it, as
in the repository) and a home of its own, so that nothing a command writes lands outside the page's temporary
folder; the commands through ``bash`` with the package's ``mlink-sim`` first on ``PATH``, output and
errors on one stream as a terminal shows them.

What a reader types and a test cannot take as it stands is turned into what the test can run, and back:

* a server's fixed loopback port (``--listen 127.0.0.1:47001``, ``--control 127.0.0.1:47100``, ``--web 8080``) is
  asked for as port 0, and the address the server prints (its ready, control or web line) is what the page's
  address means from then on: later commands, Python blocks and the update's output lines are mapped both ways;
* ``HOST:PORT`` in a command is the control endpoint started last on the page;
* a command ending in ``&``, one that printed what the page shows and goes on running, and a server (a slave, a
  proxy, the web server, a network that runs until Ctrl-C) that has printed nothing for :data:`QUIET_S` seconds
  are left running, as in a terminal of their own, until the page ends; then each gets Ctrl-C (SIGINT) and must
  end with 0 or 130;
* a command whose comment says ``until Ctrl-C`` runs for :data:`WATCH_S` seconds and gets Ctrl-C.
"""

from __future__ import annotations

import asyncio
import contextlib
import os
import re
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

__all__ = ["Command", "Shell", "Run", "commands_of", "console_of", "home_of", "at_home", "HOME_VARIABLES", "WATCH_S"]

REPO = Path(__file__).resolve().parents[2]
BIN = Path(sys.executable).parent
WATCH_S = 2.0  #: how long an ``until Ctrl-C`` command runs before it gets one
TIMEOUT_S = 60.0  #: a command that runs longer fails the page
READY_S = 30.0  #: how long a server may take to print its address
QUIET_S = 2.0  #: a server that printed nothing for this long is taken to be serving (left running)

_ADDR = r"(?:\d{1,3}(?:\.\d{1,3}){3}|localhost):\d+"
#: the line a server prints its address on, by what the option binds
_READY = {
    "listen-slave": re.compile(rf"slave ready: .* on ({_ADDR})"),
    "listen-proxy": re.compile(rf"mlink-sim proxy: ({_ADDR}) ->"),
    "control": re.compile(rf"control: ({_ADDR})"),
    "web": re.compile(rf"web: http://({_ADDR})/"),
}


#: a server whose ready line a command after it waits for, even where no fixed port of it is to be learnt
_SERVER = re.compile(r"\s*mlink-sim (?:slave|proxy|web)\b")
#: a line by which a network says it runs until Ctrl-C
_SERVING = re.compile(r"^running until Ctrl-C|^web: http")
_SERVER_READY = re.compile(r"(?:slave|proxy) ready:")


@dataclass
class Command:
    """One command of a block: its text as a reader types it, run in the background (``&``) or until Ctrl-C."""

    text: str
    background: bool = False
    until_ctrl_c: bool = False
    output: list[str] = field(default_factory=list)  #: what a console block shows it print
    typed: list[str] = field(default_factory=list)  #: a console block's lines of the command, as they stand


def _split_comment(line: str) -> tuple[str, str]:
    """*line* as ``(command, comment)``: the comment starts at a ``#`` outside quotes after a blank."""
    quote = None
    for i, ch in enumerate(line):
        if quote:
            if ch == quote:
                quote = None
        elif ch in "'\"":
            quote = ch
        elif ch == "#" and (i == 0 or line[i - 1] in " \t"):
            return line[:i].rstrip(), line[i + 1:].strip()
    return line.rstrip(), ""


def _command(text: str, comment: str) -> Command:
    background = text.endswith("&") and not text.endswith("&&")
    if background:
        text = text[:-1].rstrip()
    return Command(text, background=background, until_ctrl_c="until Ctrl-C" in comment)


def commands_of(source: str) -> list[Command]:
    """The commands of a ``sh`` block: comment lines left out, ``\\`` continuations joined."""
    out: list[Command] = []
    pending, comments = "", []
    for raw in source.splitlines():
        text, comment = _split_comment(raw)
        comments.append(comment)
        if not text.strip() and not pending:
            comments = []
            continue
        if text.endswith("\\"):
            pending += text[:-1].rstrip() + " "
            continue
        out.append(_command((pending + text).strip(), " ".join(comments)))
        pending, comments = "", []
    return out


def console_of(source: str) -> list[Command]:
    """The commands of a ``console`` block (``$ `` lines, ``\\`` continuations joined) with the lines each
    printed."""
    out: list[Command] = []
    continuing = False
    for raw in source.splitlines():
        if raw.startswith("$ ") or continuing:
            text, comment = _split_comment(raw[2:] if raw.startswith("$ ") else raw)
            if continuing:
                out[-1].text += " " + text.strip().removesuffix("\\").rstrip()
            else:
                out.append(_command(text.removesuffix("\\").rstrip(), comment))
            out[-1].typed.append(raw)
            continuing = text.endswith("\\")
            continue
        if not out:
            raise ValueError(f"a console block's output before its first command: {raw!r}")
        out[-1].output.append(raw)
    return out


@dataclass
class Run:
    """What one command did: its exit status (None: still running) and its lines so far."""

    text: str
    proc: subprocess.Popen[str]
    lines: list[str] = field(default_factory=list)
    done: threading.Event = field(default_factory=threading.Event)

    @property
    def status(self) -> int | None:
        return self.proc.poll()

    def read(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            self.lines.append(line.rstrip("\n"))
        self.done.set()

    def interrupt(self, timeout: float = 15.0) -> int:
        """Ctrl-C to the command's process group (as a terminal sends it), then its exit status."""
        if self.proc.poll() is None:
            os.killpg(self.proc.pid, signal.SIGINT)
            try:
                self.proc.wait(timeout)
            except subprocess.TimeoutExpired:
                os.killpg(self.proc.pid, signal.SIGKILL)
                self.proc.wait()
        self.done.wait(5)
        return self.proc.returncode

    def output(self) -> str:
        return "\n".join(self.lines)


#: the variables that name where a program keeps a user's files, as :func:`home_of` sets them
HOME_VARIABLES = ("HOME", "XDG_CONFIG_HOME", "XDG_DATA_HOME", "XDG_STATE_HOME", "XDG_CACHE_HOME",
                  "XDG_RUNTIME_DIR", "TMPDIR")


def home_of(root: Path) -> dict[str, str]:
    """A home of its own under *root* (``root/home``, its XDG folders, ``root/tmp``): a page's commands keep what
    they keep for a user there (``mlink-sim wireshark --install``: ``~/.local/lib/wireshark/plugins``), never in
    the home of whoever runs the tests."""
    home, tmp = root / "home", root / "tmp"
    folders = {"HOME": home, "XDG_CONFIG_HOME": home / ".config", "XDG_DATA_HOME": home / ".local" / "share",
               "XDG_STATE_HOME": home / ".local" / "state", "XDG_CACHE_HOME": home / ".cache",
               "XDG_RUNTIME_DIR": root / "run", "TMPDIR": tmp}
    for folder in folders.values():
        folder.mkdir(parents=True, exist_ok=True, mode=0o700)
    return {name: str(folder) for name, folder in folders.items()}


@contextlib.contextmanager
def at_home(root: Path, workdir: Path) -> Iterator[None]:
    """This process with :func:`home_of` *root* as its environment's home and *workdir* as its working folder, for
    a Python block run in it; then as it was."""
    saved = {name: os.environ.get(name) for name in HOME_VARIABLES}
    saved_tempdir = tempfile.tempdir
    os.environ.update(home_of(root))
    tempfile.tempdir = None  # gettempdir() asks TMPDIR again
    try:
        with contextlib.chdir(workdir):
            yield
    finally:
        for name, value in saved.items():
            if value is None:
                os.environ.pop(name, None)
            else:
                os.environ[name] = value
        tempfile.tempdir = saved_tempdir


class Shell:
    """The shell of one page (module docstring): its commands run in ``root/work`` with ``root/home`` as their
    home (:func:`home_of`)."""

    def __init__(self, root: Path) -> None:
        self.root = root
        self.workdir = root / "work"
        self.workdir.mkdir()
        (self.workdir / "configs").symlink_to(REPO / "configs")
        self.env = {**os.environ, **home_of(root), "PATH": f"{BIN}{os.pathsep}{os.environ.get('PATH', '')}",
                    "PYTHONUNBUFFERED": "1"}
        self.addresses: dict[str, str] = {}  #: the page's address -> the one its server printed
        self.control: str | None = None  #: the control endpoint started last (``HOST:PORT`` in a command)
        self.running: list[Run] = []
        self.status = 0  #: the exit status of the last command (``$?``)

    # --------------------------------------------------------------------------------------- the page's addresses
    def to_actual(self, text: str) -> str:
        """*text* with the page's addresses as the servers printed them, ``HOST:PORT`` as the last control endpoint."""
        for doc, actual in sorted(self.addresses.items(), key=lambda kv: -len(kv[0])):
            host, port = doc.rsplit(":", 1)
            ahost, aport = actual.rsplit(":", 1)
            text = re.sub(rf"(?<![\w.]){re.escape(doc)}(?!\d)", actual, text)
            text = re.sub(rf"""(["']){re.escape(host)}\1,\s*{port}\b""", rf"\g<1>{ahost}\g<1>, {aport}", text)
        if self.control is not None:
            text = text.replace("HOST:PORT", self.control)
        return text

    def to_page(self, text: str) -> str:
        """*text* (a printed line) with the servers' addresses as the page writes them."""
        for doc, actual in self.addresses.items():
            text = re.sub(rf"(?<![\w.]){re.escape(actual)}(?!\d)", doc, text)
        return text

    def _servers(self, text: str) -> tuple[str, list[tuple[str, str]]]:
        """*text* with each fixed loopback port a server binds asked for as port 0, and what to learn: ``(the
        page's address, the kind of line that prints it)``."""
        learn: list[tuple[str, str]] = []
        words = text.split()
        slave = "slave" in words[:3]

        def port0(match: re.Match[str]) -> str:
            option, host, port = match.group(1), match.group(2), match.group(3)
            if port == "0":
                return match.group(0)
            kind = {"--control": "control", "--web": "web"}.get(option) or (
                "listen-slave" if slave else "listen-proxy" if "proxy" in words[:3] else "web")
            page_host = "127.0.0.1" if host in (None, "0.0.0.0", "127.0.0.1", "localhost") else host
            learn.append((f"{page_host}:{port}", kind))
            if kind == "web":
                learn.append((f"localhost:{port}", kind))
            return f"{option} 127.0.0.1:0" if option != "--web" or host else f"{option} 0"

        def endpoint0(match: re.Match[str]) -> str:
            station, port = match.group(1), match.group(2)
            if port == "0":
                return match.group(0)
            name = f"{int(station[2:], 16) if station.lower().startswith('0x') else int(station.rstrip('hH'), 16):02X}H"
            learn.append((f"127.0.0.1:{port}", f"station {name}"))
            return f"--endpoint {station}=127.0.0.1:0"

        text = re.sub(r"(--listen|--control|--web)[ =](?:((?:\d{1,3}\.){3}\d{1,3}|localhost):)?(\d+)\b", port0, text)
        text = re.sub(r"--endpoint[ =](\w+)=(?:\d{1,3}\.){3}\d{1,3}:(\d+)\b", endpoint0, text)
        return text, learn

    # ---------------------------------------------------------------------------------------------- running
    def start(self, text: str) -> Run:
        """Start *text* (the page's command) with its output read as it comes."""
        text, learn = self._servers(self.to_actual(text))
        proc = subprocess.Popen(["bash", "-c", f"(exit {self.status}); {text}"], cwd=self.workdir, env=self.env,
                                stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                text=True, encoding="utf-8", errors="replace", start_new_session=True)
        run = Run(text, proc)
        threading.Thread(target=run.read, daemon=True).start()
        if learn:
            self._learn(run, learn)
        elif _SERVER.match(text):
            self._wait_for(run, _SERVER_READY)
        return run

    def _wait_for(self, run: Run, ready: re.Pattern[str]) -> None:
        """Until *run* printed a line *ready* finds (or ended)."""
        end = time.monotonic() + READY_S
        while time.monotonic() < end and not run.done.is_set():
            if any(ready.search(line) for line in run.lines):
                return
            time.sleep(0.05)

    def _learn(self, run: Run, learn: list[tuple[str, str]]) -> None:
        end = time.monotonic() + READY_S
        pending = dict(learn)
        while pending and time.monotonic() < end:
            for doc, kind in list(pending.items()):
                ready = _READY.get(kind) or re.compile(rf"slave ready: .* {kind} on ({_ADDR})")
                for line in run.lines:
                    found = ready.search(line)
                    if found:
                        self.addresses[doc] = found.group(1).replace("localhost", "127.0.0.1")
                        if kind == "control":
                            self.control = self.addresses[doc]
                        del pending[doc]
                        break
            if pending and run.done.is_set():
                break
            time.sleep(0.05)
        if pending:
            raise AssertionError(f"{run.text!r} printed no address for {sorted(pending)}:\n{run.output()}")
        if self.control and any(kind == "control" for _, kind in learn) and " slave " not in f" {run.text} ":
            _wait_brought_up(self.control, end)

    def run(self, command: Command, shown: Callable[[list[str]], bool] | None = None) -> Run:
        """Run *command* to its end, or (*shown*: a test of the lines so far) until it printed what the page shows
        and goes on: then it is left running (module docstring)."""
        run = self.start(command.text)
        if command.background:
            self.running.append(run)
            return run
        if command.until_ctrl_c:
            run.done.wait(WATCH_S)
            run.interrupt()
            self.status = run.proc.returncode
            return run
        end = time.monotonic() + TIMEOUT_S
        seen, quiet_since = 0, time.monotonic()
        while not run.done.wait(0.1):
            if len(run.lines) != seen:
                seen, quiet_since = len(run.lines), time.monotonic()
            serving = _SERVER.match(command.text) or any(_SERVING.search(line) for line in run.lines)
            if (shown is not None and shown(run.lines)) or (serving and time.monotonic() - quiet_since > QUIET_S):
                if run.done.wait(QUIET_S):
                    break
                self.running.append(run)
                return run
            if time.monotonic() > end:
                run.interrupt()
                raise AssertionError(f"{command.text!r} ran for more than {TIMEOUT_S:.0f} s:\n{run.output()}")
        run.proc.wait()
        self.status = run.proc.returncode
        return run

    def close(self) -> list[str]:
        """Ctrl-C to every command still running, last started first; what ended otherwise than 0 or 130."""
        bad = []
        for run in reversed(self.running):
            status = run.interrupt()
            if status not in (0, 130):
                bad.append(f"{run.text!r} ended with {status} after Ctrl-C:\n{run.output()}")
        self.running.clear()
        return bad


def _wait_brought_up(control: str, end: float) -> None:
    """Until the network behind *control* has every station at its phase: a reader's commands come after that."""
    from mlink_sim.aio.control.endpoint import query_control

    host, port = control.rsplit(":", 1)
    while time.monotonic() < end:
        reply = asyncio.run(query_control(host, int(port), "status", timeout=1.0))
        stations = (reply or {}).get("stations") or []
        if stations and all(s.get("phase") == 3 or s.get("connected") for s in stations):
            return
        time.sleep(0.1)
    raise AssertionError(f"the network at {control} did not bring its stations up")
