"""The placement of a config on a cluster, as the swarm stack (:mod:`.stack`) and the Kubernetes manifests
(:mod:`.k8s`) write it: which slave workers run where, on which UDP ports, how the master reaches each and what
each allows as its master. Pure: a :class:`~mlink_sim.config.Config` in, a :class:`Placement` out
(docs/testbeds.md, "More than one machine"; the config fields: :mod:`mlink_sim.config.deploy`).

Every process uses the host's network (UDP in real time needs no overlay, and swarm's routing mesh carries no
UDP datagrams of one source to one task): each station listens on ``0.0.0.0:PORT`` of its node, the ports
counted from a base in config order, so that two workers on one node never collide. The master reaches a
station on its own node at 127.0.0.1 and one on another node at that node's address in ``[deploy.nodes]``; a
station allows commands from 127.0.0.1 or from the master node's address the same way, and a station away from the
master's node answers the status queries of its node's own health probe (``--allow-status 127.0.0.1``).
"""

from __future__ import annotations

from dataclasses import dataclass

from ..config import Config, StationConfig
from .compose import CONFIG_IN_CONTAINER, DEFAULT_STATION_PORT, probe_argv, service_name

__all__ = ["Placement", "WorkerPlacement", "plan", "LOOPBACK"]

LOOPBACK = "127.0.0.1"


def _addr(address: int) -> str:
    return f"0x{address:02X}"


@dataclass(frozen=True)
class WorkerPlacement:
    """One ``mlink-sim slave`` process of the testbed."""

    name: str  #: ``station-21`` (a station of its own) or ``worker-0`` (``[[deploy.worker]]`` 0)
    stations: tuple[StationConfig, ...]
    node: str | None  #: the node label value of its node (None: no placement, beside an unplaced master)
    cpus: str | None  #: ``--cpus`` (``"0,2"``), None: the kernel's choice
    ports: tuple[int, ...]  #: each station's UDP port on its node, in the order of :attr:`stations`
    reach: str  #: the host the master sends to (127.0.0.1 on the master's node)
    allow_master: str  #: ``--allow-master``: the master's address as this worker sees it

    def slave_argv(self, config: Config, config_path: str = CONFIG_IN_CONTAINER) -> list[str]:
        """The ``mlink-sim`` arguments of this worker (``slave --config … --only … --endpoint …``)."""
        argv = ["slave", "--config", config_path, "--only", ",".join(_addr(st.address) for st in self.stations)]
        for st, port in zip(self.stations, self.ports, strict=True):
            argv += ["--endpoint", f"{_addr(st.address)}=0.0.0.0:{port}"]
        argv += ["--allow-master", self.allow_master]
        if self.allow_master != LOOPBACK:  # the health probe runs on the worker's node (probe_argv)
            argv += ["--allow-status", LOOPBACK]
        argv += ["--log-json", *config.network.slave_flags(), "--realtime"]
        return argv + (["--cpus", self.cpus] if self.cpus else [])

    def probe_argv(self, *, remote: bool = False) -> list[str]:
        """The health probe of this worker: a NOP to its first station (one process serves them all), on its own
        node (127.0.0.1) or, *remote*, from the master's node (the address the master reaches it at)."""
        argv = probe_argv(self.stations[0], self.ports[0])
        if remote:
            argv[1] = f"{self.reach}:{self.ports[0]}"
        return argv

    def endpoints(self) -> list[str]:
        """``--endpoint`` values of the master for this worker's stations: ``0x21=HOST:PORT``."""
        return [f"{_addr(st.address)}={self.reach}:{port}" for st, port in zip(self.stations, self.ports, strict=True)]


@dataclass(frozen=True)
class Placement:
    """Where everything runs: the node label, the master's node and CPUs, the workers."""

    label: str
    master_node: str | None
    master_cpus: str | None
    workers: tuple[WorkerPlacement, ...]

    def master_argv(self, config_path: str = CONFIG_IN_CONTAINER) -> list[str]:
        """``master CONFIG --endpoint …`` for every station (no report, duration or assertion: the caller's)."""
        argv = ["master", config_path]
        for worker in self.workers:
            for endpoint in worker.endpoints():
                argv += ["--endpoint", endpoint]
        return argv + (["--cpus", self.master_cpus] if self.master_cpus else [])

    @property
    def placed(self) -> bool:
        """True when the config names a node for anything (else everything runs on one node)."""
        return self.master_node is not None or any(w.node is not None for w in self.workers)


def plan(config: Config, base_port: int = DEFAULT_STATION_PORT) -> Placement:
    """The placement of *config* (already validated: :func:`mlink_sim.config.deploy.check_deploy`), the stations'
    ports counted from *base_port* in config order."""
    last = base_port + len(config.station) - 1
    if not 1 <= base_port or last > 65535:
        raise ValueError(f"the stations need UDP ports {base_port}…{last}, beyond 65535: choose a lower --port")
    port = {st.address: base_port + i for i, st in enumerate(config.station)}
    deploy = config.deploy
    master = deploy.master.node
    groups: list[tuple[int, str, list[StationConfig], str | None, str | None]] = []
    served: set[int] = set()
    for i, w in enumerate(deploy.worker):
        stations = [config.station_by_address(a) for a in w.stations]
        served.update(w.stations)
        first = min(config.station.index(st) for st in stations)
        groups.append((first, f"worker-{i}", stations, w.node, w.cpus))
    for i, st in enumerate(config.station):
        if st.address not in served:
            groups.append((i, service_name(st.address), [st], st.node, st.cpus))
    workers = []
    for _, name, stations, node, cpus in sorted(groups, key=lambda g: g[0]):
        node = node if node is not None else master
        beside = node == master
        workers.append(WorkerPlacement(
            name=name, stations=tuple(stations), node=node, cpus=cpus,
            ports=tuple(port[st.address] for st in stations),
            reach=LOOPBACK if beside else deploy.nodes[node or ""],
            allow_master=LOOPBACK if beside else deploy.nodes[master or ""],
        ))  # fmt: skip
    return Placement(label=deploy.label, master_node=master, master_cpus=deploy.master.cpus, workers=tuple(workers))
