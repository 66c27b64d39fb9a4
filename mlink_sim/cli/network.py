"""``mlink-sim up``, ``mlink-sim master`` and ``mlink-sim validate``."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

import click

from ..aio.run.network import EndpointError, RunOptions, run_network, run_up
from ..aio.transport.udp import new_event_loop
from ..config import Config, format_ns, parse_duration_ns
from .capture_opts import capture_options, open_capture_or_exit
from .inputs import InputError, assertions, check_stations, load_checked, report_path
from .logs import configure_logging
from .params import CPUS, Duration, station_name
from .control_token import endpoint_token
from .proxy import parse_control
from .slave import _parse_endpoints
from .web import web_choice, web_options

__all__ = ["up_cmd", "master_cmd", "validate_cmd"]


class _Workers(click.ParamType):
    """``--workers``: a number of processes, ``auto`` or ``station`` (``supervisor.parse_workers``)."""

    name = "workers"

    def get_metavar(self, param: Any, ctx: Any = None) -> str:
        return "[N|auto|station]"

    def convert(self, value: Any, param: Any, ctx: Any) -> int | str:
        from ..aio.run.supervisor import parse_workers

        try:
            return parse_workers(value)
        except ValueError as exc:
            self.fail(str(exc), param, ctx)


def _duration(text: str | None, flag: str) -> int | None:
    if text is None:
        return None
    try:
        return parse_duration_ns(text, default_unit="s")
    except ValueError as exc:
        raise InputError(f"{flag} {text!r}: {exc}") from None


#: ``--trace-interval``'s bounds: at least a millisecond (the finest transmission cycle a trace follows is 1 ms), at
#: most a minute.
TRACE_INTERVAL_NS = (1_000_000, 60_000_000_000)


def _trace_options(report_html: str | None, trace: str | None, interval: str) -> dict[str, Any]:
    """``RunOptions``' ``report_html``, ``trace_path`` and ``trace_interval_ns``, checked before the run."""
    ns = parse_duration_ns(interval, default_unit="ms")  # Duration("ms") checked the text
    lo, hi = TRACE_INTERVAL_NS
    if not lo <= ns <= hi:
        raise InputError(f"--trace-interval {interval!r}: expected a duration from {format_ns(lo)} to "
                         f"{format_ns(hi)}, e.g. 10ms")
    return {"report_html": report_path(report_html, "--report-html", "report.html"),
            "trace_path": report_path(trace, "--trace", "trace.csv"), "trace_interval_ns": ns}


def _options(config: Config, path: Path, *, command: str, duration: str | None, report: str | None,
             report_html: str | None, trace: str | None, trace_interval: str, asserts: tuple[str, ...], status: bool,
             include_bringup: bool, log_json: bool, bringup_timeout: str, rt: bool, cpus: set[int] | None,
             control: str | None, control_token: str | None, control_token_file: str | None,
             capture_path: Any, capture_max: Any, web_at: Any, web_secret: str | None,
             background: bool = True, **only: Any) -> RunOptions:
    """The :class:`RunOptions` of the flags ``up`` and ``master`` share (each checked before the run), and *only*
    those of one of them (``up``'s workers, state and run directories, clock)."""
    where = parse_control(control)
    return RunOptions(
        config_path=path,
        duration_ns=_duration(duration, "--duration"),
        report_path=report_path(report),
        **_trace_options(report_html, trace, trace_interval),
        assertions=assertions(asserts, [st.address for st in config.station]),
        status=status,
        include_bringup=include_bringup,
        log_json=log_json,
        bringup_timeout_s=_duration(bringup_timeout, "--bringup-timeout") / 1e9,  # type: ignore[operator]
        realtime=rt,
        cpus=cpus,
        control=where,
        control_token=endpoint_token(where, control_token, control_token_file),
        capture=open_capture_or_exit(command, capture_path, capture_max, background=background),
        web=web_at,
        web_token=web_secret,
        **only,
    )


def _run(coro_factory: Any, clock: str = "real") -> int:
    if clock == "virtual":
        from ..aio.virtual.vclock import VirtualEventLoop

        loop: Any = VirtualEventLoop()
    else:
        loop = new_event_loop()
    try:
        outcome = loop.run_until_complete(coro_factory())
    finally:
        loop.close()
    return outcome.exit_code


#: The live status explained, at the end of ``up --help`` and ``master --help``.
STATUS_HELP = """\b
The live status (--no-status: none):
  header   elapsed/planned time; p99: the worst station's RTT p99; missed: cycles the master's
           clock skipped (it fell behind); stalls: host stalls of mlink-sim's own processes, count
           (longest) (docs/timing.md); step: the timeline step begun last
  ADDR     the station, as the manuals write it (21H; 0x21 is accepted on input)
  PHASE    P1 answers, P2 connected (asynchronous), P3 connected and synchronous: cyclic data;
           else the master's state: offline, connecting, syncing, alarm
  RUN      FWD, REV or stop, from the station's status
  OUTPUT   the drive's output frequency in Hz; RTT: the last command's round trip
  STATE    ok: no alarm, no warning; else the alarm or warning the station reports"""

_common = [
    click.option("--duration", type=Duration(), help="Run length after bring-up, e.g. 30s (default: the timeline's "
                                                    "end + 1 s)."),
    click.option("--timeline/--no-timeline", "timeline", default=True, show_default=True,
                 help="Run the config's timeline; --no-timeline: bring the network up and run it (cyclic NOPs, no "
                      "checks) until Ctrl-C or --duration."),
    click.option("--report", "report", type=click.Path(dir_okay=False), help="Write the JSON report here."),
    click.option("--report-html", "report_html", type=click.Path(dir_okay=False), metavar="FILE",
                 help="Write the HTML report here: one self-contained file with the verdict, the checks, plots "
                      "(docs/report.md)."),
    click.option("--trace", "trace", type=click.Path(dir_okay=False), metavar="FILE.csv",
                 help="Record each station's figures (Hz, current, DC bus, phase, alarm …) and the actions taken "
                      "as CSV (docs/report.md)."),
    click.option("--trace-interval", "trace_interval", default="10ms", show_default=True, type=Duration("ms"),
                 help="How often --trace samples the stations (on the run's clock: simulated time with --clock "
                      "virtual)."),
    click.option("--assert", "asserts", multiple=True, metavar="EXPR",
                 help="Check a bound at the end, e.g. 'rtt.p99 < 500us' (repeatable; docs/report.md)."),
    click.option("--status/--no-status", default=True, show_default=True,
                 help="Live status on stdout (its columns: see above)."),
    click.option("--bringup-timeout", default="10s", show_default=True, type=Duration(),
                 help="How long bring-up may take."),
    click.option("--include-bringup", is_flag=True,
                 help="Count bring-up in the report and --assert figures (default: from the end of bring-up)."),
    click.option("--control", "control", metavar="HOST:PORT",
                 help="Answer control requests here while running: status, report, run, stop, alarm-clear, param "
                      "('mlink-sim status', 'mlink-sim param'; docs/control.md), impair, heal, faults, fault, "
                      "recovery ('mlink-sim control'; docs/faults.md); 'mlink-sim web' serves a page for it "
                      "(docs/web.md). Port 0: any free port, printed on stderr."),
    click.option("--control-token", "control_token", metavar="TOKEN",
                 help="The token every control request carries; required to bind --control to an address other "
                      "than loopback."),
    click.option("--control-token-file", "control_token_file", metavar="FILE", type=click.Path(dir_okay=False),
                 help="Read the control token from FILE (its first line)."),
    click.option("--log-json", is_flag=True, help="Log JSON lines on stderr."),
    click.option("--log-level", default="warning", show_default=True,
                 type=click.Choice(["debug", "info", "warning", "error"])),
]


def _with_common(fn: Any) -> Any:
    for option in reversed(_common):
        fn = option(fn)
    return web_options(capture_options(fn))


def _with_stalls(fn: Any) -> Any:
    """``--host-stalls`` / ``--stall-bound``: override the config's ``[network]`` policy (docs/timing.md);
    ``--realtime``, ``--cpus``."""
    fn = click.option("--cpus", type=CPUS, default=None,
                      help="The CPUs to run on, e.g. 0,1 (sched_setaffinity), with or without --realtime: the "
                           "master's clock on the highest, up's slave workers on the others (one CPU: all on it); "
                           "stderr says what was granted. Default: the kernel's choice, or with --realtime the "
                           "same plan of the CPUs this process may use, where the CPU wake-up latency is held.")(fn)
    fn = click.option("--realtime/--no-realtime", "rt", default=True, show_default=True,
                      help="SCHED_FIFO, locked memory, the master's clock on a CPU of its own, where permitted; "
                           "stderr says what was granted (docs/timing.md).")(fn)
    fn = click.option("--stall-bound", type=Duration("ms"),
                      help="Longest stall 'absorb' absorbs (default: the config's, 100ms).")(fn)
    return click.option("--host-stalls", type=click.Choice(["absorb", "strict"]),
                        help="Host-stall policy (default: the config's, 'absorb'): absorb runs the cycles a stall "
                             "of mlink-sim's own processes delayed late instead of losing them.")(fn)


def _without_timeline(config: Config, timeline: bool) -> Config:
    """``--no-timeline``: the config without its timeline and its ``network.duration`` (the run ends at Ctrl-C or
    ``--duration``)."""
    if timeline:
        return config
    return config.model_copy(update={"timeline": [], "network": config.network.model_copy(update={"duration": None})})


def _stalls(config: Config, policy: str | None, bound: str | None) -> Config:
    update: dict[str, Any] = {}
    if policy is not None:
        update["host_stalls"] = policy
    ns = None if bound is None else parse_duration_ns(bound, default_unit="ms")
    if ns is not None:
        if not 0 < ns <= 1_000_000_000:
            raise click.BadParameter(f"expected a duration above 0 and at most 1s, got {bound!r}",
                                     param_hint="--stall-bound")
        update["stall_bound"] = ns
    if not update:
        return config
    return config.model_copy(update={"network": config.network.model_copy(update=update)})


@click.command("up", epilog=STATUS_HELP)
@click.argument("config_path", metavar="CONFIG", type=click.Path(dir_okay=False))
@click.option("--workers", type=_Workers(), default="auto", show_default=True,
              help="Slave processes: N (stations spread round-robin), 'station' (one per station) or 'auto' (one "
                   "per station up to max(2, CPUs-1) stations, else CPUs-1, so the master keeps a CPU).")
@click.option("--state-dir", type=click.Path(file_okay=False), help="EEPROM images of the slaves (survive restarts).")
@click.option("--run-dir", type=click.Path(file_okay=False), help="Where worker logs go (default: a temp dir).")
@click.option("--clock", type=click.Choice(["real", "virtual"]), default="real", show_default=True,
              help="real: slave processes over UDP on the wall clock; virtual: one process, in-memory network with "
                   "[network] latency/jitter, simulated time (faster than real time, deterministic).")
@click.option("--seed", type=int, default=0, show_default=True, help="Seed of every random draw: impairments (docs/faults.md), the virtual clock's jitter.")
@_with_common
@_with_stalls
def up_cmd(config_path, workers, state_dir, run_dir, clock, seed, duration, timeline, report, report_html, trace,
           trace_interval, asserts, status, bringup_timeout, include_bringup, control, control_token,
           control_token_file, log_json, log_level, host_stalls, stall_bound, rt, cpus, capture_path,
           capture_max, web, web_token, web_token_file) -> None:
    """Bring the network in CONFIG up: slaves as processes, the master, the timeline; exit 0 if every check held.

    CONFIG is a TOML file or the name of a shipped example ('mlink-sim examples' lists them)."""
    configure_logging(json=log_json, level=log_level)
    config, path = load_checked(config_path)
    config = _without_timeline(_stalls(config, host_stalls, stall_bound), timeline)
    if clock == "virtual" and not timeline and duration is None:
        raise InputError("--clock virtual --no-timeline runs until --duration (simulated time has no Ctrl-C); "
                         "add --duration, e.g. --duration 10s")
    web_at, web_secret = web_choice(web, web_token, web_token_file)
    if clock == "virtual" and web_at is not None:
        raise InputError("--web shows a network on the wall clock; --clock virtual runs faster than a page can "
                         "follow (drop one of them)")
    if clock == "virtual" and (workers != "auto" or run_dir):
        click.echo("note: --clock virtual runs every station in this process: --workers and --run-dir are not used",
                   err=True)
    opts = _options(config, path, command="up", duration=duration, report=report, report_html=report_html,
                    trace=trace, trace_interval=trace_interval, asserts=asserts, status=status,
                    include_bringup=include_bringup, log_json=log_json, bringup_timeout=bringup_timeout, rt=rt,
                    cpus=cpus, control=control, control_token=control_token, control_token_file=control_token_file,
                    capture_path=capture_path, capture_max=capture_max, web_at=web_at, web_secret=web_secret,
                    background=clock != "virtual", workers=workers, state_dir=Path(state_dir) if state_dir else None,
                    run_dir=Path(run_dir) if run_dir else None, clock=clock, seed=seed)
    from ..aio.run.supervisor import WorkerError

    try:
        sys.exit(_run(lambda: run_up(config, opts), clock=clock))
    except WorkerError as exc:
        click.echo(f"mlink-sim up: {exc}", err=True)
        sys.exit(1)
    except ValueError as exc:  # --clock virtual: a card refused its settings (the slave process says the same)
        click.echo(f"mlink-sim up: {exc}", err=True)
        sys.exit(2)


@click.command("master", epilog=STATUS_HELP)
@click.argument("config_path", metavar="CONFIG", type=click.Path(dir_okay=False))
@click.option("--endpoint", "endpoints", multiple=True, metavar="ADDR=HOST:PORT",
              help="Where station ADDR listens (overrides the config's endpoint); repeatable.")
@click.option("--seed", type=int, default=0, show_default=True, help="Seed of the impairments' draws (docs/faults.md).")
@_with_common
@_with_stalls
def master_cmd(config_path, endpoints, seed, duration, timeline, report, report_html, trace, trace_interval, asserts,
               status, bringup_timeout, include_bringup, control, control_token, control_token_file, log_json,
               log_level, host_stalls, stall_bound, rt, cpus, capture_path, capture_max, web, web_token,
               web_token_file) -> None:
    """Run only the master of CONFIG against slaves started elsewhere (containers, other hosts)."""
    configure_logging(json=log_json, level=log_level)
    config, path = load_checked(config_path)
    config = _without_timeline(_stalls(config, host_stalls, stall_bound), timeline)
    web_at, web_secret = web_choice(web, web_token, web_token_file)
    overrides = _parse_endpoints(endpoints)
    check_stations("--endpoint", overrides, config, str(path))
    resolved: dict[int, tuple[str, int]] = {}
    missing = []
    for st in config.station:
        host, port = overrides.get(st.address) or st.host_port(config.network.host)
        if port == 0:
            missing.append(station_name(st.address))
        resolved[st.address] = (host, port)
    if missing:
        raise click.UsageError(
            f"no endpoint for station(s) {', '.join(missing)}: set 'endpoint' in the config or pass "
            "--endpoint ADDR=HOST:PORT"
        )
    opts = _options(config, path, command="master", duration=duration, report=report, report_html=report_html,
                    trace=trace, trace_interval=trace_interval, asserts=asserts, status=status,
                    include_bringup=include_bringup, log_json=log_json, bringup_timeout=bringup_timeout, rt=rt,
                    cpus=cpus, control=control, control_token=control_token, control_token_file=control_token_file,
                    capture_path=capture_path, capture_max=capture_max, web_at=web_at, web_secret=web_secret,
                    seed=seed)
    from ..aio.run.webproc import WebError

    try:
        sys.exit(_run(lambda: run_network(config, resolved, opts)))
    except EndpointError as exc:
        click.echo(f"mlink-sim master: {exc}", err=True)
        sys.exit(2)
    except WebError as exc:
        click.echo(f"mlink-sim master: {exc}", err=True)
        sys.exit(1)


@click.command("validate")
@click.argument("config_path", metavar="CONFIG", type=click.Path(dir_okay=False))
def validate_cmd(config_path: str) -> None:
    """Check CONFIG without starting anything; print a one-screen summary, and a warning for each timeline check
    the drives' settings cannot meet (exit 0 all the same)."""
    from ..scenario.expectations import timeline_warnings

    config, _ = load_checked(config_path)
    net = config.network
    click.echo(f"{config_path}: network {net.name!r}, {len(config.station)} station(s), "
               f"transmission cycle {format_ns(net.transmission_cycle)}, {len(config.timeline)} timeline step(s)")
    for st in config.station:
        assert st.link is not None
        click.echo(f"  {st.address:02X}H {st.profile.label:<8} {st.link.label:<17} {st.frame_size}-byte COM_TIM {st.com_tim}"
                   f"{' sync' if st.sync else ' async'}{' subcmd' if st.subcmd else ''}"
                   f"{'  ' + st.endpoint if st.endpoint else ''}")
    for line in timeline_warnings(config, config_path):
        click.echo(f"warning: {line}")
