"""``mlink-sim slave`` – serve one station (flags) or several stations of a config (``--config --only``)."""

from __future__ import annotations

import asyncio
import json
import signal
import sys
import time
from pathlib import Path

import click

from .._log import get_logger
from ..aio.timing import realtime
from ..aio.timing.heap import settle_heap
from ..aio.slave.allow import AllowList
from ..aio.slave.server import HostedStation, SlaveServer
from ..aio.slave.stations import StationSpec, build_station, spec_for
from ..aio.transport.udp import BindError, loop_name, new_event_loop, stop_on_signals
from ..config import ConfigError, load_config, parse_address, parse_duration_ns, parse_endpoint
from ..operations import card_text
from ..config.units import parse_arrival_poll
from ..profiles import lookup, profiles
from ..wire import Link
from .capture_opts import capture_options, open_capture_or_exit
from .control_token import control_token_options, endpoint_token
from .inputs import InputError, check_stations
from .params import ADDR, CARD, LINK, Duration, station_name
from .logs import configure_logging

__all__ = ["slave_cmd", "station_specs_from_config"]

log = get_logger("mlink_sim.slave")


def _check_link(card: str, link_name: str | None) -> None:
    """``--link`` must be one the card speaks (its profile's links: SI-T3 Table 29 / F6-22, V7 switch S1-1:
    ML-I/II; SI-ET3: ML-III)."""
    if link_name is None:
        return
    links = sorted(lookup(card).links)
    if link_name.upper() not in links:
        spoken = "/".join(Link[name].label for name in links)
        raise InputError(f"--link {link_name}: {card} speaks {spoken}; use --link {' or '.join(links)}")


def station_specs_from_config(
    config_path: str, only: list[int] | None, endpoints: dict[int, tuple[str, int]]
) -> list[StationSpec]:
    config = load_config(config_path)
    check_stations("--endpoint", endpoints, config, config_path)
    wanted = only or [st.address for st in config.station]
    specs = []
    for address in wanted:
        try:
            st = config.station_by_address(address)
        except KeyError:
            raise click.BadParameter(f"{station_name(address)} is not a station of {config_path}",
                                     param_hint="--only") from None
        host, port = endpoints.get(address) or st.host_port(config.network.host)
        specs.append(spec_for(st, host, port))
    return specs


async def _serve(server: SlaveServer, ready_json: bool, log_json: bool, rt: bool = False,
                 cpus: set[int] | None = None, control: tuple[str, int] | None = None,
                 token: str | None = None) -> int:
    """Serve until SIGINT / SIGTERM, with the control endpoint at *control* (None: none); the exit status, 128 + the
    signal's number (130 / 143)."""
    from ..aio.control.slave import serve_slave

    loop = asyncio.get_running_loop()
    stop, caught = stop_on_signals(loop)
    await server.start()
    endpoint = ops = None
    control_port = None
    if control is not None:
        try:
            endpoint, ops, (_, control_port) = await serve_slave(server, *control, token)
        except OSError:
            await server.close()
            raise
    if server.allow is None:
        print("mlink-sim slave: no --allow-master: any source may CONNECT to a free or released station "
              "(docs/cards.md, \"Who may change a station\")", file=sys.stderr, flush=True)
    settle_heap()  # before the first command arrives: no full collection of the start-up heap mid-cycle
    info = {**server.ready_info(), "control": control_port}
    if rt:  # docs/timing.md, "Real-time scheduling": below the master's clock, off its CPU
        info["realtime"] = realtime.apply(realtime.WORKER_PRIORITY, cpus or realtime.cpu_plan()[1],
                                          placed=cpus is not None)
        if not ready_json:
            print(f"mlink-sim slave: realtime: {info['realtime']} (--no-realtime: none of it)", file=sys.stderr,
                  flush=True)
    elif cpus is not None:  # --cpus alone: placed, ordinary scheduling
        info["cpus"] = realtime.pin(cpus)
        print(f"mlink-sim slave: cpus: {info['cpus']}", file=sys.stderr, flush=True)
    if ready_json:
        print(json.dumps(info), flush=True)
    else:
        for st in info["stations"]:
            print(
                f"mlink-sim slave ready: {card_text(st['card'])} station {station_name(st['address'])} on "
                f"{st['host']}:{st['port']} "
                f"({st['link']}, {st['frame_size']}-byte frames, {loop_name(loop)})",
                flush=True,
            )
        if control is not None:
            where = f"[{control[0]}]:{control_port}" if ":" in control[0] else f"{control[0]}:{control_port}"
            print(f"mlink-sim slave control: {where} (mlink-sim status {where}; mlink-sim param get|set {where} …; "
                  f"mlink-sim control {where} OP)", flush=True)
    log.info("ready", stations=[f"{s['address']:#04x}@{s['host']}:{s['port']}" for s in info["stations"]],
             control=info["control"])
    await stop.wait()
    log.info("stopping", signal=signal.Signals(caught[0]).name,
             host_stalls=server.stalls.totals("self"))  # this process's own (metrics/stalls.py)
    if ops is not None:
        ops.close()
    if endpoint is not None:
        endpoint.close()
    await server.close()
    return 128 + caught[0]


def _allow_list(rules: tuple[str, ...], status: tuple[str, ...]) -> AllowList | None:
    """``--allow-master``: the sources that may change a station, ``--allow-status`` those whose status queries are
    answered besides; without ``--allow-master``, any source (:func:`_serve` says so)."""
    if not rules:
        if status:
            raise click.UsageError("--allow-status needs --allow-master: without it every source is answered")
        return None
    for option, values in (("--allow-master", rules), ("--allow-status", status)):
        try:
            AllowList(values)
        except ValueError as exc:
            raise InputError(f"{option} {exc}") from None
    allow = AllowList(rules, status)
    log.info("allow_master", rules=allow.rules, status=allow.status_rules)
    return allow


def _parse_endpoints(values: tuple[str, ...]) -> dict[int, tuple[str, int]]:
    out = {}
    for text in values:
        addr, sep, target = text.partition("=")
        if not sep:
            raise click.BadParameter(f"expected ADDR=HOST:PORT such as 21H=0.0.0.0:47001, got {text!r}",
                                     param_hint="--endpoint")
        try:
            out[parse_address(addr)] = parse_endpoint(target)
        except ValueError as exc:
            raise click.BadParameter(str(exc), param_hint="--endpoint") from None
    return out


@click.command("slave")
@click.option("--card", type=CARD, help=f"Option card to emulate: {', '.join(p.key for p in profiles())} (as a config's "
              "card field).")
@click.option("--station", "station_text", type=ADDR, help="Station address, e.g. 21H or 0x21 (F6-20 / V7 switches).")
@click.option("--listen", default="127.0.0.1:0", show_default=True, metavar="HOST:PORT",
              help="Where to listen (port 0: any free port).")
@click.option("--frame-size", type=click.Choice(["17", "32", "64"]), help="Data size (F6-21 / V7 S1-2).")
@click.option("--link", "link_name", type=LINK,
              help="ML1 = 4 Mbps MECHATROLINK-I (F6-22 = 1 / V7 S1-1 off); default ML2 (ML3 for si-et3).")
@click.option("--param", "params", multiple=True, metavar="NAME=VALUE",
              help="Parameter in engineering units (C1-01=5.0) or raw register (0x0200=50); repeatable.")
@click.option("--config", "config_path", type=click.Path(dir_okay=False), help="Serve stations of this network config.")
@click.option("--only", metavar="ADDR[,ADDR…]", help="With --config: these stations only (default: all).")
@click.option("--endpoint", "endpoints", multiple=True, metavar="ADDR=HOST:PORT",
              help="With --config: where a station listens (overrides the config); repeatable.")
@click.option("--state-dir", type=click.Path(file_okay=False), help="Directory of the EEPROM images (CONFIG_MOD 1).")
@click.option("--control", default="127.0.0.1:0", show_default=True, metavar="HOST:PORT",
              help="The control endpoint: status, get-param, set-param, fault, release, stats, cpu ('mlink-sim "
                   "status', 'mlink-sim param', 'mlink-sim control'; docs/control.md); 'off' to disable.")
@click.option("--allow-master", "allow_master", multiple=True, metavar="ADDR",
              help="Take datagrams only from this source: HOST (any port), HOST:PORT or a CIDR network; repeatable. "
                   "The kernel drops every other source's (docs/cards.md). Default: any source, CONNECT included.")
@click.option("--allow-status", "allow_status", multiple=True, metavar="ADDR",
              help="With --allow-master: also answer this source's status queries (a NOP, read-only: a health "
                   "check, mlink-sim probe); it changes nothing. HOST, HOST:PORT or a CIDR network; repeatable.")
@control_token_options
@click.option("--log-json", is_flag=True, help="Log JSON lines on stderr.")
@click.option("--log-level", default="info", type=click.Choice(["debug", "info", "warning", "error"]))
@click.option("--ready-json", is_flag=True, help="Print the ready line as JSON (for supervisors).")
@click.option("--host-stalls", type=click.Choice(["strict", "absorb"]), default="strict", show_default=True,
              help="strict: judge the master by the wall clock, as the manuals do – a slave started alone tests "
                   "your own master, so strict is its default; absorb (the default of up/master, whose master is "
                   "mlink-sim's): a stall of mlink-sim's own processes up to --stall-bound costs no command "
                   "(docs/timing.md).")
@click.option("--stall-bound", default="100ms", show_default=True, type=Duration("ms"),
              help="With --host-stalls absorb: the bound (a bare number is ms).")
@click.option("--shared-port", is_flag=True,
              help="With --config: the stations of one link share one UDP port where their endpoints allow it "
                   "(port 0, or the same port); the address byte picks the station, as on a bus. What the packed "
                   "workers of `mlink-sim up` do (docs/cards.md).")
@click.option("--arrival-poll", "arrival_poll", default="auto", show_default=True, metavar="auto|off|DURATION",
              help="auto: at cycles up to 500us, busy-poll from 80us before each burst of commands is due (no "
                   "wake-up on arrival), unless idle CPUs poll (CPU wake-up latency held at 0); a lead such as "
                   "80us: that lead at any cycle; off: never (docs/timing.md).")
@click.option("--realtime/--no-realtime", "rt", default=False, show_default=True,
              help="SCHED_FIFO, locked memory, off the master's CPU, where permitted (docs/timing.md). Off by "
                   "default: a slave started alone does not know where its master runs, and a fixed real-time "
                   "priority could preempt a master on the same machine (up turns it on for its own workers).")
@click.option("--cpus", "cpus_text", default=None, metavar="LIST",
              help="The CPUs to run on, e.g. 0,2 (sched_setaffinity), with or without --realtime; stderr says "
                   "what was granted. Default: the kernel's choice; with --realtime, those this process may use "
                   "but the highest (the master of `mlink-sim up` takes it) where the CPU wake-up latency is held.")
@capture_options
def slave_cmd(card, station_text, listen, frame_size, link_name, params, config_path, only, endpoints, state_dir,
              control, allow_master, allow_status, control_token, control_token_file, log_json, log_level, ready_json, host_stalls, stall_bound, shared_port, arrival_poll, rt,
              cpus_text, capture_path, capture_max) -> None:
    """Serve one station over UDP until SIGINT/SIGTERM (or several stations of a --config)."""
    configure_logging(json=log_json, level=log_level)
    state = Path(state_dir) if state_dir else None
    try:
        bound = parse_duration_ns(stall_bound, default_unit="ms")
    except ValueError as exc:
        raise click.BadParameter(str(exc), param_hint="--stall-bound") from None
    if not 0 < bound <= 1_000_000_000:
        raise click.BadParameter(f"expected a duration above 0 and at most 1s, got {stall_bound!r}",
                                 param_hint="--stall-bound")
    absorb_ns = bound if host_stalls == "absorb" else 0
    try:
        poll = parse_arrival_poll(arrival_poll)
    except ValueError as exc:
        raise click.BadParameter(str(exc), param_hint="--arrival-poll") from None
    try:
        control_addr = None if control == "off" else parse_endpoint(control)
    except ValueError as exc:
        raise InputError(f"--control {exc}") from None
    token = endpoint_token(control_addr, control_token, control_token_file)
    allow = _allow_list(allow_master, allow_status)
    try:
        cpus = realtime.parse_cpus(cpus_text) if cpus_text is not None else None
    except ValueError as exc:
        raise click.BadParameter(str(exc), param_hint="--cpus") from None
    try:
        if config_path:
            if card or station_text:
                raise click.UsageError("--config takes the card and station from the file; drop --card/--station")
            try:
                only_list = [parse_address(a) for a in only.split(",")] if only else None
            except ValueError as exc:
                raise click.BadParameter(str(exc), param_hint="--only") from None
            specs = station_specs_from_config(config_path, only_list, _parse_endpoints(endpoints))
        else:
            if not card or not station_text:
                raise click.UsageError("give --card and --station (or --config FILE)")
            _check_link(card, link_name)
            host, port = parse_endpoint(listen)
            specs = [StationSpec(card, parse_address(station_text), host, port,
                                 int(frame_size) if frame_size else None, list(params),
                                 link=Link[link_name.upper()] if link_name else None)]
        now = time.monotonic_ns()
        stations = [HostedStation(build_station(s, state, now, absorb_ns=absorb_ns), s.host, s.port) for s in specs]
    except ConfigError as exc:
        click.echo(f"mlink-sim slave: {exc}", err=True)
        sys.exit(2)
    except click.ClickException:
        raise
    except ValueError as exc:  # ParamError, bad address/endpoint, bad frame size for the card, bad EEPROM image
        click.echo(f"mlink-sim slave: {exc}", err=True)
        sys.exit(2)
    capture = open_capture_or_exit("slave", capture_path, capture_max)
    server = SlaveServer(stations, state_dir=state, absorb_ns=absorb_ns, capture=capture, shared=shared_port,
                         arrival_poll=poll, allow=allow)
    loop = new_event_loop()
    try:
        code = loop.run_until_complete(_serve(server, ready_json, log_json, rt, cpus, control_addr, token))
    except OSError as exc:
        where = "" if isinstance(exc, BindError) else f" on {', '.join(f'{s.host}:{s.port}' for s in stations)}"
        click.echo(f"mlink-sim slave: cannot listen{where}: {exc.strerror or exc}", err=True)
        sys.exit(2)
    finally:
        loop.close()
        if capture is not None:
            click.echo(capture.close().summary(), err=True)
    sys.exit(code)
