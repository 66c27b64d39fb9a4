"""The arguments of the operations and how a value of each kind is read: one rule per kind and one message per
mistake, whichever surface the value came from (a control request's JSON, a command line, an HTTP request, a
Python call, a timeline step).

A :class:`Kind` reads a value (:meth:`Kind.read`) or refuses it with an :class:`OpError` whose ``kind`` is one of
:data:`ERROR_KINDS`; an :class:`Arg` is a named argument of an operation of that kind. The rules that need the
station's own settings (a speed against the drive's maximum output frequency, a parameter against its range) are
functions here too (:func:`check_speed`), given the figure the station's settings make.
"""

from __future__ import annotations

import keyword
import re
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from ..faults.spec import FAULT_ACTIONS
from ..impair.names import check_name
from ..units import parse_address, parse_duration_ns

__all__ = ["ERROR_KINDS", "OpError", "Kind", "Arg", "check_speed", "station_name", "KINDS", "STATION", "STATIONS",
           "HZ", "DIRECTION", "PARAM", "VALUE", "FLAG", "SINCE", "TEXT", "PROBABILITY", "DURATION", "NUMBER",
           "COUNT", "HANDLE", "LINK_DIRECTION", "NAME", "FAULT_NAME", "IMPAIRMENT", "FAULT", "FAULT_ACTION",
           "FAULT_KIND"]

#: The kinds of a refusal, in the order of the HTTP statuses the web API answers them with (400, 404, 404, 422,
#: 409, 409; docs/control.md, "Errors").
ERROR_KINDS = ("bad_request", "unknown_station", "unknown_param", "out_of_range", "refused", "unavailable")


class OpError(ValueError):
    """An operation refused: one line, and its :data:`ERROR_KINDS` entry (``kind``)."""

    def __init__(self, kind: str, message: str) -> None:
        if kind not in ERROR_KINDS:
            raise ValueError(f"OpError kind {kind!r} is not one of {', '.join(ERROR_KINDS)}")
        super().__init__(message)
        self.kind = kind

    def as_reply(self) -> dict[str, Any]:
        """The error reply of a control endpoint: ``{"ok": false, "error": …, "kind": …}``."""
        return {"ok": False, "error": str(self), "kind": self.kind}


def station_name(address: int) -> str:
    """``0x21`` -> ``"21H"``: a station as the manuals write it, in every line a user reads."""
    return f"{address:02X}H"


def _bad(name: str, expected: str, value: Any) -> OpError:
    return OpError("bad_request", f"{name}: expected {expected}, got {value!r}")


@dataclass(frozen=True)
class Kind:
    """What an argument's value is: how it is read (*read*: the value as given on any surface -> the value the
    operation takes, ``OpError`` otherwise), shown (*metavar*, *describe*), and typed in JSON (*schema*)."""

    name: str
    metavar: str
    describe: str
    schema: dict[str, Any]
    read: Callable[[str, Any], Any]
    #: where the command line takes it: ``"argument"`` (positional), ``"option"``, ``"flag"`` (a boolean)
    cli: str = "option"
    choices: tuple[str, ...] = ()


def _station(name: str, value: Any) -> int:
    try:
        return parse_address(value)
    except ValueError as exc:
        raise OpError("bad_request", f"{name}: {exc}") from None


def _stations(name: str, value: Any) -> int | None:
    if value is None or (isinstance(value, str) and value.strip().lower() == "all"):
        return None
    try:
        return parse_address(value)
    except ValueError as exc:
        raise OpError("bad_request", f"{name}: {exc} (or 'all')") from None


def _number(name: str, value: Any) -> float:
    if isinstance(value, str):
        try:
            value = float(value)
        except ValueError:
            raise _bad(name, "a number", value) from None
    if isinstance(value, bool) or not isinstance(value, int | float) or value != value:
        raise _bad(name, "a number", value)
    return float(value)


def _hz(name: str, value: Any) -> float:
    hz = _number(name, value)
    if hz < 0:
        raise OpError("out_of_range", f"{name}: a frequency reference is 0 Hz or more, got {hz:g} Hz (the direction "
                                      "is its own argument: 'forward' or 'reverse')")
    return hz


def _choice(choices: tuple[str, ...]) -> Callable[[str, Any], str]:
    quoted = [repr(c) for c in choices]
    expected = ", ".join(quoted[:-1]) + " or " + quoted[-1] if len(quoted) > 1 else quoted[0]

    def read(name: str, value: Any) -> str:
        text = value.strip().lower() if isinstance(value, str) else value
        if text not in choices:
            raise _bad(name, expected, value)
        return str(text)

    return read


def _given(name: str, value: Any) -> Any:
    """A value the impairment or the fault it belongs to checks itself (``mlink_sim.impair``, ``mlink_sim.faults``:
    one rule and one message for each of their fields, whichever surface gave it)."""
    return value


_PARAM_NAME = re.compile(r"[A-Za-z][A-Za-z0-9]{0,3}(-[0-9A-Za-z]{1,4})?")


def _param(name: str, value: Any) -> str:
    if not isinstance(value, str) or not _PARAM_NAME.fullmatch(value.strip()):
        raise _bad(name, "a parameter name such as 'C1-01' or 'n019'", value)
    return value.strip()


def _value(name: str, value: Any) -> float | int | str:
    """A parameter's value in its unit (``5.0``), or text its keypad takes (``"5 s"``, ``"24H"``): the station's
    parameter table reads it."""
    if isinstance(value, bool) or not isinstance(value, int | float | str) or (isinstance(value, str)
                                                                                 and not value.strip()):
        raise _bad(name, "the parameter's value in its unit (a number, or text such as '24H')", value)
    if isinstance(value, str):
        try:
            return float(value)
        except ValueError:
            return value.strip()
    return value


def _flag(name: str, value: Any) -> bool:
    if isinstance(value, bool):
        return value
    if isinstance(value, str) and value.strip().lower() in ("true", "false"):
        return value.strip().lower() == "true"
    raise _bad(name, "true or false", value)


def _whole(minimum: int) -> Callable[[str, Any], int]:
    def read(name: str, value: Any) -> int:
        if isinstance(value, str) and value.strip().lstrip("-").isdigit():
            value = int(value)
        if isinstance(value, bool) or not isinstance(value, int) or value < minimum:
            raise _bad(name, f"a whole number {minimum} or more", value)
        return value

    return read


def _text(name: str, value: Any) -> str:
    if not isinstance(value, str) or not value.strip():
        raise _bad(name, "text", value)
    return value.strip()


def _duration(name: str, value: Any) -> str:
    """A duration with its unit (``"200ms"``) or a number of seconds; passed on as exact text (``"200000000ns"``)."""
    try:
        ns = parse_duration_ns(value, default_unit="s")
    except (ValueError, TypeError):
        raise _bad(name, "a duration such as '200ms' or '2s' (a bare number is seconds)", value) from None
    if ns < 0:
        raise OpError("out_of_range", f"{name}: expected a duration of 0 or more, got {value!r}")
    return f"{ns}ns"


def _fault_name(name: str, value: Any) -> str:
    """The name of an impairment or a fault (:func:`mlink_sim.impair.names.check_name`: never a station)."""
    if not isinstance(value, str):
        raise _bad(name, "a name such as 'lossy-link'", value)
    why = check_name(value.strip())
    if why is not None:
        raise OpError("bad_request", f"{name}: {why}")
    return value.strip()


def _spec(name: str, value: Any) -> str:
    if not isinstance(value, str) or not value.strip():
        raise _bad(name, "a spec such as 'loss=10%,for=2s' or 'silence,for=200ms'", value)
    return value.strip()


STATION = Kind("station", "ADDR", "a station address: 21H, 0x21 or 33", {"type": ["string", "integer"],
               "examples": ["21H"]}, _station, cli="argument")
STATIONS = Kind("stations", "ADDR|all", "a station address, or 'all' (every station)",
                {"type": ["string", "integer"], "examples": ["21H", "all"]}, _stations, cli="argument")
HZ = Kind("hz", "HZ", "a frequency reference in Hz, 0 up to the drive's maximum output frequency (E1-04 / n011)",
          {"type": "number", "minimum": 0}, _hz)
DIRECTION = Kind("direction", "forward|reverse", "the run direction", {"enum": ["forward", "reverse"]},
                 _choice(("forward", "reverse")), cli="switch", choices=("forward", "reverse"))
LINK_DIRECTION = Kind("link-direction", "to-station|to-master|both", "which way the datagrams go",
                      {"enum": ["to-station", "to-master", "both"]}, _choice(("to-station", "to-master", "both")),
                      choices=("to-station", "to-master", "both"))
PARAM = Kind("param", "NAME", "a parameter name as the drive's manual writes it: C1-01, b1-02, n019",
             {"type": "string", "examples": ["C1-01"]}, _param, cli="argument")
VALUE = Kind("value", "VALUE", "a parameter value in its unit (5.0 for 5.0 s), or text its keypad takes",
             {"type": ["number", "string"]}, _value, cli="argument")
FLAG = Kind("flag", "", "true or false", {"type": "boolean"}, _flag, cli="flag")
SINCE = Kind("since", "N", "an event number: the events after it", {"type": "integer", "minimum": 0}, _whole(0))
TEXT = Kind("text", "TEXT", "text", {"type": "string"}, _text)
NAME = Kind("name", "NAME", "a name", {"type": "string"}, _text, cli="argument")
FAULT_NAME = Kind("fault-name", "NAME", "a name of an impairment or a fault: a letter, then letters, digits, '-', "
                  "'_' or '.' (not a station)", {"type": "string", "pattern": r"^[A-Za-z][A-Za-z0-9_.-]{0,39}$",
                                                 "examples": ["loss-21H-1"]}, _fault_name)
PROBABILITY = Kind("probability", "P", "a probability per datagram, 0…1 or a percentage such as 5%",
                   {"type": ["number", "string"], "examples": ["5%"]}, _given)
DURATION = Kind("duration", "DURATION", "a duration such as 200ms or 2s (a bare number is seconds)",
                {"type": ["string", "number"], "examples": ["200ms"]}, _duration)
NUMBER = Kind("number", "X", "a number", {"type": "number"}, _given)
COUNT = Kind("count", "N", "a whole number of transmission cycles, 1 or more", {"type": "integer", "minimum": 1},
             _given)
HANDLE = Kind("handle", "HANDLE", "the number a drive fault was answered with", {"type": "integer", "minimum": 1},
              _whole(1), cli="argument")
IMPAIRMENT = Kind("impairment", "SPEC", "an impairment as text: 'loss=10%,delay=200us,for=2s'",
                  {"type": "string", "examples": ["loss=10%,for=2s"]}, _spec, cli="argument")
FAULT = Kind("fault", "SPEC", "a fault as text: 'silence,for=200ms', 'load,torque=5,for=1s'",
             {"type": "string", "examples": ["silence,for=200ms"]}, _spec, cli="argument")
FAULT_ACTION = Kind("fault-action", "ACTION", "a fault: " + ", ".join(FAULT_ACTIONS), {"enum": list(FAULT_ACTIONS)},
                    _given, choices=FAULT_ACTIONS)
FAULT_KIND = Kind("fault-kind", "phase|combination|data-size", "which command a bad-command fault sends",
                  {"enum": ["phase", "combination", "data-size"]}, _given, choices=("phase", "combination", "data-size"))

#: Every kind, by name.
KINDS: dict[str, Kind] = {k.name: k for k in (STATION, STATIONS, HZ, DIRECTION, LINK_DIRECTION, PARAM, VALUE, FLAG,
                                              SINCE, TEXT, NAME, FAULT_NAME, PROBABILITY, DURATION, NUMBER, COUNT, HANDLE,
                                              IMPAIRMENT, FAULT, FAULT_ACTION, FAULT_KIND)}


@dataclass(frozen=True)
class Arg:
    """One argument of an operation: *name* as a control request, an HTTP body or query, a config's timeline step
    and (dashes as underscores, a keyword with ``_`` after it: ``for_``) a Python call spell it; the command line
    writes an option ``--name``."""

    name: str
    kind: Kind
    help: str
    required: bool = False
    default: Any = None
    #: the command line offers it (an alternative form of another argument need not be)
    cli: bool = field(default=True, compare=False)

    @property
    def python(self) -> str:
        """The argument's Python name: ``eeprom``, ``for_``."""
        name = self.name.replace("-", "_")
        return name + "_" if keyword.iskeyword(name) else name

    @property
    def option(self) -> str:
        """The argument's command-line option: ``--hz``, ``--for``."""
        return "--" + self.name.replace("_", "-")

    def read(self, value: Any) -> Any:
        """*value* as the operation takes it (``OpError`` when it is not of this argument's kind)."""
        return self.kind.read(self.name, value)


def check_speed(hz: float, address: int, top_hz: float, top_param: str) -> float:
    """*hz* if the station's drive can be given it as a frequency reference: 0 up to its maximum output frequency
    *top_hz* (the parameter *top_param*: A1000 E1-04, VS-606V7 n011); else an ``out_of_range`` OpError."""
    if not 0 <= hz <= top_hz:
        raise OpError("out_of_range", f"hz: {hz:g} Hz is outside 0…{top_hz:g} Hz, the maximum output frequency of "
                                      f"station {station_name(address)} ({top_param})")
    return hz
