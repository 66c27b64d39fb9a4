"""The web server of a running network (``mlink-sim web``, ``mlink-sim up --web``): the page at ``/``, its files
under ``/static/``, and the HTTP API under ``/api/`` described by the OpenAPI 3.1 document ``openapi.yaml`` (served
as ``/api/openapi.json``). docs/web.md.

The server sees the network only through the run's control endpoint: ``GET /api/status`` and the event stream
through the one shared poller (:class:`~mlink_sim.web.feed.Feed`), every other route through one control operation
per request (:class:`~mlink_sim.web.api.Control`).

Safety (docs/web.md, "Who can reach the page"): with a token, every ``/api/`` request carries it
(``Authorization: Bearer TOKEN``); without one the server answers only requests addressed to a loopback name
(``Host: 127.0.0.1:…``, ``localhost``, ``[::1]``), so that a web page elsewhere cannot reach it through a name that
resolves to this host. A state-changing request is a POST or PUT whose body is JSON (``Content-Type:
application/json``): a form of another site cannot send one without the browser asking first, and the server grants
no other origin.

Touches: the listening TCP socket; the control endpoint (UDP) through :mod:`mlink_sim.web.api`.
"""

from __future__ import annotations

import asyncio
import functools
import hmac
import json
from collections.abc import Awaitable, Callable
from pathlib import Path
from typing import Any

from aiohttp import web

from .._log import get_logger
from ..aio.run.control import ASYNC_LIMIT_S
from ..aio.slave.token import is_loopback
from .api import ApiError, Control, param_name, station_arg
from .feed import Feed, Message

__all__ = ["build_app", "openapi_document", "start_server", "STATIC"]

log = get_logger("mlink_sim.web")

STATIC = Path(__file__).parent / "static"
_OPENAPI = Path(__file__).parent / "openapi.yaml"
#: an event stream's comment line when nothing else was sent for this long (keeps proxies from closing it)
_KEEPALIVE_S = 15.0
#: how long an operation through the master (PRM_RD / PRM_WR, CONFIG, ALM_CLR) may take to answer: beyond the
#: control endpoint's own limit for it, which answers ``unavailable`` first
_MASTER_TIMEOUT_S = ASYNC_LIMIT_S + 1.0

CONTROL = web.AppKey("control", Control)
FEED = web.AppKey("feed", Feed)
TOKEN = web.AppKey("token", str)

Handler = Callable[[web.Request], Awaitable[web.StreamResponse]]
_KIND_OF_STATUS = {400: "bad_request", 401: "unauthorized", 403: "forbidden", 404: "not_found",
                   405: "method_not_allowed", 413: "too_large", 415: "unsupported_media_type"}


@functools.cache
def openapi_document() -> dict[str, Any]:
    """The OpenAPI 3.1 document of the API (``openapi.yaml``, read once)."""
    import yaml

    document: dict[str, Any] = yaml.safe_load(_OPENAPI.read_text(encoding="utf-8"))
    return document


def _json(body: Any, status: int = 200, headers: dict[str, str] | None = None) -> web.Response:
    return web.json_response(body, status=status, headers=headers, dumps=functools.partial(json.dumps,
                                                                                          separators=(",", ":")))


@web.middleware
async def _errors(request: web.Request, handler: Handler) -> web.StreamResponse:
    """Every 4xx as ``{"error", "kind"}``, whoever raised it (a handler, aiohttp's router)."""
    try:
        return await handler(request)
    except ApiError as exc:
        headers = {"WWW-Authenticate": 'Bearer realm="mlink-sim"'} if exc.status == 401 else None
        return _json(exc.body(), exc.status, headers)
    except web.HTTPException as exc:
        if exc.status < 400:
            raise
        headers = {"Allow": exc.headers["Allow"]} if "Allow" in exc.headers else None
        kind = _KIND_OF_STATUS.get(exc.status, "bad_request")
        why = {404: f"no such page: {request.path}",
               405: f"{request.method} is not allowed on {request.path}"}.get(exc.status, exc.reason)
        return _json({"error": why, "kind": kind}, exc.status, headers)


def _local_host(host_header: str) -> bool:
    """Whether a ``Host`` header names a loopback address (``127.0.0.1:8080``, ``localhost``, ``[::1]:8080``)."""
    host = host_header.strip()
    if host.startswith("["):
        host = host[1:].partition("]")[0]
    elif host.count(":") == 1:
        host = host.partition(":")[0]
    return is_loopback(host)


@web.middleware
async def _guard(request: web.Request, handler: Handler) -> web.StreamResponse:
    """The token (``/api/``), the loopback name (no token), a JSON body on a state-changing request."""
    token = request.app.get(TOKEN)
    if token is None and not _local_host(request.host):
        raise ApiError(403, "forbidden", f"this server answers requests to 127.0.0.1 or localhost only, not to "
                                         f"{request.host!r} (start it with --web-token to serve other names)")
    if token is not None and request.path.startswith("/api/"):
        scheme, _, given = request.headers.get("Authorization", "").partition(" ")
        if scheme.lower() != "bearer" or not hmac.compare_digest(given.strip().encode(), token.encode()):
            raise ApiError(401, "unauthorized", "this server needs its token: send 'Authorization: Bearer TOKEN' "
                                                "(docs/web.md)")
    if request.method in ("POST", "PUT") and request.content_type != "application/json":
        raise ApiError(415, "unsupported_media_type", f"{request.method} takes a JSON body (Content-Type: "
                                                      f"application/json), got {request.content_type!r}")
    return await handler(request)


async def _body(request: web.Request, allowed: tuple[str, ...] | None = ()) -> dict[str, Any]:
    """The request's JSON object (an empty body: ``{}``); *allowed*: the fields it may have (None: any but the
    control request's own ``op``, ``station`` and ``token``)."""
    raw = await request.read()
    if not raw.strip():
        return {}
    try:
        body = json.loads(raw)
    except (ValueError, UnicodeDecodeError) as exc:
        raise ApiError(400, "bad_request", f"the body is not JSON: {exc}") from None
    if not isinstance(body, dict):
        raise ApiError(400, "bad_request", f"the body is a JSON object, got {type(body).__name__}")
    reserved = ("op", "station", "token", "id")
    unknown = sorted(k for k in body if (k in reserved if allowed is None else k not in allowed))
    if unknown:
        expected = "none" if allowed == () else ", ".join(allowed) if allowed else "not " + ", ".join(reserved)
        raise ApiError(400, "bad_request", f"unknown field(s) {', '.join(unknown)} (expected: {expected})")
    return body


def _station(request: web.Request, *, all_ok: bool = False) -> str:
    return station_arg(request.match_info["address"], all_ok=all_ok)


async def _index(request: web.Request) -> web.StreamResponse:
    return web.FileResponse(STATIC / "index.html", headers={"Cache-Control": "no-cache"})


async def _openapi(request: web.Request) -> web.StreamResponse:
    return _json(openapi_document())


async def _network(request: web.Request) -> web.StreamResponse:
    return _json(await request.app[CONTROL].ask("network"))


async def _status(request: web.Request) -> web.StreamResponse:
    feed = request.app[FEED]
    status = await feed.status()
    if status is None:
        error = feed.error or {"error": "the network's control endpoint did not answer", "kind": "no_answer"}
        raise ApiError(503 if error["kind"] == "no_answer" else 409, error["kind"], error["error"])
    return _json(status)


async def _report(request: web.Request) -> web.StreamResponse:
    reply = await request.app[CONTROL].ask("report", timeout=5.0)
    report = reply.get("report")
    return _json(report if isinstance(report, dict) else reply)


async def _run(request: web.Request) -> web.StreamResponse:
    station = _station(request)
    body = await _body(request, ("direction", "speed_hz"))
    if body.get("direction", "forward") not in ("forward", "reverse"):
        raise ApiError(400, "bad_request", f"direction: 'forward' or 'reverse', got {body['direction']!r}")
    speed = body.get("speed_hz")
    if speed is not None and (isinstance(speed, bool) or not isinstance(speed, int | float)):
        raise ApiError(400, "bad_request", f"speed_hz: a number of Hz, got {speed!r}")
    return _json(await request.app[CONTROL].ask("run", station=station, **body))


def _simple(op: str) -> Handler:
    async def handler(request: web.Request) -> web.StreamResponse:
        station = _station(request)
        await _body(request)
        timeout = _MASTER_TIMEOUT_S if op == "alarm-clear" else 2.0
        return _json(await request.app[CONTROL].ask(op, timeout=timeout, station=station))

    handler.__name__ = f"_{op.replace('-', '_')}"
    return handler


async def _param_get(request: web.Request) -> web.StreamResponse:
    station, name = _station(request), param_name(request.match_info["name"])
    return _json(await request.app[CONTROL].ask("param", timeout=_MASTER_TIMEOUT_S, station=station, name=name))


async def _param_put(request: web.Request) -> web.StreamResponse:
    station, name = _station(request), param_name(request.match_info["name"])
    body = await _body(request, ("value", "eeprom"))
    value = body.get("value")
    if value is None or isinstance(value, bool) or not isinstance(value, int | float | str):
        raise ApiError(400, "bad_request", f"value: the parameter's value in its unit (a number), got {value!r}")
    eeprom = body.get("eeprom", False)
    if not isinstance(eeprom, bool):
        raise ApiError(400, "bad_request", f"eeprom: true or false, got {eeprom!r}")
    fields: dict[str, Any] = {"station": station, "name": name, "value": value}
    if eeprom:
        fields["eeprom"] = True
    return _json(await request.app[CONTROL].ask("param", timeout=_MASTER_TIMEOUT_S, **fields))


def _spec(op: str) -> Handler:
    """``fault`` / ``impair``: the timeline's spec, as text (``{"fault": "silence,for=200ms"}``) or as its fields
    (``{"do": "silence", "for": "200ms"}``); ``heal``: an empty object."""

    async def handler(request: web.Request) -> web.StreamResponse:
        station = _station(request, all_ok=True)
        body = await _body(request, () if op == "heal" else None)
        if op != "heal" and not body:
            example = '{"fault": "silence,for=200ms"}' if op == "fault" else '{"impair": "loss=10%,for=2s"}'
            raise ApiError(400, "bad_request", f"{op}: give the spec, e.g. {example}")
        return _json(await request.app[CONTROL].ask(op, station=station, **body))

    handler.__name__ = f"_{op}"
    return handler


def _sse(name: str, data: Any) -> bytes:
    seq = data.get("seq") if name == "event" and isinstance(data, dict) else None
    head = f"id: {seq}\n" if isinstance(seq, int) else ""
    return f"{head}event: {name}\ndata: {json.dumps(data, separators=(',', ':'))}\n\n".encode()


async def _events(request: web.Request) -> web.StreamResponse:
    feed = request.app[FEED]
    response = web.StreamResponse(headers={"Content-Type": "text/event-stream", "Cache-Control": "no-cache",
                                           "X-Accel-Buffering": "no"})
    await response.prepare(request)
    queue = feed.subscribe()
    try:
        await response.write(b"retry: 1000\n\n")
        while True:
            message: Message
            try:
                message = await asyncio.wait_for(queue.get(), _KEEPALIVE_S)
            except TimeoutError:
                await response.write(b": keep-alive\n\n")
                continue
            if message[0] == "end":
                break
            await response.write(_sse(*message))
    except (ConnectionResetError, ConnectionError):
        pass  # the client went away
    finally:
        feed.unsubscribe(queue)
    return response


def build_app(control: Control, token: str | None = None, *, interval: float = 0.1) -> web.Application:
    """The application: routes of docs/web.md over *control*; with *token*, every ``/api/`` request must carry
    it. *interval*: the status poller's period (at most 10 Hz: 0.1 s)."""
    app = web.Application(middlewares=[_errors, _guard], client_max_size=64 * 1024)
    app[CONTROL] = control
    app[FEED] = Feed(control.query, interval=interval)
    if token is not None:
        app[TOKEN] = token
    add = app.router.add_route
    add("GET", "/", _index)
    add("GET", "/api/openapi.json", _openapi)
    add("GET", "/api/network", _network)
    add("GET", "/api/status", _status)
    add("GET", "/api/report", _report)
    add("GET", "/api/events", _events)
    add("POST", "/api/stations/{address}/run", _run)
    for op in ("stop", "alarm-clear"):
        add("POST", f"/api/stations/{{address}}/{op}", _simple(op))
    for op in ("fault", "impair", "heal"):
        add("POST", f"/api/stations/{{address}}/{op}", _spec(op))
    add("GET", "/api/stations/{address}/params/{name}", _param_get)
    add("PUT", "/api/stations/{address}/params/{name}", _param_put)
    app.router.add_static("/static/", STATIC, append_version=False)

    async def on_shutdown(app: web.Application) -> None:
        app[FEED].close()

    app.on_shutdown.append(on_shutdown)
    return app


async def start_server(app: web.Application, host: str, port: int) -> tuple[web.AppRunner, tuple[str, int]]:
    """Serve *app* on *host*:*port* (0: any free port); the runner (``await runner.cleanup()`` stops it) and
    where it listens. OSError: the address cannot be bound."""
    runner = web.AppRunner(app, access_log=None, handle_signals=False)
    await runner.setup()
    site = web.TCPSite(runner, host, port, shutdown_timeout=1.0)
    try:
        await site.start()
    except BaseException:
        await runner.cleanup()
        raise
    bound = runner.addresses[0]
    return runner, (str(bound[0]), int(bound[1]))
