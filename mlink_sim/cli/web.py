"""``mlink-sim web`` (the page and the HTTP API of a network running with ``--control``) and the ``--web``
options of ``up`` / ``master``; docs/web.md."""

from __future__ import annotations

import asyncio
import json
import signal
import sys
from collections.abc import Callable
from typing import Any

import click

from ..aio.control.token import is_loopback
from ..aio.transport.udp import new_event_loop, stop_on_signals
from ..config import parse_endpoint
from .control_token import control_token as resolve_token
from .inputs import InputError
from .logs import configure_logging

__all__ = ["web_cmd", "web_options", "web_choice", "required_token", "parse_listen", "DEFAULT_LISTEN"]

DEFAULT_LISTEN = "127.0.0.1:8080"


def parse_listen(text: str, flag: str) -> tuple[str, int]:
    """``[HOST:]PORT`` (the host 127.0.0.1 unless given; port 0: any free port) -> (host, port); a usage error
    otherwise."""
    text = text.strip()
    try:
        if text.isdigit():
            port = int(text)
            if port > 65535:
                raise ValueError(f"port {port} is out of range 0…65535")
            return "127.0.0.1", port
        return parse_endpoint(text)
    except ValueError as exc:
        raise InputError(f"{flag} {text!r}: {exc} (or a PORT alone, on 127.0.0.1)") from None


def web_options(fn: Callable[..., Any]) -> Callable[..., Any]:
    """``--web [HOST:]PORT``, ``--web-token``, ``--web-token-file`` (parameters ``web``, ``web_token``,
    ``web_token_file``) of ``up`` / ``master``."""
    fn = click.option("--web-token-file", "web_token_file", metavar="FILE", type=click.Path(dir_okay=False),
                      help="Read the web token from FILE (its first line).")(fn)
    fn = click.option("--web-token", "web_token", metavar="TOKEN",
                      help="The token every API request carries (Authorization: Bearer TOKEN); required to bind "
                           "--web to an address other than loopback.")(fn)
    fn = click.option("--web", "web", metavar="[HOST:]PORT",
                      help="Serve the live page and the HTTP API here (host 127.0.0.1 unless given; port 0: any "
                           "free port); the address is printed on stderr (docs/web.md).")(fn)
    return fn


def web_choice(web: str | None, token: str | None,
               token_file: str | None) -> tuple[tuple[str, int] | None, str | None]:
    """``--web``, ``--web-token``, ``--web-token-file`` of ``up`` / ``master``: where the web server listens (None:
    no server) and its token; usage errors for a token without a server and for an address other than loopback
    without a token."""
    listen = None if web is None else parse_listen(web, "--web")
    value = resolve_token(token, token_file, "--web-token")
    if listen is None and value is not None:
        raise InputError("--web-token is the token of the page's server: give --web [HOST:]PORT too")
    return listen, required_token(listen, value, "--web")


def required_token(listen: tuple[str, int] | None, token: str | None, flag: str) -> str | None:
    """*token*; a usage error when there is none and the server listens on an address other than loopback."""
    if listen is not None and token is None and not is_loopback(listen[0]):
        raise InputError(f"{flag} {listen[0]}:{listen[1]} is reachable from other hosts: give --web-token or "
                         "--web-token-file (or bind 127.0.0.1)")
    return token


def _url(host: str, port: int) -> str:
    return f"http://[{host}]:{port}/" if ":" in host else f"http://{host}:{port}/"


@click.command("web")
@click.option("--control", "control", required=True, metavar="HOST:PORT",
              help="The control endpoint of the network (mlink-sim up/master --control HOST:PORT).")
@click.option("--listen", default=DEFAULT_LISTEN, show_default=True, metavar="HOST:PORT",
              help="Where the page and the API are served (a PORT alone: on 127.0.0.1; port 0: any free port).")
@click.option("--control-token", "control_token", metavar="TOKEN",
              help="The control endpoint's token (the network's --control-token), if it has one.")
@click.option("--control-token-file", "control_token_file", metavar="FILE", type=click.Path(dir_okay=False),
              help="Read the control endpoint's token from FILE (its first line).")
@click.option("--web-token", "web_token", metavar="TOKEN",
              help="The token every API request carries (Authorization: Bearer TOKEN; the page: "
                   "http://HOST:PORT/#token=TOKEN); required to --listen on an address other than loopback.")
@click.option("--web-token-file", "web_token_file", metavar="FILE", type=click.Path(dir_okay=False),
              help="Read the web token from FILE (its first line; keeps it off the command line).")
@click.option("--ready-json", is_flag=True, hidden=True,
              help="Print one JSON line on stdout once listening (up --web reads it).")
@click.option("--tokens-stdin", is_flag=True, hidden=True,
              help="Read both tokens from one JSON line on stdin (up --web: no token on a command line).")
@click.option("--log-json", is_flag=True, help="Log JSON lines on stderr.")
@click.option("--log-level", default="warning", show_default=True,
              type=click.Choice(["debug", "info", "warning", "error"]))
def web_cmd(control, listen, control_token, control_token_file, web_token, web_token_file, ready_json, tokens_stdin,
            log_json, log_level) -> None:
    """Serve the live page and the HTTP API of a network running with --control (in a container, on another
    machine) until SIGINT/SIGTERM; docs/web.md.

    The server reads the network only through its control endpoint: one status query at most ten times a second,
    whatever the number of pages open."""
    configure_logging(json=log_json, level=log_level)
    try:
        where = parse_endpoint(control)
    except ValueError as exc:
        raise click.BadParameter(str(exc), param_hint="--control") from None
    listen_at = parse_listen(listen, "--listen")
    if tokens_stdin:
        try:
            given = json.loads(sys.stdin.readline() or "{}")
        except ValueError:
            raise InputError("--tokens-stdin: expected one JSON line") from None
        ctoken, wtoken = given.get("control_token"), given.get("web_token")
    else:
        ctoken = resolve_token(control_token, control_token_file)
        wtoken = resolve_token(web_token, web_token_file, "--web-token")
    required_token(listen_at, wtoken, "--listen")
    loop = new_event_loop()
    try:
        code = loop.run_until_complete(_serve(where, listen_at, ctoken, wtoken, ready_json))
    finally:
        loop.close()
    sys.exit(code)


async def _serve(control: tuple[str, int], listen: tuple[str, int], control_token: str | None,
                 web_token: str | None, ready_json: bool) -> int:
    from ..web import Control, build_app, start_server

    loop = asyncio.get_running_loop()
    stop, caught = stop_on_signals(loop)
    endpoint = Control(*control, token=control_token)
    try:
        runner, (host, port) = await start_server(build_app(endpoint, web_token), *listen)
    except OSError as exc:
        click.echo(f"mlink-sim web: cannot listen on {listen[0]}:{listen[1]}: {exc.strerror or exc}", err=True)
        return 2
    try:
        if ready_json:
            print(json.dumps({"event": "ready", "url": _url(host, port), "host": host, "port": port}), flush=True)
        else:
            click.echo(f"web: {_url(host, port)}", err=True)
            if await endpoint.query("ping") is None:
                click.echo(f"mlink-sim web: warning: the control endpoint {endpoint.where} does not answer (yet): "
                           "is the network running with --control, with this --control-token?", err=True)
        await stop.wait()
    finally:
        await runner.cleanup()
        for sig in (signal.SIGINT, signal.SIGTERM):
            loop.remove_signal_handler(sig)
    return 128 + caught[0] if caught else 0
