"""The web server of ``mlink-sim up --web`` / ``master --web``: ``mlink-sim web`` as a process of its own, pointed
at the run's control endpoint (docs/web.md).

A process of its own, so that serving the page and its plots never takes the master's loop: the server reads the
network through the control endpoint only (one status query at most ten times a second). The child gets a process
group of its own, dies with its parent (``PR_SET_PDEATHSIG``, :func:`~mlink_sim.aio.run.supervisor.child_setup`),
begins with ordinary scheduling on every CPU (not the master's real-time CPU) and runs at a lower priority (nice
10) than the network's processes. Both tokens reach it on its standard input, never on a command line; it answers
with one JSON line (``{"event": "ready", "url": …}``) once it listens. Its log lines go to the run's stderr.

Touches: one child process, its stdin and stdout pipes.
"""

from __future__ import annotations

import asyncio
import json
import os
import signal
import sys

from ..._log import get_logger
from .supervisor import WorkerError, child_setup

__all__ = ["WebProcess", "WebError"]

log = get_logger("mlink_sim.web")

_NICE = 10


class WebError(WorkerError):
    """The web server could not start (its own message, e.g. the address in use, is on stderr)."""


def _setup() -> None:  # runs in the child between fork and exec
    child_setup()
    os.nice(_NICE)


class WebProcess:
    """``mlink-sim web --control …`` listening on *listen* with *token* (None: none), logging as the run does."""

    def __init__(self, listen: tuple[str, int], token: str | None = None, *, log_json: bool = False) -> None:
        self.listen = listen
        self.token = token
        self.log_json = log_json
        self.url: str | None = None
        self.proc: asyncio.subprocess.Process | None = None
        self._drain: asyncio.Task[None] | None = None

    def argv(self, control: tuple[str, int]) -> list[str]:
        def where(host: str, port: int) -> str:
            return f"[{host}]:{port}" if ":" in host else f"{host}:{port}"

        return [sys.executable, "-m", "mlink_sim", "web", "--control", where(*control), "--listen",
                where(*self.listen), "--ready-json", "--tokens-stdin", *(["--log-json"] if self.log_json else [])]

    async def start(self, control: tuple[str, int], control_token: str | None, timeout: float = 60.0) -> str:
        """Start the server against the control endpoint at *control*; its URL once it listens. WebError: it did
        not start. *timeout* is generous: at nice 10 beside a busy network (62 stations on two CPUs) the server
        gets a small share of a CPU, and its start (importing aiohttp) takes seconds of it."""
        self.proc = await asyncio.create_subprocess_exec(
            *self.argv(control), stdin=asyncio.subprocess.PIPE, stdout=asyncio.subprocess.PIPE, stderr=None,
            preexec_fn=_setup, env={**os.environ, "PYTHONUNBUFFERED": "1"})
        assert self.proc.stdin is not None and self.proc.stdout is not None
        self.proc.stdin.write(json.dumps({"control_token": control_token, "web_token": self.token}).encode() + b"\n")
        await self.proc.stdin.drain()
        self.proc.stdin.close()
        try:
            line = await asyncio.wait_for(self.proc.stdout.readline(), timeout)
            ready = json.loads(line)
            if ready.get("event") != "ready":
                raise ValueError(line)
        except (TimeoutError, ValueError):
            await self.stop()
            raise WebError(f"the web server did not start on {self.listen[0]}:{self.listen[1]} (see above)") from None
        self.url = str(ready["url"])
        self._drain = asyncio.get_running_loop().create_task(self._drain_stdout())
        log.info("web_ready", url=self.url, pid=self.proc.pid)
        return self.url

    async def _drain_stdout(self) -> None:
        assert self.proc is not None and self.proc.stdout is not None
        while await self.proc.stdout.readline():
            pass

    async def stop(self, grace: float = 3.0) -> None:
        """SIGTERM, then SIGKILL after *grace* seconds; idempotent."""
        proc = self.proc
        if proc is None or proc.returncode is not None:
            return
        try:
            proc.send_signal(signal.SIGTERM)
            await asyncio.wait_for(proc.wait(), grace)
        except ProcessLookupError:
            return
        except TimeoutError:
            log.warning("web_kill", pid=proc.pid)
            proc.kill()
            await proc.wait()
        if self._drain is not None:
            self._drain.cancel()
            await asyncio.gather(self._drain, return_exceptions=True)
