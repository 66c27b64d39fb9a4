"""``mlink-sim param get|set`` and ``mlink-sim status``: a running network's parameters and status through its
control endpoint (``up``/``master --control``), and a standalone slave's status through its stats endpoint
(``slave --control``); docs/control.md.

Exit 0 when answered, 1 when the endpoint does not answer or the station refuses (its phase, A.94/A.95, CMD_ALM), 2
for a usage error (a bad address, an unknown station or parameter, a value out of range).

Touches: one UDP socket per request (:func:`~mlink_sim.aio.run.control.query_control`), stdout and stderr.
"""

from __future__ import annotations

import asyncio
import json
import secrets
import sys
import time
from collections.abc import Callable
from typing import Any

import click

from ..config import parse_endpoint
from ..units import parse_address
from .control_token import control_token as resolve_token
from .control_token import control_token_options
from .inputs import InputError
from .params import Seconds

__all__ = ["param_cmd", "status_cmd", "status_lines", "ask"]

_ATTEMPTS = 3  #: a request is sent up to this often (UDP); a repeat carries the same id and does not act twice
#: error kinds that mean the request itself was wrong (exit 2); the others (refused, unavailable) exit 1
_USAGE_KINDS = ("bad_request", "unknown_station", "unknown_param", "out_of_range")


def _where(text: str) -> tuple[str, int]:
    try:
        return parse_endpoint(text)
    except ValueError as exc:
        raise InputError(f"HOST:PORT {text!r}: {exc}") from None


def ask(where: tuple[str, int], op: str, timeout: float, token: str | None, **fields: Any) -> dict[str, Any] | None:
    """*op* asked of the endpoint at *where*, up to :data:`_ATTEMPTS` times within *timeout* s (each with the same
    ``id``): its reply, or None when it did not answer."""
    from ..aio.run.control import query_control

    fields.setdefault("id", secrets.token_hex(8))
    for _ in range(_ATTEMPTS):
        reply = asyncio.run(query_control(where[0], where[1], op, timeout=timeout / _ATTEMPTS, token=token, **fields))
        if reply is not None:
            return reply
    return None


def _no_answer(command: str, address: str, timeout: float) -> None:
    click.echo(f"mlink-sim {command}: no answer from {address} within {timeout:g} s (is it running with --control? "
               "an endpoint with a token answers only requests that carry it: --control-token)", err=True)
    sys.exit(1)


def _refused(command: str, address: str, reply: dict[str, Any]) -> None:
    kind = reply.get("kind", "refused")
    click.echo(f"mlink-sim {command}: {address}: {reply.get('error', 'refused, no reason given')}", err=True)
    sys.exit(2 if kind in _USAGE_KINDS else 1)


# -- param ----------------------------------------------------------------------------------------------------------


@click.group("param")
def param_cmd() -> None:
    """Read or write a drive parameter of a running network's station by name, through its master (PRM_RD;
    PRM_WR, CONFIG and a read back), at the network's control endpoint (up/master --control HOST:PORT):

    \b
      mlink-sim param get 127.0.0.1:47000 0x21 C1-01
      C1-01 = 2.0 s (raw 20, register 0200H)
      mlink-sim param set 127.0.0.1:47000 0x21 C1-01=5.0 --eeprom

    Names, units and ranges are the card's (docs/parameters.md), checked as in a config."""


def _param_options(fn: Callable[..., Any]) -> Callable[..., Any]:
    fn = control_token_options(fn)
    return click.option("--timeout", default="5s", show_default=True, type=Seconds(60.0),
                        help="How long to wait for the answer (the request is sent up to three times).")(fn)


def _station(text: str) -> str:
    try:
        return f"0x{parse_address(text):02x}"
    except ValueError as exc:
        raise InputError(f"ADDR {text!r}: {exc}") from None


def _param(command: str, address: str, station: str, fields: dict[str, Any], timeout: float,
           token: str | None) -> None:
    reply = ask(_where(address), "param", timeout, token, station=_station(station), **fields)
    if reply is None:
        _no_answer(command, address, timeout)
    assert reply is not None
    if not reply.get("ok"):
        _refused(command, address, reply)
    p = reply["param"]
    click.echo(f"{p['name']} = {p['text']} (raw {p['raw']}, register {p['register']})")


@param_cmd.command("get")
@click.argument("address", metavar="HOST:PORT")
@click.argument("station", metavar="ADDR")
@click.argument("name", metavar="NAME")
@_param_options
def param_get(address: str, station: str, name: str, timeout: float, control_token: str | None,
              control_token_file: str | None) -> None:
    """Read parameter NAME (e.g. C1-01, n019) of station ADDR (0x21, 21H) of the network at HOST:PORT."""
    _param("param get", address, station, {"name": name}, timeout, resolve_token(control_token, control_token_file))


@param_cmd.command("set")
@click.argument("address", metavar="HOST:PORT")
@click.argument("station", metavar="ADDR")
@click.argument("assignment", metavar="NAME=VALUE")
@click.option("--eeprom", is_flag=True, help="Save it too (CONFIG with CONFIG_MOD 1: kept across a power cycle, "
                                             "with the slave's --state-dir).")
@_param_options
def param_set(address: str, station: str, assignment: str, eeprom: bool, timeout: float,
              control_token: str | None, control_token_file: str | None) -> None:
    """Write NAME=VALUE (in the parameter's unit: C1-01=5.0) to station ADDR of the network at HOST:PORT, enter it
    (CONFIG) and print the value read back."""
    name, sep, text = assignment.partition("=")
    if not sep or not name.strip() or not text.strip():
        raise InputError(f"NAME=VALUE: expected e.g. C1-01=5.0, got {assignment!r}")
    try:
        value: Any = float(text)
    except ValueError:
        value = text.strip()  # as the keypad takes it ("5 s", "24H"): the card's table reads it
    _param("param set", address, station, {"name": name.strip(), "value": value, "eeprom": eeprom}, timeout,
           resolve_token(control_token, control_token_file))


# -- status ---------------------------------------------------------------------------------------------------------

_HEADINGS = ("ADDR", "CARD", "LINK", "PHASE", "RUN", "REF", "OUTPUT", "CURRENT", "DC BUS", "SPEED", "RTT p99",
             "LEDS", "STATE")
_RIGHT = {5, 6, 7, 8, 9, 10}


def _num(value: Any, unit: str, digits: int = 2) -> str:
    return "-" if value is None else f"{value:.{digits}f} {unit}"


def _row(f: dict[str, Any]) -> tuple[str, ...]:
    direction = {"forward": "FWD", "reverse": "REV"}.get(f.get("direction") or "", "stop")
    leds = " ".join(f"{name}{'' if state == 'on' else '*' if state == 'blink' else '-'}"
                    for name, state in (f.get("leds") or {}).items())
    alarm = f.get("alarm")
    state = (f"{alarm['code'] + ' ' if alarm.get('code') else ''}{alarm['name']}" if alarm else
             "warn " + ", ".join(f["warnings"]) if f.get("warnings") else "ok")
    return (f.get("name") or "", str(f.get("card") or ""), str(f.get("link") or ""),
            f"P{f['phase']}" if f.get("phase") else "offline", direction, _num(f.get("reference_hz"), "Hz"),
            _num(f.get("output_hz"), "Hz"), _num(f.get("output_current_a"), "A", 1), _num(f.get("dc_bus_v"), "V", 0),
            _num(f.get("motor_speed_rpm"), "r/min", 0), _num(f.get("rtt_p99_us"), "us", 0), leds, state)


def status_lines(reply: dict[str, Any], events: list[dict[str, Any]] | None = None) -> list[str]:
    """A status reply as lines: a header (the network, elapsed time, timeline step, host stalls; a slave: its
    process), one line per station (LEDs: a name alone is lit, ``-`` unlit, ``*`` blinking), then *events*."""
    from ..aio.run.status import aligned

    if "elapsed_s" in reply:
        stalls = reply.get("stalls") or {}
        head = (f"{reply.get('network', '')}  {reply['elapsed_s']:.1f} s  step {reply.get('step') or '-'}  "
                f"stalls {stalls.get('count', 0)}" + (f" (max {stalls['max'] / 1e6:.1f} ms)" if stalls.get("count")
                                                      else ""))
    else:
        head = f"slave pid {reply.get('pid')}  {reply.get('wall_s', 0):.1f} s  CPU {reply.get('cpu_pct', 0):.0f} %"
    rows = [_HEADINGS, *(_row(f) for f in reply.get("stations") or [])]
    out = [head, *aligned(rows, 2, _RIGHT)]
    for ev in events or []:
        detail = {k: v for k, v in ev.items() if k not in ("seq", "at_s", "kind")}
        out.append(f"  {ev['at_s']:8.3f} s  {ev['kind']:<6} " + "  ".join(f"{k}={v}" for k, v in detail.items()))
    return out


def _slave_status(reply: dict[str, Any]) -> dict[str, Any]:
    """A slave's ``stats`` reply with its stations as figures (:func:`~mlink_sim.aio.run.figures.snapshot_figures`),
    in the shape of a network's status."""
    from ..aio.run.figures import snapshot_figures

    stations = reply.get("stations") if isinstance(reply.get("stations"), dict) else {}
    assert isinstance(stations, dict)
    return {"ok": True, "pid": reply.get("pid"), "wall_s": reply.get("wall_s"), "cpu_pct": reply.get("cpu_pct"),
            "stations": [snapshot_figures(s) for _, s in sorted(stations.items()) if isinstance(s, dict)]}


def _read_status(where: tuple[str, int], timeout: float, token: str | None, since: int,
                 slave: list[bool]) -> dict[str, Any] | None:
    """One reply: a network's ``status`` (events after *since*), or a slave's ``stats``; *slave* holds what the
    endpoint turned out to be (a slave answers ``status`` with an error naming its own operations)."""
    if not slave[0]:
        reply = ask(where, "status", timeout, token, since=since)
        if reply is None or reply.get("ok") or "'stats'" not in str(reply.get("error")):
            return reply
        slave[0] = True
    return ask(where, "stats", timeout, token)


@click.command("status")
@click.argument("address", metavar="HOST:PORT")
@click.option("--watch", "watch", is_flag=False, flag_value="1s", default=None, type=Seconds(3600.0),
              metavar="[INTERVAL]", help="Show it again every INTERVAL (default 1s) until Ctrl-C, with the events "
                                         "(phase changes, alarms, steps, checks, actions) as they come.")
@click.option("--json", "as_json", is_flag=True, help="Print the reply as JSON (with --watch: one line per reply).")
@click.option("--timeout", default="3s", show_default=True, type=Seconds(60.0),
              help="How long to wait for an answer (the request is sent up to three times).")
@control_token_options
def status_cmd(address: str, watch: float | None, as_json: bool, timeout: float, control_token: str | None,
               control_token_file: str | None) -> None:
    """Print the status of the network (up/master --control HOST:PORT) or standalone slave (slave --control
    HOST:PORT) at HOST:PORT: per station its phase, run state, reference and output Hz, current, DC bus, motor
    speed, RTT p99, the card's LEDs and its alarm; a network's elapsed time, timeline step and host stalls. The
    figures are those of the web API's /api/status (docs/control.md)."""
    from ..aio.run.status import LiveStatus

    where, token = _where(address), resolve_token(control_token, control_token_file)
    slave, since = [False], 0
    events: list[dict[str, Any]] = []
    live = LiveStatus() if watch is not None and not as_json else None
    if live is not None:
        live.start()
    try:
        while True:
            started = time.monotonic()
            reply = _read_status(where, timeout, token, since, slave)
            if reply is None:
                _no_answer("status", address, timeout)
            assert reply is not None
            if not reply.get("ok"):
                _refused("status", address, reply)
            since = reply.get("seq", since)
            shown = _slave_status(reply) if slave[0] else reply
            if as_json:  # the endpoint's reply as it came
                click.echo(json.dumps(reply, indent=None if watch is not None else 2))
            elif live is None:
                click.echo("\n".join(status_lines(shown)))
            else:
                events = (events + shown.get("events", []))[-8:]
                live.show(status_lines(shown, events), force=True)
            if watch is None:
                return
            time.sleep(max(0.0, watch - (time.monotonic() - started)))
    finally:
        if live is not None:
            live.stop()
