"""Where the slave workers and the master run on a cluster: a station's ``node`` and ``cpus``, and the ``[deploy]``
table (``mlink-sim compose --stack`` and ``--k8s``; docs/testbeds.md, "More than one machine").

A *node* is the value of a node label (``label``, default ``mlink.node``): a swarm placement constraint
``node.labels.mlink.node == rack-b``, a Kubernetes ``nodeSelector``. A *worker* is one ``mlink-sim slave``
process: a ``[[deploy.worker]]`` with its stations, or each station not named by one. A worker without a node runs
beside the master. The master reaches a worker on its own node at 127.0.0.1 and one on another node at that node's
address in ``[deploy.nodes]``; each station takes commands only from the master's address (``--allow-master``).
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from typing import TYPE_CHECKING, Annotated

from pydantic import BaseModel, BeforeValidator, ConfigDict, Field, field_validator

from ..units import format_cpus, parse_address, parse_cpus

if TYPE_CHECKING:
    from .model import Config

__all__ = ["DeployConfig", "DeployMaster", "DeployWorker", "NodeName", "CpuList", "check_deploy", "DEFAULT_NODE_LABEL",
           "parse_node_address", "with_node_addresses"]

DEFAULT_NODE_LABEL = "mlink.node"
#: a label value (Kubernetes: at most 63 characters, alphanumeric at both ends; swarm takes the same)
_NAME = re.compile(r"[A-Za-z0-9]([A-Za-z0-9_.-]{0,61}[A-Za-z0-9])?")
#: a label key: an optional DNS-subdomain prefix and ``/``, then a name
_KEY = re.compile(r"([a-z0-9]([a-z0-9.-]{0,251}[a-z0-9])?/)?[A-Za-z0-9]([A-Za-z0-9_.-]{0,61}[A-Za-z0-9])?")
_HOST = re.compile(r"[A-Za-z0-9_.:-]+")


def _node(value: object) -> str:
    if not isinstance(value, str) or not _NAME.fullmatch(value):
        raise ValueError(f"expected a node label value such as 'rack-b' (letters, digits, '-', '_', '.'; at most "
                         f"63 characters, a letter or digit at both ends), got {value!r}")
    return value


def _cpus(value: object) -> str:
    """``"0,2"`` or ``[0, 2]`` -> ``"0,2"`` (the form of ``--cpus``)."""
    if isinstance(value, list) and value and all(isinstance(v, int) and not isinstance(v, bool) for v in value):
        value = ",".join(map(str, value))
    if not isinstance(value, str):
        raise ValueError(f"expected CPU numbers such as \"0,2\" or [0, 2], got {value!r}")
    return format_cpus(parse_cpus(value))


NodeName = Annotated[str, BeforeValidator(_node)]
CpuList = Annotated[str, BeforeValidator(_cpus)]


class DeployMaster(BaseModel):
    """``[deploy.master]``: where the master runs."""

    model_config = ConfigDict(extra="forbid")

    node: NodeName | None = Field(None, description="the node label value of the master's node")
    cpus: CpuList | None = Field(None, description="the CPUs the master pins itself to (--cpus), e.g. \"1\"")


class DeployWorker(BaseModel):
    """``[[deploy.worker]]``: one slave process serving *stations*."""

    model_config = ConfigDict(extra="forbid")

    stations: list[Annotated[int, BeforeValidator(parse_address)]] = Field(
        min_length=1, description="the stations this worker serves, e.g. [0x21, 0x22]")
    node: NodeName | None = Field(None, description="the node label value of its node (default: the master's)")
    cpus: CpuList | None = Field(None, description="the CPUs it pins itself to (--cpus), e.g. \"0\"")


class DeployConfig(BaseModel):
    """``[deploy]``: the placement of a cluster testbed."""

    model_config = ConfigDict(extra="forbid")

    label: str = Field(DEFAULT_NODE_LABEL, description="the node label whose value names a node")
    nodes: dict[str, str] = Field(default_factory=dict,
                                  description="node label value -> the address the master reaches that node at")
    master: DeployMaster = Field(default_factory=DeployMaster, description="where the master runs")
    worker: list[DeployWorker] = Field(default_factory=list, description="slave processes serving several stations")

    @field_validator("label")
    @classmethod
    def _label(cls, v: str) -> str:
        if not _KEY.fullmatch(v):
            raise ValueError(f"expected a node label key such as 'mlink.node' or 'example.com/rack', got {v!r}")
        return v

    @field_validator("nodes")
    @classmethod
    def _nodes(cls, v: dict[str, str]) -> dict[str, str]:
        for node, address in v.items():
            _node(node)
            if not _HOST.fullmatch(address):
                raise ValueError(f"{node}: expected a host name or IP address, got {address!r}")
        return v


def check_deploy(config: Config) -> None:
    """The placement's consistency, ValueError naming the field: every station of a ``[[deploy.worker]]`` exists
    and is in one worker only, without a ``node``/``cpus`` of its own; and the master can reach every node a worker
    runs on, and be told apart there (``[deploy.nodes]`` has the address of both ends)."""
    deploy = config.deploy
    known = {st.address for st in config.station}
    owner: dict[int, int] = {}
    for i, worker in enumerate(deploy.worker):
        for address in worker.stations:
            where = f"deploy.worker[{i}].stations"
            if address not in known:
                raise ValueError(f"{where}: {address:02X}H is not a station of this network")
            if address in owner:
                raise ValueError(f"{where}: {address:02X}H is already served by deploy.worker[{owner[address]}]")
            owner[address] = i
            st = config.station_by_address(address)
            if st.node is not None or st.cpus is not None:
                raise ValueError(f"station {address:02X}H: its node and cpus are those of deploy.worker[{i}], "
                                 "which serves it; set them there")
    master = deploy.master.node
    nodes = {w.node for w in deploy.worker} | {st.node for st in config.station if st.address not in owner}
    elsewhere = sorted(n for n in nodes if n is not None and n != master)
    if elsewhere and master is None:
        raise ValueError(f"deploy.master.node: stations run on node {', '.join(elsewhere)}; place the master too, "
                         "so that it knows which stations it reaches at 127.0.0.1 and the others know its address")
    missing = [n for n in elsewhere + ([master] if elsewhere else []) if n is not None and n not in deploy.nodes]
    if missing:
        raise ValueError(f"deploy.nodes: no address for node {', '.join(dict.fromkeys(missing))} (the master and "
                         "the stations on other nodes reach each other there), e.g. "
                         f"nodes = {{ {missing[0]} = \"192.0.2.10\" }}")


def parse_node_address(text: str) -> tuple[str, str]:
    """``rack-b=192.0.2.2`` -> ``("rack-b", "192.0.2.2")`` (``mlink-sim compose --node-address``); ValueError with
    a one-line reason otherwise."""
    node, sep, address = (part.strip() for part in text.partition("="))
    if not sep or not node or not address:
        raise ValueError(f"expected NODE=ADDRESS such as rack-b=192.0.2.2, got {text!r}")
    _node(node)
    if not _HOST.fullmatch(address):
        raise ValueError(f"{node}: expected a host name or IP address, got {address!r}")
    return node, address


def with_node_addresses(config: Config, addresses: Mapping[str, str]) -> Config:
    """*config* with ``[deploy.nodes]`` entries set or replaced by *addresses* (the same placement on a cluster
    whose nodes have other addresses)."""
    deploy = config.deploy.model_copy(update={"nodes": {**config.deploy.nodes, **addresses}})
    return config.model_copy(update={"deploy": deploy})
