"""Values the master core hands out: station states and views, events, requests and their errors."""

from __future__ import annotations

import enum
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from .commands import Cmd

__all__ = [
    "StationState",
    "StationView",
    "Control",
    "Event",
    "Rtt",
    "Missing",
    "Late",
    "Dropped",
    "StateChanged",
    "AlarmRaised",
    "AlarmCleared",
    "Recovered",
    "MasterDrop",
    "MasterError",
    "StationAlarmError",
    "RequestTimeout",
    "StationDisconnected",
    "Request",
]


class StationState(enum.Enum):
    """The master's view of one station (docs/master.md, "State machine")."""

    OFFLINE = "offline"  #: no answer for ``offline_after`` communication cycles (or never answered)
    PHASE1 = "phase1"  #: answers, not connected
    CONNECTING = "connecting"  #: CONNECT sent (after a DISCONNECT when the slave must be reset first)
    PHASE2 = "phase2"  #: connected, asynchronous
    SYNCING = "syncing"  #: SYNC_SET sent
    PHASE3 = "phase3"  #: connected, synchronous
    ALARM = "alarm"  #: communication alarm reported (E5/E6, COMM_ALM >= 8); ALM_CLR being sent

    @property
    def phase(self) -> int:
        """The slave's communication phase as the master believes it (0 = unknown/offline)."""
        return _PHASE[self]


_PHASE = {
    StationState.OFFLINE: 0,
    StationState.PHASE1: 1,
    StationState.CONNECTING: 1,
    StationState.PHASE2: 2,
    StationState.SYNCING: 2,
    StationState.PHASE3: 3,
    StationState.ALARM: 2,
}


@dataclass(frozen=True, slots=True)
class Control:
    """Cyclic INV_CTL contents of one station (SI-T3 Table 16 / SI-ET3 Table 20 signals, references, selections).

    ``multi_inputs`` bit 0 is terminal S3 … bit 5 is S8. ``sel_mon`` 41H selects MON1 = motor speed (1) and
    MON2 = frequency reference (4) (SI-T3 Table 18, SI-ET3 Table 22)."""

    forward: bool = False
    reverse: bool = False
    speed_ref: int = 0
    torque_ref: int = 0
    fault_reset: bool = False
    ef0: bool = False
    ext_bb: bool = False
    fault_history_clear: bool = False
    multi_inputs: int = 0
    sel_ref: int = 0
    sel_mon: int = 0x41
    ref1: int = 0
    ref2: int = 0

    def __post_init__(self) -> None:
        for name in ("speed_ref", "ref1", "ref2"):
            v = getattr(self, name)
            if not 0 <= v <= 0xFFFF:
                raise ValueError(f"{name} {v} does not fit an unsigned 16-bit word")
        if not -0x8000 <= self.torque_ref <= 0x7FFF:
            raise ValueError(f"torque_ref {self.torque_ref} does not fit a signed 16-bit word (0.1 % units)")
        for name in ("sel_ref", "sel_mon"):
            if not 0 <= getattr(self, name) <= 0xFF:
                raise ValueError(f"{name} must be one byte (two 4-bit selections)")
        if not 0 <= self.multi_inputs <= 0x3F:
            raise ValueError("multi_inputs holds terminals S3–S8 in bits 0–5")


@dataclass(frozen=True, slots=True)
class StationView:
    """Snapshot of one station as the master sees it (built on demand)."""

    address: int
    name: str
    state: StationState
    phase: int
    at_target: bool
    alarm: int  #: ML-II ALARM byte of the latest response (0 = none); ML-III: 0
    alarm_name: str | None
    comm_alm: int  #: ML-III COMM_ALM of the latest response
    cmd_alm: int  #: ML-III CMD_ALM of the latest response
    fault: bool  #: ML-II STATUS.ALM / ML-III CMD_STAT.D_ALM
    warning: bool  #: ML-II STATUS.WARNG / ML-III CMD_STAT.D_WAR
    status: int  #: ML-II STATUS / ML-III INVCMD_STAT (latest INV_CTL response)
    output_freq: int
    output_current: int
    mon1: int
    mon2: int
    rtt_ns: int | None
    last_response_ns: int | None
    wdt: int  #: last WDT sent
    rwdt: int  #: last RWDT received
    sent: int
    responses: int
    missing: int
    late: int
    recoveries: int
    last_error: str | None  #: why bring-up is stuck or recovery escalated, if it is


# --- events -------------------------------------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class Rtt:
    """A response matched its command: round trip *ns*."""

    station: int
    ns: int


@dataclass(frozen=True, slots=True)
class Missing:
    """No response to the command of *cycle* by the station's next slot."""

    station: int
    cycle: int


@dataclass(frozen=True, slots=True)
class Late:
    """A response to *cycle* arrived after it had been recorded missing, *ns* after the command was sent."""

    station: int
    cycle: int
    ns: int


class MasterDrop(enum.Enum):
    """Reasons the master drops a well-formed datagram (next to :class:`mlink_sim.wire.DropReason`)."""

    UNKNOWN_STATION = "station not in the plan"
    WRONG_LINK = "link differs from the plan"
    NOT_EXPECTED = "no command outstanding for this cycle"
    DUPLICATE = "second response to a cycle"
    MALFORMED = "undecodable data"


@dataclass(frozen=True, slots=True)
class Dropped:
    """A datagram was not accepted; *station* is None when it could not be read."""

    station: int | None
    reason: Any  #: a :class:`mlink_sim.wire.DropReason` or a :class:`MasterDrop`


@dataclass(frozen=True, slots=True)
class StateChanged:
    station: int
    old: StationState
    new: StationState


@dataclass(frozen=True, slots=True)
class AlarmRaised:
    """A new alarm/warning code appeared in the station's responses. *source*: "alarm" (ML-II ALARM byte),
    "comm" (ML-III COMM_ALM), "command" (ML-III CMD_ALM)."""

    station: int
    code: int
    name: str
    source: str


@dataclass(frozen=True, slots=True)
class AlarmCleared:
    station: int
    source: str


@dataclass(frozen=True, slots=True)
class Recovered:
    """The station is back at its target phase after *reason*, without operator action."""

    station: int
    reason: str
    ns: int  #: time from the fault being seen to recovery


@dataclass(frozen=True, slots=True)
class RunHeld:
    """After a recovery the run command is held back: the motor may still coast and the drive has no speed
    search (docs/master.md, "Running again after a recovery")."""

    station: int
    until: str  #: "standstill" (the motor speed monitor shows it) or "the next run command"


@dataclass(frozen=True, slots=True)
class RunResumed:
    """The held (or searching) run command goes out again."""

    station: int
    reason: str  #: "speed search", "standstill" or "run command" (the application released a held run)


Event = Rtt | Missing | Late | Dropped | StateChanged | AlarmRaised | AlarmCleared | Recovered | RunHeld | RunResumed


# --- requests -----------------------------------------------------------------------------------------------------


class MasterError(Exception):
    """Base of the errors a request can fail with."""


class StationAlarmError(MasterError):
    """The station refused the command: A.94/A.95 (ML-II ALARM with STATUS.WARNG or SUBSTATUS) or
    CMD_ALM/SUBCMD_ALM != 0 (ML-III)."""

    def __init__(self, station: int, code: int, name: str, message: str) -> None:
        super().__init__(message)
        self.station = station
        self.code = code
        self.name = name


class RequestTimeout(MasterError, TimeoutError):
    """No completed response within the request's time limit (absent station, CMDRDY busy, no connection)."""

    def __init__(self, station: int, command: str, attempts: int, busy: int, unanswered: int = 0) -> None:
        detail = f"{attempts} sent, {busy} answered busy"
        if unanswered:
            detail += f", the last {unanswered} not answered at all"
        super().__init__(f"station {station:02X}H: {command} not completed in time ({detail})")
        self.station = station
        self.command = command
        self.attempts = attempts
        self.busy = busy


class StationDisconnected(MasterError):
    """The station was disconnected on request; commands other than CONNECT are not sent to it."""


class Request:
    """A queued command for one station, completed by the core with the decoded response body or an error.

    Not thread-safe: the core and its callbacks run in one thread (the event loop's)."""

    __slots__ = ("station", "body", "sub", "command", "code", "kind", "deadline_ns", "attempts", "busy",
                 "unanswered", "result", "error", "done", "_callbacks")

    def __init__(self, station: int, body: Any, sub: bool, command: str, code: int, deadline_ns: int,
                 kind: Cmd | None = None) -> None:
        self.station = station
        self.body = body
        self.sub = sub
        self.command = command  #: the command's name ("PRM_RD"; "30H" for a code the manuals do not define)
        self.code = code
        self.kind = kind
        self.deadline_ns = deadline_ns
        self.attempts = 0  #: times sent
        self.busy = 0  #: answers with CMDRDY/SUBCMDRDY = 0
        self.unanswered = 0  #: consecutive sends without an answer
        self.result: Any = None
        self.error: MasterError | None = None
        self.done = False
        self._callbacks: list[Callable[[Request], None]] = []

    def add_done_callback(self, fn: Callable[[Request], None]) -> None:
        """Call *fn(request)* on completion (at once if already complete)."""
        if self.done:
            fn(self)
        else:
            self._callbacks.append(fn)

    def _finish(self, result: Any = None, error: MasterError | None = None) -> None:
        if self.done:
            return
        self.done = True
        self.result = result
        self.error = error
        callbacks, self._callbacks = self._callbacks, []
        for fn in callbacks:
            fn(self)

    def __repr__(self) -> str:
        state = "pending" if not self.done else ("failed" if self.error else "done")
        return f"<Request {self.command}{' (sub)' if self.sub else ''} station {self.station:02X}H {state}>"
