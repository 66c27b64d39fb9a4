"""A docker-compose testbed for a network config: one container per slave station, one for the master.

:func:`compose_document` is pure (a :class:`~mlink_sim.config.Config` in, a plain ``dict`` out, keys in a fixed
order) so the output is reproducible and can be validated against the Compose Specification schema;
:func:`render_compose` turns it into YAML with a header naming the command that made it.

The layout (docs/testbeds.md):

* ``station-21`` … – ``mlink-sim slave --config /config/network.toml --only 0x21 --endpoint 0x21=0.0.0.0:PORT
  --allow-master master --allow-status 127.0.0.1``, every station on the same UDP port in its own container, taking
  datagrams only from the master's container (its name resolves once that container exists) and status queries from
  its own loopback: a healthcheck that sends the station a NOP (``mlink-health 127.0.0.1:PORT --station 0x21 --link
  ml2 --frame-size 32``, the image's stdlib-only probe, :mod:`mlink_sim.testbed.health`).
* ``master`` – ``mlink-sim master /config/network.toml --endpoint 0x21=station-21:PORT … --report
  /reports/report.json --no-status``, started only once every station is healthy (``depends_on`` with
  ``condition: service_healthy``), never restarted.
* the config file bind-mounted read-only into every container (:func:`config_source_for`: relative to the
  file's directory when the config lies under it, else absolute), the report on the named volume ``reports``,
  every service on the user-defined bridge network ``mlink``.

A station's ``endpoint`` in the config is not used: inside its container every station listens on
``0.0.0.0:station_port`` and is reached by its service name.

The document is accepted by Compose v2 and by Debian's docker-compose 1.29, whose schema allows no top-level
``name`` and no ``healthcheck.start_interval`` (tests/testbed/test_compose.py runs ``docker-compose config``):
the project name comes from ``-p``. ``start_interval=True`` adds the faster start-up probing of Compose v2.20.2+
on Docker Engine 25+ (:data:`HEALTH_START` against :data:`HEALTH_PORTABLE`).
"""

from __future__ import annotations

import os
import posixpath
import re
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from ..config import Config, StationConfig

__all__ = [
    "compose_document",
    "render_compose",
    "to_yaml",
    "service_name",
    "project_name",
    "probe_argv",
    "HealthTiming",
    "HEALTH_PORTABLE",
    "HEALTH_START",
    "config_source_for",
    "DEFAULT_IMAGE",
    "DEFAULT_STATION_PORT",
    "DEFAULT_REPORT_DIR",
    "CONFIG_IN_CONTAINER",
    "NETWORK_NAME",
    "REPORTS_VOLUME",
]

DEFAULT_IMAGE = "mlink-sim:latest"
DEFAULT_STATION_PORT = 47001
DEFAULT_REPORT_DIR = "/reports"  #: created owned by the image's non-root user (Dockerfile), so the volume is too
CONFIG_IN_CONTAINER = "/config/network.toml"
NETWORK_NAME = "mlink"
REPORTS_VOLUME = "reports"

PROBE_TIMEOUT_S = 2  #: the probe itself waits at most this long for the station's answer
STOP_GRACE_PERIOD = "5s"


@dataclass(frozen=True)
class HealthTiming:
    """When Docker runs a station's health probe. Every probe is a process started in the container (the engine's
    exec: about 30 ms of CPU in dockerd/containerd/runc, plus 15 ms for ``mlink-health``; docs/testbeds.md), so
    the interval is what the health check costs for the whole run. The master waits for the first success."""

    interval: str  #: between probes (the first one comes one interval after the container starts)
    start_period: str  #: failures in this time do not count (Python start-up, binding)
    retries: int  #: failures in a row, after the start period, that make the container unhealthy
    start_interval: str | None = None  #: between probes during the start period (Compose v2 on Engine 25+ only)
    timeout: str = "5s"

    def as_compose(self) -> dict[str, Any]:
        doc: dict[str, Any] = {"interval": self.interval, "timeout": self.timeout, "retries": self.retries,
                               "start_period": self.start_period}  # fmt: skip
        if self.start_interval is not None:
            doc["start_interval"] = self.start_interval
        return doc


#: Every Compose and engine: a probe each 5 s throughout (the station is healthy 5–10 s after it starts).
HEALTH_PORTABLE = HealthTiming(interval="5s", start_period="30s", retries=3)
#: Compose v2.20.2+ with Docker Engine 25+: a probe each second while starting, then one each 30 s.
HEALTH_START = HealthTiming(interval="30s", start_period="30s", retries=3, start_interval="1s")


def service_name(address: int) -> str:
    """``0x21`` -> ``"station-21"`` (lower-case hex: service names double as DNS names)."""
    return f"station-{address:02x}"


def project_name(name: str) -> str:
    """A Compose project name (``^[a-z0-9][a-z0-9_-]*$``) derived from the network name."""
    text = re.sub(r"[^a-z0-9_-]+", "-", name.lower()).strip("-_")
    return text if text and text[0].isalnum() else f"mlink-{text}".rstrip("-")


def _addr(address: int) -> str:
    return f"0x{address:02X}"


def _literal(text: str) -> str:
    """*text* as Compose passes it on: ``$`` would start a variable interpolation, ``$$`` is a literal ``$``."""
    return text.replace("$", "$$")


def _config_mount(config_source: str, target: str) -> dict[str, Any]:
    return {"type": "bind", "source": config_source, "target": target, "read_only": True}


def probe_argv(st: StationConfig, port: int) -> list[str]:
    """``mlink-health 127.0.0.1:PORT --station 0x21 --link ml2 --frame-size 32 --timeout 2`` for *st*."""
    assert st.link is not None and st.frame_size is not None  # filled in by Config validation
    return ["mlink-health", f"127.0.0.1:{port}", "--station", _addr(st.address), "--link", st.link.name.lower(),
            "--frame-size", str(st.frame_size), "--timeout", str(PROBE_TIMEOUT_S)]  # fmt: skip


def _healthcheck(st: StationConfig, port: int, timing: HealthTiming) -> dict[str, Any]:
    # A card answers a NOP from another source with its status, also while a master is connected, without
    # executing anything (docs/cards.md, "Who may change a station"), so the probe checks the live station
    # throughout the run.
    return {"test": ["CMD", *probe_argv(st, port)], **timing.as_compose()}


def compose_document(
    config: Config,
    *,
    config_source: str = "./network.toml",
    config_path_in_container: str = CONFIG_IN_CONTAINER,
    image: str = DEFAULT_IMAGE,
    station_port: int = DEFAULT_STATION_PORT,
    report_dir: str = DEFAULT_REPORT_DIR,
    duration: str | None = None,
    asserts: Iterable[str] = (),
    start_interval: bool = False,
    realtime_budget_us: int | None = None,
) -> dict[str, Any]:
    """The Compose document for *config*.

    *config_source* is the config file's path as the compose file names it (:func:`config_source_for`); *duration* and *asserts* are passed to ``mlink-sim master`` unchanged;
    *start_interval* chooses :data:`HEALTH_START` over :data:`HEALTH_PORTABLE`; *realtime_budget_us* set, the
    master's container may use SCHED_FIFO (:func:`_realtime_master`).
    """
    if not 1 <= station_port <= 65535:
        raise ValueError(f"station port {station_port} is out of range 1…65535")
    if not report_dir.startswith("/"):
        raise ValueError(f"report directory must be an absolute path inside the container, got {report_dir!r}")
    config_volume = _config_mount(config_source, config_path_in_container)
    timing = HEALTH_START if start_interval else HEALTH_PORTABLE
    services: dict[str, Any] = {}
    for st in config.station:
        services[service_name(st.address)] = {
            "image": image,
            "init": True,
            "command": ["slave", "--config", config_path_in_container, "--only", _addr(st.address),
                        "--endpoint", f"{_addr(st.address)}=0.0.0.0:{station_port}", "--allow-master", "master",
                        "--allow-status", "127.0.0.1", "--log-json", *config.network.slave_flags()],
            "volumes": [dict(config_volume)],
            "networks": [NETWORK_NAME],
            "healthcheck": _healthcheck(st, station_port, timing),
            "stop_grace_period": STOP_GRACE_PERIOD,
        }
    master_cmd = ["master", config_path_in_container]
    for st in config.station:
        master_cmd += ["--endpoint", f"{_addr(st.address)}={service_name(st.address)}:{station_port}"]
    master_cmd += ["--report", posixpath.join(report_dir, "report.json"), "--no-status"]
    if duration is not None:
        master_cmd += ["--duration", _literal(duration)]
    for expr in asserts:
        master_cmd += ["--assert", _literal(expr)]
    services["master"] = {
        "image": image,
        "init": True,
        "command": master_cmd,
        "depends_on": {service_name(st.address): {"condition": "service_healthy"} for st in config.station},
        "volumes": [dict(config_volume), {"type": "volume", "source": REPORTS_VOLUME, "target": report_dir}],
        "networks": [NETWORK_NAME],
        "healthcheck": {"disable": True},
        "restart": "no",
        "stop_grace_period": STOP_GRACE_PERIOD,
        **(_realtime_master(realtime_budget_us) if realtime_budget_us is not None else {}),
    }
    return {
        "services": services,
        "networks": {NETWORK_NAME: {"driver": "bridge"}},
        "volumes": {REPORTS_VOLUME: {}},
    }


def _realtime_master(budget_us: int) -> dict[str, Any]:
    """What lets ``mlink-sim master --realtime`` (the default) be granted SCHED_FIFO and locked memory in its
    container (docs/testbeds.md, "Real time in the containers"): root in the container with CAP_SYS_NICE and
    CAP_IPC_LOCK (the image's non-root user would need RLIMIT_RTPRIO, which not every engine can raise), and on a
    host with cgroup v1 and RT group scheduling a real-time budget of *budget_us* µs per second (0: none asked)."""
    if budget_us < 0:
        raise ValueError(f"the real-time budget is µs per second, at least 0, got {budget_us}")
    extra: dict[str, Any] = {"user": "0:0", "cap_add": ["SYS_NICE", "IPC_LOCK"]}
    if budget_us:
        extra["cpu_rt_runtime"] = budget_us
    return extra


class _PlainDumper(yaml.SafeDumper):
    """YAML without anchors and aliases: a value used twice (a pod's labels) is written out twice."""

    def ignore_aliases(self, data: Any) -> bool:
        return True


def to_yaml(document: dict[str, Any], header: str = "") -> str:
    """YAML in the document's own key order; *header* lines become ``#`` comments."""
    body = yaml.dump(document, Dumper=_PlainDumper, sort_keys=False, default_flow_style=False, width=4096,
                     allow_unicode=True)
    lines = [f"# {line}".rstrip() for line in header.splitlines()]
    return ("\n".join(lines) + "\n" if lines else "") + body


def config_source_for(config_path: str | Path, output_path: str | Path | None) -> str:
    """The config's path as the compose or stack file names it: ``./``-relative when the config lies in the file's
    directory or below it (Compose and ``docker stack deploy`` resolve it from the file's directory, so the file
    runs from any working directory, and moves with its folder), else absolute (a config elsewhere, or a file
    written to stdout, whose directory is not known)."""
    # abspath, not resolve(): a path through a link (configs/ → mlink_sim/examples/) stays as the user wrote it
    target = Path(os.path.abspath(config_path))
    if output_path is None or str(output_path) == "-":
        return target.as_posix()
    base = Path(os.path.abspath(output_path)).parent
    try:
        rel = Path(os.path.relpath(target, base)).as_posix()
    except ValueError:  # pragma: no cover - different drives (Windows)
        return target.as_posix()
    return target.as_posix() if rel.startswith("../") else f"./{rel}"


def render_compose(
    config: Config,
    config_path: str | Path,
    output_path: str | Path | None = None,
    *,
    command: str | None = None,
    **options: Any,
) -> str:
    """The compose file for *config* (read from *config_path*) as it will be written to *output_path*."""
    source = config_source_for(config_path, output_path)
    document = compose_document(config, config_source=source, **options)
    header = (
        f"Generated by `{command}` – do not edit; regenerate instead.\n" if command else "Generated by mlink-sim.\n"
    ) + (
        f"Testbed for network {config.network.name!r}: {len(config.station)} station container(s) + 1 master.\n"
        f"Build the image first (docker build -t {options.get('image', DEFAULT_IMAGE)} . or scripts/docker-build), then:\n"
        f"  docker compose -p {project_name(config.network.name)} -f THIS_FILE up --abort-on-container-exit "
        "--exit-code-from master\n"
        "(docker-compose 1.29 takes the same options) or all in one: scripts/docker-testbed CONFIG. "
        "See docs/testbeds.md."
    )
    return to_yaml(document, header)
