"""``--assert`` expressions: bounds on report fields, checked at the end of a run.

Grammar (docs/report.md has the full description and examples)::

    assertion = path , op , value ;
    path      = name , { "[" , address , "]" | "." , name } ;      (* only station takes [address] *)
    address   = hex | decimal | "*" ;                             (* 0x21, 33 → "0x21"; * = every station *)
    op        = "<" | "<=" | "==" | "!=" | ">=" | ">" ;
    value     = number , [ unit ] ;                               (* 500us, 0.5 ms, 1e3ns, 0, 2.5% *)
    unit      = "ns" | "us" | "µs" | "ms" | "s" | "%" ;

Paths are checked against :data:`~mlink_sim.metrics.report.REPORT_SCHEMA` while parsing, so an unknown field,
a unit on a count or a time without a unit is an :class:`AssertionSyntaxError` before the run starts (the CLI
turns it into a usage error, exit 2). What can only be known from the report (a station that did not take
part, a histogram without samples) makes the assertion fail at check time with a message that says so.

Times are compared in integer nanoseconds. ``p99.9`` is accepted for ``p99_9``.
"""

from __future__ import annotations

import difflib
import operator
import re
from collections.abc import Callable, Collection, Iterable, Mapping
from dataclasses import dataclass
from decimal import Decimal, InvalidOperation
from typing import Any

from ..units import format_ns
from .report import REPORT_SCHEMA

__all__ = [
    "Assertion", "AssertionResult", "AssertionSyntaxError", "parse_assertion", "parse_assertions", "check_all",
    "assertable_fields", "OPERATORS", "TIME_UNITS",
]

OPERATORS: dict[str, Callable[[Any, Any], bool]] = {
    "<": operator.lt, "<=": operator.le, "==": operator.eq, "!=": operator.ne, ">=": operator.ge, ">": operator.gt,
}
_OP_ALIASES = {"≤": "<=", "≥": ">=", "≠": "!="}
_OP_SCAN = ("<=", ">=", "==", "!=", "<", ">", *_OP_ALIASES)          # longest first
_OP_LIST = "(<, <=, ==, !=, >=, >)"
_OP_HINTS = {"=": "use '==' to test equality", "=<": "did you mean '<='?", "=>": "did you mean '>='?",
             "<>": "use '!=' for 'not equal'", "!": "did you mean '!='?"}

#: Time units, in ns. ``µs`` is accepted with the micro sign (U+00B5) and the Greek mu (U+03BC).
TIME_UNITS: dict[str, int] = {"ns": 1, "us": 1_000, "µs": 1_000, "μs": 1_000, "ms": 1_000_000,
                              "s": 1_000_000_000}
_UNIT_LIST = "ns, us, µs, ms, s"
_IDENT = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
_PCT_SUFFIX = re.compile(r"\.(\d+)(?![A-Za-z0-9_])")
_ADDRESS = re.compile(r"0[xX][0-9A-Fa-f]+|[0-9A-Fa-f]+[hH](?![\w])|\d+|\*")  # 0x21, 21H (the manuals'), 33, *
_NUMBER = re.compile(r"(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][+-]?\d+)?")
_UNIT = re.compile(r"[A-Za-zµμ%]+")
_TOKEN = re.compile(r"[A-Za-z_µμ%][\wµμ%]*|\d[\w.]*|[=<>!&|]+|\S")   # what 'got' shows


class AssertionSyntaxError(ValueError):
    """A malformed expression. ``str()`` says what was expected where, e.g. ``expected a comparison operator
    (<, <=, ==, !=, >=, >) after 'rtt.p99' at column 9, got '500us'``. Columns count from 1."""

    def __init__(self, text: str, column: int, expected: str, got: str | None = None, hint: str | None = None):
        self.text = text
        self.column = column
        self.expected = expected
        self.got = got
        self.hint = hint
        msg = f"expected {expected} at column {column}"
        if got is not None:
            msg += f", got {got}"
        if hint:
            msg += f" ({hint})"
        super().__init__(msg)

    def caret(self) -> str:
        """The expression with a caret under the column, for a terminal."""
        return f"  {self.text}\n  {' ' * (self.column - 1)}^"


# ---------------------------------------------------------------------------------------------- schema walk
def _deref(node: Mapping[str, Any]) -> Mapping[str, Any]:
    while "$ref" in node:
        target = REPORT_SCHEMA["$defs"][node["$ref"].rsplit("/", 1)[1]]
        node = {**target, **{k: v for k, v in node.items() if k != "$ref"}}
    return node


def _is_map(node: Mapping[str, Any]) -> bool:
    return "patternProperties" in node


def _map_value(node: Mapping[str, Any]) -> Mapping[str, Any]:
    return _deref(next(iter(node["patternProperties"].values())))


def _assertable(node: Mapping[str, Any]) -> bool:
    node = _deref(node)
    if "x-kind" in node:
        return True
    if _is_map(node):
        return _assertable(_map_value(node))
    return any(_assertable(c) for c in node.get("properties", {}).values())


def _fields(node: Mapping[str, Any]) -> dict[str, Mapping[str, Any]]:
    return {k: _deref(v) for k, v in node.get("properties", {}).items() if _assertable(v)}


def assertable_fields() -> dict[str, str]:
    """Every path an assertion can name, with its kind: ``{"rtt.p99": "time", "station[ADDR].late": "count"}``."""
    out: dict[str, str] = {}

    def walk(node: Mapping[str, Any], prefix: str) -> None:
        for name, child in _fields(node).items():
            path = f"{prefix}.{name}" if prefix else name
            if _is_map(child):
                path += "[ADDR]"
                child = _map_value(child)
            if "x-kind" in child:
                out[path] = child["x-kind"]
            else:
                walk(child, path)

    walk(REPORT_SCHEMA, "")
    return out


# ---------------------------------------------------------------------------------------------- parsing
@dataclass(frozen=True)
class Assertion:
    """A parsed bound. ``bound`` is in ns for times, a plain number otherwise (a fraction for ratios)."""

    text: str                      # as written (stripped)
    path: tuple[str, ...]          # ("station", "0x21", "rtt", "p99"); "*" for every station
    op: str                        # one of OPERATORS
    bound: int | float
    kind: str                      # "time", "count", "percent" or "ratio" (REPORT_SCHEMA x-kind)
    bound_text: str = ""           # the value as written, normalised: "500us", "0", "1%"

    @property
    def path_text(self) -> str:
        return _path_text(self.path)

    def __str__(self) -> str:
        return f"{self.path_text} {self.op} {self.bound_text or self.bound}"

    def check(self, report: Mapping[str, Any]) -> AssertionResult:
        """Evaluate against a report document; never raises for a missing or odd field (the result fails)."""
        if "*" in self.path:
            return self._check_every_station(report)
        ok, measured, why = self._check_one(report, self.path)
        return AssertionResult(self, ok, measured, f"{self} {'ok' if ok else 'failed'}: {why}")

    def _check_one(self, report: Mapping[str, Any], path: tuple[str, ...]) -> tuple[bool, Any, str]:
        node: Any = report
        parent: Any = None
        for i, part in enumerate(path):
            if not isinstance(node, Mapping) or part not in node:
                return False, None, _missing(report, path[: i + 1])
            parent, node = node, node[part]
        if isinstance(node, bool) or not isinstance(node, (int, float)):
            return False, None, f"'{_path_text(path)}' is not a number in the report ({node!r})"
        if self.kind == "time" and isinstance(parent, Mapping) and parent.get("count") == 0:
            return False, None, f"no samples ('{_path_text(path[:-1] + ('count',))}' is 0)"
        ok = OPERATORS[self.op](node, self.bound)
        return ok, node, f"measured {self._format(node, ok)}"

    def _check_every_station(self, report: Mapping[str, Any]) -> AssertionResult:
        stations = report.get("station")
        if not isinstance(stations, Mapping) or not stations:
            return AssertionResult(self, False, None, f"{self} failed: no stations in the report")
        star = self.path.index("*")
        rows = []
        for key in sorted(stations):
            path = self.path[:star] + (key,) + self.path[star + 1:]
            rows.append((key, *self._check_one(report, path)))
        measured = [m for _, _, m, _ in rows if m is not None]
        worst = None
        if measured:
            worst = max(measured) if self.op in ("<", "<=") else min(measured) if self.op in (">", ">=") else None
        bad = [r for r in rows if not r[1]]
        if not bad:
            if worst is None:
                worst = measured[0]
            key = next(k for k, _, m, _ in rows if m == worst)
            msg = f"{self} ok at all {len(rows)} stations: worst station[{key}] {self._format(worst, True)}"
            return AssertionResult(self, True, worst, msg)
        if self.op in ("<", "<=", ">", ">="):        # worst first: largest for an upper bound, else smallest
            sign = -1 if self.op in ("<", "<=") else 1
            bad.sort(key=lambda r: (0, sign * r[2]) if r[2] is not None else (1, 0))
        shown = ", ".join(f"station[{k}] {why}" for k, _, _, why in bad[:5]) + (", ..." if len(bad) > 5 else "")
        msg = f"{self} failed at {len(bad)} of {len(rows)} stations: {shown}"
        return AssertionResult(self, False, worst if worst is not None else bad[0][2], msg)

    def _format(self, value: int | float, ok: bool) -> str:
        if self.kind == "time":
            text = format_ns(value)
            if not ok and text == format_ns(self.bound):
                text += f" ({value}ns)"
            return text
        if self.kind == "percent":
            return f"{value:.4g}%"
        if self.kind == "ratio":
            return f"{value:.4g} ({value * 100:.4g}%)"
        return f"{value:g}" if isinstance(value, float) else str(value)


@dataclass(frozen=True)
class AssertionResult:
    assertion: Assertion
    ok: bool
    measured: int | float | None   # ns for times; for station[*] the worst station's value
    message: str                   # "rtt.p99 < 500us failed: measured 731.2us"

    def as_dict(self) -> dict[str, Any]:
        """The report's ``assertions[]`` entry."""
        return {"text": str(self.assertion), "ok": self.ok, "measured": self.measured,
                "bound": self.assertion.bound, "message": self.message}


def _path_text(path: Iterable[str]) -> str:
    out = ""
    for part in path:
        if part == "*" or part.startswith("0x"):
            out += f"[{part}]"
        else:
            out += f".{part}" if out else part
    return out


def _missing(report: Mapping[str, Any], path: tuple[str, ...]) -> str:
    msg = f"no field '{_path_text(path)}' in the report"
    if len(path) == 2 and path[0] == "station" and isinstance(report.get("station"), Mapping):
        known = ", ".join(sorted(report["station"])) or "none"
        msg += f" (stations: {known})"
    return msg


class _Parser:
    def __init__(self, text: str, stations: Collection[int] | None) -> None:
        self.text = text
        self.pos = 0
        self.stations = stations

    # -- helpers
    def error(self, expected: str, *, at: int | None = None, hint: str | None = None) -> AssertionSyntaxError:
        at = self.pos if at is None else at
        rest = self.text[at:].lstrip()
        m = _TOKEN.match(rest)
        got = f"'{m.group()[:24]}'" if m else "the end of the expression"
        return AssertionSyntaxError(self.text, at + 1, expected, got, hint)

    def skip_ws(self) -> None:
        while self.pos < len(self.text) and self.text[self.pos].isspace():
            self.pos += 1

    def peek(self, s: str) -> bool:
        return self.text.startswith(s, self.pos)

    def name(self, expected: str) -> tuple[str, int]:
        m = _IDENT.match(self.text, self.pos)
        if not m:
            raise self.error(expected)
        start, self.pos = self.pos, m.end()
        name = m.group()
        pct = _PCT_SUFFIX.match(self.text, self.pos)
        if re.fullmatch(r"p\d+", name) and pct:          # p99.9 → p99_9
            name += "_" + pct.group(1)
            self.pos = pct.end()
        return name, start

    def like(self, fields: Mapping[str, Mapping[str, Any]]) -> list[str]:
        """Fields of the shape the text goes on with: a group before '.', station before '[', else a value."""
        if self.peek("."):
            return [k for k, v in fields.items() if "x-kind" not in v and not _is_map(v)]
        if self.peek("["):
            return [k for k, v in fields.items() if _is_map(v)]
        return [k for k, v in fields.items() if "x-kind" in v]

    # -- grammar
    def path(self) -> tuple[tuple[str, ...], Mapping[str, Any], str]:
        self.skip_ws()
        start = self.pos
        node: Mapping[str, Any] = REPORT_SCHEMA
        parts: list[str] = []
        name, at = self.name("a report field (e.g. rtt.p99, missed, station[0x21].late)")
        while True:
            fields = _fields(node)
            if name not in fields:
                where = f"'{_path_text(parts)}'" if parts else "the report"
                close = difflib.get_close_matches(name, self.like(fields), n=1) or \
                    difflib.get_close_matches(name, list(fields), n=1)
                raise self.error(f"a field of {where} ({', '.join(fields)})", at=at,
                                 hint=f"did you mean '{close[0]}'?" if close else None)
            node = fields[name]
            parts.append(name)
            if _is_map(node):
                parts.append(self.address(name))
                node = _map_value(node)
            elif self.peek("["):
                raise self.error(f"'.' or a comparison operator after '{_path_text(parts)}'",
                                 hint="only station[...] takes an address")
            if not self.peek("."):
                break
            self.pos += 1
            name, at = self.name(f"a field name after '{_path_text(parts)}.'")
        if "x-kind" not in node:
            raise self.error(f"'.' and a field of '{_path_text(parts)}' ({', '.join(_fields(node))})",
                             hint=f"'{_path_text(parts)}' is a group of fields, not a value")
        return tuple(parts), node, self.text[start:self.pos]

    def address(self, name: str) -> str:
        if not self.peek("["):
            raise self.error(f"'[' and a station address after '{name}' (e.g. {name}[0x21])")
        self.pos += 1
        self.skip_ws()
        m = _ADDRESS.match(self.text, self.pos)
        if not m:
            raise self.error(f"a station address after '{name}[' (21H or 0x21, decimal 33, or * for every station)")
        at, self.pos = self.pos, m.end()
        raw = m.group()
        if raw == "*":
            key = "*"
        else:
            if raw[:2].lower() == "0x":
                value = int(raw, 16)
            else:
                value = int(raw[:-1], 16) if raw[-1] in "hH" else int(raw, 10)
            if value > 0xFF:
                raise self.error("a station address from 0x00 to 0xff", at=at)
            if self.stations is not None and value not in self.stations:
                known = ", ".join(f"0x{s:02x}" for s in sorted(self.stations)) or "none"
                raise self.error(f"a station of the configuration ({known})", at=at)
            key = f"0x{value:02x}"
        self.skip_ws()
        if not self.peek("]"):
            raise self.error(f"']' after the station address '{raw}'")
        self.pos += 1
        return key

    def op(self, path_text: str) -> str:
        self.skip_ws()
        for tok in _OP_SCAN:
            if self.peek(tok):
                self.pos += len(tok)
                return _OP_ALIASES.get(tok, tok)
        m = re.compile(r"[=<>!]+").match(self.text, self.pos)
        hint = _OP_HINTS.get(m.group()) if m else None
        raise self.error(f"a comparison operator {_OP_LIST} after '{path_text}'", hint=hint)

    def value(self, kind: str, path_text: str, op: str) -> tuple[int | float, str]:
        self.skip_ws()
        m = _NUMBER.match(self.text, self.pos)
        if not m:
            raise self.error(f"a number after '{op}'")
        self.pos = m.end()
        number = Decimal(m.group())
        num_text = m.group()
        self.skip_ws()
        u = _UNIT.match(self.text, self.pos)
        unit = u.group() if u else None
        unit_at = self.pos
        if u:
            self.pos = u.end()
        if kind == "time":
            if unit is None:
                if number != 0:
                    raise self.error(f"a time unit ({_UNIT_LIST}) after '{num_text}'", at=unit_at,
                                     hint=f"'{path_text}' is a time; only 0 may go without a unit")
                return 0, "0"
            if unit not in TIME_UNITS:
                raise self.error(f"a time unit ({_UNIT_LIST}) after '{num_text}'", at=unit_at,
                                 hint=f"'{path_text}' is a time")
            ns = number * TIME_UNITS[unit]
            return _plain(ns), f"{num_text}{'us' if unit in ('µs', 'μs') else unit}"
        if kind == "count":
            if unit is not None:
                raise self.error(f"a plain number for '{path_text}'", at=unit_at,
                                 hint=f"'{path_text}' is a count; it takes no unit")
            return _plain(number), num_text
        # percent (stored in %) and ratio (stored as a fraction)
        if unit not in (None, "%"):
            what = "a percentage" if kind == "percent" else "a ratio from 0 to 1; write 1% or 0.01"
            raise self.error(f"'%' or no unit after '{num_text}'", at=unit_at, hint=f"'{path_text}' is {what}")
        if kind == "ratio" and unit == "%":
            return float(number / 100), f"{num_text}%"
        return _plain(number), f"{num_text}{unit or ''}"

    def end(self) -> None:
        self.skip_ws()
        if self.pos < len(self.text):
            hint = "give each condition its own --assert" if re.match(r"&&|and\b|\|\||or\b|,", self.text[self.pos:]) \
                else None
            raise self.error("the end of the expression", hint=hint)


def _plain(d: Decimal) -> int | float:
    return int(d) if d == d.to_integral_value() else float(d)


def parse_assertion(text: str, *, stations: Collection[int] | None = None) -> Assertion:
    """Parse ``PATH OP VALUE``; raises :class:`AssertionSyntaxError` saying what was expected where.

    With ``stations`` (the configured station addresses), ``station[N]`` naming another station is an error
    too, found before the run.
    """
    p = _Parser(text, stations)
    try:
        path, node, path_text = p.path()
        op = p.op(path_text)
        bound, bound_text = p.value(node["x-kind"], _path_text(path), op)
        p.end()
    except InvalidOperation:      # pragma: no cover - _NUMBER only lets valid decimals through
        raise p.error("a number") from None
    return Assertion(text.strip(), path, op, bound, node["x-kind"], bound_text)


def parse_assertions(texts: Iterable[str], *, stations: Collection[int] | None = None) -> list[Assertion]:
    """Parse several; the first malformed one raises."""
    return [parse_assertion(t, stations=stations) for t in texts]


def check_all(assertions: Iterable[Assertion], report: Mapping[str, Any]) -> list[AssertionResult]:
    """Evaluate each assertion against the report (put ``[r.as_dict() for r in results]`` in its
    ``assertions`` field; the run fails if any ``not r.ok``)."""
    return [a.check(report) for a in assertions]
