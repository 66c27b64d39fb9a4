"""Values the master core hands out: station states and views, events, requests and their errors."""

from __future__ import annotations

import enum
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from ..params import ParamError
from ..profiles import lookup
from ..wire import CmdAlm, CommAlm, InvCmdStat, Link, M2Status

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
    "ParamValue",
    "ParamRequestError",
    "status_bits",
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


#: The status bits a response reports, by card: SI-T3 "STATUS Field" (MECHATROLINK-II STATUS, bits 0–F), SI-T/V7
#: §7.3 "STATUS Field" (the same bits 0–D; E and F are not used: ``CardProfile.status_bits_e_f``), SI-ET3
#: "INVCMD_STAT" (the INV_CTL response's INVCMD_STAT, bits 0–13 and the SEL_MON statuses 24/25).
_BITS_E_F = M2Status.SEL_M | M2Status.ZERO_SERVO


def status_bits(link: Link | str, status: int, card: str = "") -> tuple[str, ...]:
    """The names of the bits set in *status* (ML-I/II STATUS, ML-III INVCMD_STAT), in bit order, as the card's
    manual names them (SI-T3 / SI-T/V7 "STATUS Field", SI-ET3 "INVCMD_STAT"); a card without bits E and F (the
    SI-T/V7) shows neither. *card*: any spelling of a registered card, "" when not known."""
    flags: type[M2Status] | type[InvCmdStat]
    if (link if isinstance(link, Link) else Link[link]) is Link.ML3:
        flags = InvCmdStat
    else:
        flags = M2Status
        if card and not lookup(card).status_bits_e_f:
            status &= ~_BITS_E_F
    return tuple(m.name for m in flags if m.name and m.value.bit_count() == 1 and status & m.value)


def _code_name(table: Any, code: int) -> str:
    try:
        return str(table(code).name)
    except ValueError:
        return "(no name in the manual)"


def _decimals(step: float) -> int:
    """Decimals that show one step of *step* (0.01 -> 2), at most 3."""
    for digits in range(4):
        if abs(step * 10**digits - round(step * 10**digits)) < 1e-9:
            return digits
    return 3


@dataclass(frozen=True, slots=True)
class StationView:
    """Snapshot of one station as the master sees it (built on demand). The raw fields are as the wire carries
    them; the properties decode them: :attr:`output_hz`, :attr:`status_bits` (and :meth:`bit`),
    :attr:`alarm_text`."""

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
    output_freq: int  #: raw, in the drive's frequency units (o1-03 / n035): :attr:`output_hz` in Hz
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
    link: str = "ML2"  #: the link's name (``Link`` member: "ML1", "ML2", "ML3")
    card: str = ""  #: the card's key ("si-t3", "si-et3", "si-t-v7"; empty when the plan does not say)
    hz_per_count: float = 0.0  #: Hz of one count of ``output_freq`` (the drive's o1-03 / n035 units); 0 = unknown

    @property
    def output_hz(self) -> float | None:
        """The output frequency in Hz at the drive's resolution (627 in 0.01 Hz units -> 6.27); None when the
        station's frequency units are not known (a plan without them)."""
        step = self.hz_per_count
        if not step:
            return None
        return round(self.output_freq * step, _decimals(step))

    @property
    def status_bits(self) -> tuple[str, ...]:
        """The names of the status bits set (:func:`status_bits`: ``("CMDRDY", "PON", "RUNX", …)``)."""
        return status_bits(self.link, self.status, self.card)

    def bit(self, name: str) -> bool:
        """Whether status bit *name* is set ("RUNX", "agree"; case-insensitive). ValueError for a name the
        station's status field does not have."""
        flags: Any = InvCmdStat if self.link == "ML3" else M2Status
        member = flags.__members__.get(name.strip().upper())
        if member is None:
            known = ", ".join(m.name for m in flags if m.name and m.value.bit_count() == 1)
            raise ValueError(f"station {self.address:02X}H: no status bit {name!r} on {self.link} (bits: {known})")
        return name.strip().upper() in self.status_bits

    @property
    def alarm_text(self) -> str | None:
        """The alarm as text: ``"E6H COMM_ERROR"`` (ML-II ALARM and its name), ``"COMM_ALM 8H WDT_ERROR"`` /
        ``"CMD_ALM 1H INVALID_DATA_WARNING"`` (ML-III, SI-ET3 "COMM_ALM" / "CMD_ALM"); None without one."""
        if self.link != "ML3":
            return f"{self.alarm:02X}H {self.alarm_name}" if self.alarm else None
        parts = [f"{label} {code:X}H {_code_name(table, code)}"
                 for label, table, code in (("COMM_ALM", CommAlm, self.comm_alm), ("CMD_ALM", CmdAlm, self.cmd_alm))
                 if code]
        return ", ".join(parts) or None


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
                 "unanswered", "result", "error", "done", "result_of", "_callbacks")

    def __init__(self, station: int, body: Any, sub: bool, command: str, code: int, deadline_ns: int,
                 kind: Cmd | None = None, result_of: Callable[[Any], Any] | None = None) -> None:
        self.station = station
        self.body = body
        self.sub = sub
        self.command = command  #: the command's name ("PRM_RD"; "30H" for a code the manuals do not define)
        self.code = code
        self.kind = kind
        #: the result the answer's body gives (a parameter's value, the bytes asked for); None: the body itself
        self.result_of = result_of
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


# --- parameters by name -------------------------------------------------------------------------------------------


class ParamValue(float):
    """A parameter read by name (``await master.prm_rd(0x21, "C1-01")``): a float in engineering units that compares
    and computes as one (``== 10.0``), with the row it came from: :attr:`name`, :attr:`unit`, :attr:`raw` (the
    count the register holds), :attr:`register`. ``str()`` reads as the keypad shows it: ``"10.0 s"``."""

    __slots__ = ("name", "unit", "raw", "register", "text")

    name: str
    unit: str
    raw: int
    register: int
    text: str

    def __new__(cls, name: str, value: float, unit: str, raw: int, register: int, text: str = "") -> ParamValue:
        self = super().__new__(cls, value)
        self.name, self.unit, self.raw, self.register = name, unit, raw, register
        self.text = text or (f"{value:g} {unit}" if unit else f"{value:g}")
        return self

    @property
    def value(self) -> float:
        """The plain float."""
        return float(self)

    def __str__(self) -> str:
        return self.text

    def __repr__(self) -> str:
        return (f"ParamValue({self.name!r}, {float(self)!r}, {self.unit!r}, raw={self.raw}, "
                f"register=0x{self.register:04X})")

    def __reduce__(self) -> tuple[Any, ...]:
        return (ParamValue, (self.name, float(self), self.unit, self.raw, self.register, self.text))


class ParamRequestError(ParamError):
    """A parameter request that cannot be sent: an unknown name or register, a value of the wrong type, out of
    range or finer than the setting's resolution, a read-only row. Raised before anything is sent.

    ``station`` (the address), ``name`` (what was asked for), ``allowed`` (the range, or what would be
    accepted); ``str()`` is one sentence that names all three."""

    def __init__(self, station: int, name: str, allowed: str, message: str) -> None:
        super().__init__(message)
        self.station = station
        self.name = name
        self.allowed = allowed
