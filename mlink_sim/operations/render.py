"""Each thing a user reads, written one way in every human output (``mlink-sim status``, the events of ``status
--watch``, the trace, the live status): stations as the manuals write them (``21H``), a card's LEDs, an alarm by
name and code, an event. JSON replies carry the same values as data (``"station": "0x21"``, ``"leds": {"RUN":
"on"}``); these functions are their text.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from ..plots import BEFORE_ZERO
from ..units import parse_address
from .args import station_name

__all__ = ["station_name", "station_text", "card_text", "leds_text", "alarm_text", "event_text", "LED_MARKS"]

#: A LED's state -> the mark after its name: lit is the name alone, unlit ``-``, blinking ``*`` (SI-T3 Table 3,
#: SI-ET3 Table 4, SI-T/V7 §3.3 "LED Indicators" name the states).
LED_MARKS = {"on": "", "off": "-", "blink": "*"}


def station_text(value: Any) -> str:
    """A station as JSON names it (``"0x21"``, ``33``) or ``"all"``, as a user reads it: ``21H``, ``all``."""
    if value in (None, "all", ""):
        return "all"
    try:
        return station_name(parse_address(value))
    except ValueError:
        return str(value)


def card_text(card: Any) -> str:
    """A card as JSON names it (its key, ``"si-t-v7"``) as its manual does (``"SI-T/V7"``); an unknown one as it is."""
    from ..profiles import lookup

    try:
        return lookup(str(card)).label
    except ValueError:
        return str(card or "")


def leds_text(leds: Mapping[str, str] | None) -> str:
    """``{"RUN": "on", "ERR": "off", "TX": "blink", "RX": "on"}`` -> ``"RUN ERR- TX* RX"`` (:data:`LED_MARKS`)."""
    return " ".join(f"{name}{LED_MARKS.get(state, '?')}" for name, state in (leds or {}).items())


def alarm_text(alarm: Mapping[str, Any] | None) -> str:
    """``{"code": "E6H", "name": "COMM_ERROR"}`` -> ``"COMM_ERROR (E6H)"``; a drive fault whose code the master has
    not read yet: its name alone (``"D_ALM"``); no alarm: ``"ok"``."""
    if not alarm:
        return "ok"
    name, code = alarm.get("name") or "", alarm.get("code")
    if not code:
        return str(name) or "alarm"
    return f"{name} ({code})" if name and name != code else str(code)


def event_text(event: Mapping[str, Any]) -> str:
    """One event of a run (docs/control.md, "Events") as a line: its time, its kind, what happened; an event before
    the timeline's 0 s ends with ``(bring-up)``: its negative time counts up to the end of bring-up."""
    kind = str(event.get("kind", ""))
    at = event.get("at_s")
    head = f"{at:8.3f} s  {kind:<6} " if isinstance(at, int | float) else f"{'':10}  {kind:<6} "
    who = station_text(event["station"]) + " " if "station" in event else ""
    if kind == "phase":
        if event.get("state") == "recovered":
            what = f"recovered after {event.get('after_s', 0):g} s ({event.get('reason', '')})"
        else:
            what = f"phase {event.get('phase')} ({event.get('state')}, was {event.get('was')})"
    elif kind == "alarm":
        field = {"comm": "COMM_ALM", "command": "CMD_ALM"}.get(str(event.get("source")), "ALARM")
        what = (f"{field} cleared" if event.get("cleared")
                else f"{alarm_text({'code': event.get('code'), 'name': event.get('name')})}")
    elif kind == "check":
        what = f"{'ok' if event.get('ok') else 'FAIL'} {event.get('what', '')}: {event.get('detail', '')}"
    else:
        what = str(event.get("describe", ""))
    during = f" ({BEFORE_ZERO})" if isinstance(at, int | float) and at < 0 else ""
    return (head + who + what).rstrip() + during
