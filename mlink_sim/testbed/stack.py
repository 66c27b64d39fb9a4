"""A Docker Swarm stack for a network config (``mlink-sim compose CONFIG --stack``; docs/testbeds.md, "More than
one machine"): one service per slave worker, placed by node label, and the master's service.

:func:`stack_document` is pure (a :class:`~mlink_sim.config.Config` in, a ``dict`` in a fixed key order out);
:func:`render_stack` adds the header. What each service gets, and why:

* **the host's network** (the external network ``host``): UDP in real time needs no overlay and no routing mesh;
  every station listens on its own port of its node (:mod:`.placement`);
* **root in the container with** ``cap_add: [SYS_NICE, IPC_LOCK]`` **and an** ``rtprio`` **ulimit**, so that
  ``--realtime`` (SCHED_FIFO, locked memory) is granted where the host allows it; a swarm service has no
  ``cpu_rt_runtime``, so on a host with cgroup v1 RT group scheduling SCHED_FIFO is refused all the same and the
  process says so. An engine that cannot raise ``rtprio`` (its own bounding set without CAP_SYS_RESOURCE) does not
  start the container: *rtprio* 0 writes no ulimit;
* **a health check** with the image's cheap probe (``mlink-health``, :mod:`.health`) against the worker's first
  station;
* **placement**: ``node.labels.LABEL == NODE``; a service with no node anywhere in the config runs on a manager
  (one node: the whole stack there);
* **the config as a swarm config** (``configs:``), which the swarm copies to every node, named after its content
  so that a changed file is a new config;
* each worker pins itself to its ``cpus`` (``--cpus``), since a swarm service has no cpuset.

The master's service runs the timeline once (``restart_policy: none``), waits up to a minute for the stations
(``--bringup-timeout``: a swarm has no ``depends_on``) and writes its report to the volume ``reports`` on its
node. Without it (*master_service* False) the header gives the ``mlink-sim master`` command to run elsewhere.
``docker stack config -c`` accepts the file (tests/testbed/test_stack.py).
"""

from __future__ import annotations

import hashlib
import posixpath
import shlex
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from ..config import Config
from .compose import (CONFIG_IN_CONTAINER, DEFAULT_IMAGE, DEFAULT_REPORT_DIR, DEFAULT_STATION_PORT, HEALTH_PORTABLE,
                      REPORTS_VOLUME, STOP_GRACE_PERIOD, _literal, config_source_for, project_name, to_yaml)
from .placement import Placement, plan

__all__ = ["stack_document", "render_stack", "master_command", "DEFAULT_RTPRIO", "STACK_VERSION", "HOST_NETWORK",
           "CAPABILITIES", "BRINGUP_TIMEOUT"]

STACK_VERSION = "3.8"  #: the compose file format of `docker stack deploy` (configs with a name: 3.5+)
HOST_NETWORK = "hostnet"  #: the stack's name for the external network ``host``
CAPABILITIES = ["SYS_NICE", "IPC_LOCK"]
DEFAULT_RTPRIO = 40  #: the master's SCHED_FIFO priority (aio/timing/realtime.py), the highest any process asks for
BRINGUP_TIMEOUT = "60s"  #: the master's service starts with the stations': it waits this long for them
CONFIG_NAME = "network"


def _placement(placement: Placement, node: str | None) -> dict[str, Any]:
    if node is not None:
        return {"constraints": [f"node.labels.{placement.label} == {node}"]}
    return {"constraints": ["node.role == manager"]}


def _realtime(rtprio: int) -> dict[str, Any]:
    extra: dict[str, Any] = {"user": "0:0", "cap_add": list(CAPABILITIES)}
    if rtprio:
        extra["ulimits"] = {"rtprio": rtprio}
    return extra


def master_command(config: Config, placement: Placement, *, config_path: str = CONFIG_IN_CONTAINER,
                   report: str | None = None, duration: str | None = None,
                   asserts: Iterable[str] = ()) -> list[str]:
    """``mlink-sim``'s arguments for the master of *placement*: every endpoint, the report, the run's options."""
    argv = placement.master_argv(config_path) + ["--no-status", "--bringup-timeout", BRINGUP_TIMEOUT]
    if report is not None:
        argv += ["--report", report]
    if duration is not None:
        argv += ["--duration", duration]
    for expr in asserts:
        argv += ["--assert", expr]
    return argv


def stack_document(
    config: Config,
    *,
    config_source: str = "./network.toml",
    config_digest: str = "",
    project: str | None = None,
    image: str = DEFAULT_IMAGE,
    station_port: int = DEFAULT_STATION_PORT,
    report_dir: str = DEFAULT_REPORT_DIR,
    duration: str | None = None,
    asserts: Iterable[str] = (),
    rtprio: int = DEFAULT_RTPRIO,
    master_service: bool = True,
) -> dict[str, Any]:
    """The stack document for *config*. *config_source* is the config file as the stack file sees it,
    *config_digest* a digest of its content (names the swarm config), *rtprio* the ``rtprio`` ulimit (0: none)."""
    if not 0 <= rtprio <= 99:
        raise ValueError(f"rtprio is a SCHED_FIFO priority 0…99 (0: no ulimit), got {rtprio}")
    if not report_dir.startswith("/"):
        raise ValueError(f"report directory must be an absolute path inside the container, got {report_dir!r}")
    placement = plan(config, station_port)
    project = project or project_name(config.network.name)
    config_ref = [{"source": CONFIG_NAME, "target": CONFIG_IN_CONTAINER, "mode": 0o444}]
    services: dict[str, Any] = {}
    for worker in placement.workers:
        services[worker.name] = {
            "image": image,
            "init": True,
            "command": worker.slave_argv(config),
            **_realtime(rtprio),
            "configs": [dict(c) for c in config_ref],
            "networks": [HOST_NETWORK],
            "healthcheck": {"test": ["CMD", *worker.probe_argv()], **HEALTH_PORTABLE.as_compose()},
            "stop_grace_period": STOP_GRACE_PERIOD,
            "deploy": {
                "replicas": 1,
                "restart_policy": {"condition": "on-failure", "delay": "1s", "max_attempts": 3},
                "placement": _placement(placement, worker.node),
            },
        }
    if master_service:
        report = posixpath.join(report_dir, "report.json")
        services["master"] = {
            "image": image,
            "init": True,
            "command": [_literal(a) for a in master_command(config, placement, report=report, duration=duration,
                                                              asserts=asserts)],
            **_realtime(rtprio),
            "configs": [dict(c) for c in config_ref],
            "volumes": [{"type": "volume", "source": REPORTS_VOLUME, "target": report_dir}],
            "networks": [HOST_NETWORK],
            "healthcheck": {"disable": True},
            "stop_grace_period": STOP_GRACE_PERIOD,
            "deploy": {
                "replicas": 1,
                "restart_policy": {"condition": "none"},
                "placement": _placement(placement, placement.master_node),
            },
        }
    name = f"{project}-{CONFIG_NAME}" + (f"-{config_digest[:12]}" if config_digest else "")
    document: dict[str, Any] = {
        "version": STACK_VERSION,
        "services": services,
        "configs": {CONFIG_NAME: {"name": name, "file": config_source}},
        "networks": {HOST_NETWORK: {"external": True, "name": "host"}},
    }
    if master_service:
        document["volumes"] = {REPORTS_VOLUME: {}}
    return document


def render_stack(config: Config, config_path: str | Path, output_path: str | Path | None = None, *,
                 command: str | None = None, **options: Any) -> str:
    """The stack file for *config* (read from *config_path*) as it will be written to *output_path*."""
    digest = hashlib.sha256(Path(config_path).read_bytes()).hexdigest()
    source = config_source_for(config_path, output_path)
    document = stack_document(config, config_source=source, config_digest=digest, **options)
    placement = plan(config, options.get("station_port", DEFAULT_STATION_PORT))
    project = options.get("project") or project_name(config.network.name)
    header = (f"Generated by `{command}` – do not edit; regenerate instead.\n" if command
              else "Generated by mlink-sim.\n")
    header += (f"Swarm stack for network {config.network.name!r}: {len(placement.workers)} slave worker service(s)"
               f"{' + the master' if options.get('master_service', True) else ''}, on the hosts' network.\n"
               f"  docker stack deploy --resolve-image never -c THIS_FILE {project}\n")
    if not options.get("master_service", True):
        argv = master_command(config, placement, config_path=str(config_path), report="report.json",
                              duration=options.get("duration"), asserts=options.get("asserts", ()))
        header += "The master runs outside the swarm, on the master's node:\n  mlink-sim " + shlex.join(argv) + "\n"
    header += "All in one on this machine: scripts/swarm-testbed CONFIG. See docs/testbeds.md."
    return to_yaml(document, header)
