"""Slave worker processes for ``mlink-sim up``: start, wait until ready, watch, restart, stop – no orphans.

Each worker runs ``python -m mlink_sim slave --config CONFIG --only ADDRS --ready-json`` and prints one JSON
``ready`` line on stdout once every station it hosts is listening (ports chosen by the OS on the first start and
kept on restarts). Its log goes to ``RUN_DIR/worker-N.log``. Children get ``PR_SET_PDEATHSIG`` (Linux), so even a
``kill -9`` of the supervisor leaves no orphan; a normal stop sends SIGTERM, then SIGKILL after a grace period.
Each worker runs in a process group of its own, so a Ctrl-C at the terminal reaches only the supervisor.

Touches: child processes (their process groups, their log files in the run directory) and their stdout's ready line.
"""

from __future__ import annotations

import asyncio
import ctypes
import json
import os
import signal
import sys
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..._log import get_logger
from ...operations import request_of
from ..control.endpoint import query_control
from ..slave.faults import PlantError
from ..timing.realtime import unplace_child

__all__ = ["WorkerSpec", "Worker", "WorkerError", "child_setup", "die_with_parent", "plan_workers", "parse_workers",
           "resolve_workers"]

log = get_logger("mlink_sim.supervisor")

_PR_SET_PDEATHSIG = 1


def child_setup() -> None:
    """A child process's ``preexec_fn`` (it runs between fork and exec): a process group of its own, the death of
    its parent, ordinary scheduling (the workers, the web server of ``up --web``)."""
    # A process group of its own: the terminal's Ctrl-C reaches `up` only, which DISCONNECTs the stations first
    # and then stops the workers. (uvloop's subprocess has no process_group argument.)
    os.setpgid(0, 0)
    die_with_parent()
    unplace_child()  # a worker begins with ordinary scheduling on every CPU, then asks for its own


def die_with_parent() -> None:
    """A child's ``preexec_fn`` (it runs between fork and exec): the child gets SIGTERM when its parent dies, even
    of a kill -9, so no process is left behind (Linux ``PR_SET_PDEATHSIG``; elsewhere nothing)."""
    try:
        libc = ctypes.CDLL("libc.so.6", use_errno=True)
        libc.prctl(_PR_SET_PDEATHSIG, signal.SIGTERM)
    except OSError:  # pragma: no cover - not Linux
        pass


class WorkerError(RuntimeError):
    """A worker that could not be started; the message says why (and where its log is)."""


def parse_workers(text: str | int | None) -> int | str:
    """A ``--workers`` value: a number ≥ 1, ``auto`` (also for None) or ``station``; ValueError says what is
    expected."""
    if text is None:
        return "auto"
    if isinstance(text, int) and not isinstance(text, bool):
        value = text
    else:
        word = str(text).strip().lower()
        if word in ("auto", "station"):
            return word
        try:
            value = int(word)
        except ValueError:
            raise ValueError(f"expected a number of processes (≥ 1), 'auto' or 'station', got {text!r}") from None
    if value < 1:
        raise ValueError(f"expected a number of processes (≥ 1), 'auto' or 'station', got {value}")
    return value


def resolve_workers(spec: int | str | None, stations: int, cpus: int | None = None) -> int | None:
    """How many worker processes host *stations* stations (None: one process per station).

    ``auto`` (the default, also None): one process per station while there are at most ``max(2, CPUs − 1)``
    stations; beyond that, ``CPUs − 1`` processes (at least one), so that the master's cycle clock keeps a CPU of
    its own: every process wakes up for its own datagrams, and a wake-up costs CPU, so beyond a few stations one
    process per station takes more CPU for the same work and misses more cycles (docs/performance.md, "Packed
    slave workers"). ``station``: one process per station; a number: that many (round-robin, at most one per
    station)."""
    spec = parse_workers(spec)
    if spec == "station":
        return None
    if spec == "auto":
        cpus = cpus if cpus is not None else (os.cpu_count() or 1)
        packed = max(1, cpus - 1)
        return packed if stations > max(2, packed) else None
    return int(spec)


def plan_workers(addresses: list[int], workers: int | None) -> list[list[int]]:
    """Split station addresses over *workers* processes (None: one process per station), round-robin."""
    if not workers or workers >= len(addresses):
        return [[a] for a in addresses]
    groups: list[list[int]] = [[] for _ in range(workers)]
    for i, address in enumerate(addresses):
        groups[i % workers].append(address)
    return groups


@dataclass
class WorkerSpec:
    """What one worker process hosts and how to start it."""

    index: int
    config: Path
    addresses: list[int]
    run_dir: Path
    state_dir: Path | None = None
    endpoints: dict[int, tuple[str, int]] = field(default_factory=dict)  #: fixed after the first start
    extra_args: list[str] = field(default_factory=list)

    def argv(self) -> list[str]:
        args = [sys.executable, "-m", "mlink_sim", "slave", "--config", str(self.config), "--ready-json",
                "--only", ",".join(f"0x{a:02X}" for a in self.addresses)]  # fmt: skip
        for address, (host, port) in sorted(self.endpoints.items()):
            args += ["--endpoint", f"0x{address:02X}={host}:{port}"]
        if self.state_dir is not None:
            args += ["--state-dir", str(self.state_dir)]
        return args + self.extra_args

    @property
    def log_path(self) -> Path:
        return self.run_dir / f"worker-{self.index}.log"


class Worker:
    """One slave worker process and its lifecycle."""

    def __init__(self, spec: WorkerSpec, *, on_exit: Callable[[Worker, int], None] | None = None) -> None:
        self.spec = spec
        self.on_exit = on_exit
        self.proc: asyncio.subprocess.Process | None = None
        self.ready: dict[str, Any] | None = None
        self.restarts = 0
        self.stopping = False
        self._watch: asyncio.Task[None] | None = None

    @property
    def pid(self) -> int | None:
        return self.proc.pid if self.proc else None

    @property
    def alive(self) -> bool:
        return self.proc is not None and self.proc.returncode is None

    @property
    def control_port(self) -> int | None:
        return None if self.ready is None else self.ready.get("control")

    async def ask(self, op: str, timeout: float = 1.0, **args: Any) -> dict[str, Any] | None:
        """The reply of the worker's control endpoint to the operation *op* with *args* (by their Python names), or
        None when it does not run or did not answer within *timeout* s."""
        port = self.control_port
        if not (self.alive and port):
            return None
        request = request_of(op, **args)
        return await query_control("127.0.0.1", port, request.pop("op"), timeout=timeout, **request)

    async def drive_fault(self, station: int, fault: Any) -> int:
        """Apply the drive fault *fault* (a :mod:`mlink_sim.faults.spec` value) to *station*'s drive in the worker,
        which ends it by itself after its ``for``; the fault's handle. :class:`PlantError` when the worker refused
        or did not answer."""
        fields = {("for_" if k == "for" else k): v for k, v in fault.as_fields().items()}
        reply = await self.ask("fault", station=station, **fields)
        if reply is None:
            raise PlantError(f"the slave of station {station:02X}H did not answer the drive-fault request")
        if not reply.get("ok"):
            raise PlantError(str(reply.get("error")))
        return int(reply.get("handle", 0))

    async def release_drive_fault(self, station: int, handle: int) -> None:
        """End the drive fault *handle* of *station* on the worker now (``heal``); one the worker released already
        (its ``for`` ran out) is no error."""
        await self.ask("release", station=station, handle=handle)

    async def drive_activity(self, station: int) -> Any:
        """What *station*'s drive model is doing (:class:`~mlink_sim.drive.activity.DriveActivity`), asked of the
        worker; None when it does not answer within 0.5 s."""
        from ...drive.activity import DriveActivity

        reply = await self.ask("drive", timeout=0.5, station=station)
        if not reply or not reply.get("ok"):
            return None
        try:
            return DriveActivity.from_dict(reply["activity"])
        except (ValueError, KeyError, TypeError):
            return None

    def log_tail(self, lines: int = 8) -> str:
        try:
            text = self.spec.log_path.read_text(errors="replace").splitlines()
        except OSError:
            return ""
        return "\n".join(text[-lines:])

    async def start(self, timeout: float = 15.0) -> dict[str, Any]:
        """Start the process and wait for its ready line; raises :class:`WorkerError`."""
        self.stopping = False
        self.spec.run_dir.mkdir(parents=True, exist_ok=True)
        logf = open(self.spec.log_path, "ab")  # noqa: SIM115 - handed to the child
        try:
            self.proc = await asyncio.create_subprocess_exec(
                *self.spec.argv(),
                stdin=asyncio.subprocess.DEVNULL,
                stdout=asyncio.subprocess.PIPE,
                stderr=logf,
                preexec_fn=child_setup,
                env={**os.environ, "PYTHONUNBUFFERED": "1"},
            )
        finally:
            logf.close()
        assert self.proc.stdout is not None
        try:
            line = await asyncio.wait_for(self.proc.stdout.readline(), timeout)
        except TimeoutError:
            await self.stop()
            raise WorkerError(
                f"worker {self.spec.index} was not ready after {timeout:g}s (log: {self.spec.log_path})") from None
        try:
            ready = json.loads(line)
            if ready.get("event") != "ready":
                raise ValueError(line)
        except ValueError:
            await self.stop()
            tail = self.log_tail()
            raise WorkerError(
                f"worker {self.spec.index} for stations {self._names()} did not start"
                + (f":\n{tail}" if tail else f" (log: {self.spec.log_path})")
            ) from None
        self.ready = ready
        for st in ready["stations"]:
            self.spec.endpoints[st["address"]] = (st["host"], st["port"])
        self._watch = asyncio.get_running_loop().create_task(self._watch_exit())
        log.info("worker_ready", worker=self.spec.index, pid=self.proc.pid, stations=self._names())
        return ready

    def _names(self) -> str:
        return ",".join(f"{a:02X}H" for a in self.spec.addresses)

    async def _watch_exit(self) -> None:
        assert self.proc is not None
        proc = self.proc
        # keep draining stdout so the child never blocks on a full pipe
        assert proc.stdout is not None
        while await proc.stdout.readline():
            pass
        code = await proc.wait()
        if not self.stopping and self.on_exit is not None:
            self.on_exit(self, code)

    async def restart(self) -> dict[str, Any]:
        self.restarts += 1
        return await self.start()

    async def stop(self, grace: float = 3.0) -> None:
        """SIGTERM, then SIGKILL after *grace* seconds; idempotent."""
        self.stopping = True
        proc = self.proc
        if proc is None or proc.returncode is not None:
            return
        try:
            proc.send_signal(signal.SIGTERM)
        except ProcessLookupError:
            return
        try:
            await asyncio.wait_for(proc.wait(), grace)
        except TimeoutError:
            log.warning("worker_kill", worker=self.spec.index, pid=proc.pid)
            try:
                proc.kill()
            except ProcessLookupError:
                pass
            await proc.wait()
        if self._watch is not None:
            try:
                await asyncio.wait_for(self._watch, 1.0)
            except (TimeoutError, asyncio.CancelledError):
                self._watch.cancel()

    def kill(self) -> None:
        """SIGKILL without waiting (used by a scenario step that simulates a crashed slave)."""
        if self.proc is not None and self.proc.returncode is None:
            self.proc.kill()
