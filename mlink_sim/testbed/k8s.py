"""Kubernetes manifests for a network config (``mlink-sim compose CONFIG --k8s -o DIR``; docs/testbeds.md, "More
than one machine"): the config as a ConfigMap, one Deployment per slave worker, the master as a Job.

:func:`k8s_manifests` is pure (a :class:`~mlink_sim.config.Config` and the config file's text in, ``{file name:
manifest}`` out, keys in a fixed order); :func:`write_k8s` writes them. What every pod gets, and why:

* ``hostNetwork: true``: UDP in real time on the node's own network, the ports of :mod:`.placement`;
* **Guaranteed QoS with whole CPUs**: requests equal to limits, the CPU a whole number (a worker's or the master's
  ``cpus`` count, else 1), so that the kubelet's static CPU manager policy gives the container CPUs of its own.
  There the kubelet chooses which CPUs, so the processes get no ``--cpus``;
* root with ``SYS_NICE`` and ``IPC_LOCK`` added, so that ``--realtime`` is granted where the node allows it;
* placement: ``nodeSelector`` ``LABEL: NODE``; with no node anywhere in the config, a required pod affinity on
  ``kubernetes.io/hostname`` to the testbed's other pods, which puts them all on one node;
* readiness and liveness probes with the image's cheap probe (``mlink-health``, :mod:`.health`).

The master's Job waits in an init container until every station answers a NOP (a cluster has no ``depends_on``),
runs the timeline once (``backoffLimit: 0``) and writes its report to a ``hostPath`` directory of its node,
``/var/lib/mlink-sim/PROJECT``. The manifests validate against the Kubernetes schemas (tests/testbed/test_k8s.py,
``kubernetes-validate``).
"""

from __future__ import annotations

import re
import shlex
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from .._files import write_atomically
from ..config import Config
from .compose import CONFIG_IN_CONTAINER, DEFAULT_IMAGE, DEFAULT_STATION_PORT, project_name, to_yaml
from .placement import Placement, WorkerPlacement, plan
from .stack import CAPABILITIES, master_command

__all__ = ["k8s_manifests", "write_k8s", "object_prefix", "MEMORY", "REPORT_HOST_DIR", "HOSTNAME_KEY"]

MEMORY = "256Mi"  #: a worker's or the master's memory, request = limit (a 62-station worker uses about 90 MiB)
WAIT_MEMORY = "64Mi"
REPORT_HOST_DIR = "/var/lib/mlink-sim"  #: the master's report: DIR/PROJECT/report.json on the master's node
HOSTNAME_KEY = "kubernetes.io/hostname"
_CONFIG_DIR = str(Path(CONFIG_IN_CONTAINER).parent)


def object_prefix(network_name: str) -> str:
    """A prefix for the objects' names from the network's name: lower-case letters, digits and ``-`` (RFC 1123),
    at most 40 characters, so that every name and label value derived from it stays within 63."""
    text = re.sub(r"[^a-z0-9-]+", "-", project_name(network_name))[:40].strip("-")
    return text or "mlink"


def _labels(project: str, component: str) -> dict[str, str]:
    return {"app.kubernetes.io/name": "mlink-sim", "app.kubernetes.io/instance": project,
            "app.kubernetes.io/component": component}  # fmt: skip


def _resources(cpus: str | None, memory: str = MEMORY) -> dict[str, Any]:
    amount = {"cpu": str(len(cpus.split(",")) if cpus else 1), "memory": memory}
    return {"requests": dict(amount), "limits": dict(amount)}


def _security() -> dict[str, Any]:
    return {"runAsUser": 0, "runAsGroup": 0, "capabilities": {"add": list(CAPABILITIES)}}


def _probe(worker: WorkerPlacement) -> dict[str, Any]:
    return {"exec": {"command": worker.probe_argv()}, "periodSeconds": 5, "timeoutSeconds": 5, "failureThreshold": 3}


def _pod(project: str, placement: Placement, node: str | None, config_map: str) -> dict[str, Any]:
    """The parts every pod spec shares: the host's network, placement, the config volume."""
    spec: dict[str, Any] = {"hostNetwork": True, "dnsPolicy": "ClusterFirstWithHostNet"}
    if node is not None:
        spec["nodeSelector"] = {placement.label: node}
    elif not placement.placed:
        term = {"labelSelector": {"matchLabels": {"app.kubernetes.io/instance": project}}, "topologyKey": HOSTNAME_KEY}
        spec["affinity"] = {"podAffinity": {"requiredDuringSchedulingIgnoredDuringExecution": [term]}}
    spec["volumes"] = [{"name": "config", "configMap": {"name": config_map}}]
    return spec


def _mounts() -> list[dict[str, Any]]:
    return [{"name": "config", "mountPath": _CONFIG_DIR, "readOnly": True}]


def _unpinned(argv: list[str]) -> list[str]:
    """*argv* without ``--cpus LIST``: in a pod the kubelet's CPU manager chooses the CPUs."""
    out: list[str] = []
    skip = False
    for arg in argv:
        if skip:
            skip = False
        elif arg == "--cpus":
            skip = True
        else:
            out.append(arg)
    return out


def _worker(project: str, placement: Placement, worker: WorkerPlacement, config: Config, image: str,
            config_map: str) -> dict[str, Any]:
    labels = {**_labels(project, "slave"), "mlink-sim/worker": worker.name}
    container = {
        "name": "slave",
        "image": image,
        "args": _unpinned(worker.slave_argv(config)),
        "resources": _resources(worker.cpus),
        "securityContext": _security(),
        "volumeMounts": _mounts(),
        "readinessProbe": {**_probe(worker), "initialDelaySeconds": 2},
        "livenessProbe": {**_probe(worker), "initialDelaySeconds": 30},
    }
    pod = _pod(project, placement, worker.node, config_map)
    pod["containers"] = [container]
    pod["terminationGracePeriodSeconds"] = 5
    return {
        "apiVersion": "apps/v1",
        "kind": "Deployment",
        "metadata": {"name": f"{project}-{worker.name}", "labels": labels},
        "spec": {
            "replicas": 1,
            "strategy": {"type": "Recreate"},  # the host's UDP ports: never two pods of one worker at once
            "selector": {"matchLabels": labels},
            "template": {"metadata": {"labels": labels}, "spec": pod},
        },
    }


def _wait_script(placement: Placement) -> str:
    """A shell loop until every worker's first station answers a NOP."""
    probes = []
    for worker in placement.workers:
        argv = worker.probe_argv(remote=True)
        probes.append(f"until {shlex.join(argv)}; do sleep 1; done")
    return "; ".join(probes)


def _master(project: str, placement: Placement, config: Config, image: str, config_map: str,
            duration: str | None, asserts: Iterable[str]) -> dict[str, Any]:
    labels = _labels(project, "master")
    argv = _unpinned(master_command(config, placement, report="/reports/report.json", duration=duration,
                                    asserts=asserts))
    pod = _pod(project, placement, placement.master_node, config_map)
    pod["volumes"].append({"name": "reports", "hostPath": {"path": f"{REPORT_HOST_DIR}/{project}",
                                                          "type": "DirectoryOrCreate"}})
    pod["restartPolicy"] = "Never"
    pod["initContainers"] = [{
        "name": "wait-for-stations",
        "image": image,
        "command": ["sh", "-c", _wait_script(placement)],
        "resources": _resources(None, WAIT_MEMORY),
    }]
    pod["containers"] = [{
        "name": "master",
        "image": image,
        "args": argv,
        "resources": _resources(placement.master_cpus),
        "securityContext": _security(),
        "volumeMounts": [*_mounts(), {"name": "reports", "mountPath": "/reports"}],
    }]
    return {
        "apiVersion": "batch/v1",
        "kind": "Job",
        "metadata": {"name": f"{project}-master", "labels": labels},
        "spec": {"backoffLimit": 0, "template": {"metadata": {"labels": labels}, "spec": pod}},
    }


def k8s_manifests(config: Config, config_text: str, *, project: str | None = None, image: str = DEFAULT_IMAGE,
                  station_port: int = DEFAULT_STATION_PORT, duration: str | None = None,
                  asserts: Iterable[str] = ()) -> dict[str, dict[str, Any]]:
    """``{file name: manifest}`` for *config* (whose file holds *config_text*), in the order to apply them."""
    project = project or object_prefix(config.network.name)
    placement = plan(config, station_port)
    config_map = f"{project}-config"
    out: dict[str, dict[str, Any]] = {
        "00-config.yaml": {"apiVersion": "v1", "kind": "ConfigMap",
                           "metadata": {"name": config_map, "labels": _labels(project, "config")},
                           "data": {Path(CONFIG_IN_CONTAINER).name: config_text}},
    }  # fmt: skip
    for worker in placement.workers:
        out[f"10-{worker.name}.yaml"] = _worker(project, placement, worker, config, image, config_map)
    out["20-master.yaml"] = _master(project, placement, config, image, config_map, duration, list(asserts))
    return out


def write_k8s(config: Config, config_path: str | Path, directory: str | Path, *, command: str | None = None,
              **options: Any) -> list[Path]:
    """Write :func:`k8s_manifests` into *directory* (created), each file atomically; the paths written."""
    text = Path(config_path).read_text(encoding="utf-8")
    manifests = k8s_manifests(config, text, **options)
    folder = Path(directory)
    folder.mkdir(parents=True, exist_ok=True)
    header = (f"Generated by `{command}` – do not edit; regenerate instead.\n" if command else "Generated by mlink-sim.\n")
    project = options.get("project") or object_prefix(config.network.name)
    header += (f"Apply with: kubectl apply -f {folder}; the master's report: {REPORT_HOST_DIR}/{project}/report.json "
               "on its node. See docs/testbeds.md.")
    written = []
    for name, manifest in manifests.items():
        path = folder / name
        write_atomically(path, to_yaml(manifest, header), mode=0o644)
        written.append(path)
    return written
