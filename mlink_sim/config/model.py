"""The network description: one TOML file with ``[network]``, ``[[station]]`` and an optional ``[[timeline]]``.

Every field carries its documentation (``Field(description=...)``); ``docs/configuration.md`` is the user guide.
Validation errors are turned into ``CONFIG: field: what was expected`` lines by :mod:`mlink_sim.config.load`.
"""

from __future__ import annotations

import difflib
import json
import re
from typing import Annotated, Any, Literal

from pydantic import (BaseModel, BeforeValidator, ConfigDict, Field, TypeAdapter, ValidationError, field_validator,
                      model_validator)

from ..faults.spec import FAULT_ACTIONS
from ..impair.spec import Impairment, parse_probability
from ..operations import OPERATIONS, OpError, operation, parse_request
from ..profiles import CardProfile, lookup, profiles
from ..units import format_ns, parse_address, parse_duration_ns
from ..wire.codes import CmdAlm, CommAlm, Link, M2Alarm
from ..wire.drive_codes import SiT3DriveAlarm, SiT3DriveWarning, V7InverterAlarm, V7InverterWarning
from .deploy import CpuList, DeployConfig, NodeName, check_deploy
from .faults import check_fault_step, check_fault_targets, fault_end_ns
from .units import parse_arrival_poll

__all__ = [
    "CardKey",
    "MAX_STATIONS",
    "LoadConfig",
    "StationConfig",
    "TimelineStep",
    "NetworkConfig",
    "Config",
    "parse_endpoint",
    "check_cycle",
    "check_card_options",
    "check_alarm_name",
]

#: Stations one link carries: SI-T3 Table 29 "Maximum number of stations 30" (MECHATROLINK-I and -II; SI-T/V7 §9
#: "Number of connectable stations 30 slaves max."), SI-ET3 Table 28 "Maximum number of stations 62".
MAX_STATIONS = {Link.ML1: (30, "SI-T3 Table 29"), Link.ML2: (30, "SI-T3 Table 29"), Link.ML3: (62, "SI-ET3 Table 28")}
#: Default COM_TIM per link: SI-T3 errata (MECHATROLINK-II 1, MECHATROLINK-I 2); SI-ET3 CONNECT 1–255.
DEFAULT_COM_TIM = {Link.ML1: 2, Link.ML2: 1, Link.ML3: 1}

_LINK_NAMES = {
    "ml1": Link.ML1, "mechatrolink-i": Link.ML1, "m-i": Link.ML1, "1": Link.ML1,
    "ml2": Link.ML2, "mechatrolink-ii": Link.ML2, "m-ii": Link.ML2, "2": Link.ML2,
    "ml3": Link.ML3, "mechatrolink-iii": Link.ML3, "m-iii": Link.ML3, "3": Link.ML3,
}  # fmt: skip


def parse_endpoint(value: str) -> tuple[str, int]:
    """``"host:port"`` (``"[::1]:5000"`` for IPv6) -> ``(host, port)``."""
    text = value.strip()
    m = re.fullmatch(r"\[([^\]]+)\]:(\d+)|([^:\s]+):(\d+)", text)
    if not m:
        raise ValueError(f"expected HOST:PORT such as 127.0.0.1:47001, got {value!r}")
    host = m.group(1) or m.group(3)
    port = int(m.group(2) or m.group(4))
    if not 0 <= port <= 65535:
        raise ValueError(f"port {port} is out of range 0…65535")
    return host, port


def _link(value: Any) -> Link:
    if isinstance(value, Link):
        return value
    key = str(value).strip().lower()
    if key not in _LINK_NAMES:
        raise ValueError(f"expected ML1, ML2 or ML3 (MECHATROLINK-I/II/III), got {value!r}")
    return _LINK_NAMES[key]


def _duration(value: Any) -> int:
    return parse_duration_ns(value)


def _card(value: Any) -> str:
    """A card in any spelling (``"SI-T/V7"``, ``"sitv7"``) -> its registry key (``"si-t-v7"``)."""
    if not isinstance(value, str):
        raise ValueError(f"expected an option card such as 'si-t3' (known cards: "
                         f"{', '.join(p.key for p in profiles())}), got {value!r}")
    return lookup(value).key


def _registered_cards(schema: dict[str, Any]) -> None:
    """The JSON schema of a card field: the cards registered when the schema is made (:mod:`mlink_sim.profiles`)."""
    cards = profiles()
    schema["enum"] = [p.key for p in cards]
    schema["description"] = "option card, by its key: " + ", ".join(f"{p.key} ({p.label})" for p in cards)


Address = Annotated[int, BeforeValidator(parse_address)]
#: A station's ``card``: the key of a registered card (any spelling of one is read as its key).
CardKey = Annotated[str, BeforeValidator(_card)]
DurationNs = Annotated[int, BeforeValidator(_duration)]
LinkField = Annotated[Link, BeforeValidator(_link)]


def check_cycle(link: Link, frame_size: int, tcycle_ns: int) -> str | None:
    """Why *tcycle_ns* is not a transmission cycle the cards accept on *link*, or None.

    MECHATROLINK-II (SI-T3 CONNECT + errata): 32-byte 1–8 ms in whole ms, 17-byte 0.5–8 ms in 0.5 ms steps.
    MECHATROLINK-I: 2 ms (SI-T3 Table 29 note <1>). MECHATROLINK-III: 250 µs–8 ms (SI-ET3 Table 14 ID_CODE
    16H/17H) on the granularity of ID_CODE 18H = 03H: 31.25/62.5/125/250/500/750 µs, then 1 ms … in 0.5 ms steps.
    """
    ms = tcycle_ns / 1e6
    if link is Link.ML1:
        return None if tcycle_ns == 2_000_000 else "MECHATROLINK-I runs at a 2 ms transmission cycle"
    if link is Link.ML2:
        if frame_size == 32:
            ok = 1_000_000 <= tcycle_ns <= 8_000_000 and tcycle_ns % 1_000_000 == 0
            return None if ok else f"32-byte MECHATROLINK-II needs 1–8 ms in whole ms, got {ms:g} ms"
        ok = 500_000 <= tcycle_ns <= 8_000_000 and tcycle_ns % 500_000 == 0
        return None if ok else f"17-byte MECHATROLINK-II needs 0.5–8 ms in 0.5 ms steps, got {ms:g} ms"
    allowed = tcycle_ns in (250_000, 500_000, 750_000) or (
        1_000_000 <= tcycle_ns <= 8_000_000 and tcycle_ns % 500_000 == 0
    )
    return None if allowed else f"MECHATROLINK-III needs 250/500/750 µs or 1–8 ms in 0.5 ms steps, got {ms:g} ms"


def _card_options_fields() -> dict[str, tuple[Any, Any]]:
    """Name -> (type, default) of the card options: the fields of ``cards.settings.CardOptions``, read from the
    dataclass itself so that a new option is accepted (and type-checked) here without a second list."""
    import dataclasses
    import typing

    from ..cards.settings import CardOptions

    hints = typing.get_type_hints(CardOptions)
    return {f.name: (hints[f.name], f.default) for f in dataclasses.fields(CardOptions)}


def check_card_options(options: dict[str, Any]) -> dict[str, Any]:
    """The ``options`` table of a station, each name known and each value of its option's type (strict: a bool
    takes ``true``/``false``, not 0/1); ValueError names the option and what was expected."""
    fields = _card_options_fields()
    for name, value in options.items():
        if name not in fields:
            near = difflib.get_close_matches(name, fields, n=1)
            hint = f"; did you mean {near[0]!r}?" if near else ""
            raise ValueError(f"unknown card option {name!r}{hint} (known: {', '.join(fields)}; docs/cards.md)")
        kind, default = fields[name]
        try:
            TypeAdapter(kind).validate_python(value, strict=True)
        except ValidationError:
            expected = "true or false" if kind is bool else getattr(kind, "__name__", None) or str(kind)
            raise ValueError(f"card option {name!r} expects {expected} (default {json.dumps(default)}), "
                             f"got {value!r}") from None
    return options


def _alarm_names() -> dict[str, str]:
    """Lower-case name -> name of every alarm a station can report (what ``expect = "alarm"`` compares with):
    the cards' own codes (SI-T3 Tables 23/25, V7 Table 8; SI-ET3 COMM_ALM / CMD_ALM tables) and the drive codes
    (SI-T3 Tables 26/27, V7 Tables 10/11)."""
    tables = (M2Alarm, CommAlm, CmdAlm, SiT3DriveAlarm, SiT3DriveWarning, V7InverterAlarm, V7InverterWarning)
    return {m.name.lower(): m.name for t in tables for m in t if m.value}


def check_alarm_name(name: str) -> str:
    """*name* if a station can report it (any case; an unnamed code as ``94H``), else ValueError."""
    if re.fullmatch(r"[0-9A-Fa-f]{1,2}[hH]", name) or name.lower() in _alarm_names():
        return name
    names = _alarm_names()
    near = difflib.get_close_matches(name.lower(), names, n=3)
    hint = f"; did you mean {', '.join(repr(names[n]) for n in near)}?" if near else ""
    raise ValueError(f"expected an alarm name of SI-T3 Tables 23/25–27, V7 Tables 8/10/11 or the SI-ET3 COMM_ALM/"
                     f"CMD_ALM tables (e.g. 'E5', 'bUS', 'OV') or a code such as '94H', got {name!r}{hint}")


class LoadConfig(BaseModel):
    """The mechanical load on the motor of one station (see docs/drive-model.md)."""

    model_config = ConfigDict(extra="forbid")

    kind: Literal["inertia", "constant", "fan", "friction"] = Field(
        "inertia", description="inertia only, constant torque, quadratic fan, or viscous friction"
    )
    inertia: float | None = Field(None, gt=0, description="load inertia in kg·m² (default: scaled to the motor)")
    torque: float | None = Field(None, ge=0, description="constant: load torque N·m; fan: torque at rated speed")
    friction: float | None = Field(None, ge=0, description="viscous friction coefficient N·m·s/rad")


class StationConfig(BaseModel):
    """One slave station: one option card on one drive."""

    model_config = ConfigDict(extra="forbid")

    address: Address = Field(description="station address, e.g. 0x21 (F6-20 / V7 switches S1-3 + S2)")
    card: CardKey = Field(description="option card, by its key", json_schema_extra=_registered_cards)
    link: LinkField | None = Field(
        None, description="ML1/ML2/ML3 for this station (default: network.link, else the card's own: ML3 for si-et3, "
        "ML2 for si-t3 and si-t-v7)"
    )
    name: str | None = Field(None, description="label shown in status lines and reports")
    frame_size: int | None = Field(None, description="data bytes: 17/32 (MECHATROLINK-I/II) or 32/64 (III)")
    com_tim: int | None = Field(None, ge=1, le=255, description="communication cycle = COM_TIM × transmission cycle")
    sync: bool = Field(True, description="bring the station to phase 3 (synchronous) rather than phase 2")
    subcmd: bool | None = Field(
        None,
        description="enable sub-commands (32-byte MECHATROLINK-II, 64-byte III); default on for a 32-byte SI-T/V7, "
        "which takes PRM_RD/PRM_WR only as sub-commands (V7 §7.1), off otherwise",
    )
    endpoint: str | None = Field(None, description="HOST:PORT the slave listens on (port 0: chosen at start)")
    node: NodeName | None = Field(None, description="compose --stack/--k8s: the node label value of its node")
    cpus: CpuList | None = Field(None, description="compose --stack/--k8s: the CPUs its process pins itself to")
    params: dict[str, float | int | str] = Field(
        default_factory=dict, description="parameters in engineering units, e.g. {'C1-01' = 5.0, 'b1-02' = 3}"
    )
    load: LoadConfig = Field(default_factory=LoadConfig, description="mechanical load on the motor")
    options: dict[str, Any] = Field(default_factory=dict, description="card options (docs/cards.md)")

    @field_validator("options")
    @classmethod
    def _options(cls, v: dict[str, Any]) -> dict[str, Any]:
        return check_card_options(v)

    @field_validator("endpoint")
    @classmethod
    def _endpoint(cls, v: str | None) -> str | None:
        if v is not None:
            parse_endpoint(v)
        return v

    @property
    def profile(self) -> CardProfile:
        """Its card's profile (:mod:`mlink_sim.profiles`)."""
        return lookup(self.card)

    @property
    def label(self) -> str:
        return self.name or f"{self.profile.label}@{self.address:02X}H"

    def host_port(self, default_host: str) -> tuple[str, int]:
        return parse_endpoint(self.endpoint) if self.endpoint else (default_host, 0)


#: The timeline's actions: every operation of the table a timeline offers (``do = NAME``, its arguments as the step's
#: fields), and each fault by its name (``do = "silence"``: the ``fault`` operation of that fault).
_ACTIONS = (*(op.name for op in OPERATIONS.values() if op.timeline), *FAULT_ACTIONS)
_EXPECTS = ("running", "stopped", "speed-agree", "phase", "no-alarm", "alarm", "output-hz", "alarm-seen", "recovered",
            "refused")


#: The step's fields that are durations (ns), given to the operations as text with their unit.
_DURATION_FIELDS = frozenset({"delay", "jitter", "for"})
Probability = float | str


class TimelineStep(BaseModel):
    """One timed action or check of a scenario. ``at`` is measured from the moment every station is up."""

    model_config = ConfigDict(extra="forbid", populate_by_name=True)

    at: DurationNs = Field(description="when, e.g. '0.5s', from the end of bring-up")
    station: Address | Literal["all"] = Field("all", description="station address, or 'all'")
    do: Literal[_ACTIONS] | None = Field(None, description="action: " + ", ".join(_ACTIONS))  # type: ignore[valid-type]
    expect: Literal[_EXPECTS] | None = Field(None, description="check: " + ", ".join(_EXPECTS))  # type: ignore[valid-type]
    direction: str | None = Field(
        None, description="run: 'forward' (default) or 'reverse'; impair: 'to-station', 'to-master' or 'both' "
        "(default)")
    hz: float | None = Field(None, description="run, speed: frequency reference in Hz, up to E1-04 / n011")
    param: str | None = Field(None, description="set-param: parameter name, e.g. 'C1-01'")
    value: float | int | str | None = Field(None, description="set-param: value in engineering units")
    eeprom: bool | None = Field(None, description="set-param, enter: save it too (CONFIG_MOD 1)")
    output_hz: float | None = Field(None, description="output-hz: expected output frequency in Hz")
    tolerance_hz: float = Field(0.5, ge=0, description="output-hz: tolerance in Hz")
    phase: int | None = Field(None, ge=1, le=3, description="phase: expected communication phase")
    alarm: str | None = Field(None, description="alarm: expected alarm name, e.g. 'E5' or 'bUS'")
    loss: Probability | None = Field(None, description="impair: probability per datagram of a loss, 0…1 or '5%'")
    burst: float | None = Field(None, description="impair: mean length of a loss burst (Gilbert–Elliott), ≥ 1")
    delay: DurationNs | None = Field(None, description="impair: added one-way delay, e.g. '300us'")
    jitter: DurationNs | None = Field(None, description="impair: uniform spread ± around the delay, e.g. '200us'")
    duplicate: Probability | None = Field(None, description="impair: probability of a duplicated datagram")
    reorder: Probability | None = Field(None, description="impair: probability that the next datagram overtakes")
    corrupt: Probability | None = Field(None, description="impair: probability of a bit flipped after the FCS")
    for_: DurationNs | None = Field(None, alias="for", description="impair: how long it lasts (default: until "
                                    "'heal'), e.g. '2s'; silence, freeze-wdt, mains-loss (required), load, lock-rotor: "
                                    "how long the fault lasts")
    # station, master and drive faults (docs/faults.md)
    count: int | None = Field(None, description="skip-cycles: transmission cycles the master sends nothing")
    kind: str | None = Field(None, description="bad-command: 'phase', 'combination' or 'data-size'")
    torque: float | None = Field(None, description="load: N·m of constant load torque added")
    inertia: float | None = Field(None, description="load: kg·m² of inertia added")
    within: DurationNs | None = Field(None, description="recovered: the longest recovery time, e.g. '50ms'")
    name: str | None = Field(None, description="impair and the faults: its name (docs/faults.md, \"Names\"; default: "
                             "made, e.g. 'loss-21H-1'); heal: only the impairment or fault of this name")

    @field_validator("alarm")
    @classmethod
    def _alarm(cls, v: str | None) -> str | None:
        return None if v is None else check_alarm_name(v)

    @model_validator(mode="after")
    def _one_of(self) -> TimelineStep:
        if (self.do is None) == (self.expect is None):
            raise ValueError("a timeline step needs exactly one of 'do' (an action) or 'expect' (a check)")
        if self.do is not None:
            self._check_action()
        if self.expect == "output-hz" and self.output_hz is None:
            raise ValueError("'expect = \"output-hz\"' needs output_hz")
        if self.expect == "phase" and self.phase is None:
            raise ValueError("'expect = \"phase\"' needs phase")
        if self.do == "impair":
            self.impairment  # noqa: B018 - ImpairError (a ValueError) names the bad field
        check_fault_step(self)
        return self

    @property
    def operation(self) -> str:
        """The operation an action step performs: its own name, or ``fault`` for a fault (``do = "silence"`` …)."""
        assert self.do is not None
        return "fault" if self.do in FAULT_ACTIONS else self.do

    def request(self, station: Any) -> dict[str, Any]:
        """The control request this action step makes of *station* (an address, or ``"all"``): its operation and
        the step's fields as the operation's arguments (a duration as exact text with its unit)."""
        op = operation(self.operation)
        fields: dict[str, Any] = {"op": op.name, "station": station}
        for arg in op.args:
            value = getattr(self, arg.python, None)
            if arg.name in ("station", "do") or value is None:
                continue
            fields[arg.name] = f"{value}ns" if arg.name in _DURATION_FIELDS else value
        if op.name == "fault":
            fields["do"] = self.do
        return fields

    def _check_action(self) -> None:
        """An action's fields are its operation's arguments, read by the operations table as every other surface
        reads them (:func:`~mlink_sim.operations.parse_request`): a field the operation does not take, one it needs
        and lacks, a value of the wrong kind, with the operation's own message."""
        op = operation(self.operation)
        takes = {a.python for a in op.args}
        extra = sorted(k for k in self.model_fields_set if k not in ("at", "station", "do") and k not in takes
                       and getattr(self, k) is not None)
        if extra:
            names = ", ".join(a.name for a in op.args if a.name not in ("station", "do")) or "no field but station"
            field = "for" if extra[0] == "for_" else extra[0]
            raise ValueError(f"{field}: 'do = \"{self.do}\"' does not take it (it takes {names})")
        # a step on every station is one request per station (the fault operations take 'all' themselves)
        takes_all = any(a.name == "station" and not a.required for a in op.args)
        try:
            parse_request(op, self.request(self.station if self.station != "all" else "all" if takes_all else 0))
        except OpError as exc:
            raise ValueError(str(exc).removeprefix(f"{op.name}: ")) from None
        if op.name in ("run", "impair") and self.direction is None:
            self.direction = "forward" if op.name == "run" else "both"

    @property
    def impairment(self) -> Impairment:
        """``do = "impair"``: the :class:`~mlink_sim.impair.Impairment` (ImpairError for a bad value)."""
        probs = {n: parse_probability(getattr(self, n), n) for n in ("loss", "duplicate", "reorder", "corrupt")
                 if getattr(self, n) is not None}
        return Impairment(direction=self.direction or "both", burst=self.burst, delay=self.delay or 0,
                          jitter=self.jitter or 0, for_ns=self.for_, **probs)

    @property
    def end_ns(self) -> int:
        """When the step is over: ``at``, plus its fault's duration and a recovery check's ``within``."""
        return fault_end_ns(self)

    @property
    def describe(self) -> str:
        who = "all stations" if self.station == "all" else f"station {self.station:02X}H"
        what = f"do {self.do}" if self.do else f"expect {self.expect}"
        extra = ""
        if self.do == "run":
            extra = f" {self.direction} {self.hz:g} Hz"
        elif self.do == "speed":
            extra = f" {self.hz:g} Hz"
        elif self.do == "set-param":
            extra = f" {self.param}={self.value}" + (" (EEPROM)" if self.eeprom else "")
        elif self.expect == "output-hz":
            extra = f" {self.output_hz:g}±{self.tolerance_hz:g} Hz"
        elif self.expect == "phase":
            extra = f" {self.phase}"
        elif self.expect in ("alarm", "alarm-seen") and self.alarm:
            extra = f" {self.alarm}"
        elif self.do == "impair":
            extra = f" {self.impairment.describe()}"
        elif self.expect == "refused" and self.alarm:
            extra = f" {self.alarm}"
        elif self.expect == "recovered" and self.within is not None:
            extra = f" within {format_ns(self.within)}"
        elif self.do in FAULT_ACTIONS:
            extra = "".join(f" {k}={v}" for k, v in (("kind", self.kind), ("count", self.count),
                            ("torque", self.torque), ("inertia", self.inertia)) if v is not None)
            extra += f" for {format_ns(self.for_)}" if self.for_ is not None else ""
        return f"{self.at / 1e9:g}s {who}: {what}{extra}"


class NetworkConfig(BaseModel):
    """The network as a whole."""

    model_config = ConfigDict(extra="forbid")

    name: str = Field("network", description="name shown in status lines and reports")
    link: LinkField | None = Field(
        None, description="default link of the stations: ML1, ML2 or ML3 (MECHATROLINK-I, -II, -III)"
    )
    transmission_cycle: DurationNs = Field(description="transmission cycle, e.g. '1ms' or '250us'")
    master_address: Address = Field(0x01, description="the master's own address (informational)")
    host: str = Field("127.0.0.1", description="address slaves bind by default (loopback)")
    duration: DurationNs | None = Field(None, description="run length when there is no timeline, e.g. '10s'")
    latency: DurationNs = Field(
        50_000, description="virtual clock (--clock virtual): one-way delay of every datagram, default 50us"
    )
    jitter: DurationNs = Field(
        10_000,
        description="virtual clock: the one-way delay varies uniformly by up to ± this much (drawn from --seed), "
        "default 10us; at most the latency",
    )

    host_stalls: Literal["absorb", "strict"] = Field(
        "absorb", description="host-stall policy of up/master/compose: 'absorb' runs the cycles a stall of "
        "mlink-sim's own processes delayed (up to stall_bound) late instead of losing them; 'strict' judges "
        "by the wall clock as the manuals do (docs/timing.md, 'Host stalls')")
    stall_bound: DurationNs = Field(100_000_000, description="longest stall 'absorb' absorbs, e.g. '100ms'")
    arrival_poll: str = Field(
        "auto", description="the slave workers' arrival poll: 'auto' busy-polls from 80us before each burst of "
        "commands is due at cycles up to 500us where idle CPUs halt, a lead such as '80us' does so at any cycle, "
        "'off' never (docs/timing.md)")

    @model_validator(mode="after")
    def _jitter(self) -> NetworkConfig:
        if self.jitter > self.latency:
            raise ValueError(f"jitter: at most the latency ({self.latency} ns), got {self.jitter} ns")
        return self

    @field_validator("stall_bound")
    @classmethod
    def _bound(cls, v: int) -> int:
        if not 0 < v <= 1_000_000_000:
            raise ValueError("expected a duration above 0 and at most 1s, e.g. '50ms'")
        return v

    @field_validator("arrival_poll")
    @classmethod
    def _poll(cls, v: str) -> str:
        parse_arrival_poll(v)  # ValueError with the accepted forms
        return v

    @property
    def absorb_ns(self) -> int:
        """The stall bound when the policy is 'absorb', else 0 (nothing absorbed)."""
        return self.stall_bound if self.host_stalls == "absorb" else 0

    def slave_flags(self) -> list[str]:
        """The ``mlink-sim slave`` flags that give a slave this network's host-stall policy (``up``'s workers,
        the compose testbed's station containers), and their arrival poll."""
        return ["--host-stalls", self.host_stalls, "--stall-bound", f"{self.stall_bound}ns",
                "--arrival-poll", self.arrival_poll]


class Config(BaseModel):
    """A whole configuration file."""

    model_config = ConfigDict(extra="forbid")

    network: NetworkConfig
    station: list[StationConfig] = Field(min_length=1, description="the slave stations")
    timeline: list[TimelineStep] = Field(default_factory=list, description="timed actions and checks")
    deploy: DeployConfig = Field(default_factory=DeployConfig, description="placement on a cluster (compose --stack/--k8s)")

    @model_validator(mode="after")
    def _consistency(self) -> Config:
        links = [st.link or self.network.link or Link[st.profile.default_link] for st in self.station]
        for link in sorted(set(links)):
            n, (limit, source) = links.count(link), MAX_STATIONS[link]
            if n > limit:
                raise ValueError(f"station: {n} {link.label} stations, but one link carries at most {limit} ({source})")
        seen: dict[int, int] = {}
        for i, st in enumerate(self.station):
            where = f"station[{i}]"
            profile = st.profile
            if st.link is None:
                st.link = self.network.link or Link[profile.default_link]
            link = st.link
            if st.address in seen:
                raise ValueError(f"{where}.address: {st.address:02X}H is already used by station[{seen[st.address]}]")
            seen[st.address] = i
            lo, hi = profile.addresses
            if not lo <= st.address <= hi:
                raise ValueError(
                    f"{where}.address: {st.address:02X}H is outside {st.card}'s range {lo:02X}H–{hi:02X}H"
                )
            if link.name not in profile.frames:
                spoken = "/".join(Link[name].label for name in sorted(profile.links))
                raise ValueError(f"{where}.link: {st.card} speaks {spoken}, not {link.label}")
            if st.frame_size is None:
                st.frame_size = profile.frames[link.name][0]
            if st.frame_size not in link.data_sizes:
                sizes = " or ".join(map(str, link.data_sizes))
                raise ValueError(f"{where}.frame_size: {link.label} uses {sizes}-byte frames, got {st.frame_size}")
            if st.com_tim is None:
                st.com_tim = DEFAULT_COM_TIM[link]
            if st.subcmd is None:  # on for a 32-byte card that takes PRM_RD/PRM_WR only as sub-commands (V7 §7.1)
                st.subcmd = profile.prm_as_subcommand and st.frame_size == 32
            if st.subcmd and st.frame_size not in (32, 64) or st.subcmd and link is Link.ML1:
                raise ValueError(f"{where}.subcmd: sub-commands need 32-byte MECHATROLINK-II or 64-byte III frames")
            why = check_cycle(link, st.frame_size, self.network.transmission_cycle)
            if why:
                raise ValueError(f"network.transmission_cycle: {why} (for {where}, {st.frame_size}-byte)")
        for i, step in enumerate(self.timeline):
            if step.station != "all" and step.station not in seen:
                raise ValueError(f"timeline[{i}].station: {step.station:02X}H is not a station of this network")
            targets = self.station if step.station == "all" else [self.station[seen[step.station]]]
            check_fault_targets(step, targets, f"timeline[{i}]")
        check_deploy(self)
        return self

    def station_by_address(self, address: int) -> StationConfig:
        for st in self.station:
            if st.address == address:
                return st
        raise KeyError(address)

    @property
    def run_length_ns(self) -> int | None:
        """The end of the scenario: the last timeline step plus one second, or ``network.duration``."""
        if self.timeline:
            return max(s.end_ns for s in self.timeline) + 1_000_000_000
        return self.network.duration
