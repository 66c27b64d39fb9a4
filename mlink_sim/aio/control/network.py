"""The operations of a running network (:data:`mlink_sim.operations.OPERATIONS` served by ``"network"``): the one
implementation the control endpoint, the HTTP API (through the endpoint), the Python API, the pytest plugin and
the timeline all call, so that one name does one thing wherever it is asked (docs/control.md).

    ops = NetworkOps(session, log)
    ops.handlers()["set-param"](station=0x21, param="C1-01", value=1.0, eeprom=False)   # an awaitable reply

Each handler takes its arguments as :func:`~mlink_sim.operations.parse_request` reads them (a station as its
address, ``hz`` as a float) and answers the reply's fields, or an awaitable of them for an operation that goes
through the station's master; it refuses with :class:`~mlink_sim.operations.OpError`: ``unknown_station``,
``unknown_param``, ``out_of_range`` (a speed beyond E1-04 / n011, a value outside its parameter's range),
``refused`` (the station's phase, or the station itself: A.94/A.95, CMD_ALM), ``unavailable`` (no answer in time).

Touches: the masters (INV_CTL fields, requests), the slave workers' stats endpoints (snapshots, at most once a second
while someone asks for the status), a thread for a report's figures.
"""

from __future__ import annotations

import asyncio
import inspect
import json
import time
from collections.abc import Awaitable, Callable, Sequence
from typing import Any

from ..._log import get_logger
from ...master.named import read_target
from ...master.types import MasterError, ParamRequestError, RequestTimeout, StationAlarmError
from ...operations import OpError, check_speed, station_name
from ...scenario.values import SpeedScale
from ...units import format_ns
from ..present.figures import NetworkFigures, station_key
from .endpoint import Encoded, Handler
from .events import RunLog
from .faults import FaultOps, ImpairmentOps

__all__ = ["NetworkOps", "SNAPSHOT_EVERY_S", "STATIONS_PER_STEP", "FAULT_RESET_S"]

log = get_logger("mlink_sim.control")

SNAPSHOT_EVERY_S = 1.0  #: the slaves' snapshots (DC bus, the cards' LEDs) are refreshed this often at most
#: a status of more stations is built and encoded this many at a time, the loop free in between: the figures of
#: many stations and their JSON together would hold the cycle (docs/performance.md, "The status")
STATIONS_PER_STEP = 4
FAULT_RESET_S = 0.05  #: how long ``fault-reset`` holds the fault reset of the cyclic command


class NetworkOps:
    """The operations of one running network (a :class:`~mlink_sim.aio.run.session.NetworkSession`), its events in
    *log*. *assertions*: the run's ``--assert`` expressions (evaluated into ``report``); *in_thread*: build a
    report's figures in a thread (the wall clock; the virtual clock builds them in place); *scales*: the stations'
    speed scales, when the run built them already."""

    def __init__(self, session: Any, log: RunLog, assertions: Sequence[Any] = (), *, in_thread: bool = True,
                 snapshot_every_s: float = SNAPSHOT_EVERY_S, scales: dict[int, SpeedScale] | None = None) -> None:
        self.session = session
        self.log = log
        self.assertions = list(assertions)
        self.in_thread = in_thread
        self.snapshot_every_s = snapshot_every_s
        self.figures = NetworkFigures(session.config)
        self.scales = scales or {a: SpeedScale(f.settings) for a, f in self.figures.by_address.items()}
        #: each station's maximum output frequency and its parameter (E1-04 / n011): every speed's bound
        self.tops = {st.address: (self.figures.by_address[st.address].settings.max_freq_hz, st.profile.max_frequency)
                     for st in session.config.station}
        self.plans = {sp.address: sp for m in session.masters.values() for sp in m.core.plan.stations}
        self.timeline: Any = None  #: the run's timeline (its steps, checks), once it runs
        self.impairments = ImpairmentOps(session, self._station_or_all, lambda: session.net.fault_control)
        self.faults = FaultOps(session, self._station_or_all)
        self._refreshed = float("-inf")
        self._refreshing: asyncio.Task[None] | None = None

    def handlers(self) -> dict[str, Handler]:
        """Operation name -> handler, for every operation a network serves."""
        own: dict[str, Handler] = {
            "network": self.network, "status": self.status, "report": self.report, "get-param": self.get_param,
            "run": self.run, "speed": self.speed, "stop": self.stop, "fault-reset": self.fault_reset,
            "ef0": self.ef0, "alarm-clear": self.alarm_clear, "set-param": self.set_param, "enter": self.enter,
            "disconnect": self.disconnect, "connect": self.connect, "kill-slave": self.kill_slave,
        }
        return {**own, **self._logged(self.impairments.handlers()), **self._logged(self.faults.handlers())}

    # -- reading ------------------------------------------------------------------------------------------------

    def network(self) -> dict[str, Any]:
        config = self.session.config
        cycle = config.network.transmission_cycle
        return {"name": config.network.name, "cycle": format_ns(cycle), "cycle_ns": cycle,
                "stations": [{"address": station_key(st.address), "name": station_name(st.address), "card": st.card,
                              "link": st.link.name if st.link is not None else None, "frame_size": st.frame_size}
                             for st in config.station],
                "timeline": [{"at_s": step.at / 1e9, "describe": step.describe}
                             for step in sorted(config.timeline, key=lambda s: s.at)]}

    def status(self, since: int = 0) -> Any:
        """The figures of every station, the network's elapsed time, step and host stalls, and the events after
        *since*. The slaves' snapshots are refreshed in the background (the first status waits for them)."""
        session = self.session
        refreshing = self._refresh_snapshots()
        first = refreshing is not None and not session.slave_snapshots and session.worker_list
        if not first and len(self.figures.by_address) <= STATIONS_PER_STEP:  # one step: as it is
            return self._status(since, self.figures.stations(session.net, session.metrics,
                                                             session.slave_snapshots or None))

        async def later() -> Encoded:
            if first:
                assert refreshing is not None
                await asyncio.shield(refreshing)
            self.figures.rtt.step(session.metrics)
            parts: list[str] = []
            addresses = list(self.figures.by_address)
            for i in range(0, len(addresses), STATIONS_PER_STEP):
                await asyncio.sleep(0)  # the cycle's callbacks run in between
                rows = [self.figures.station(a, session.net, session.slave_snapshots or None)
                        for a in addresses[i:i + STATIONS_PER_STEP]]
                parts.append(json.dumps(rows, separators=(",", ":"))[1:-1])
            head = json.dumps({"ok": True, **self._status(since, [])}, separators=(",", ":"))
            # the first '"stations":[]' is the key's: inside a JSON string a quote is always escaped
            return Encoded(head.replace('"stations":[]', '"stations":[' + ",".join(parts) + "]", 1))

        return later()

    def _status(self, since: int, stations: list[dict[str, Any]]) -> dict[str, Any]:
        session, timeline = self.session, self.timeline
        self.log.poll(timeline)
        events, seq = self.log.since(since)
        stalls = session.metrics.stalls
        step = timeline.current if timeline is not None else None
        return {"network": session.config.network.name, "elapsed_s": round(self.log.elapsed_s, 3),
                "step": step.describe if step is not None else None,
                "stalls": {**stalls.overview(), "policy": stalls.policy},
                "stations": stations, "events": events, "seq": seq}

    async def report_parts(self, *, slave_stats: bool = True) -> tuple[Any, dict[str, Any]]:
        """A copy of the figures with the timeline's checks so far, and the report's ``meta``: the report as
        ``--report`` would write it now is ``build_report`` of them (outside the loop where it can be)."""
        timeline = self.timeline
        not_run = [s.describe for s in timeline.not_run()] if timeline is not None else []
        metrics, meta = await self.session.snapshot(extra_meta={"interrupted": None, "not_run": not_run},
                                                    slave_stats=slave_stats)
        for c in timeline.results if timeline is not None else ():
            metrics.record_check(c.at_s, c.what, c.ok, c.detail, c.cause, station=c.station)
        return metrics, meta

    async def report(self) -> dict[str, Any]:
        """The report as ``--report`` would write it now: the figures so far, the checks made so far, the
        assertions evaluated on them (docs/report.md)."""
        from ...metrics import build_report

        metrics, meta = await self.report_parts()
        if not self.in_thread:
            return {"report": build_report(metrics, meta, self.assertions)}
        loop = asyncio.get_running_loop()
        return {"report": await loop.run_in_executor(None, build_report, metrics, meta, self.assertions)}

    def _refresh_snapshots(self) -> asyncio.Task[None] | None:
        """Ask the slaves for their snapshots in the background, at most once every :attr:`snapshot_every_s`;
        the refresh under way, if any."""
        loop = asyncio.get_running_loop()
        if (self._refreshing is not None or loop.time() - self._refreshed < self.snapshot_every_s
                or time.monotonic() - self.session.snapshots_at < self.snapshot_every_s):  # a trace took them
            return self._refreshing
        self._refreshed = loop.time()

        async def refresh() -> None:
            try:
                await self.session.refresh_slave_stats()
            except Exception as exc:  # noqa: BLE001 - the figures go without the snapshots this time
                log.warning("slave_stats_unread", error=repr(exc))
            finally:
                self._refreshing = None

        self._refreshing = loop.create_task(refresh())
        return self._refreshing

    # -- stations -----------------------------------------------------------------------------------------------

    def station(self, address: int) -> int:
        """*address* if it is a station of this network; ``unknown_station`` naming the stations otherwise."""
        if address not in self.plans:
            known = ", ".join(station_name(a) for a in self.plans)
            raise OpError("unknown_station", f"station {station_name(address)} is not a station of this network "
                                             f"({known})")
        return address

    def _station_or_all(self, address: int | None) -> list[int]:
        return list(self.plans) if address is None else [self.station(address)]

    def _connected(self, address: int, what: str) -> None:
        view = self.session.net.view(address)
        if view.phase < 2:
            raise OpError("refused", f"station {station_name(address)} is in phase {view.phase} "
                                     f"({view.state.value}): {what} needs a connection (phase 2 or 3)")

    def _figures(self, address: int) -> dict[str, Any]:
        return {"station": self.figures.station(address, self.session.net, self.session.slave_snapshots or None)}

    def _act(self, address: int, describe: str) -> dict[str, Any]:
        self.log.add("action", station=station_key(address), describe=describe)
        return self._figures(address)

    def _speed(self, address: int, hz: float) -> int:
        top, param = self.tops[address]
        return self.scales[address].to_raw(check_speed(hz, address, top, param))

    def run(self, station: int, hz: float, direction: str = "forward") -> dict[str, Any]:
        """The run command and the reference, sent every cycle from now on (SI-T3 Table 16, SI-ET3 Table 20)."""
        address = self.station(station)
        raw = self._speed(address, hz)
        self._connected(address, "a run command")
        self.session.net.set_control(address, forward=direction == "forward", reverse=direction == "reverse",
                                     speed_ref=raw)
        return self._act(address, f"run {direction} {hz:g} Hz")

    def speed(self, station: int, hz: float) -> dict[str, Any]:
        address = self.station(station)
        raw = self._speed(address, hz)
        self.session.net.set_control(address, speed_ref=raw)
        return self._act(address, f"speed {hz:g} Hz")

    def stop(self, station: int) -> dict[str, Any]:
        address = self.station(station)
        self.session.net.set_control(address, forward=False, reverse=False)
        return self._act(address, "stop")

    def fault_reset(self, station: int) -> Awaitable[dict[str, Any]]:
        address = self.station(station)
        net = self.session.net
        net.set_control(address, forward=False, reverse=False, fault_reset=True)

        async def release() -> dict[str, Any]:
            await asyncio.sleep(FAULT_RESET_S)
            net.set_control(address, fault_reset=False)
            return self._act(address, "fault reset")

        return release()

    def ef0(self, station: int) -> dict[str, Any]:
        address = self.station(station)
        self.session.net.set_control(address, ef0=True)
        return self._act(address, "external fault (EF0)")

    def kill_slave(self, station: int) -> dict[str, Any]:
        address = self.station(station)
        if not self.session.net.kill_slave(address):
            raise OpError("unavailable", f"station {station_name(address)}: kill-slave needs the slave processes "
                                         "of 'mlink-sim up' (or the virtual clock), not 'mlink-sim master'")
        return self._act(address, "kill-slave")

    # -- through the master -------------------------------------------------------------------------------------

    def alarm_clear(self, station: int) -> Awaitable[dict[str, Any]]:
        """ALM_CLR mode 0, clear the present faults and alarms (SI-T3 Table 15, SI-ET3 "ALM_CLR")."""
        address = self.station(station)
        self._connected(address, "ALM_CLR")

        async def clear() -> dict[str, Any]:
            await self._request(address, "ALM_CLR", self.session.net.alm_clr(address))
            return self._act(address, "alarm clear (ALM_CLR)")

        return clear()

    def enter(self, station: int, eeprom: bool = False) -> Awaitable[dict[str, Any]]:
        address = self.station(station)
        self._connected(address, "CONFIG")

        async def enter() -> dict[str, Any]:
            await self._request(address, "CONFIG", self.session.net.config(address, 1 if eeprom else 0))
            return self._act(address, "enter (CONFIG" + (", EEPROM)" if eeprom else ")"))

        return enter()

    def disconnect(self, station: int) -> Awaitable[dict[str, Any]]:
        address = self.station(station)

        async def disconnect() -> dict[str, Any]:
            await self._request(address, "DISCONNECT", self.session.net.disconnect(address))
            return self._act(address, "disconnect")

        return disconnect()

    def connect(self, station: int, timeout: float = 10.0) -> Awaitable[dict[str, Any]]:
        address = self.station(station)
        net = self.session.net

        async def connect() -> dict[str, Any]:
            await net.reconnect(address)
            try:
                await net.master(address).wait_until(lambda: net.view(address).at_target, timeout)
            except TimeoutError:
                raise OpError("unavailable", f"station {station_name(address)} did not get back to its phase "
                                             f"within {timeout:g} s") from None
            return self._act(address, "connect")

        return connect()

    def _param_target(self, address: int, param: str, what: str) -> None:
        try:
            read_target(self.plans[address], param)
        except ParamRequestError as exc:
            raise OpError("unknown_param", str(exc)) from None
        self._connected(address, what)

    def get_param(self, station: int, param: str) -> Awaitable[dict[str, Any]]:
        """PRM_RD of the parameter, its value in units (SI-T3 Table 8, SI-ET3 "PRM_RD")."""
        address = self.station(station)
        self._param_target(address, param, "PRM_RD")
        return self._read(address, param)

    def set_param(self, station: int, param: str, value: Any, eeprom: bool = False) -> Awaitable[dict[str, Any]]:
        """PRM_WR, then CONFIG (with *eeprom* CONFIG_MOD 1, saved: SI-T3 Table 12, SI-ET3 Table 15), and the value
        read back. Names, units and ranges are checked as in the config (docs/parameters.md) before anything is
        sent."""
        address = self.station(station)
        self._param_target(address, param, "PRM_WR")
        net = self.session.net

        async def write() -> dict[str, Any]:
            await self._request(address, "PRM_WR", net.prm_wr(address, param, value))
            await self._request(address, "CONFIG", net.config(address, 1 if eeprom else 0))
            reply = await self._read(address, param)
            row = reply["param"]
            self.log.add("action", station=station_key(address),
                         describe=f"set {row['name']} = {row['text']}" + (" (EEPROM)" if eeprom else ""))
            return reply

        return write()

    async def _read(self, address: int, param: str) -> dict[str, Any]:
        got = await self._request(address, "PRM_RD", self.session.net.prm_rd(address, param))
        return {"station": station_key(address),
                "param": {"name": got.name, "value": float(got), "unit": got.unit, "raw": got.raw,
                          "register": f"{got.register:04X}H", "text": str(got)}}

    async def _request(self, address: int, what: str, pending: Any) -> Any:
        """Await a master request, its errors as error kinds: the station refused it (``refused``), no answer in
        time (``unavailable``)."""
        try:
            return await pending
        except ParamRequestError as exc:
            raise OpError("out_of_range", str(exc)) from None
        except StationAlarmError as exc:
            raise OpError("refused", f"station {station_name(address)} refused {what}: {exc}") from None
        except RequestTimeout as exc:
            raise OpError("unavailable", str(exc)) from None
        except MasterError as exc:
            raise OpError("refused", f"station {station_name(address)}: {what}: {exc}") from None

    def _logged(self, handlers: dict[str, Handler]) -> dict[str, Handler]:
        """The fault operations that act, each request logged as an ``action`` event once it was done."""
        def wrap(name: str, fn: Callable[..., Any]) -> Handler:
            def note(station: int | None, reply: Any) -> None:
                got = reply if isinstance(reply, dict) else {}
                what = f"{name} {got['name']}" if got.get("name") else name
                what += f": {got['describe']}" if got.get("describe") else ""
                what += f" {', '.join(got['names'])}" if got.get("names") else ""
                self.log.add("action", station="all" if station is None else station_key(station), describe=what)

            def op(**args: Any) -> Any:
                reply = fn(**args)
                if not inspect.isawaitable(reply):
                    note(args.get("station"), reply)
                    return reply

                async def done() -> Any:
                    out = await reply
                    note(args.get("station"), out)
                    return out

                return done()

            return op

        return {name: wrap(name, fn) if name in ("impair", "heal", "fault") else fn for name, fn in handlers.items()}
