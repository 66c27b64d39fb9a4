"""The option types every command shares, so that one idea is spelled one way on the whole command line:

- ``ADDR`` a station address, ``21H`` as the manuals write it, ``0x21`` or ``33`` accepted too;
- ``HOST:PORT`` an endpoint (``[::1]:47001`` for IPv6; port 0 where a command listens: any free port);
- ``DURATION`` a time with its unit, ``250us``, ``2ms``, ``30s`` (a bare number is seconds);
- ``ML1|ML2|ML3`` a link, as the config's ``link`` field spells it, in any case;
- ``CARD`` an option card by its key as the config's ``card`` field spells it (``si-t3``, ``si-et3``, ``si-t-v7``,
  and any card registered with :func:`mlink_sim.profiles.register`), any spelling read as that key (``SI-T/V7``);
- ``LIST`` a list of CPUs, ``0,2`` (``--cpus``).

Output names a station the manuals' way, :func:`station_name` (``21H``)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import click

from ..profiles import lookup, profiles
from ..units import parse_address, parse_cpus, parse_duration_ns

__all__ = ["ADDR", "LINK", "CARD", "Card", "Parsed", "Duration", "Seconds", "CPUS", "station_name", "LINKS"]

LINKS = ("ML1", "ML2", "ML3")


def station_name(address: int) -> str:
    """``0x21`` -> ``"21H"``, the manuals' notation."""
    return f"{address:02X}H"


class Parsed(click.ParamType):
    """An option value read by *parse* (its ValueError is the one-line usage error), shown as *name*; a value of
    *kind* already (a default) is taken as it is. ``ADDR`` and ``LIST`` are two of them."""

    def __init__(self, name: str, parse: Callable[[Any], Any], kind: type | tuple[type, ...] = ()) -> None:
        self.name = name
        self.parse = parse
        self.kind = kind

    def get_metavar(self, param: Any, ctx: Any = None) -> str:
        return self.name

    def convert(self, value: Any, param: Any, ctx: Any) -> Any:
        if self.kind and isinstance(value, self.kind):
            return value
        try:
            return self.parse(value)
        except ValueError as exc:
            self.fail(str(exc), param, ctx)


class Duration(click.ParamType):
    """``DURATION``: checked here (a time with its unit; a bare number is in *default_unit*), passed on as the
    text the user typed, which the command parses with the same rule."""

    name = "DURATION"

    def __init__(self, default_unit: str = "s") -> None:
        self.default_unit = default_unit

    def get_metavar(self, param: Any, ctx: Any = None) -> str:
        return "DURATION"

    def convert(self, value: Any, param: Any, ctx: Any) -> str:
        try:
            parse_duration_ns(value, default_unit=self.default_unit)
        except ValueError as exc:
            self.fail(str(exc), param, ctx)
        return str(value)


class Seconds(click.ParamType):
    """``DURATION`` given as ``500ms`` or ``2s`` (a bare number is seconds) -> seconds as a float above 0 and at
    most *maximum*."""

    name = "DURATION"

    def __init__(self, maximum: float = 3600.0, *, zero: bool = False) -> None:
        self.maximum = maximum
        self.zero = zero

    def get_metavar(self, param: Any, ctx: Any = None) -> str:
        return "DURATION"

    def convert(self, value: Any, param: Any, ctx: Any) -> float:
        if isinstance(value, float):
            return value
        try:
            seconds = parse_duration_ns(value, default_unit="s") / 1e9
        except ValueError as exc:
            self.fail(str(exc), param, ctx)
        if not (0 <= seconds if self.zero else 0 < seconds) or seconds > self.maximum:
            low = "0" if self.zero else "above 0"
            self.fail(f"expected a duration of {low} to {self.maximum:g}s, got {value!r}", param, ctx)
        return seconds


class _Spelled(click.Choice):
    """A choice shown as the config spells it (click lower-cases the choices of a case-insensitive one)."""

    def get_metavar(self, param: Any, ctx: Any = None) -> str:
        return f"[{'|'.join(map(str, self.choices))}]"


class Card(click.ParamType):
    """``CARD``: a registered card (:mod:`mlink_sim.profiles`, read when the value is converted, so a card
    registered after the command was made is taken), in any spelling; the value is its key (``si-t-v7``)."""

    name = "CARD"

    def get_metavar(self, param: Any, ctx: Any = None) -> str:
        return "CARD"

    def convert(self, value: Any, param: Any, ctx: Any) -> str:
        try:
            return lookup(str(value)).key
        except ValueError as exc:
            self.fail(str(exc), param, ctx)

    def shell_complete(self, ctx: Any, param: Any, incomplete: str) -> list[Any]:
        from click.shell_completion import CompletionItem

        return [CompletionItem(p.key) for p in profiles() if p.key.startswith(incomplete.lower())]


#: ``ADDR`` options and arguments: ``21H``, ``0x21`` or ``33`` -> the address as an int
ADDR = Parsed("ADDR", parse_address)
#: ``--cpus`` options: ``0,2`` -> ``{0, 2}``
CPUS = Parsed("LIST", parse_cpus, set)
#: ``--link``: the config's spelling, any case; the value is ``ML1``, ``ML2`` or ``ML3``
LINK = _Spelled(LINKS, case_sensitive=False)
#: ``--card``: the config's spelling, any spelling read as it; the value is the card's key
CARD = Card()
