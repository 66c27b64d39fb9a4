"""Kubernetes manifests for a network config (``mlink-sim compose CONFIG --k8s -o DIR``; docs/testbeds.md, "More
than one machine"): the config as a ConfigMap, one Deployment per slave worker, the master as a Job, the Services
that name them.

:func:`k8s_manifests` is pure (a :class:`~mlink_sim.config.Config` and the config file's text in, ``{file name:
manifest}`` out, keys in a fixed order); :func:`write_k8s` writes them, each with a header that says how to apply
it and what it asks of the cluster. What every pod gets, and why:

* ``hostNetwork: true``: UDP in real time on the node's own network, the ports of :mod:`.placement`;
* the image as it is on the node (``imagePullPolicy: IfNotPresent``): a locally built or loaded image starts
  without a registry, and an image of a registry (``--image``) is pulled once;
* **CPU sized to the work**: a worker or master whose ``cpus`` the config gives asks for real time, so it gets
  Guaranteed QoS with that many whole CPUs (requests equal to limits), which the kubelet's static CPU manager
  policy makes CPUs of its own (the kubelet chooses them, so the process gets no ``--cpus``). Every other one
  requests what its cycle costs (:func:`cpu_request`) and no CPU limit, since a CFS quota that runs out stalls a
  cycle; memory is limited either way;
* **no root unless real time needs it**: the image's user (uid 10001) with every capability dropped and
  ``--no-realtime``; a real-time pod runs as root with ``SYS_NICE`` (SCHED_FIFO) and ``IPC_LOCK`` (mlockall)
  only, because a non-root process keeps no added capability across ``exec`` (its file's header says so);
* placement: ``nodeSelector`` ``LABEL: NODE`` where the config places a worker (else beside the master, on the
  master's node). A config that places nothing puts no constraint on any pod: the scheduler spreads them, and
  the master reaches each worker by the name of its headless Service, as each worker allows the master by the
  name of the master's (``--allow-master``, which resolves a name again while it does not resolve);
* readiness and liveness probes with the image's cheap probe (``mlink-health``, :mod:`.health`).

The master's Job waits in an init container until every station answers a NOP from its node (a cluster has no
``depends_on``), runs the timeline once (``backoffLimit: 0``) and writes its report into the pod, which it keeps
for *report_hold* seconds after the run, so that ``kubectl cp`` can fetch it; then the Job ends with the master's
exit code. ``web_port``/``control_port`` serve the live page and the control endpoint on the master's node, with
the token of a Secret the user creates, and give the master's Service those ports. The manifests validate
against the Kubernetes schemas (tests/testbed/test_k8s.py, ``kubernetes-validate``; ``kubectl apply
--dry-run=client`` where kubectl is installed).
"""

from __future__ import annotations

import dataclasses
import math
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

__all__ = ["k8s_manifests", "write_k8s", "object_prefix", "cpu_request", "MEMORY", "IMAGE_UID", "REPORT_HOLD_S"]

MEMORY = "256Mi"  #: a worker's or the master's memory limit (a 62-station worker uses about 90 MiB)
WAIT_MEMORY = "64Mi"
IMAGE_UID = 10001  #: the image's non-root user and group (Dockerfile)
REPORT_HOLD_S = 600  #: how long the master's pod keeps its report after the run, for kubectl cp
REPORT_DIR = "/reports"
TOKEN_DIR = "/run/mlink-sim"
#: CPU one process spends per transmission cycle, µs, rounded up: a one-station slave worker and the master of
#: three stations as the quickstart's containers used it in the two-node swarm testbed (docs/testbeds.md,
#: "Kubernetes manifests"), and each further station's exchange (docs/performance.md: 3–4 µs per station)
WORKER_CYCLE_US, MASTER_CYCLE_US, STATION_US = 130, 300, 4
MIN_CPU_MILLI = 50
_CONFIG_DIR = str(Path(CONFIG_IN_CONTAINER).parent)
_RT_NOTE = ("Real time (the config gives its cpus): root in the container with SYS_NICE (SCHED_FIFO) and IPC_LOCK "
            "(mlockall) only, every other capability dropped; a non-root process keeps no added capability across "
            "exec.")


def object_prefix(network_name: str) -> str:
    """A prefix for the objects' names from the network's name: lower-case letters, digits and ``-`` (RFC 1123),
    at most 40 characters, so that every name and label value derived from it stays within 63."""
    text = re.sub(r"[^a-z0-9-]+", "-", project_name(network_name))[:40].strip("-")
    return text or "mlink"


def cpu_request(cycle_ns: int, stations: int, per_cycle_us: int) -> str:
    """The CPU request of a process serving *stations* at a transmission cycle of *cycle_ns*: its cost per cycle
    times the cycles per second, in millicores, at least :data:`MIN_CPU_MILLI`."""
    us_per_s = (per_cycle_us + STATION_US * max(0, stations - 1)) * 1e9 / cycle_ns
    return f"{max(MIN_CPU_MILLI, math.ceil(us_per_s / 1000))}m"


def _labels(project: str, component: str) -> dict[str, str]:
    return {"app.kubernetes.io/name": "mlink-sim", "app.kubernetes.io/instance": project,
            "app.kubernetes.io/component": component}  # fmt: skip


def _resources(cpus: str | None, request: str, memory: str = MEMORY) -> dict[str, Any]:
    if cpus:  # real time: Guaranteed, whole CPUs
        amount = {"cpu": str(len(cpus.split(","))), "memory": memory}
        return {"requests": dict(amount), "limits": dict(amount)}
    return {"requests": {"cpu": request, "memory": memory}, "limits": {"memory": memory}}


def _security(realtime: bool) -> dict[str, Any]:
    if realtime:
        return {"runAsUser": 0, "runAsGroup": 0, "allowPrivilegeEscalation": False,
                "capabilities": {"drop": ["ALL"], "add": list(CAPABILITIES)}}  # fmt: skip
    return {"runAsNonRoot": True, "runAsUser": IMAGE_UID, "runAsGroup": IMAGE_UID, "allowPrivilegeEscalation": False,
            "capabilities": {"drop": ["ALL"]}}  # fmt: skip


def _probe(worker: WorkerPlacement) -> dict[str, Any]:
    return {"exec": {"command": worker.probe_argv()}, "periodSeconds": 5, "timeoutSeconds": 5, "failureThreshold": 3}


def _pod(placement: Placement, node: str | None, config_map: str) -> dict[str, Any]:
    """The parts every pod spec shares: the host's network, placement, the config volume."""
    spec: dict[str, Any] = {"hostNetwork": True, "dnsPolicy": "ClusterFirstWithHostNet"}
    if node is not None:
        spec["nodeSelector"] = {placement.label: node}
    spec["volumes"] = [{"name": "config", "configMap": {"name": config_map}}]
    return spec


def _mounts() -> list[dict[str, Any]]:
    return [{"name": "config", "mountPath": _CONFIG_DIR, "readOnly": True}]


def _unpinned(argv: list[str], realtime: bool) -> list[str]:
    """*argv* without ``--cpus LIST`` (in a pod the kubelet's CPU manager chooses the CPUs) and, without real
    time, without ``--realtime``."""
    out: list[str] = []
    skip = False
    for arg in argv:
        if skip:
            skip = False
        elif arg == "--cpus":
            skip = True
        elif arg != "--realtime" or realtime:
            out.append(arg)
    return out


def _service(project: str, name: str, selector: dict[str, str], ports: dict[str, int], *,
             before_ready: bool) -> dict[str, Any]:
    """A headless Service: its name resolves to the node address of the pods it selects (hostNetwork)."""
    spec: dict[str, Any] = {"clusterIP": "None", "selector": selector, "publishNotReadyAddresses": before_ready}
    if ports:
        spec["ports"] = [{"name": n, "port": p, "targetPort": p, "protocol": "TCP"} for n, p in ports.items()]
    return {"apiVersion": "v1", "kind": "Service",
            "metadata": {"name": name, "labels": _labels(project, "service")}, "spec": spec}  # fmt: skip


def _worker(project: str, placement: Placement, worker: WorkerPlacement, config: Config, image: str,
            config_map: str) -> dict[str, Any]:
    labels = {**_labels(project, "slave"), "mlink-sim/worker": worker.name}
    realtime = worker.cpus is not None
    request = cpu_request(config.network.transmission_cycle, len(worker.stations), WORKER_CYCLE_US)
    container = {
        "name": "slave",
        "image": image,
        "imagePullPolicy": "IfNotPresent",
        "args": _unpinned(worker.slave_argv(config), realtime),
        "resources": _resources(worker.cpus, request),
        "securityContext": _security(realtime),
        "volumeMounts": _mounts(),
        "readinessProbe": {**_probe(worker), "initialDelaySeconds": 2},
        "livenessProbe": {**_probe(worker), "initialDelaySeconds": 30},
    }
    pod = _pod(placement, worker.node, config_map)
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
    """A shell loop until every worker's first station answers a NOP from the master's node."""
    return "; ".join(f"until {shlex.join(w.probe_argv(remote=True))}; do sleep 1; done" for w in placement.workers)


def _hold_script(hold_s: int) -> str:
    """The master, then *hold_s* seconds in which its report can be copied out, then its exit code."""
    return (f'mlink-sim "$@"; code=$?; echo "mlink-sim master exited $code; the report stays in this pod for {hold_s} '
            f's: kubectl cp <pod>:{REPORT_DIR}/report.json report.json" >&2; sleep {hold_s}; exit $code')


def _master(project: str, placement: Placement, config: Config, image: str, config_map: str,
            duration: str | None, asserts: Iterable[str], web_port: int | None, control_port: int | None,
            report_hold: int) -> dict[str, Any]:
    labels = _labels(project, "master")
    realtime = placement.master_cpus is not None
    argv = _unpinned(master_command(config, placement, report=f"{REPORT_DIR}/report.json", duration=duration,
                                    asserts=asserts), realtime)  # fmt: skip
    argv += [] if realtime else ["--no-realtime"]
    pod = _pod(placement, placement.master_node, config_map)
    mounts = [*_mounts(), {"name": "reports", "mountPath": REPORT_DIR}]
    pod["volumes"].append({"name": "reports", "emptyDir": {"sizeLimit": "64Mi"}})
    for flag, port in (("--web", web_port), ("--control", control_port)):
        if port is not None:
            argv += [flag, f"0.0.0.0:{port}", f"{flag}-token-file", f"{TOKEN_DIR}/token"]
    if web_port is not None or control_port is not None:
        pod["volumes"].append({"name": "token", "secret": {"secretName": f"{project}-token"}})
        mounts.append({"name": "token", "mountPath": TOKEN_DIR, "readOnly": True})
    pod["restartPolicy"] = "Never"
    pod["securityContext"] = {"fsGroup": IMAGE_UID}  # the token file readable by the image's user
    pod["initContainers"] = [{
        "name": "wait-for-stations",
        "image": image,
        "imagePullPolicy": "IfNotPresent",
        "command": ["sh", "-c", _wait_script(placement)],
        "resources": {"requests": {"cpu": f"{MIN_CPU_MILLI}m", "memory": WAIT_MEMORY},
                      "limits": {"memory": WAIT_MEMORY}},
        "securityContext": _security(False),
    }]  # fmt: skip
    request = cpu_request(config.network.transmission_cycle, len(config.station), MASTER_CYCLE_US)
    pod["containers"] = [{
        "name": "master",
        "image": image,
        "imagePullPolicy": "IfNotPresent",
        "command": ["sh", "-c", _hold_script(report_hold), "mlink-sim"] if report_hold else ["mlink-sim"],
        "args": argv,
        "resources": _resources(placement.master_cpus, request),
        "securityContext": _security(realtime),
        "volumeMounts": mounts,
    }]
    return {
        "apiVersion": "batch/v1",
        "kind": "Job",
        "metadata": {"name": f"{project}-master", "labels": labels},
        "spec": {"backoffLimit": 0, "template": {"metadata": {"labels": labels}, "spec": pod}},
    }


def _by_name(project: str, placement: Placement) -> Placement:
    """*placement* with every worker reached by its Service's name and allowing the master by its Service's: a
    config that places nothing leaves the pods wherever the scheduler puts them."""
    workers = tuple(dataclasses.replace(w, reach=f"{project}-{w.name}", allow_master=f"{project}-master")
                    for w in placement.workers)  # fmt: skip
    return dataclasses.replace(placement, workers=workers)


def k8s_manifests(config: Config, config_text: str, *, project: str | None = None, image: str = DEFAULT_IMAGE,
                  station_port: int = DEFAULT_STATION_PORT, duration: str | None = None,
                  asserts: Iterable[str] = (), web_port: int | None = None, control_port: int | None = None,
                  report_hold: int = REPORT_HOLD_S) -> dict[str, dict[str, Any]]:
    """``{file name: manifest}`` for *config* (whose file holds *config_text*), in the order to apply them."""
    if report_hold < 0:
        raise ValueError(f"the report's hold is seconds, at least 0, got {report_hold}")
    project = project or object_prefix(config.network.name)
    placement = plan(config, station_port)
    if not placement.placed:
        placement = _by_name(project, placement)
    config_map = f"{project}-config"
    out: dict[str, dict[str, Any]] = {
        "00-config.yaml": {"apiVersion": "v1", "kind": "ConfigMap",
                           "metadata": {"name": config_map, "labels": _labels(project, "config")},
                           "data": {Path(CONFIG_IN_CONTAINER).name: config_text}},
    }  # fmt: skip
    for worker in placement.workers:
        out[f"10-{worker.name}.yaml"] = _worker(project, placement, worker, config, image, config_map)
        if not placement.placed:
            out[f"15-{worker.name}-service.yaml"] = _service(
                project, f"{project}-{worker.name}", {"mlink-sim/worker": worker.name,
                                                      "app.kubernetes.io/instance": project}, {}, before_ready=False)
    out["20-master.yaml"] = _master(project, placement, config, image, config_map, duration, list(asserts),
                                    web_port, control_port, report_hold)  # fmt: skip
    ports = {n: p for n, p in (("web", web_port), ("control", control_port)) if p is not None}
    if ports or not placement.placed:
        out["25-master-service.yaml"] = _service(project, f"{project}-master", _labels(project, "master"), ports,
                                                 before_ready=True)  # fmt: skip
    return out


def _header(manifest: dict[str, Any], project: str, folder: Path, *, web: bool, hold: int) -> str:
    lines = [f"Apply with: kubectl apply -f {folder} (the namespace must admit hostNetwork: Pod Security level "
             "privileged). See docs/testbeds.md, \"Kubernetes manifests\"."]
    pod = manifest.get("spec", {}).get("template", {}).get("spec", {})
    if any(c.get("securityContext", {}).get("runAsUser") == 0 for c in pod.get("containers", [])):
        lines.append(_RT_NOTE)
    if manifest["kind"] == "Job":
        lines.append(f"Follow it: kubectl logs -f job/{project}-master. "
                     + (f"The report stays in its pod for {hold} s after the run: kubectl cp "
                        f"\"$(kubectl get pod -l job-name={project}-master -o name | cut -d/ -f2)\":{REPORT_DIR}/"
                        "report.json report.json -c master" if hold else "The report is not kept (--report-hold 0)."))
        if web:
            lines.append(f"The page and the control endpoint take the token of the Secret {project}-token: kubectl "
                         f"create secret generic {project}-token --from-literal=token=\"$(openssl rand -hex 16)\"")
    return "\n".join(lines)


def write_k8s(config: Config, config_path: str | Path, directory: str | Path, *, command: str | None = None,
              **options: Any) -> list[Path]:
    """Write :func:`k8s_manifests` into *directory* (created), each file atomically; the paths written."""
    text = Path(config_path).read_text(encoding="utf-8")
    manifests = k8s_manifests(config, text, **options)
    folder = Path(directory)
    folder.mkdir(parents=True, exist_ok=True)
    first = f"Generated by `{command}` – do not edit; regenerate instead.\n" if command else "Generated by mlink-sim.\n"
    project = options.get("project") or object_prefix(config.network.name)
    web = options.get("web_port") is not None or options.get("control_port") is not None
    hold = options.get("report_hold", REPORT_HOLD_S)
    written = []
    for name, manifest in manifests.items():
        path = folder / name
        header = first + _header(manifest, project, folder, web=web, hold=hold)
        write_atomically(path, to_yaml(manifest, header), mode=0o644)
        written.append(path)
    return written
