"""``mlink-sim param get|set`` and ``mlink-sim status``: the operations ``get-param``, ``set-param`` and ``status``
asked of a running network's control endpoint (``up``/``master --control``) or a standalone slave's (``slave
--control``), their replies printed for a person; docs/control.md. ``mlink-sim control HOST:PORT OP`` sends the same
operations and prints their JSON.

Exit 0 when answered, 1 when the endpoint does not answer or the station refuses (its phase, A.94/A.95, CMD_ALM), 2
for a usage error (a bad address, an unknown station or parameter, a value out of range, a station's data port).

Touches: one UDP socket per request (:func:`~mlink_sim.aio.control.endpoint.query_control`), stdout and stderr.
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable
from typing import Any

import click

from ..operations import alarm_text, card_text, event_text, leds_text, request_of, station_text
from .client import ask, endpoint, no_answer, refused, usage
from .control_token import control_token as resolve_token
from .control_token import control_token_options
from .inputs import InputError
from .params import Seconds

__all__ = ["param_cmd", "status_cmd", "status_lines"]


# -- param ----------------------------------------------------------------------------------------------------------


@click.group("param")
def param_cmd() -> None:
    """Read or write a drive parameter of a station by name (the operations get-param, set-param): through the
    master of a running network (up/master --control HOST:PORT: PRM_RD; PRM_WR, CONFIG and a read back), or in a
    standalone slave's own parameter store, as the drive's keypad would (slave --control HOST:PORT):

    \b
      mlink-sim param get 127.0.0.1:47000 21H C1-01
      C1-01 = 2.0 s (raw 20, register 0200H)
      mlink-sim param set 127.0.0.1:47000 21H C1-01=5.0 --eeprom

    Names, units and ranges are the card's (docs/parameters.md), checked as in a config."""


def _param_options(fn: Callable[..., Any]) -> Callable[..., Any]:
    fn = control_token_options(fn)
    return click.option("--timeout", default="5s", show_default=True, type=Seconds(60.0),
                        help="How long to wait for the answer (the request is sent up to three times).")(fn)


def _param(command: str, address: str, request: dict[str, Any], timeout: float, token: str | None) -> None:
    request = usage(request)
    reply = ask(endpoint(address), request, timeout, token, station=int(request_station(request)))
    if reply is None:
        no_answer(command, address, timeout)
    assert reply is not None
    if not reply.get("ok"):
        refused(command, address, reply)
    p = reply["param"]
    click.echo(f"{p['name']} = {p['text']} (raw {p['raw']}, register {p['register']})")


def request_station(request: dict[str, Any]) -> int:
    """The station a request names, as an address (the request was read by the table: it is one)."""
    from ..units import parse_address

    return parse_address(request["station"])


@param_cmd.command("get")
@click.argument("address", metavar="HOST:PORT")
@click.argument("station", metavar="ADDR")
@click.argument("name", metavar="NAME")
@_param_options
def param_get(address: str, station: str, name: str, timeout: float, control_token: str | None,
              control_token_file: str | None) -> None:
    """Read parameter NAME (e.g. C1-01, n019) of station ADDR (21H, 0x21) at HOST:PORT."""
    _param("param get", address, request_of("get-param", station=station, param=name), timeout,
           resolve_token(control_token, control_token_file))


@param_cmd.command("set")
@click.argument("address", metavar="HOST:PORT")
@click.argument("station", metavar="ADDR")
@click.argument("assignment", metavar="NAME=VALUE")
@click.option("--eeprom", is_flag=True, help="Save it too (CONFIG with CONFIG_MOD 1: kept across a power cycle, "
                                             "with the slave's --state-dir).")
@_param_options
def param_set(address: str, station: str, assignment: str, eeprom: bool, timeout: float,
              control_token: str | None, control_token_file: str | None) -> None:
    """Write NAME=VALUE (in the parameter's unit: C1-01=5.0) to station ADDR at HOST:PORT, enter it (CONFIG) and
    print the value read back."""
    name, sep, text = assignment.partition("=")
    if not sep or not name.strip() or not text.strip():
        raise InputError(f"NAME=VALUE: expected e.g. C1-01=5.0, got {assignment!r}")
    _param("param set", address, request_of("set-param", station=station, param=name.strip(), value=text.strip(),
                                            eeprom=eeprom), timeout, resolve_token(control_token, control_token_file))


# -- status ---------------------------------------------------------------------------------------------------------

_HEADINGS = ("ADDR", "CARD", "LINK", "PHASE", "RUN", "REF", "OUTPUT", "CURRENT", "DC BUS", "SPEED", "RTT p99",
             "LEDS", "STATE")
_RIGHT = {5, 6, 7, 8, 9, 10}


def _num(value: Any, unit: str, digits: int = 2) -> str:
    return "-" if value is None else f"{value:.{digits}f} {unit}"


def _row(f: dict[str, Any]) -> tuple[str, ...]:
    direction = {"forward": "FWD", "reverse": "REV"}.get(f.get("direction") or "", "stop")
    alarm = f.get("alarm")
    state = alarm_text(alarm) if alarm else "warn " + ", ".join(f["warnings"]) if f.get("warnings") else "ok"
    leds = leds_text(f.get("leds"))
    return (station_text(f.get("address")), card_text(f.get("card")), str(f.get("link") or ""),
            f"P{f['phase']}" if f.get("phase") else "offline", direction, _num(f.get("reference_hz"), "Hz"),
            _num(f.get("output_hz"), "Hz"), _num(f.get("output_current_a"), "A", 1), _num(f.get("dc_bus_v"), "V", 0),
            _num(f.get("motor_speed_rpm"), "r/min", 0), _num(f.get("rtt_p99_us"), "us", 0), leds, state)


def status_lines(reply: dict[str, Any], events: list[dict[str, Any]] | None = None) -> list[str]:
    """A status reply as lines: a header (the network, elapsed time, timeline step, host stalls; a slave: its
    process), one line per station (LEDs: a name alone is lit, ``-`` unlit, ``*`` blinking), then *events*."""
    from ..aio.present.status import aligned

    if "elapsed_s" in reply:
        stalls = reply.get("stalls") or {}
        head = (f"{reply.get('network', '')}  {reply['elapsed_s']:.1f} s  step {reply.get('step') or '-'}  "
                f"stalls {stalls.get('count', 0)}" + (f" (max {stalls['max'] / 1e6:.1f} ms)" if stalls.get("count")
                                                      else ""))
    else:
        head = f"slave pid {reply.get('pid')}  {reply.get('wall_s', 0):.1f} s  CPU {reply.get('cpu_pct', 0):.0f} %"
    rows = [_HEADINGS, *(_row(f) for f in reply.get("stations") or [])]
    out = [head, *aligned(rows, 2, _RIGHT)]
    out += ["  " + event_text(ev) for ev in events or []]
    return out


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
    from ..aio.present.status import LiveStatus

    where, token = endpoint(address), resolve_token(control_token, control_token_file)
    since = 0
    events: list[dict[str, Any]] = []
    live = LiveStatus() if watch is not None and not as_json else None
    if live is not None:
        live.start()
    try:
        while True:
            started = time.monotonic()
            reply = ask(where, request_of("status", since=since), timeout, token)
            if reply is None:
                no_answer("status", address, timeout)
            assert reply is not None
            if not reply.get("ok"):
                refused("status", address, reply)
            since = reply.get("seq", since)
            shown = reply
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
