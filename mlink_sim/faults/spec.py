"""What one station, master or drive fault is: frozen, validated values built from the timeline,
a control request or the pytest plugin (docs/faults.md).

Two families, by where the fault acts:

* **master side** (:data:`MASTER_FAULTS`) — a sans-I/O stage between the master core and its transport
  (:mod:`mlink_sim.faults.stage`): ``silence`` (the station's answers never reach the master), ``skip-cycles`` (the
  master sends the station nothing for *count* transmission cycles), ``freeze-wdt`` (the WDT count of the commands
  stops advancing), ``bad-command`` (one refused command: a phase, combination or data-size error);
* **plant side** (:data:`PLANT_FAULTS`) — the drive model of the station itself (:mod:`mlink_sim.faults.plant`):
  ``load`` (a load step), ``lock-rotor`` (a mechanical jam), ``mains-loss`` (the rectifier's supply is gone).

Every value is checked here, with a message naming the field and what was expected, so that the config loader, a
control request and the plugin refuse bad values alike (:class:`FaultError`, a ``ValueError``).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import asdict, dataclass
from typing import Any, ClassVar

from ..units import format_ns, parse_duration_ns

__all__ = [
    "FaultError", "Silence", "SkipCycles", "FreezeWdt", "BadCommand", "LoadStep", "LockRotor", "MainsLoss",
    "FaultSpec", "MasterFault", "PlantFault", "MASTER_FAULTS", "PLANT_FAULTS", "FAULT_ACTIONS", "BAD_COMMAND_KINDS",
    "fault_from_fields", "MAX_SKIP_CYCLES",
]

#: ``kind`` of ``do = "bad-command"``: which of the manuals' refusals to provoke (docs/faults.md).
BAD_COMMAND_KINDS = ("phase", "combination", "data-size")
#: The longest ``skip-cycles`` (a minute of 1 ms cycles): beyond it, silence the station or kill it instead.
MAX_SKIP_CYCLES = 60_000


class FaultError(ValueError):
    """A bad fault value; ``str()`` names the field and what was expected."""


def _duration(value: Any, name: str, *, required: bool) -> int | None:
    """A duration above 0 in ns from ``"300ms"`` or a bare number of seconds (the plugin's ``for_=2.0``)."""
    if value is None:
        if required:
            raise FaultError(f"{name}: required, e.g. {name} = \"500ms\"")
        return None
    try:
        ns = parse_duration_ns(value, default_unit="s") if isinstance(value, (int, float)) \
            else parse_duration_ns(value)
    except (TypeError, ValueError) as exc:
        raise FaultError(f"{name}: {exc}") from None
    if ns <= 0:
        raise FaultError(f"{name}: expected a duration above 0, got {value!r}")
    return ns


def _number(value: Any, name: str, unit: str) -> float | None:
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value < 0:
        raise FaultError(f"{name}: expected a number of {unit} of 0 or more, got {value!r}")
    return float(value)


@dataclass(frozen=True)
class _Fault:
    action: ClassVar[str] = ""
    #: the fault needs ``for``: what it measures, for the message when it is missing (None: optional or not taken)
    needs_for: ClassVar[str | None] = None
    #: the fault takes no ``for``: why (None: it takes one)
    no_for: ClassVar[str | None] = None
    for_ns: int | None = None

    def __post_init__(self) -> None:
        if self.needs_for and self.for_ns is None:
            raise FaultError(f"for: required, e.g. for = \"200ms\" ({self.needs_for})")
        if self.no_for and self.for_ns is not None:
            raise FaultError(f"for: {self.no_for}; it takes no 'for'")

    def as_fields(self) -> dict[str, Any]:
        """The fields as a timeline step or a control request spells them (``for`` as ``"…ms"``)."""
        out = {k: v for k, v in asdict(self).items() if v is not None and k != "for_ns"}
        if self.for_ns is not None:
            out["for"] = format_ns(self.for_ns)
        return {"do": self.action, **out}

    @property
    def describe(self) -> str:
        fields = self.as_fields()
        fields.pop("do")
        return self.action + "".join(f" {k}={v}" for k, v in fields.items())


@dataclass(frozen=True)
class Silence(_Fault):
    """The station answers nothing for ``for_ns``: its responses are dropped on their way to the master, so the card
    itself keeps running its state machine, as a card whose transmitter is mute does."""

    action: ClassVar[str] = "silence"
    needs_for: ClassVar[str | None] = "how long the station stays silent"


@dataclass(frozen=True)
class SkipCycles(_Fault):
    """The master sends the station nothing in the next ``count`` transmission cycles (SI-T3 Table 22: reception
    failures, 96 then E6; SI-ET3 COMM_ALM 2/3 then 9/A; bUS after F6-26 of them)."""

    action: ClassVar[str] = "skip-cycles"
    no_for: ClassVar[str | None] = "skip-cycles lasts 'count' cycles"
    count: int | None = None

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.count is None:
            raise FaultError("count: required, e.g. count = 3 (transmission cycles the master sends nothing)")
        if isinstance(self.count, bool) or not isinstance(self.count, int) or not 1 <= self.count <= MAX_SKIP_CYCLES:
            raise FaultError(f"count: expected a whole number of transmission cycles 1…{MAX_SKIP_CYCLES}, "
                             f"got {self.count!r}")


@dataclass(frozen=True)
class FreezeWdt(_Fault):
    """The master's WDT count (command WDT bits 4–7) stops advancing for ``for_ns``; then the commands carry the
    master's own count again, which ran on underneath (SI-T3 Tables 23/24 E5 "WDT Error"; SI-ET3 COMM_ALM CH)."""

    action: ClassVar[str] = "freeze-wdt"
    needs_for: ClassVar[str | None] = "how long the WDT stays frozen"


@dataclass(frozen=True)
class BadCommand(_Fault):
    """One command the card must refuse, in the station's next cyclic slot (docs/faults.md has the tables):

    * ``data-size`` — PRM_RD with SIZE 3: A.94 (SI-T3 / SI-T/V7 PRM_RD "If SIZE is an odd number"), CMD_ALM or
      SUBCMD_ALM 9H (SI-ET3 PRM_RD "If the SIZE data is invalid");
    * ``combination`` — ALM_RD with a PRM_RD sub-command: A.95 (SI-T3 Table 7 "NG"), CMD_ALM BH (SI-ET3 Table 13);
    * ``phase`` — a DISCONNECT in the slot, after which the master's next INV_CTL finds the card in phase 1: A.95
      (SI-T3 INV_CTL "If not in phase 2 or 3"), CMD_ALM CH (SI-ET3 Table 9 "–")."""

    action: ClassVar[str] = "bad-command"
    no_for: ClassVar[str | None] = "a bad command is one command"
    kind: str | None = None

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.kind is None:
            raise FaultError(f"kind: required, one of {', '.join(repr(k) for k in BAD_COMMAND_KINDS)}")
        if self.kind not in BAD_COMMAND_KINDS:
            raise FaultError(f"kind: expected one of {', '.join(repr(k) for k in BAD_COMMAND_KINDS)}, "
                             f"got {self.kind!r}")


@dataclass(frozen=True)
class LoadStep(_Fault):
    """A load step on the motor shaft: ``torque`` N·m of passive constant load torque added to the station's load,
    and/or ``inertia`` kg·m² added to its inertia (docs/drive-model.md §4); removed again after ``for_ns``."""

    action: ClassVar[str] = "load"
    torque: float | None = None
    inertia: float | None = None

    def __post_init__(self) -> None:
        super().__post_init__()
        torque = _number(self.torque, "torque", "N·m")
        inertia = _number(self.inertia, "inertia", "kg·m²")
        if not (torque or inertia):
            raise FaultError("load: give torque (N·m added to the load) or inertia (kg·m² added), above 0")
        object.__setattr__(self, "torque", torque)
        object.__setattr__(self, "inertia", inertia)


@dataclass(frozen=True)
class LockRotor(_Fault):
    """The shaft jams: a passive load torque no motor current below the drive's oC level can overcome; the drive
    then trips as its equations decide (oC at once when running, oL1 under stall prevention from a standstill).
    Released after ``for_ns`` (never without it)."""

    action: ClassVar[str] = "lock-rotor"


@dataclass(frozen=True)
class MainsLoss(_Fault):
    """The drive's mains supply is gone for ``for_ns``: the DC bus feeds the motor and the control power and sags
    (docs/drive-model.md §5): Uv1 while running, the Uv minor fault while stopped."""

    action: ClassVar[str] = "mains-loss"
    needs_for: ClassVar[str | None] = "how long the mains are gone"


MasterFault = Silence | SkipCycles | FreezeWdt | BadCommand
PlantFault = LoadStep | LockRotor | MainsLoss
FaultSpec = MasterFault | PlantFault

_CLASSES: dict[str, type[_Fault]] = {c.action: c for c in (Silence, SkipCycles, FreezeWdt, BadCommand, LoadStep,
                                                           LockRotor, MainsLoss)}
#: The ``do`` values of the faults of this module, by side.
MASTER_FAULTS: tuple[str, ...] = ("silence", "skip-cycles", "freeze-wdt", "bad-command")
PLANT_FAULTS: tuple[str, ...] = ("load", "lock-rotor", "mains-loss")
FAULT_ACTIONS: tuple[str, ...] = MASTER_FAULTS + PLANT_FAULTS
#: The fields each action takes (besides ``do``).
_FIELDS: dict[str, tuple[str, ...]] = {
    "silence": ("for",), "skip-cycles": ("count",), "freeze-wdt": ("for",), "bad-command": ("kind",),
    "load": ("torque", "inertia", "for"), "lock-rotor": ("for",), "mains-loss": ("for",),
}


def fault_from_fields(action: str, values: Mapping[str, Any]) -> FaultSpec:
    """The fault *action* (``"silence"`` …) with *values* as a timeline step spells them (``for`` = ``"2s"`` or a
    number of seconds, ``count``, ``kind``, ``torque``, ``inertia``); None values are absent. A field the action
    does not take is a FaultError naming the ones it does."""
    cls = _CLASSES.get(action)
    if cls is None:
        raise FaultError(f"do: expected one of {', '.join(FAULT_ACTIONS)}, got {action!r}")
    allowed = _FIELDS[action]
    kw: dict[str, Any] = {}
    for name, value in values.items():
        if value is None or (name == "do" and value == action):  # as_fields() names the action too
            continue
        key = "for" if name in ("for", "for_", "for_ns") else name
        if key not in allowed:
            takes = ", ".join(allowed) if allowed else "nothing"
            raise FaultError(f"{name}: do = \"{action}\" does not take it (it takes {takes})")
        if key == "for":
            kw["for_ns"] = value if name == "for_ns" else _duration(value, "for", required=False)
        else:
            kw[key] = value
    return cls(**kw)  # type: ignore[return-value]
