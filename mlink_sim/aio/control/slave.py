"""The operations of a standalone slave (:data:`mlink_sim.operations.OPERATIONS` served by ``"slave"``; ``mlink-sim
slave --control``): what makes sense without a master of ours — its stations' status and figures from their own
snapshots, a parameter by name read and set in the card's own parameter store as the drive's keypad would, the
drive faults — and the process's stats, CPU time and a drive's activity, which ``mlink-sim up`` asks its slave
workers for (docs/control.md, "A standalone slave").

Touches: the card cores of the :class:`~mlink_sim.aio.slave.server.SlaveServer` it is given, and the loop (a drive
fault's ``for``).
"""

from __future__ import annotations

import asyncio
import json
import time
from typing import Any

from ...cards.parameters import keypad_read, keypad_write
from ...cards.results import Err
from ...impair import Names
from ...operations import OpError, fault_of, station_name
from ...params import ParamError
from ..present.figures import REGULATION_WINDOW_NS, snapshot_figures, station_key
from ..slave.faults import apply_drive_fault, release_drive_fault
from .endpoint import ControlServer, Encoded, Handler

__all__ = ["SlaveOps", "serve_slave"]


class SlaveOps:
    """The operations of *server* (a :class:`~mlink_sim.aio.slave.server.SlaveServer`)."""

    def __init__(self, server: Any) -> None:
        self.server = server
        self.endpoint: ControlServer | None = None  #: the endpoint serving them (its refused requests are counted)
        self._releases: set[asyncio.TimerHandle] = set()
        self._names = Names()  #: the drive faults' made names (load-21H-1, …)

    def handlers(self) -> dict[str, Handler]:
        return {"status": self.status, "get-param": self.get_param, "set-param": self.set_param,
                "fault": self.fault, "release": self.release, "stats": self.stats, "cpu": self.cpu,
                "drive": self.drive}

    def _hosted(self, station: int) -> Any:
        hs = self.server.hosted(station)
        if hs is None:
            known = ", ".join(station_name(h.station.address) for h in self.server.stations)
            raise OpError("unknown_station", f"station {station_name(station)} is not served by this slave "
                                             f"(it serves {known})")
        return hs

    # -- seeing -------------------------------------------------------------------------------------------------

    def status(self, since: int = 0) -> dict[str, Any]:
        """The process and every station's figures from its own snapshot (no RTT: only a master measures it)."""
        cpu = self.server.cpu()
        regulation = self._regulation()
        stations = [snapshot_figures({**_jsonable(hs.station.snapshot()),
                                      "regulation": regulation.get(station_key(hs.station.address), 0)})
                    for hs in self.server.stations]
        return {"pid": cpu["pid"], "wall_s": cpu["wall_s"], "cpu_pct": cpu["cpu_pct"], "stations": stations,
                "events": [], "seq": since}

    def stats(self, since: int = 0) -> Any:
        refused = self.endpoint.token.refused if self.endpoint is not None else 0

        async def build() -> Encoded:
            text = await self.server.stats_text(since, control_refused=refused)
            # the drives' regulation states beside the snapshots (a JSON object's last '}' closes it)
            return Encoded(f'{text[:-1]},"regulation":{json.dumps(self._regulation(), separators=(",", ":"))}}}')

        return build()

    def _regulation(self) -> dict[str, int]:
        """Each station's drive regulation over the :data:`REGULATION_WINDOW_NS` before now, where not 0
        (:meth:`mlink_sim.drive.Drive.regulation`: stall prevention, the torque limit)."""
        since = time.monotonic_ns() - REGULATION_WINDOW_NS
        codes = {station_key(hs.station.address): hs.station.drive.drive.regulation(since)
                 for hs in self.server.stations}
        return {key: code for key, code in codes.items() if code}

    def cpu(self) -> dict[str, Any]:
        return {k: v for k, v in self.server.cpu().items() if k != "ok"}

    def drive(self, station: int) -> dict[str, Any]:
        """The station's drive activity as of its last advance (reading it changes nothing)."""
        return {"activity": self._hosted(station).station.drive_activity().as_dict()}

    # -- parameters, as the keypad -----------------------------------------------------------------------------

    def get_param(self, station: int, param: str) -> dict[str, Any]:
        hs = self._hosted(station)
        try:
            row, raw = keypad_read(hs.station, param)
        except ParamError as exc:
            raise OpError("unknown_param", f"station {station_name(station)}: {exc}") from None
        return _param_reply(station, row, raw)

    def set_param(self, station: int, param: str, value: Any, eeprom: bool = False) -> dict[str, Any]:
        hs = self._hosted(station)
        table = hs.station.store.table
        try:
            row = table.resolve(param)
        except ParamError as exc:
            raise OpError("unknown_param", f"station {station_name(station)}: {exc}") from None
        try:
            _, raw = table.parse_assignment(f"{row.name}={value}")
        except ParamError as exc:
            raise OpError("out_of_range", f"station {station_name(station)}: {exc}") from None
        err = keypad_write(hs.station, row.name, raw, time.monotonic_ns(), save=eeprom)
        if err is Err.UNDERVOLTAGE:
            raise OpError("refused", f"station {station_name(station)}: {row.name} cannot be written while the "
                                     "main power is off (undervoltage)")
        if err is not Err.OK:
            raise OpError("out_of_range", f"station {station_name(station)}: {row.name} = {value!r} is refused "
                                          f"(range {row.format_range()})")
        self.server.changed(hs)
        return _param_reply(station, *keypad_read(hs.station, row.name))

    # -- drive faults -------------------------------------------------------------------------------------------

    def fault(self, station: int | None = None, name: str | None = None, **fields: Any) -> dict[str, Any]:
        """A drive fault on *station* (every station: None); with ``for`` released by itself after that long. Its
        name is answered (given, or made as ``load-21H-1``); ``release`` takes its handle."""
        spec = fault_of(fields)
        targets = [self._hosted(station)] if station is not None else list(self.server.stations)
        now = time.monotonic_ns()
        handles = {}
        for hs in targets:
            address = hs.station.address
            handles[station_key(address)] = handle = apply_drive_fault(self.server.cores(), self.server.plants,
                                                                       address, spec, now)
            self.server.changed(hs)
            if spec.for_ns is not None:
                timer = asyncio.get_running_loop().call_later(spec.for_ns / 1e9, self._release_later, address, handle)
                self._releases.add(timer)
        if name is None:
            name = self._names.new(spec.action, "all" if station is None else station_name(station))
        return {"name": name, "fault": spec.as_fields(), "describe": spec.describe, "handles": handles,
                **({"handle": next(iter(handles.values()))} if len(handles) == 1 else {})}

    def _release_later(self, address: int, handle: int) -> None:
        try:
            self.release(address, handle)
        except OpError:  # released already (by a request)
            pass

    def release(self, station: int, handle: int) -> dict[str, Any]:
        hs = self._hosted(station)
        release_drive_fault(self.server.cores(), self.server.plants, station, handle, time.monotonic_ns())
        self.server.changed(hs)
        return {"released": handle}

    def close(self) -> None:
        for timer in self._releases:
            timer.cancel()


def _jsonable(snapshot: Any) -> dict[str, Any]:
    from ...jsonable import to_jsonable

    out: dict[str, Any] = to_jsonable(snapshot)
    return out


def _param_reply(address: int, row: Any, raw: int) -> dict[str, Any]:
    return {"station": station_key(address),
            "param": {"name": row.name, "value": row.to_eng(raw), "unit": row.eng_unit, "raw": raw,
                      "register": f"{row.register:04X}H", "text": row.format(raw)}}


async def serve_slave(server: Any, host: str, port: int, token: str | None) -> tuple[ControlServer, SlaveOps,
                                                                                    tuple[str, int]]:
    """The control endpoint of *server* on *host*:*port* (0: any free port) with *token*: the endpoint, its
    operations and where it listens."""
    ops = SlaveOps(server)
    endpoint = ops.endpoint = ControlServer(ops.handlers(), "slave", token=token)
    where = await endpoint.start(host, port)
    return endpoint, ops, where

