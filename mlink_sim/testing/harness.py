"""A whole network running beside a test: :class:`RunningNetwork`.

The network (slave worker processes + one master per link, exactly as ``mlink-sim up`` runs them) is hosted by
a child process (:mod:`mlink_sim.testing.host`), so the cycle keeps its timing whatever the test does with its
own interpreter; the test talks to it over a loopback socket. Every method is a plain blocking call;
``net.aio`` offers the request methods as awaitables for ``async def`` tests.

    with RunningNetwork("configs/quickstart.toml") as net:      # bring-up done on entry
        net.set_param(0x21, "C1-01", 1.0)                        # PRM_WR and CONFIG: a 1 s ramp from now on
        net.run(0x21, hz=30)                                     # forward at 30 Hz (o1-03 units handled)
        net.wait_until(lambda: net.output_hz(0x21) > 29.9, timeout=10)
        assert net.get_param(0x21, "C1-01") == 1.0               # PRM_RD C1-01 through the master
        assert net.metrics.rtt.p99 < 0.5e-3                      # live figures, seconds
        net.check("missed == 0", "station[0x21].rtt.p99 < 1ms")  # the --assert language

The network's operations are :class:`~mlink_sim.operations.NetworkOperations`' methods, performed in the host by the
handlers a control request reaches; the bare master requests (``prm_rd``, ``prm_wr``, ``send_config``, ``id_rd``,
``alm_rd``, ``alm_clr``, ``set_control``) stay beside them for tests of a master's own handling.
"""

from __future__ import annotations

import asyncio
import json
import os
import select
import socket
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable
from pathlib import Path
from types import SimpleNamespace
from typing import Any

from ..aio.run.supervisor import parse_workers
from ..config import Config, load_config, resolve_config_path
from ..master.types import (ParamRequestError, ParamValue, RequestTimeout, StationAlarmError, StationState,
                            StationView)
from ..operations import NetworkOperations, OpError, request_of
from ..scenario import CheckResult, StationViews, speed_scale
from .faults import FaultMethods
from .metrics import ReportChecks
from .wait import poll_until

__all__ = ["RunningNetwork", "NetworkNotUp", "HostError"]


class NetworkNotUp(RuntimeError):
    """Bring-up did not complete: ``problems`` says which station is stuck where."""

    def __init__(self, problems: list[str]) -> None:
        super().__init__("network did not come up: " + "; ".join(problems))
        self.problems = problems


class HostError(RuntimeError):
    """The network's host process failed (did not start, died, or answered with an error of another kind)."""


def _decode(value: Any) -> Any:
    if isinstance(value, dict):
        if set(value) == {"bytes"}:
            return bytes.fromhex(value["bytes"])
        if set(value) == {"param"}:
            return ParamValue(**value["param"])
        return SimpleNamespace(**{k: _decode(v) for k, v in value.items()})
    if isinstance(value, list):
        return [_decode(v) for v in value]
    return value


def _raise(error: dict[str, Any]) -> None:
    kind, message = error.get("type"), error.get("message", "")
    if kind == "OpError":
        raise OpError(str(error.get("kind", "bad_request")), message)
    if kind == "StationAlarmError":
        raise StationAlarmError(error.get("station", 0), error.get("code", 0), error.get("name", ""), message)
    if kind == "ParamRequestError":
        raise ParamRequestError(error.get("station", 0), error.get("name", ""), error.get("allowed", ""), message)
    if kind == "RequestTimeout":
        exc = RequestTimeout(error.get("station", 0), error.get("command", "?"), error.get("attempts", 0),
                             error.get("busy", 0))
        exc.args = (message,)
        raise exc
    if kind in ("TimeoutError",):
        raise TimeoutError(message)
    if kind in ("ValueError", "KeyError"):
        raise ValueError(message)
    raise HostError(f"{kind}: {message}")


class _AsyncApi:
    """``await net.aio.prm_rd(...)`` etc. for ``async def`` tests (each call runs in a worker thread)."""

    _METHODS = frozenset({"prm_rd", "prm_wr", "send_config", "id_rd", "alm_rd", "alm_clr", "get_param",
                          "set_param", "alarm_clear", "enter", "disconnect", "connect", "fault"})

    def __init__(self, owner: RunningNetwork) -> None:
        self._owner = owner

    def __getattr__(self, name: str) -> Callable[..., Any]:
        if name not in self._METHODS:
            raise AttributeError(f"net.aio has no {name!r} (has: {', '.join(sorted(self._METHODS))})")
        fn = getattr(self._owner, name)

        async def call(*args: Any, **kwargs: Any) -> Any:
            return await asyncio.to_thread(fn, *args, **kwargs)

        return call


class RunningNetwork(NetworkOperations, StationViews, ReportChecks, FaultMethods):
    """The network of *config* (a TOML path), up for as long as the ``with`` block (or :meth:`start`/:meth:`close`).

    *workers* is ``up --workers``: a number of slave processes, ``"station"`` (one per station) or ``"auto"``
    (None, the default: one per station up to max(2, CPUs − 1) stations, else CPUs − 1); *seed* fixes the draws
    of the impairments (:meth:`impair`, docs/faults.md); *timeline* also runs
    the config's timeline (its checks: :meth:`wait_timeline`); *reset_after_bringup* starts the figures after
    bring-up so they describe the steady state; *log_level* is the host's (its log: :attr:`log_path`)."""

    def __init__(self, config: str | Path, *, workers: int | str | None = None, bringup_timeout: float = 10.0,
                 timeline: bool = False, reset_after_bringup: bool = True, state_dir: str | Path | None = None,
                 run_dir: str | Path | None = None, log_level: str | None = None, seed: int = 0) -> None:
        self.config_path = resolve_config_path(config)  # a path, or the name of a shipped example
        self.config: Config = load_config(self.config_path)
        self._args = [str(self.config_path), "--bringup-timeout", str(bringup_timeout),
                      "--log-level", log_level or os.environ.get("MLINK_SIM_LOG_LEVEL", "warning")]
        if workers is not None:
            self._args += ["--workers", str(parse_workers(workers))]  # ValueError here, not in the host
        if timeline:
            self._args.append("--timeline")
        if not reset_after_bringup:
            self._args.append("--no-reset")
        if seed:
            self._args += ["--seed", str(int(seed))]
        if state_dir:
            self._args += ["--state-dir", str(state_dir)]
        self.run_dir = Path(run_dir) if run_dir else Path(tempfile.mkdtemp(prefix="mlink-sim-test-"))
        self._args += ["--run-dir", str(self.run_dir)]
        self._bringup_timeout = bringup_timeout
        self._scales = {st.address: speed_scale(st) for st in self.config.station}
        self._links = {st.address: st.link for st in self.config.station}
        self._proc: subprocess.Popen[bytes] | None = None
        self._sock: socket.socket | None = None
        self._rfile: Any = None
        self._lock = threading.Lock()
        self._next_id = 0
        self.problems: list[str] = []
        self.final_report: dict[str, Any] | None = None
        self.aio = _AsyncApi(self)

    @property
    def log_path(self) -> Path:
        """The host's log (stderr); the slave workers log next to it (``worker-N.log``)."""
        return self.run_dir / "host.log"

    # ------------------------------------------------------------------ life cycle
    def start(self) -> RunningNetwork:
        """Start the host (slaves, masters), wait for bring-up; :class:`NetworkNotUp` if a station did not come
        up, :class:`HostError` if the host failed. Nothing is left running after either."""
        if self._proc is not None:
            raise RuntimeError("network already started")
        from ..aio.run.supervisor import die_with_parent as _die_with_parent

        self.run_dir.mkdir(parents=True, exist_ok=True)
        with open(self.log_path, "ab") as log:
            self._proc = subprocess.Popen(
                [sys.executable, "-m", "mlink_sim.testing.host", *self._args], stdin=subprocess.DEVNULL,
                stdout=subprocess.PIPE, stderr=log, preexec_fn=_die_with_parent,
                env={**os.environ, "PYTHONUNBUFFERED": "1"})
        try:
            ready = self._read_ready(timeout=self._bringup_timeout + 60.0)
            self.problems = list(ready.get("problems", []))
            if ready.get("not_up"):
                raise NetworkNotUp(ready["not_up"])
            self._sock = socket.create_connection(("127.0.0.1", ready["port"]), timeout=10.0)
            self._sock.settimeout(None)
            self._rfile = self._sock.makefile("rb")
        except BaseException:
            self._kill()
            raise
        return self

    def _read_ready(self, timeout: float) -> dict[str, Any]:
        assert self._proc is not None and self._proc.stdout is not None
        out = self._proc.stdout
        ready, _, _ = select.select([out], [], [], timeout)
        line = out.readline() if ready else b""
        try:
            msg = json.loads(line) if line else {}
        except ValueError:
            msg = {}
        if msg.get("event") == "ready":
            return msg
        if msg.get("event") == "error":
            raise HostError(msg.get("message", "host failed"))
        tail = self._log_tail()
        raise HostError("the network host did not start" + (f":\n{tail}" if tail else f" (log: {self.log_path})"))

    def _log_tail(self, lines: int = 12) -> str:
        try:
            return "\n".join(self.log_path.read_text(errors="replace").splitlines()[-lines:])
        except OSError:
            return ""

    def close(self) -> dict[str, Any] | None:
        """DISCONNECT, stop masters and slaves, end the host; returns the final report (None if never up)."""
        if self._proc is None:
            return self.final_report
        try:
            if self._sock is not None and self._proc.poll() is None:
                self.final_report = self._rpc("stop", rpc_timeout=60.0)
        except (HostError, OSError, TimeoutError):
            pass
        finally:
            self._kill()
        return self.final_report

    def _kill(self) -> None:
        proc, self._proc = self._proc, None
        if self._sock is not None:
            self._sock.close()
            self._sock = self._rfile = None
        if proc is None:
            return
        try:
            proc.wait(timeout=15.0)
        except subprocess.TimeoutExpired:
            proc.terminate()
            try:
                proc.wait(timeout=5.0)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
        if proc.stdout is not None:
            proc.stdout.close()

    def __enter__(self) -> RunningNetwork:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.close()

    # ------------------------------------------------------------------ requests to the host
    def _rpc(self, method: str, *args: Any, rpc_timeout: float | None = 30.0, **kwargs: Any) -> Any:
        if self._sock is None or self._proc is None:
            raise RuntimeError("the network is not running")
        with self._lock:
            self._next_id += 1
            rid = self._next_id
            self._sock.settimeout(rpc_timeout)
            try:
                self._sock.sendall(json.dumps({"id": rid, "method": method, "args": args,
                                               "kwargs": kwargs}).encode() + b"\n")
                line = self._rfile.readline()
            except TimeoutError:
                raise TimeoutError(f"{method}: no answer from the network host after {rpc_timeout} s") from None
            finally:
                if self._sock is not None:
                    self._sock.settimeout(None)
        if not line:
            raise HostError(f"the network host went away (log: {self.log_path})\n{self._log_tail()}")
        reply = json.loads(line)
        if "error" in reply:
            _raise(reply["error"])
        return reply.get("result")

    # ------------------------------------------------------------------ the operations
    def _perform(self, op: str, **args: Any) -> dict[str, Any]:
        timeout = 30.0 if op in ("connect", "report") else 15.0
        return dict(self._rpc("op", request_of(op, **args), rpc_timeout=timeout))

    # ------------------------------------------------------------------ the bare master API, blocking
    def prm_rd(self, station: int, register: int | str, size: int = 2, *,
               timeout: float = 10.0) -> int | bytes | ParamValue:
        """PRM_RD of a parameter by name (``"C1-01"``: a :class:`~mlink_sim.master.ParamValue` in its unit) or by
        register (an unsigned int for ``size=2``, else the bytes); raises
        :class:`~mlink_sim.master.ParamRequestError` for a name, value or register the station's table refuses,
        and the station's alarm (:class:`~mlink_sim.master.StationAlarmError`: ``.code`` 0x94 A.94, ``.name`` …)."""
        return _decode(self._rpc("prm_rd", station, register, size, rpc_timeout=timeout + 5))

    def prm_wr(self, station: int, register: int | str, value: int | float | str, size: int = 2, *,
               timeout: float = 10.0) -> None:
        """PRM_WR by name in engineering units (``prm_wr(0x21, "C1-01", 5.0)``) or by register with the raw int:
        written, not entered (the drive keeps its value until :meth:`send_config`; :meth:`set_param` does both)."""
        self._rpc("prm_wr", station, register, value, size, rpc_timeout=timeout + 5)

    def send_config(self, station: int, mode: int = 0, *, timeout: float = 10.0) -> None:
        """CONFIG (enter the parameters written by PRM_WR; mode 1 also stores them in EEPROM)."""
        self._rpc("config", station, mode, rpc_timeout=timeout + 5)

    def id_rd(self, station: int, code: int, offset: int = 0, size: int = 8, *, timeout: float = 10.0) -> bytes:
        return _decode(self._rpc("id_rd", station, code, offset, size, rpc_timeout=timeout + 5))

    def alm_rd(self, station: int, mode: int = 0, index: int = 0, *, timeout: float = 10.0) -> Any:
        """ALM_RD: the decoded response body (attributes as in the wire layouts, e.g. ``.alm_data``)."""
        return _decode(self._rpc("alm_rd", station, mode, index, rpc_timeout=timeout + 5))

    def alm_clr(self, station: int, *, timeout: float = 10.0) -> None:
        self._rpc("alm_clr", station, rpc_timeout=timeout + 5)

    def set_control(self, station: int, **fields: Any) -> None:
        """Cyclic INV_CTL fields (forward, reverse, speed_ref [raw], fault_reset, ef0, …); others stay as set."""
        self._rpc("set_control", station, **fields)

    def _fault_episode(self, station: int) -> dict[str, Any] | None:
        return self._rpc("fault_episode", station)

    # ------------------------------------------------------------------ what the master sees
    @staticmethod
    def _view(d: dict[str, Any]) -> StationView:
        return StationView(**{**d, "state": StationState[d["state"]]})

    def view(self, station: int) -> StationView:
        """The master's :class:`~mlink_sim.master.StationView` of *station* (state, phase, status, alarm …)."""
        return self._view(self._rpc("view", station))

    def views(self) -> dict[int, StationView]:
        return {int(a): self._view(v) for a, v in self._rpc("views").items()}

    def wait(self, seconds: float) -> None:
        """Let the network cycle for *seconds*."""
        time.sleep(seconds)

    def wait_until(self, check: Callable[[], Any], timeout: float, interval: float = 0.02, *,
                   until: Callable[[Any], Any] | None = None) -> Any:
        """Poll *check* every *interval* s until it holds, or with *until*, until ``until(check())`` holds
        (``wait_until(lambda: net.output_hz(0x21), 10, until=lambda hz: hz > 29.5)``); return the last result.
        ``TimeoutError`` after *timeout* s, naming the last value seen."""
        return poll_until(check, until, timeout, interval, time.monotonic, time.sleep)

    def wait_timeline(self, timeout: float | None = None) -> list[CheckResult]:
        """Wait for the config's timeline (``timeline=True``) to finish; returns its checks."""
        t = timeout if timeout is not None else (self.config.run_length_ns or 0) / 1e9 + 30.0
        return [CheckResult(**c) for c in self._rpc("timeline", rpc_timeout=t + 5, timeout=t)]

    # ------------------------------------------------------------------ figures
    def report(self) -> dict[str, Any]:
        """The report document as of now (docs/report.md); after :meth:`close`, the final one."""
        if self._proc is None and self.final_report is not None:
            return self.final_report
        from ..metrics import NetworkMetrics

        snap = self._rpc("snapshot")
        report = NetworkMetrics.from_wire(snap["metrics"]).report(meta=snap["meta"])
        return report

    def reset_metrics(self) -> None:
        """Start the figures afresh from now."""
        self._rpc("reset_metrics")

    def __repr__(self) -> str:
        state = "running" if self._proc is not None else "stopped"
        return f"RunningNetwork({str(self.config_path)!r}, {len(self.config.station)} stations, {state})"
