"""``mlink-sim compose CONFIG [-o compose.yaml]`` – write a docker-compose testbed for the network in CONFIG;
``--stack`` a Docker Swarm stack, ``--k8s -o DIR`` Kubernetes manifests (docs/testbeds.md)."""

from __future__ import annotations

import re
import shlex
import sys
from collections.abc import Mapping
from typing import NoReturn

import click

from .._files import write_atomically
from ..config import ConfigError, load_config, resolve_config_path
from .params import Duration, Parsed
from ..config.deploy import parse_node_address, with_node_addresses
from ..testbed.compose import DEFAULT_IMAGE, DEFAULT_REPORT_DIR, DEFAULT_STATION_PORT, render_compose
from ..testbed.k8s import REPORT_HOLD_S, write_k8s
from ..testbed.stack import DEFAULT_RTPRIO, render_stack

__all__ = ["compose_cmd"]


def _command_line(config_path: str, output: str | None, options: Mapping[str, object]) -> str:
    """The command as a user would retype it (only the options given), for the file's header."""
    args = ["mlink-sim", "compose", config_path]
    if output is not None:
        args += ["-o", output]
    for flag, value in options.items():
        if value is None or value is False or value == ():
            continue
        if value is True:
            args.append(flag)
        elif isinstance(value, tuple):
            for item in value:
                args += [flag, str(item)]
        else:
            args += [flag, str(value)]
    return shlex.join(args)


def _fail(message: str) -> NoReturn:
    click.echo(f"mlink-sim compose: {message}", err=True)
    sys.exit(2)


@click.command("compose")
@click.argument("config_path", metavar="CONFIG")
@click.option("-o", "--output", help="Write the file here (atomically) instead of stdout; with --k8s: the directory.")
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
@click.option("--stack", is_flag=True,
              help="Write a Docker Swarm stack instead (docker stack deploy): one service per slave worker on the "
                   "hosts' network, placed by node label ([deploy], a station's node), the master as a service.")
@click.option("--k8s", "k8s_dir", is_flag=True,
              help="Write Kubernetes manifests into the directory -o DIR instead: a Deployment per slave worker, the "
                   "master as a Job, hostNetwork, CPU sized to each cycle (whole CPUs where the config gives cpus), the "
                   "same placement.")
@click.option("--rtprio", type=click.IntRange(0, 99), default=DEFAULT_RTPRIO, show_default=True,
              help="With --stack: the services' rtprio ulimit (0: none, for an engine that cannot raise it).")
@click.option("--no-master", "no_master", is_flag=True,
              help="With --stack: no master service; the file's header gives the `mlink-sim master` command to run "
                   "outside the swarm.")
@click.option("--web", "web_port", type=click.IntRange(1, 65535), metavar="PORT",
              help="With --k8s: the master serves the live page and the HTTP API on PORT of its node, with the token "
                   "of a Secret PROJECT-token, and the master's Service has the port.")
@click.option("--control", "control_port", type=click.IntRange(1, 65535), metavar="PORT",
              help="With --k8s: the master answers control requests (mlink-sim status) on PORT of its node, with the "
                   "same token, and the master's Service has the port.")
@click.option("--report-hold", type=click.IntRange(0, 86400), default=REPORT_HOLD_S, show_default=True,
              metavar="SECONDS", help="With --k8s: how long the master's pod keeps its report after the run, for "
                                      "kubectl cp (0: it ends with the run).")
@click.option("--node-address", "node_addresses", multiple=True, type=Parsed("NODE=ADDR", parse_node_address),
              help="With --stack/--k8s: the address of node NODE on this cluster, in place of the one in "
                   "[deploy.nodes] (repeatable), e.g. rack-b=10.0.0.12.")
@click.option("--project", help="With --stack/--k8s: the name of the swarm config or the Kubernetes objects' prefix "
                                "(default: from the network's name).")
def compose_cmd(config_path: str, output: str | None, image: str, report_dir: str, port: int,
                duration: str | None, asserts: tuple[str, ...], start_interval: bool,
                realtime_budget: int | None, stack: bool, k8s_dir: bool, rtprio: int, no_master: bool,
                web_port: int | None, control_port: int | None, report_hold: int,
                node_addresses: tuple[tuple[str, str], ...], project: str | None) -> None:
    """Write a docker-compose file for the network in CONFIG: one container per slave station, a master that
    starts once every station answers its healthcheck, the config mounted read-only, the report on a volume.
    --stack writes a Docker Swarm stack and --k8s Kubernetes manifests for one machine or several."""
    if stack and k8s_dir:
        _fail("--stack and --k8s: choose one")
    for flag, given, needs in (("--start-interval", start_interval, not (stack or k8s_dir)),
                               ("--realtime-master", realtime_budget is not None, not (stack or k8s_dir)),
                               ("--rtprio", rtprio != DEFAULT_RTPRIO, stack), ("--no-master", no_master, stack),
                               ("--web", web_port is not None, k8s_dir), ("--control", control_port is not None, k8s_dir),
                               ("--report-hold", report_hold != REPORT_HOLD_S, k8s_dir),
                               ("--node-address", bool(node_addresses), stack or k8s_dir),
                               ("--project", project is not None, stack or k8s_dir)):
        if given and not needs:
            _fail(f"{flag} does not apply here (see mlink-sim compose --help)")
    if k8s_dir and output in (None, "-"):
        _fail("--k8s writes one file per object: give the directory with -o DIR")
    if project is not None and not re.fullmatch(r"[a-z0-9]([a-z0-9-]{0,40}[a-z0-9])?", project):
        _fail(f"--project {project!r}: lower-case letters, digits and '-', at most 42 characters")
    try:
        config = load_config(config_path)
    except ConfigError as exc:
        _fail(str(exc))
    config_path = str(resolve_config_path(config_path))  # a shipped example's name: the file it names
    if node_addresses:
        config = with_node_addresses(config, dict(node_addresses))
    if not report_dir.startswith("/"):
        raise click.BadParameter("must be an absolute path inside the container, e.g. /reports",
                                 param_hint="--report-dir")
    options = {"--image": None if image == DEFAULT_IMAGE else image,
               "--report-dir": None if report_dir == DEFAULT_REPORT_DIR else report_dir,
               "--port": None if port == DEFAULT_STATION_PORT else port, "--duration": duration,
               "--assert": asserts, "--start-interval": start_interval, "--realtime-master": realtime_budget,
               "--stack": stack, "--k8s": k8s_dir, "--rtprio": None if rtprio == DEFAULT_RTPRIO else rtprio,
               "--no-master": no_master, "--web": web_port, "--control": control_port,
               "--report-hold": None if report_hold == REPORT_HOLD_S else report_hold, "--node-address": tuple(f"{n}={a}" for n, a in node_addresses),
               "--project": project}  # fmt: skip
    command = _command_line(config_path, output, options)
    try:
        if k8s_dir:
            assert output is not None
            written = write_k8s(config, config_path, output, command=command, project=project, image=image,
                                station_port=port, duration=duration, asserts=asserts, web_port=web_port,
                                control_port=control_port, report_hold=report_hold)
            click.echo(f"wrote {len(written)} manifest(s) into {output} (kubectl apply -f {shlex.quote(output)})",
                       err=True)
            return
        if stack:
            text = render_stack(config, config_path, output, command=command, project=project, image=image,
                                station_port=port, report_dir=report_dir, duration=duration, asserts=asserts,
                                rtprio=rtprio, master_service=not no_master)
        else:
            text = render_compose(
                config, config_path, output, command=command, image=image, station_port=port,
                report_dir=report_dir, duration=duration, asserts=asserts, start_interval=start_interval,
                realtime_budget_us=realtime_budget,
            )  # fmt: skip
    except ValueError as exc:  # e.g. the stations' ports beyond 65535
        _fail(str(exc))
    except OSError as exc:
        _fail(f"cannot write {output}: {exc.strerror or exc}")
    if output is None or output == "-":
        click.echo(text, nl=False)
        return
    try:
        write_atomically(output, text, mode=0o644)
    except OSError as exc:
        _fail(f"cannot write {output}: {exc.strerror or exc}")
    if stack:
        click.echo(f"wrote {output}: a swarm stack (docker stack deploy --resolve-image never -c "
                   f"{shlex.quote(output)} NAME)", err=True)
        return
    click.echo(f"wrote {output}: {len(config.station)} station service(s) + master "
               f"(docker compose -f {shlex.quote(output)} up --abort-on-container-exit --exit-code-from master)",
               err=True)
