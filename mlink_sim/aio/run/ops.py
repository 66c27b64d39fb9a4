"""The control endpoint's operations on a running network (docs/control.md): see it (``network``, ``status``,
``report``) and steer it (``run``, ``stop``, ``alarm-clear``, ``param``), beside the faults' (``impair``, ``heal``,
``faults``, ``fault``, ``recovery``).

    → {"op": "status", "since": 12}
    ← {"ok": true, "elapsed_s": 4.2, "step": "…", "stalls": {…}, "stations": [figures…], "events": […], "seq": 15}
    → {"op": "param", "station": "0x21", "name": "C1-01", "value": 5.0, "id": "w1"}
    ← {"ok": true, "station": "0x21", "param": {"name": "C1-01", "value": 5.0, "unit": "s", "raw": 50,
                                               "register": "0200H", "text": "5.0 s"}}

Stations are named ``0x21``, ``21H`` or ``33``. Errors carry a ``kind`` (:data:`~.control.ERROR_KINDS`):
``unknown_station`` (no such station in this network), ``unknown_param`` (no such parameter on its card),
``out_of_range`` (a value outside the parameter's range or resolution, a speed beyond the maximum frequency),
``refused`` (the station's phase, or the station itself, refuses: not connected, A.94/A.95, CMD_ALM),
``unavailable`` (no answer in time), ``bad_request`` (anything else malformed).

``param`` and ``alarm-clear`` send PRM_RD / PRM_WR (+ CONFIG) / ALM_CLR through the station's master and answer once
it answers (the master's request time limit; the endpoint's :data:`~.control.ASYNC_LIMIT_S` at most).

Touches: the masters (INV_CTL fields, requests), the slave workers' stats endpoints (snapshots, at most once a second
while someone asks for the status), a thread for a report's figures.
"""

from __future__ import annotations

import asyncio
import json
import time
from collections.abc import Sequence
from typing import Any

from ..._log import get_logger
from ...master.named import read_target
from ...master.types import MasterError, ParamRequestError, RequestTimeout, StationAlarmError
from ...units import format_ns, parse_address
from .control import Encoded, Op, OpError
from .events import RunLog
from .figures import NetworkFigures, station_key
from .scenario import SpeedScale
from .session import build_report

__all__ = ["RunOps", "SNAPSHOT_EVERY_S", "STATIONS_PER_STEP"]

log = get_logger("mlink_sim.control")

SNAPSHOT_EVERY_S = 1.0  #: the slaves' snapshots (DC bus, the cards' LEDs) are refreshed this often at most
#: a status of more stations is built and encoded this many at a time, the loop free in between: a station's
#: figures and their JSON take about 15 µs, 62 stations' together a millisecond, one 1 ms cycle
STATIONS_PER_STEP = 4


class RunOps:
    """The operations of one running network (a :class:`~mlink_sim.aio.run.session.NetworkSession`), with its
    events in *log*. *assertions* are the run's ``--assert`` expressions (evaluated into ``report``); *in_thread*:
    build a report's figures in a thread (the wall clock; the virtual clock builds them in place)."""

    def __init__(self, session: Any, log: RunLog, assertions: Sequence[Any] = (), *, in_thread: bool = True,
                 snapshot_every_s: float = SNAPSHOT_EVERY_S) -> None:
        self.session = session
        self.log = log
        self.assertions = list(assertions)
        self.in_thread = in_thread
        self.snapshot_every_s = snapshot_every_s
        self.figures = NetworkFigures(session.config)
        self.scales = {a: SpeedScale(f.settings) for a, f in self.figures.by_address.items()}
        self.plans = {sp.address: sp for m in session.masters.values() for sp in m.core.plan.stations}
        self.scenario: Any = None  #: the timeline (its steps, checks), once it runs
        self._refreshed = float("-inf")
        self._refreshing: asyncio.Task[None] | None = None

    def ops(self, others: dict[str, Op] | None = None) -> dict[str, Op]:
        """This network's operations; *others* (the faults' ``impair``, ``heal``, ``fault``) are included, each
        request that acts logged as an ``action`` event."""
        own: dict[str, Op] = {"network": self.network, "status": self.status, "report": self.report,
                              "run": self.run, "stop": self.stop, "alarm-clear": self.alarm_clear,
                              "param": self.param}
        wrapped = {name: self._logged(name, fn) if name in ("impair", "heal", "fault") else fn
                   for name, fn in (others or {}).items()}
        return {**wrapped, **own}

    # -- reading ------------------------------------------------------------------------------------------------

    def network(self, request: dict[str, Any]) -> dict[str, Any]:
        config = self.session.config
        cycle = config.network.transmission_cycle
        return {"name": config.network.name, "cycle": format_ns(cycle), "cycle_ns": cycle,
                "stations": [{"address": station_key(st.address), "name": f"{st.address:02X}H", "card": st.card,
                              "link": st.link.name if st.link is not None else None, "frame_size": st.frame_size}
                             for st in config.station],
                "timeline": [{"at_s": step.at / 1e9, "describe": step.describe}
                             for step in sorted(config.timeline, key=lambda s: s.at)]}

    def status(self, request: dict[str, Any]) -> Any:
        """The figures of every station, the network's elapsed time, step and host stalls, and the events after
        ``since``. The slaves' snapshots are refreshed in the background (the first status waits for them)."""
        since = request.get("since", 0)
        if isinstance(since, bool) or not isinstance(since, int) or since < 0:
            raise OpError("bad_request", f"since: expected an event number (0, 1, …), got {since!r}")
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
        session, scenario = self.session, self.scenario
        self.log.poll(scenario)
        events, seq = self.log.since(since)
        stalls = session.metrics.stalls
        step = scenario.current if scenario is not None else None
        return {"network": session.config.network.name, "elapsed_s": round(self.log.elapsed_s, 3),
                "step": step.describe if step is not None else None,
                "stalls": {**stalls.overview(), "policy": stalls.policy},
                "stations": stations, "events": events, "seq": seq}

    async def report(self, request: dict[str, Any]) -> dict[str, Any]:
        """The report as ``--report`` would write it now: the figures so far, the checks made so far, the
        assertions evaluated on them (docs/report.md)."""
        scenario = self.scenario
        not_run = [s.describe for s in scenario.not_run()] if scenario is not None else []
        metrics, meta = await self.session.snapshot(extra_meta={"interrupted": None, "not_run": not_run})
        for c in scenario.results if scenario is not None else ():
            metrics.record_check(c.at_s, c.what, c.ok, c.detail, c.cause, station=c.station)
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

    # -- steering -----------------------------------------------------------------------------------------------

    def station(self, request: dict[str, Any]) -> int:
        """The request's ``station`` as an address of this network."""
        value = request.get("station")
        if value is None:
            raise OpError("bad_request", "station: missing (e.g. \"station\": \"0x21\")")
        try:
            address = parse_address(value)
        except ValueError as exc:
            raise OpError("bad_request", f"station: {exc}") from None
        if address not in self.plans:
            known = ", ".join(f"{a:02X}H" for a in self.plans)
            raise OpError("unknown_station", f"station {address:02X}H is not a station of this network ({known})")
        return address

    def _connected(self, address: int, what: str) -> None:
        view = self.session.net.view(address)
        if view.phase < 2:
            raise OpError("refused", f"station {address:02X}H is in phase {view.phase} ({view.state.value}): "
                                     f"{what} needs a connection (phase 2 or 3)")

    def _figures(self, address: int) -> dict[str, Any]:
        return {"station": self.figures.station(address, self.session.net, self.session.slave_snapshots or None)}

    def run(self, request: dict[str, Any]) -> dict[str, Any]:
        """``{"station", "direction": "forward"|"reverse", "speed_hz"}``: the run command and the reference, sent
        every cycle from now on (SI-T3 Table 16, SI-ET3 Table 20)."""
        address = self.station(request)
        direction = request.get("direction", "forward")
        if direction not in ("forward", "reverse"):
            raise OpError("bad_request", f"direction: 'forward' or 'reverse', got {direction!r}")
        hz = request.get("speed_hz")
        if isinstance(hz, bool) or not isinstance(hz, (int, float)):
            raise OpError("bad_request", f"speed_hz: expected a number of Hz, got {hz!r}")
        top = self.figures.by_address[address].settings.max_freq_hz
        if not 0 <= hz <= top:
            raise OpError("out_of_range", f"speed_hz: {hz:g} Hz is outside 0…{top:g} Hz (the maximum output "
                                          f"frequency of station {address:02X}H, E1-04 / n011)")
        self._connected(address, "a run command")
        self.session.net.set_control(address, forward=direction == "forward", reverse=direction == "reverse",
                                     speed_ref=self.scales[address].to_raw(hz))
        self.log.add("action", station=station_key(address), describe=f"run {direction} {hz:g} Hz")
        return self._figures(address)

    def stop(self, request: dict[str, Any]) -> dict[str, Any]:
        """``{"station"}``: the run command taken away (the drive stops as its stopping method says)."""
        address = self.station(request)
        self.session.net.set_control(address, forward=False, reverse=False)
        self.log.add("action", station=station_key(address), describe="stop")
        return self._figures(address)

    def alarm_clear(self, request: dict[str, Any]) -> Any:
        """``{"station"}``: ALM_CLR mode 0, clear the present faults and alarms (SI-T3 Table 15, SI-ET3
        "ALM_CLR"); answers once the station did."""
        address = self.station(request)
        self._connected(address, "ALM_CLR")

        async def clear() -> dict[str, Any]:
            await self._request(address, "ALM_CLR", self.session.net.alm_clr(address))
            self.log.add("action", station=station_key(address), describe="alarm clear (ALM_CLR)")
            return self._figures(address)

        return clear()

    def param(self, request: dict[str, Any]) -> Any:
        """``{"station", "name"}``: PRM_RD of the parameter, its value in units; with ``"value"`` PRM_WR first, then
        CONFIG (with ``"eeprom": true`` CONFIG_MOD 1, saved: SI-T3 Table 12, SI-ET3 Table 15), and the value read
        back. Names, units and ranges are checked as in the config (docs/parameters.md) before anything is sent."""
        address = self.station(request)
        name = request.get("name")
        if not isinstance(name, str) or not name.strip():
            raise OpError("bad_request", f"name: expected a parameter name such as 'C1-01', got {name!r}")
        try:
            read_target(self.plans[address], name.strip())
        except ParamRequestError as exc:
            raise OpError("unknown_param", str(exc)) from None
        writing = "value" in request
        value, eeprom = request.get("value"), request.get("eeprom", False)
        if writing and (isinstance(value, bool) or not isinstance(value, (int, float, str))):
            raise OpError("bad_request", f"value: expected a number (in the parameter's unit), got {value!r}")
        if not isinstance(eeprom, bool):
            raise OpError("bad_request", f"eeprom: expected true or false, got {eeprom!r}")
        self._connected(address, "PRM_WR" if writing else "PRM_RD")
        net, key = self.session.net, station_key(address)

        async def go() -> dict[str, Any]:
            if writing:
                await self._request(address, "PRM_WR", net.prm_wr(address, name.strip(), value))
                await self._request(address, "CONFIG", net.config(address, 1 if eeprom else 0))
            got = await self._request(address, "PRM_RD", net.prm_rd(address, name.strip()))
            row = {"name": got.name, "value": float(got), "unit": got.unit, "raw": got.raw,
                   "register": f"{got.register:04X}H", "text": str(got)}
            if writing:
                self.log.add("action", station=key, describe=f"set {got.name} = {got}"
                                                             + (" (EEPROM)" if eeprom else ""))
            return {"station": key, "param": row}

        return go()

    async def _request(self, address: int, what: str, pending: Any) -> Any:
        """Await a master request, its errors as error kinds: the station refused it (``refused``), no answer in
        time (``unavailable``)."""
        try:
            return await pending
        except ParamRequestError as exc:
            raise OpError("out_of_range", str(exc)) from None
        except StationAlarmError as exc:
            raise OpError("refused", f"station {address:02X}H refused {what}: {exc}") from None
        except RequestTimeout as exc:
            raise OpError("unavailable", str(exc)) from None
        except MasterError as exc:
            raise OpError("refused", f"station {address:02X}H: {what}: {exc}") from None

    def _logged(self, name: str, fn: Op) -> Op:
        def op(request: dict[str, Any]) -> Any:
            reply: Any = fn(request)  # the faults' operations answer at once
            what = request.get(name) if isinstance(request.get(name), str) else reply.get("describe")
            station = request.get("station", "all")
            self.log.add("action", station=station if isinstance(station, str) else str(station),
                         describe=f"{name} {what}" if what else name)
            return reply

        return op
