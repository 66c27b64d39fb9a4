"""Faults on a running network (docs/faults.md): where each one is applied and how its end is timed, for both
clocks.

* Master-side faults (silence, skip-cycles, freeze-wdt, bad-command) go to the fault stage of the station's master
  (:meth:`mlink_sim.aio.master.runner.Master.inject_fault`), in this process.
* Drive faults (load, lock-rotor, mains-loss) are applied to the card core's drive where it runs: in a slave worker
  of ``mlink-sim up`` through its control endpoint (``{"op": "plant", ...}``, answered by
  :func:`~mlink_sim.aio.slave.faults.handle_plant_request`), on the virtual clock directly on the fabric's card core. A
  fault with ``for`` is released by a second request that long after (``loop.call_later``: simulated time on the virtual
  clock). The master's fault stage records the episode, so the recovery after the fault's end is measured the same way.

Touches: the masters' fault stages in this process, and the slave workers' control endpoints (drive faults).
"""

from __future__ import annotations

import asyncio
from typing import Any

from ..._log import get_logger
from ...faults import Episode, FaultError, FaultSpec, fault_from_fields
from ...faults.spec import PLANT_FAULTS
from ..slave.faults import PlantError
from .control import OpError, query_control

__all__ = ["FaultControl", "fault_ops", "parse_fault_text"]

log = get_logger("mlink_sim.faults")


class FaultControl:
    """The faults of a :class:`~mlink_sim.aio.run.session.NetworkApi` (``net.fault(0x21, spec)``)."""

    def __init__(self, net: Any) -> None:
        self.net = net
        self._tasks: set[asyncio.Task[Any]] = set()
        self._handles: list[asyncio.TimerHandle] = []

    async def inject(self, station: int, fault: FaultSpec) -> Episode:
        """Start *fault* on *station* now; returns its episode (its recovery is measured once it has ended)."""
        master = self.net.master(station)
        if fault.action not in PLANT_FAULTS:
            return master.inject_fault(station, fault)
        handle = await self._plant(station, {"op": "plant", "station": station, "fault": fault.as_fields()})
        episode = master.begin_fault(station, fault)
        if fault.for_ns is None:
            master.end_fault(episode)  # a step: it is over once applied
        else:
            loop = asyncio.get_running_loop()
            self._handles.append(loop.call_later(fault.for_ns / 1e9, self._release, station, handle, episode))
        return episode

    def clear(self, station: int | None = None) -> None:
        """End every master-side fault of *station* (None: every station) now."""
        for master in self.net.masters.values():
            if master.faults is not None:
                master.faults.clear(station, master.now_ns())

    def stage(self, station: int) -> Any:
        """The master-side fault stage of *station*'s master (episodes, answers to bad commands)."""
        return self.net.master(station).fault_stage()

    def _release(self, station: int, handle: int, episode: Episode) -> None:
        async def release() -> None:
            try:
                await self._plant(station, {"op": "release", "station": station, "handle": handle})
            except PlantError as exc:
                log.warning("drive_fault_release_failed", station=f"{station:02X}H", error=str(exc))
            self.net.master(station).end_fault(episode)

        task = asyncio.get_running_loop().create_task(release())
        self._tasks.add(task)
        task.add_done_callback(self._tasks.discard)

    async def _plant(self, station: int, request: dict[str, Any]) -> int:
        worker = self.net.workers.get(station)
        if worker is None:
            raise PlantError("drive faults act on the stations' own drive models: they need the slaves of "
                             "'mlink-sim up' (or the virtual clock), not 'mlink-sim master'")
        plant = getattr(worker, "plant", None)
        if plant is not None:  # a station in this process (the virtual clock)
            reply = plant(request)
        else:
            port = worker.control_port
            reply = None
            if worker.alive and port:
                reply = await query_control("127.0.0.1", port, request.pop("op"), timeout=1.0, **request)
            if reply is None:
                raise PlantError(f"the slave of station {station:02X}H did not answer the drive-fault request")
        if not reply.get("ok"):
            raise PlantError(str(reply.get("error")))
        return int(reply.get("handle", 0))


def parse_fault_text(text: str) -> tuple[str, dict[str, Any]]:
    """``"silence,for=200ms"`` / ``"bad-command,kind=phase"`` / ``"load,torque=5,for=1s"`` -> (action, fields), the
    values as strings or numbers (:func:`~mlink_sim.faults.fault_from_fields` checks them)."""
    action, *rest = [part.strip() for part in text.split(",") if part.strip()] or [""]
    fields: dict[str, Any] = {}
    for part in rest:
        name, sep, value = part.partition("=")
        if not sep:
            raise FaultError(f"{part}: expected NAME=VALUE after the fault's name, e.g. 'silence,for=200ms'")
        try:
            fields[name.strip()] = int(value) if value.strip().lstrip("-").isdigit() else float(value)
        except ValueError:
            fields[name.strip()] = value.strip()
    return action, fields


def fault_ops(session: Any) -> dict[str, Any]:
    """The control endpoint's operations for station, master and drive faults (aio/run/control.py, docs/faults.md):

    * ``{"op": "fault", "station": "0x21", "fault": "silence,for=200ms"}`` (or the fields: ``"do": "silence",
      "for": "200ms"``; ``"station": "all"`` for every station) → ``{"ok": true, "faults": [...]}`` (a request
      repeated with the same ``"id"`` does not inject twice: :class:`~mlink_sim.aio.run.control.ControlServer`);
    * ``{"op": "recovery"}`` → every station's latest fault episode (its end, its recovery time)."""
    from ...metrics.network import station_key

    def stations(value: Any) -> list[int]:
        if value in (None, "all"):
            return [st.address for st in session.config.station]
        from ...config import parse_address

        address = parse_address(value)
        if address not in session.net.by_station:
            raise OpError("unknown_station", f"station: {address:02X}H is not a station of this network")
        return [address]

    def fault(request: dict[str, Any]) -> dict[str, Any]:
        fields = {k: v for k, v in request.items() if k not in ("op", "station", "fault", "id")}
        action = fields.pop("do", None)
        if isinstance(request.get("fault"), str):
            action, parsed = parse_fault_text(request["fault"])
            fields = {**parsed, **fields}
        spec = fault_from_fields(str(action or ""), fields)
        loop = asyncio.get_running_loop()
        for address in stations(request.get("station")):
            task = loop.create_task(session.net.fault(address, spec))
            session.net.fault_control._tasks.add(task)
            task.add_done_callback(_fault_done(session.net.fault_control, address))
        return {"fault": spec.as_fields(), "describe": spec.describe}

    def recovery(request: dict[str, Any]) -> dict[str, Any]:
        control = session.net.fault_control
        latest = {a: control.stage(a).latest(a) for a in stations(request.get("station"))}
        return {"episodes": {station_key(a): None if ep is None else ep.as_dict() for a, ep in latest.items()}}

    return {"fault": fault, "recovery": recovery}


def _fault_done(control: FaultControl, station: int) -> Any:
    def done(task: asyncio.Task[Any]) -> None:
        control._tasks.discard(task)
        if not task.cancelled() and task.exception() is not None:
            log.warning("fault_failed", station=f"{station:02X}H", error=str(task.exception()))

    return done
