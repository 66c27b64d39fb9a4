"""``mlink-sim proxy``: an impairing UDP proxy between any master and any slaves, steered through its control
endpoint (the operations ``impair``, ``heal``, ``faults``: ``mlink-sim control HOST:PORT impair …``); docs/faults.md."""

from __future__ import annotations

import asyncio
import json
import signal
import sys
from typing import Any

import click

from ..aio.transport.udp import new_event_loop, stop_on_signals
from ..config import parse_endpoint
from .capture_opts import capture_options, open_capture_or_exit
from .control_token import control_token_options, endpoint_token
from .logs import configure_logging

__all__ = ["proxy_cmd", "parse_control"]


def _endpoint(text: str, flag: str) -> tuple[str, int]:
    try:
        return parse_endpoint(text)
    except ValueError as exc:
        raise click.BadParameter(str(exc), param_hint=flag) from None


def parse_control(text: str | None) -> tuple[str, int] | None:
    """``--control HOST:PORT`` (``off``/None: no control endpoint)."""
    if text is None or text == "off":
        return None
    return _endpoint(text, "--control")


def _impairment(text: str | None) -> Any:
    if text is None:
        return None
    from ..impair import ImpairError, parse_impair_text

    try:
        return parse_impair_text(text)
    except ImpairError as exc:
        raise click.BadParameter(str(exc), param_hint="--impair") from None


@click.command("proxy")
@click.option("--listen", "listens", multiple=True, required=True, metavar="HOST:PORT",
              help="Where the master sends (0 = any free port); repeatable, one per --to.")
@click.option("--to", "targets", multiple=True, required=True, metavar="HOST:PORT",
              help="The slave the datagrams go to; repeatable, paired with --listen in order.")
@click.option("--impair", "impair_text", metavar="SPEC",
              help="Impair every station from the start, e.g. 'loss=5%,delay=200us,jitter=50us' (docs/faults.md).")
@click.option("--seed", type=int, default=0, show_default=True, help="Seed of every random draw.")
@click.option("--control", default="127.0.0.1:0", show_default=True, metavar="HOST:PORT",
              help="The control endpoint (impair/heal while it runs: 'mlink-sim control'; 'off').")
@control_token_options
@click.option("--log-json", is_flag=True, help="Log JSON lines on stderr.")
@click.option("--log-level", default="warning", show_default=True,
              type=click.Choice(["debug", "info", "warning", "error"]))
@capture_options
def proxy_cmd(listens, targets, impair_text, seed, control, control_token, control_token_file, log_json, log_level,
              capture_path, capture_max) -> None:
    """Forward datagrams between any master and any slaves through the impairment layer, until SIGINT/SIGTERM.

    The master sends to --listen; each datagram goes to the paired --to, and the answers come back to the master.
    Impairments apply per station (the envelope's station byte) and can change while it runs:
    mlink-sim control HOST:PORT impair 0x21 'loss=10%,for=2s'."""
    configure_logging(json=log_json, level=log_level)
    if len(listens) != len(targets):
        raise click.UsageError(f"give one --to per --listen (got {len(listens)} --listen, {len(targets)} --to)")
    links = [(_endpoint(a, "--listen"), _endpoint(b, "--to")) for a, b in zip(listens, targets)]
    spec = _impairment(impair_text)
    control_addr = parse_control(control)
    token = endpoint_token(control_addr, control_token, control_token_file)
    capture = open_capture_or_exit("proxy", capture_path, capture_max)
    loop = new_event_loop()
    try:
        code = loop.run_until_complete(_serve(links, spec, seed, control_addr, capture, token))
    except OSError as exc:
        click.echo(f"mlink-sim proxy: cannot listen or resolve: {exc.strerror or exc}", err=True)
        code = 2
    finally:
        loop.close()
        if capture is not None:
            click.echo(capture.close().summary(), err=True)
    sys.exit(code)


async def _serve(links: list[Any], spec: Any, seed: int, control_addr: tuple[str, int] | None,
                 capture: Any, token: str | None = None) -> int:
    from ..aio.control.endpoint import ControlServer
    from ..aio.control.faults import ImpairmentOps
    from ..aio.tools.proxy import ImpairingProxy
    from ..impair import ImpairmentLayer
    from ..metrics.network import station_key

    loop = asyncio.get_running_loop()
    stop, caught = stop_on_signals(loop)
    proxy = ImpairingProxy(links, ImpairmentLayer(seed=seed), capture=capture)
    server = ControlServer(ImpairmentOps(proxy).handlers(), "proxy", token=token)
    try:
        await proxy.start()
        named = proxy.impair(None, spec) if spec is not None else None
        where = None if control_addr is None else await server.start(*control_addr)
        for link in proxy.links:
            print(f"mlink-sim proxy: {link.listen[0]}:{link.listen[1]} -> {link.to[0]}:{link.to[1]}", flush=True)
        print(f"mlink-sim proxy ready: seed {seed}; impair: {f'{named} ({spec.describe()})' if spec else 'none'}; "
              "control: "
              + (f"{where[0]}:{where[1]}" if where else "off"), flush=True)
        await stop.wait()
    finally:
        server.close()
        proxy.close()
        for sig in (signal.SIGINT, signal.SIGTERM):
            loop.remove_signal_handler(sig)
    totals = proxy.totals()
    injected = {station_key(a): c for a, c in proxy.impairments.injected().items()}
    print(f"mlink-sim proxy: stopped by {signal.Signals(caught[0]).name}: {totals['to_station']} datagram(s) to the "
          f"stations, {totals['to_master']} to the master; injected {json.dumps(injected)}", flush=True)
    return 128 + caught[0]
