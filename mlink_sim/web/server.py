"""The web server of a running network (``mlink-sim web``, ``mlink-sim up --web``): the page at ``/``, its files
under ``/static/``, and the HTTP API under ``/api/`` described by the OpenAPI 3.1 document ``openapi.yaml`` (served
as ``/api/openapi.json``). docs/web.md.

The page draws in the vocabulary of :mod:`mlink_sim.plots` (served as ``/plots.json``), the HTML report's. The server
sees the network only through the run's control endpoint: ``GET /api/status`` and the event stream (which begins
with the last minute of status answers, ``history``) through the one shared poller (:class:`~mlink_sim.web.feed.Feed`), every other route through one control operation
per request (:class:`~mlink_sim.web.api.Control`). The operations' routes are built from the operations table (each
operation with an HTTP route: its path's arguments from the path, the others from the query or the JSON body, read
by the table before anything is sent), as is their OpenAPI document (:mod:`.openapi`).

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
from ..aio.control.endpoint import ASYNC_LIMIT_S
from ..plots import vocabulary
from ..aio.control.token import is_loopback
from ..operations import OpError, Operation, parse_request, served_by
from .api import ApiError, Control
from .feed import Feed, Message
from .openapi import STATUS_OF_KIND, openapi_document, path_args

__all__ = ["build_app", "openapi_document", "start_server", "STATIC"]

log = get_logger("mlink_sim.web")

STATIC = Path(__file__).parent / "static"
#: an event stream's comment line when nothing else was sent for this long (keeps proxies from closing it)
_KEEPALIVE_S = 15.0
#: the status poller's period while no page is open (the minute a page opened later begins with)
BACKGROUND_S = 0.5
#: how long an operation through the master (PRM_RD / PRM_WR, CONFIG, ALM_CLR) may take to answer: beyond the
#: control endpoint's own limit for it, which answers ``unavailable`` first
_MASTER_TIMEOUT_S = ASYNC_LIMIT_S + 1.0

CONTROL = web.AppKey("control", Control)
FEED = web.AppKey("feed", Feed)
TOKEN = web.AppKey("token", str)

Handler = Callable[[web.Request], Awaitable[web.StreamResponse]]
_KIND_OF_STATUS = {400: "bad_request", 401: "unauthorized", 403: "forbidden", 404: "not_found",
                   405: "method_not_allowed", 413: "too_large", 415: "unsupported_media_type"}


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


async def _body(request: web.Request) -> dict[str, Any]:
    """The request's JSON object (an empty body: ``{}``)."""
    raw = await request.read()
    if not raw.strip():
        return {}
    try:
        body = json.loads(raw)
    except (ValueError, UnicodeDecodeError) as exc:
        raise ApiError(400, "bad_request", f"the body is not JSON: {exc}") from None
    if not isinstance(body, dict):
        raise ApiError(400, "bad_request", f"the body is a JSON object, got {type(body).__name__}")
    return body


async def _index(request: web.Request) -> web.StreamResponse:
    return web.FileResponse(STATIC / "index.html", headers={"Cache-Control": "no-cache"})


async def _plots(request: web.Request) -> web.StreamResponse:
    """The plotting vocabulary the page draws with (mlink_sim.plots: the HTML report's too)."""
    return _json(vocabulary(), headers={"Cache-Control": "no-cache"})


async def _openapi(request: web.Request) -> web.StreamResponse:
    return _json(openapi_document())


async def _status(request: web.Request) -> web.StreamResponse:
    feed = request.app[FEED]
    status = await feed.status()
    if status is None:
        error = feed.error or {"error": "the network's control endpoint did not answer", "kind": "no_answer"}
        raise ApiError(503 if error["kind"] == "no_answer" else 409, error["kind"], error["error"])
    return _json(status)


def _route(op: Operation) -> Handler:
    """The handler of *op*'s route: its arguments from the path, the query (GET) or the JSON body, read by the table
    (a 400 before anything is sent), then the operation asked of the network's control endpoint."""
    assert op.http is not None
    method = op.http[0]
    in_path = path_args(op)
    timeout = _MASTER_TIMEOUT_S if op.through_master or op.name in ("report", "fault") else 2.0

    async def handler(request: web.Request) -> web.StreamResponse:
        fields: dict[str, Any] = dict(request.query) if method == "GET" else await _body(request)
        clash = sorted(set(fields) & set(in_path) | set(fields) & {"op", "token", "id"})
        if clash:
            raise ApiError(400, "bad_request", f"{op.name}: {', '.join(clash)} is given by the path or the "
                                               "endpoint, not in the request")
        fields.update({name: request.match_info[name] for name in in_path})
        try:
            parse_request(op, fields)
        except OpError as exc:
            raise ApiError(STATUS_OF_KIND[exc.kind], exc.kind, str(exc)) from None
        reply = await request.app[CONTROL].ask(op.name, timeout=timeout, **fields)
        if op.name == "report" and isinstance(reply.get("report"), dict):
            return _json(reply["report"])
        return _json(reply)

    handler.__name__ = "_" + op.python
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


def build_app(control: Control, token: str | None = None, *, interval: float = 0.1,
              background: float | None = BACKGROUND_S) -> web.Application:
    """The application: routes of docs/web.md over *control*; with *token*, every ``/api/`` request must carry
    it. *interval*: the status poller's period while someone looks (at most 10 Hz: 0.1 s); *background*: while
    nobody does (None: not at all), so that a page opened later has the last minute."""
    app = web.Application(middlewares=[_errors, _guard], client_max_size=64 * 1024)
    app[CONTROL] = control
    app[FEED] = Feed(control.query, interval=interval, background=background)
    if token is not None:
        app[TOKEN] = token
    add = app.router.add_route
    add("GET", "/", _index)
    add("GET", "/plots.json", _plots)
    add("GET", "/api/openapi.json", _openapi)
    add("GET", "/api/events", _events)
    for op in served_by("network"):
        if op.http is not None:
            add(op.http[0], op.http[1], _status if op.name == "status" else _route(op))
    app.router.add_static("/static/", STATIC, append_version=False)

    async def on_startup(app: web.Application) -> None:
        app[FEED].start()

    async def on_shutdown(app: web.Application) -> None:
        app[FEED].close()

    app.on_startup.append(on_startup)
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
