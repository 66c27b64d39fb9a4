"""The command line's side of a control endpoint: one operation asked of HOST:PORT with retries
(:func:`ask`), what a silent address most likely is (:func:`silence`), and the exit status of an error reply.

Exit 0 when answered, 1 when the endpoint does not answer or refuses (the station's phase, A.94/A.95, CMD_ALM), 2 for a
request that was wrong (a bad address, an unknown station or parameter, a value out of range).

Touches: one UDP socket per request (:func:`~mlink_sim.aio.control.endpoint.query_control`); a probe's socket.
"""

from __future__ import annotations

import asyncio
import secrets
import sys
import time
from typing import Any

import click

from ..config import parse_endpoint
from ..operations import OpError, operation, parse_request
from .inputs import InputError

__all__ = ["ask", "endpoint", "refused", "silence", "usage", "USAGE_KINDS", "ATTEMPTS"]

ATTEMPTS = 3  #: a request is sent up to this often (UDP); a repeat carries the same id and does not act twice
FIRST_S = 0.4  #: how long the first attempt waits: a silent address is looked at (:func:`silence`) after it
PROBE_S = 0.4  #: how long that look waits for a station's answer
#: error kinds that mean the request itself was wrong (exit 2); the others (refused, unavailable) exit 1
USAGE_KINDS = ("bad_request", "unknown_station", "unknown_param", "out_of_range")


def endpoint(text: str) -> tuple[str, int]:
    try:
        return parse_endpoint(text)
    except ValueError as exc:
        raise InputError(f"HOST:PORT {text!r}: {exc}") from None


def usage(request: dict[str, Any]) -> dict[str, Any]:
    """*request* read by the table before it is sent (:func:`~mlink_sim.operations.parse_request`): a value of the
    wrong kind is a usage error here (exit 2), and nothing goes out."""
    try:
        parse_request(operation(request["op"]), request)
    except OpError as exc:
        raise InputError(str(exc)) from None
    return request


def ask(where: tuple[str, int], request: dict[str, Any], timeout: float, token: str | None, *,
        station: int | None = None) -> dict[str, Any] | None:
    """*request* (``op`` and its fields) asked of the endpoint at *where*, up to :data:`ATTEMPTS` times within
    *timeout* s (each with the same ``id``): its reply, or None when it did not answer. After a first attempt
    unanswered, what is at *where* is looked at (:func:`silence`): a station's data port ends the command with exit
    2 and how to find its control port."""
    from ..aio.control.endpoint import query_control

    fields = {k: v for k, v in request.items() if k != "op"}
    fields.setdefault("id", secrets.token_hex(8))
    end = time.monotonic() + timeout
    first = min(timeout / ATTEMPTS, FIRST_S)
    for attempt in range(ATTEMPTS):
        each = first if attempt == 0 else max(0.05, (end - time.monotonic()) / (ATTEMPTS - attempt))
        reply = asyncio.run(query_control(where[0], where[1], request["op"], timeout=each, token=token, **fields))
        if reply is not None:
            return reply
        if attempt == 0:
            found = silence(where, station, PROBE_S)
            if found:
                click.echo(f"mlink-sim: {where[0]}:{where[1]} {found}", err=True)
                sys.exit(2)
    return None


def silence(where: tuple[str, int], station: int | None, timeout: float) -> str | None:
    """What answers MECHATROLINK at *where* instead of control requests: ``"is the data port of station 21H …"``
    (a station answered a NOP: *station*, else every address a card can have), or None (nothing answers it)."""
    from ..aio.tools.probe import find_station

    try:
        frame = asyncio.run(find_station(where[0], where[1], station, timeout))
    except OSError:
        return None
    if frame is None:
        return None
    return (f"is the data port of station {frame.station:02X}H ({frame.link.label}, {frame.data_size}-byte), not a "
            "control endpoint: a slave's control endpoint is the one it printed at its start ('mlink-sim slave "
            "control: HOST:PORT'; \"control\" in its --ready-json line), or start it with --control 127.0.0.1:PORT; "
            "a network's is up/master --control")


def no_answer(command: str, address: str, timeout: float) -> None:
    click.echo(f"mlink-sim {command}: no answer from {address} within {timeout:g} s (is it running with --control? "
               "an endpoint with a token answers only requests that carry it: --control-token)", err=True)
    sys.exit(1)


def refused(command: str, address: str, reply: dict[str, Any]) -> None:
    kind = reply.get("kind", "refused")
    click.echo(f"mlink-sim {command}: {address}: {reply.get('error', 'refused, no reason given')}", err=True)
    sys.exit(2 if kind in USAGE_KINDS else 1)
