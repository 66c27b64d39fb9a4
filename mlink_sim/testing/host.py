"""The process that hosts a network for :class:`~mlink_sim.testing.RunningNetwork`
(``python -m mlink_sim.testing.host``).

The test process must not share a GIL with the master's cycle (a test computing anything would delay it), so
the network — slave workers and masters, exactly as ``mlink-sim up`` runs them — lives in this process. It
prints one JSON line ``{"event": "ready", "port": P, "not_up": [...], "problems": [...]}`` on stdout once
bring-up is over, then serves requests on ``127.0.0.1:P``: one JSON object per line each way::

    → {"id": 7, "method": "prm_rd", "args": [33, 512]}
    ← {"id": 7, "result": 20}
    ← {"id": 7, "error": {"type": "StationAlarmError", "message": "…", "station": 33, "code": 148, "name": "…"}}

Methods: ``op`` (one of the network's operations, ``{"method": "op", "args": [{"op": "set-param", …}]}``,
performed by the same handlers as a control request: :mod:`mlink_sim.aio.control.network`), the bare master requests
of :class:`~mlink_sim.aio.run.netapi.NetworkApi` (``prm_rd`` … ``disconnect``), ``set_control``, ``view``, ``views``,
``fault_episode`` (docs/faults.md), ``snapshot`` (figures as bucket pairs + report meta; the client builds the report,
so the cycle is never held up by it), ``reset_metrics``, ``timeline`` (waits for the config's timeline and returns
its checks) and ``stop`` (DISCONNECT, final report, exit). SIGTERM, SIGINT or the
test process dying (``PR_SET_PDEATHSIG``) stop it too; its slave workers never outlive it.
"""

from __future__ import annotations

import argparse
import asyncio
import dataclasses
import json
import signal
import sys
from pathlib import Path
from typing import Any


from .._log import get_logger
from ..aio.control.endpoint import perform
from ..aio.control.events import RunLog
from ..aio.control.network import NetworkOps
from ..aio.control.timeline import TimelineRunner
from ..aio.run.session import NetworkSession
from ..aio.run.supervisor import resolve_workers
from ..aio.transport.udp import new_event_loop
from ..config import ConfigError, load_config
from ..jsonable import to_jsonable
from ..master.types import ParamValue
from ..scenario import Timeline, speed_scales
from .faults import episode_dict

log = get_logger("mlink_sim.testing.host")

#: the bare master requests (:class:`~mlink_sim.aio.run.netapi.NetworkApi`), for tests of a master's own handling
_REQUESTS = frozenset({"prm_rd", "prm_wr", "config", "id_rd", "alm_rd", "alm_clr"})


def encode_value(value: Any) -> Any:
    """A result as JSON: bytes as ``{"bytes": hex}``, a parameter read by name as ``{"param": {…}}``, dataclasses
    and mappings as objects."""
    if isinstance(value, ParamValue):
        return {"param": {"name": value.name, "value": float(value), "unit": value.unit, "raw": value.raw,
                          "register": value.register, "text": value.text}}
    if isinstance(value, (bytes, bytearray)):
        return {"bytes": bytes(value).hex()}
    return to_jsonable(value)


def encode_error(exc: BaseException) -> dict[str, Any]:
    out: dict[str, Any] = {"type": type(exc).__name__, "message": str(exc)}
    for name in ("station", "code", "name", "command", "attempts", "busy", "allowed", "kind"):
        value = getattr(exc, name, None)
        if isinstance(value, (int, str)):
            out[name] = value
    return out


class Host:
    """Serves one :class:`NetworkSession` to one test process."""

    def __init__(self, session: NetworkSession, *, timeline: bool, scales: dict[int, Any] | None = None) -> None:
        self.session = session
        self.stop = asyncio.Event()
        self.final: dict[str, Any] | None = None
        events = RunLog(next(iter(session.masters.values())).now_ns)
        for master in session.masters.values():
            events.watch(master)
        self.ops = NetworkOps(session, events, scales=scales)
        self.handlers = self.ops.handlers()
        self.scenario: Timeline | None = None
        self.scenario_task: asyncio.Task[None] | None = None
        if timeline:
            loop = asyncio.get_running_loop()
            self.scenario = self.ops.timeline = Timeline(session.config)
            self.scenario_task = loop.create_task(TimelineRunner(self.scenario, self.ops).run(loop.time()))

    async def handle(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        try:
            while line := await reader.readline():
                try:
                    req = json.loads(line)
                    rid, method, args = req.get("id"), req["method"], req.get("args", [])
                    kwargs = req.get("kwargs", {})
                except (ValueError, KeyError, TypeError, AttributeError) as exc:
                    reply: dict[str, Any] = {"id": None, "error": {"type": "ValueError",
                                                                   "message": f"bad request: {exc}"}}
                else:
                    try:
                        reply = {"id": rid, "result": await self.dispatch(method, args, kwargs)}
                    except Exception as exc:  # noqa: BLE001 - every failure goes back to the test as an error
                        reply = {"id": rid, "error": encode_error(exc)}
                writer.write(json.dumps(reply).encode() + b"\n")
                await writer.drain()
                if method == "stop":
                    break
        except (ConnectionError, asyncio.IncompleteReadError):
            pass
        finally:
            writer.close()

    async def dispatch(self, method: str, args: list[Any], kwargs: dict[str, Any]) -> Any:
        net = self.session.net
        assert net is not None
        if method == "op":
            return await perform(self.handlers, args[0])
        if method in _REQUESTS:
            return encode_value(await getattr(net, method)(*args, **kwargs))
        if method == "set_control":
            net.set_control(*args, **kwargs)
            return None
        if method == "view":
            return encode_value(net.view(*args))
        if method == "views":
            return {str(a): encode_value(v) for a, v in net.views().items()}
        if method == "fault_episode":
            return episode_dict(net.fault_control.stage(args[0]).latest(args[0]))
        if method == "snapshot":  # the report op's figures; the client builds the report
            metrics, meta = await self.ops.report_parts(slave_stats=kwargs.get("slave_stats", True))
            return {"metrics": metrics.to_wire(hdr=False), "meta": meta}
        if method == "reset_metrics":
            self.session.reset_metrics()
            return None
        if method == "timeline":
            if self.scenario is None or self.scenario_task is None:
                raise RuntimeError("the network was started without timeline=True")
            await asyncio.wait_for(asyncio.shield(self.scenario_task), kwargs.get("timeout"))
            results = self.scenario.results_naming_stalls(self.session.metrics.stalls)
            return [dataclasses.asdict(c) for c in results]
        if method == "stop":
            self.final = await self._final_report()
            self.stop.set()
            return self.final
        raise ValueError(f"unknown method {method!r}")

    async def _final_report(self) -> dict[str, Any]:
        if self.scenario_task is not None:
            self.scenario_task.cancel()
        await self.session.refresh_slave_stats()
        await self.session.close_masters()
        for c in self.scenario.results if self.scenario else []:
            self.session.metrics.record_check(c.at_s, c.what, c.ok, c.detail, c.cause, station=c.station)
        return await self.session.report(slave_stats=False)


async def serve(args: argparse.Namespace) -> int:
    loop = asyncio.get_running_loop()
    config = load_config(args.config)
    interrupted = asyncio.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        loop.add_signal_handler(sig, interrupted.set)
    scales = speed_scales(config) if args.timeline else None  # before the clock starts (scenario/timeline.py)
    workers = resolve_workers(args.workers, len(config.station))  # ValueError: reported as an error event
    session = await NetworkSession.open(config, Path(args.config), workers=workers,
                                        state_dir=args.state_dir, run_dir=args.run_dir, seed=args.seed)
    try:
        not_up = await session.bring_up(args.bringup_timeout)
        if args.reset:
            session.reset_metrics()
        host = Host(session, timeline=args.timeline, scales=scales)
        server = await asyncio.start_server(host.handle, "127.0.0.1", 0)
        port = server.sockets[0].getsockname()[1]
        print(json.dumps({"event": "ready", "port": port, "not_up": not_up, "problems": session.problems}),
              flush=True)
        waiters = [loop.create_task(host.stop.wait()), loop.create_task(interrupted.wait())]
        await asyncio.wait(waiters, return_when=asyncio.FIRST_COMPLETED)
        for w in waiters:
            w.cancel()
        server.close()
        await asyncio.sleep(0.05)  # let the reply to "stop" leave
    finally:
        await session.close()
    return 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m mlink_sim.testing.host", description=__doc__.splitlines()[0])
    parser.add_argument("config")
    parser.add_argument("--workers", default="auto", help="N, 'auto' or 'station' (as for mlink-sim up)")
    parser.add_argument("--bringup-timeout", type=float, default=10.0)
    parser.add_argument("--timeline", action="store_true")
    parser.add_argument("--no-reset", dest="reset", action="store_false")
    parser.add_argument("--state-dir", type=Path)
    parser.add_argument("--run-dir", type=Path)
    parser.add_argument("--log-level", default="warning")
    parser.add_argument("--seed", type=int, default=0, help="seed of the impairments' draws (docs/faults.md)")
    args = parser.parse_args(argv)
    from .._log import configure_logging
    from ..aio.run.supervisor import WorkerError

    configure_logging(level=args.log_level)
    loop = new_event_loop()
    try:
        return loop.run_until_complete(serve(args))
    except (ConfigError, WorkerError, OSError, ValueError) as exc:
        print(json.dumps({"event": "error", "message": str(exc)}), flush=True)
        return 1
    finally:
        loop.close()


if __name__ == "__main__":
    sys.exit(main())
