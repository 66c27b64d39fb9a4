"""``mlink-sim compose CONFIG [-o compose.yaml]`` – write a docker-compose testbed for the network in CONFIG."""

from __future__ import annotations

import shlex
import sys

import click

from .._files import write_atomically
from ..config import ConfigError, load_config, resolve_config_path
from .params import Duration
from ..testbed.compose import DEFAULT_IMAGE, DEFAULT_REPORT_DIR, DEFAULT_STATION_PORT, render_compose

__all__ = ["compose_cmd"]


def _command_line(config_path: str, output: str | None, image: str, report_dir: str, port: int,
                  duration: str | None, asserts: tuple[str, ...], start_interval: bool,
                  realtime_budget: int | None) -> str:
    """The command as a user would retype it (only non-default options), for the file's header."""
    args = ["mlink-sim", "compose", config_path]
    if output is not None:
        args += ["-o", output]
    if image != DEFAULT_IMAGE:
        args += ["--image", image]
    if report_dir != DEFAULT_REPORT_DIR:
        args += ["--report-dir", report_dir]
    if port != DEFAULT_STATION_PORT:
        args += ["--port", str(port)]
    if duration is not None:
        args += ["--duration", duration]
    for expr in asserts:
        args += ["--assert", expr]
    if start_interval:
        args.append("--start-interval")
    if realtime_budget is not None:
        args += ["--realtime-master", str(realtime_budget)]
    return shlex.join(args)


@click.command("compose")
@click.argument("config_path", metavar="CONFIG")
@click.option("-o", "--output", help="Write the compose file here (atomically) instead of stdout.")
@click.option("--image", default=DEFAULT_IMAGE, show_default=True, help="Image of every service.")
@click.option("--report-dir", default=DEFAULT_REPORT_DIR, show_default=True,
              help="Directory of the report inside the master container (the 'reports' volume).")
@click.option("--port", "port", default=DEFAULT_STATION_PORT, show_default=True, type=click.IntRange(1, 65535),
              help="UDP port every station listens on inside its container.")
@click.option("--duration", type=Duration(), help="Passed to `mlink-sim master --duration` (default: the config's timeline).")
@click.option("--assert", "asserts", multiple=True, metavar="EXPR",
              help="Passed to `mlink-sim master --assert`; repeatable, e.g. 'rtt.p99 < 2ms'.")
@click.option("--start-interval", is_flag=True,
              help="Probe each station every 1 s while it starts and every 30 s after (healthcheck.start_interval: "
                   "Compose v2.20.2+ on Docker Engine 25+; docker-compose 1.29 rejects it). Default: every 5 s.")
@click.option("--realtime-master", "realtime_budget", type=click.IntRange(0, 1_000_000), metavar="BUDGET_US",
              help="Let the master's container use SCHED_FIFO: root in the container with SYS_NICE and IPC_LOCK, and "
                   "BUDGET_US µs per second of real-time budget (cpu_rt_runtime; 0 = none, for hosts without RT "
                   "group scheduling). The engine must grant it (docs/testbeds.md).")
def compose_cmd(config_path: str, output: str | None, image: str, report_dir: str, port: int,
                duration: str | None, asserts: tuple[str, ...], start_interval: bool,
                realtime_budget: int | None) -> None:
    """Write a docker-compose file for the network in CONFIG: one container per slave station, a master that
    starts once every station answers its healthcheck, the config mounted read-only, the report on a volume."""
    try:
        config = load_config(config_path)
    except ConfigError as exc:
        click.echo(f"mlink-sim compose: {exc}", err=True)
        sys.exit(2)
    config_path = str(resolve_config_path(config_path))  # a shipped example's name: the file it names
    if not report_dir.startswith("/"):
        raise click.BadParameter("must be an absolute path inside the container, e.g. /reports",
                                 param_hint="--report-dir")
    text = render_compose(
        config, config_path, output,
        command=_command_line(config_path, output, image, report_dir, port, duration, asserts, start_interval,
                              realtime_budget),
        image=image, station_port=port, report_dir=report_dir, duration=duration, asserts=asserts,
        start_interval=start_interval, realtime_budget_us=realtime_budget,
    )  # fmt: skip
    if output is None or output == "-":
        click.echo(text, nl=False)
        return
    try:
        write_atomically(output, text, mode=0o644)
    except OSError as exc:
        click.echo(f"mlink-sim compose: cannot write {output}: {exc.strerror or exc}", err=True)
        sys.exit(2)
    click.echo(f"wrote {output}: {len(config.station)} station service(s) + master "
               f"(docker compose -f {shlex.quote(output)} up --abort-on-container-exit --exit-code-from master)",
               err=True)
