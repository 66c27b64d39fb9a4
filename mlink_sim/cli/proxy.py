"""``mlink-sim proxy`` (an impairing UDP proxy) and ``mlink-sim control`` (requests to a running ``up``/``master``,
proxy or slave); docs/faults.md."""

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
from .control_token import control_token as resolve_token
from .control_token import control_token_options, endpoint_token
from .logs import configure_logging
from .params import Seconds

__all__ = ["proxy_cmd", "control_cmd", "parse_control", "CONTROL_OPS"]

_ATTEMPTS = 3


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
    from ..aio.run.control import ControlServer, impairment_ops
    from ..aio.tools.proxy import ImpairingProxy
    from ..impair import ImpairmentLayer
    from ..metrics.network import station_key

    loop = asyncio.get_running_loop()
    stop, caught = stop_on_signals(loop)
    proxy = ImpairingProxy(links, ImpairmentLayer(seed=seed), capture=capture)
    server = ControlServer(impairment_ops(proxy), token=token)
    try:
        await proxy.start()
        if spec is not None:
            proxy.impair(None, spec)
        where = None if control_addr is None else await server.start(*control_addr)
        for link in proxy.links:
            print(f"mlink-sim proxy: {link.listen[0]}:{link.listen[1]} -> {link.to[0]}:{link.to[1]}", flush=True)
        print(f"mlink-sim proxy ready: seed {seed}; impair: {spec.describe() if spec else 'none'}; control: "
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


#: What each control endpoint answers (aio/run/control.py, aio/run/faults.py, aio/slave/server.py): the
#: operations ``control`` offers, by the command whose endpoint answers them.
CONTROL_OPS = {
    "impair": "up/master --control, proxy", "heal": "up/master --control, proxy",
    "faults": "up/master --control, proxy", "fault": "up/master --control", "recovery": "up/master --control",
    "network": "up/master --control", "status": "up/master --control", "report": "up/master --control",
    "stop": "up/master --control", "alarm-clear": "up/master --control",
    "stats": "slave", "cpu": "slave", "plant": "slave", "release": "slave", "ping": "all",
}


@click.command("control", short_help="Send a request to a running network, proxy or slave (impair, fault, stats …).")
@click.argument("address", metavar="HOST:PORT")
@click.argument("op", metavar="OP", type=click.Choice(list(CONTROL_OPS)))
@click.argument("station", metavar="[ADDR|all]", required=False)
@click.argument("spec", metavar="[SPEC|HANDLE]", required=False)
@click.option("--timeout", default="3s", show_default=True, type=Seconds(60.0),
              help="How long to wait for the answer (the request is sent up to three times).")
@control_token_options
def control_cmd(address: str, op: str, station: str | None, spec: str | None, timeout: float,
                control_token: str | None, control_token_file: str | None) -> None:
    """Send the request OP to the control endpoint at HOST:PORT and print the answer (JSON). Each endpoint
    answers its own operations:

    \b
    a network, mlink-sim up/master --control HOST:PORT (docs/faults.md):
      impair ADDR|all SPEC   impair a station's datagrams, e.g. impair 21H 'loss=10%,delay=200us,for=2s'
      heal [ADDR|all]        end the impairments
      faults                 the impairments in force and what they injected
      fault ADDR|all SPEC    a station, master or drive fault, e.g. fault 21H 'silence,for=200ms'
      recovery [ADDR|all]    each station's latest fault episode and its recovery time
      network                the stations and the timeline
      status                 every station's figures and the latest events (mlink-sim status prints them)
      report                 the report as --report would write it now
      stop ADDR              take the run command away
      alarm-clear ADDR       ALM_CLR: clear the station's alarms and faults
    (parameters: mlink-sim param get|set; docs/control.md)
    \b
    an impairing proxy, mlink-sim proxy --control HOST:PORT: impair, heal, faults (as above)
    \b
    a slave, mlink-sim slave --control HOST:PORT (printed on its start):
      stats                  every station's snapshot, counters, the process's CPU time and host stalls
      cpu                    the process's CPU time only
      plant ADDR SPEC        a drive fault on the station's model, e.g. plant 21H 'load,torque=5'; the answer
                             carries a HANDLE
      release ADDR HANDLE    end the drive fault HANDLE
    \b
    any of them: ping (is it there?)

    Exit 0 if it was done, 1 if refused or unanswered, 2 for a bad request."""
    import secrets

    from ..aio.run.control import query_control
    from ..aio.run.faults import parse_fault_text
    from ..config import parse_address
    from ..faults import FaultError, fault_from_fields
    from ..faults.spec import PLANT_FAULTS
    from ..impair import ImpairError, parse_impair_text, target_station

    host, port = _endpoint(address, "HOST:PORT")
    token = resolve_token(control_token, control_token_file)
    fields: dict[str, Any] = {}
    try:
        if op in ("impair", "heal", "fault", "recovery") and station is not None:
            target_station(station)
            fields["station"] = station
        if op in ("stop", "alarm-clear"):
            if station is None:
                raise click.UsageError(f"{op} needs ADDR, e.g. {op} 21H")
            parse_address(station)
            fields["station"] = station
            fields["id"] = secrets.token_hex(8)  # a repeated request acts once
        if op in ("plant", "release"):
            if station is None or spec is None:
                what = "SPEC, e.g. plant 21H 'load,torque=5'" if op == "plant" else "HANDLE, e.g. release 21H 1"
                raise click.UsageError(f"{op} needs ADDR and {what}")
            fields["station"] = parse_address(station)  # a slave takes the address as a number
        if op == "plant":
            assert spec is not None
            action, values = parse_fault_text(spec)
            fault = fault_from_fields(action, values)
            if fault.action not in PLANT_FAULTS:
                raise click.UsageError(f"plant takes a drive fault ({', '.join(PLANT_FAULTS)}), got {fault.action!r}")
            fields["fault"] = fault.as_fields()
        elif op == "release":
            assert spec is not None
            if not spec.isdigit():
                raise click.UsageError(f"release: HANDLE is the number plant answered, got {spec!r}")
            fields["handle"] = int(spec)
        elif op == "fault":
            if spec is None:
                raise click.UsageError("fault needs ADDR and SPEC, e.g. fault 21H 'silence,for=200ms'")
            action, values = parse_fault_text(spec)
            fault_from_fields(action, values)
            fields["fault"] = spec
            fields["id"] = secrets.token_hex(8)  # a repeated request is not injected twice
        elif op == "impair":
            if spec is None:
                raise click.UsageError("impair needs ADDR and SPEC, e.g. impair 21H 'loss=10%,for=2s'")
            parse_impair_text(spec)
            fields["impair"] = spec
        elif op not in ("plant", "release") and spec is not None:
            raise click.UsageError(f"{op} takes no SPEC")
        if op in ("faults", "stats", "cpu", "ping", "network", "status", "report") and station is not None:
            raise click.UsageError(f"{op} takes no station")
    except (ImpairError, FaultError, ValueError) as exc:
        raise click.UsageError(str(exc)) from None
    reply = None
    for _ in range(_ATTEMPTS):  # UDP: a request can go unanswered; each operation can be repeated safely
        reply = asyncio.run(query_control(host, port, op, timeout=timeout / _ATTEMPTS, token=token,
                                           **fields))
        if reply is not None:
            break
    if reply is None:
        click.echo(f"mlink-sim control: no answer from {address} within {timeout:g} s (an endpoint with a token "
                   "answers only requests that carry it: --control-token)", err=True)
        sys.exit(1)
    click.echo(json.dumps(reply, indent=2))
    if not reply.get("ok"):
        click.echo(f"mlink-sim control: {address} refused {op}: {reply.get('error', 'no reason given')} ({op} is "
                   f"answered by: {CONTROL_OPS[op]})", err=True)
    sys.exit(0 if reply.get("ok") else 1)
