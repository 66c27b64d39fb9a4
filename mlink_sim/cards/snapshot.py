"""What a station shows: its counters and its snapshot (``Station.counters``, ``Station.snapshot()``)."""

from __future__ import annotations

from collections.abc import Hashable, Mapping
from dataclasses import dataclass, field, fields
from typing import Any

__all__ = ["StationCounters", "StationSnapshot", "DriveSnapshot"]


@dataclass(slots=True)
class StationCounters:
    """What happened to the datagrams a station saw. ``dropped_by_reason`` keys are wire
    :class:`~mlink_sim.wire.DropReason` names plus the card's own: ``WRONG_LINK`` (a datagram for another
    MECHATROLINK generation), ``DUPLICATE`` (a cycle number seen again), ``AER`` (station address error:
    the card does not answer)."""

    rx_ok: int = 0  #: valid commands for this station from the accepted source
    tx: int = 0  #: responses returned
    dropped_by_reason: dict[str, int] = field(default_factory=dict)
    other_station: int = 0  #: valid datagrams addressed to another station
    foreign_source: int = 0  #: commands from a source other than the connected master (ignored)
    status_queries: int = 0  #: NOPs from another source, answered with the status only (health checks)
    wdt_errors: int = 0
    reception_failures: int = 0  #: missed communication cycles (gap, silence, FCS) in phases 2/3
    fcs_errors: int = 0  #: bad-FCS datagrams for this station in phases 2/3
    commands_refused: int = 0  #: main or sub-commands answered with A.94/A.95 or CMD_ALM/SUBCMD_ALM
    bus_alarms: int = 0  #: communication alarms counted towards F6-26
    internal_errors: int = 0  #: exceptions caught at the station boundary (a bug if not 0)

    def drop(self, reason: str) -> None:
        self.dropped_by_reason[reason] = self.dropped_by_reason.get(reason, 0) + 1

    def as_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {name: getattr(self, name) for name in _COUNTER_NAMES}
        out["dropped_by_reason"] = dict(self.dropped_by_reason)
        return out


#: the counters' names in their order (not ``__slots__``: a compiled class has none)
_COUNTER_NAMES = tuple(f.name for f in fields(StationCounters))


@dataclass(frozen=True)
class DriveSnapshot:
    """The drive as a status display shows it."""

    running: bool
    reverse: bool
    output_hz: float
    reference_hz: float
    output_current_a: float
    dc_bus_v: float
    motor_rpm: float
    ready: bool
    remote: bool
    baseblock: bool
    fault: str | None  #: operator display name of the active fault
    minors: tuple[str, ...]  #: minor faults / alarms
    ope: str | None
    fault_history: tuple[str, ...]  #: most recent first


@dataclass(frozen=True)
class StationSnapshot:
    """A station's state for status displays (``mlink-sim slave`` status, logs)."""

    card: str
    address: int
    link: str  #: "ML1" / "ML2" / "ML3"
    data_size: int
    phase: int
    connected_source: Hashable | None
    tcycle_ns: int  #: transmission cycle in use (2 ms before CONNECT)
    com_tim: int
    comm_cycle_ns: int
    subcommands: bool
    leds: Mapping[str, str]  #: LED name -> "on" / "off" / "blink"
    led_colors: Mapping[str, str]  #: LED name -> colour while lit (SI-ET3 R/E is green or red)
    alarm_code: int  #: MECHATROLINK-II ALARM byte / MECHATROLINK-III COMM_ALM
    alarm_name: str | None
    warnings: tuple[str, ...]
    cmd_alm: int  #: MECHATROLINK-III CMD_ALM of the last response (0 on MECHATROLINK-II)
    station_error: str | None  #: "AEr" when the station address is invalid
    drive: DriveSnapshot
    counters: Mapping[str, Any]
    eeprom_error: str | None
