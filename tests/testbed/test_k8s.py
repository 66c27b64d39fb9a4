"""``mlink-sim compose --k8s -o DIR``: every manifest validates against the Kubernetes schemas offline
(kubernetes-validate, the 1.30 schemas and the newest it ships; ``kubectl apply --dry-run=client`` where a kubectl
reaches an API server) and means what docs/testbeds.md ("Kubernetes manifests") says: a Deployment per slave
worker, the master as a Job, hostNetwork, the image as it is on the node, CPU sized to the work and whole CPUs only
for real time, root only for real time, the config's placement or none, the master reachable and its report
kept."""

from __future__ import annotations

import os
import shutil
import subprocess

import pytest
import yaml
from click.testing import CliRunner

from mlink_sim.cli.compose import compose_cmd
from mlink_sim.config import load_config
from mlink_sim.testbed.k8s import IMAGE_UID, cpu_request, k8s_manifests, object_prefix

from .test_stack import QUICKSTART, TWO_NODES, two_nodes

KUBERNETES_VERSION = "1.30"


@pytest.fixture(scope="module")
def validate():
    try:
        import kubernetes_validate
    except ImportError:
        if os.environ.get("CI", "").lower() == "true":
            pytest.fail("kubernetes-validate is missing in CI: pip install -e '.[test]'")
        pytest.skip("kubernetes-validate is a test dependency: pip install -e '.[test]'")
    versions = sorted({KUBERNETES_VERSION, kubernetes_validate.latest_version()})

    def check(manifest):
        for version in versions:  # its schemas ship with the package
            kubernetes_validate.validate(manifest, version, strict=True)

    return check


def _pods(manifests):
    return {name: m["spec"]["template"]["spec"] for name, m in manifests.items() if m["kind"] in ("Deployment", "Job")}


def _containers(pod):
    return [*pod.get("initContainers", []), *pod["containers"]]


@pytest.mark.parametrize("which", ["quickstart", "two-nodes"])
def test_every_manifest_validates_against_the_kubernetes_schemas(validate, which):
    config = load_config(QUICKSTART) if which == "quickstart" else two_nodes()
    text = QUICKSTART.read_text(encoding="utf-8") if which == "quickstart" else TWO_NODES
    manifests = k8s_manifests(config, text)
    for manifest in manifests.values():
        validate(yaml.safe_load(yaml.safe_dump(manifest)))  # what kubectl reads: the YAML


def test_the_schemas_reject_what_the_api_server_would(validate):
    import kubernetes_validate

    job = k8s_manifests(two_nodes(), TWO_NODES)["20-master.yaml"]
    job["spec"]["template"]["spec"]["hostNetwrk"] = True
    with pytest.raises(kubernetes_validate.ValidationError):
        validate(job)


def test_slaves_are_deployments_and_the_master_a_job_in_apply_order():
    manifests = k8s_manifests(two_nodes(), TWO_NODES, project="two")
    assert list(manifests) == ["00-config.yaml", "10-worker-0.yaml", "10-station-23.yaml", "20-master.yaml"]
    kinds = [m["kind"] for m in manifests.values()]
    assert kinds == ["ConfigMap", "Deployment", "Deployment", "Job"]
    assert manifests["00-config.yaml"]["data"] == {"network.toml": TWO_NODES}
    worker = manifests["10-worker-0.yaml"]
    assert worker["spec"]["replicas"] == 1 and worker["spec"]["strategy"] == {"type": "Recreate"}
    assert worker["spec"]["selector"]["matchLabels"] == worker["spec"]["template"]["metadata"]["labels"]
    job = manifests["20-master.yaml"]["spec"]
    assert job["backoffLimit"] == 0 and job["template"]["spec"]["restartPolicy"] == "Never"


def test_every_pod_is_on_the_hosts_network_with_the_image_as_it_is_on_the_node():
    pods = _pods(k8s_manifests(two_nodes(), TWO_NODES))
    for name, pod in pods.items():
        assert pod["hostNetwork"] is True and pod["dnsPolicy"] == "ClusterFirstWithHostNet", name
        for container in _containers(pod):
            assert container["imagePullPolicy"] == "IfNotPresent", name  # a locally loaded image starts
            assert container["resources"]["limits"]["memory"] == container["resources"]["requests"]["memory"]


def test_whole_cpus_and_root_with_two_capabilities_only_where_the_config_asks_for_real_time():
    pods = _pods(k8s_manifests(two_nodes(), TWO_NODES))
    worker = pods["10-worker-0.yaml"]["containers"][0]  # cpus = [0, 1]
    assert worker["resources"]["requests"] == worker["resources"]["limits"] == {"cpu": "2", "memory": "256Mi"}
    assert worker["securityContext"]["runAsUser"] == 0
    assert worker["securityContext"]["capabilities"] == {"drop": ["ALL"], "add": ["SYS_NICE", "IPC_LOCK"]}
    assert "--realtime" in worker["args"] and "--cpus" not in worker["args"]  # the kubelet chooses the CPUs
    master = pods["20-master.yaml"]["containers"][0]  # cpus = "1"
    assert master["resources"]["limits"]["cpu"] == "1" and "--no-realtime" not in master["args"]


def test_without_real_time_a_pod_requests_what_its_cycle_costs_and_runs_as_the_images_user():
    pods = _pods(k8s_manifests(load_config(QUICKSTART), QUICKSTART.read_text(encoding="utf-8"), project="qs"))
    for name, pod in pods.items():
        for container in _containers(pod):
            res = container["resources"]
            assert "cpu" not in res["limits"], name  # no CFS quota to run out in a cycle
            assert res["requests"]["cpu"].endswith("m") and int(res["requests"]["cpu"][:-1]) < 1000, name
            sec = container["securityContext"]
            assert sec["runAsNonRoot"] is True and sec["runAsUser"] == IMAGE_UID, name
            assert sec["capabilities"] == {"drop": ["ALL"]} and sec["allowPrivilegeEscalation"] is False, name
    slave = pods["10-station-21.yaml"]["containers"][0]["args"]
    assert "--realtime" not in slave
    assert "--no-realtime" in pods["20-master.yaml"]["containers"][0]["args"]


def test_the_cpu_request_follows_the_cycle_and_the_stations():
    assert cpu_request(2_000_000, 1, 60) == "50m"  # the floor: 30 ms a second
    assert cpu_request(250_000, 1, 60) == "240m"
    assert cpu_request(250_000, 11, 60) == "400m"  # + 4 µs per further station, per cycle


def test_placement_is_the_configs_node_selector():
    pods = _pods(k8s_manifests(two_nodes(), TWO_NODES))
    assert pods["10-worker-0.yaml"]["nodeSelector"] == {"mlink.node": "rack-b"}
    assert pods["10-station-23.yaml"]["nodeSelector"] == {"mlink.node": "plc"}
    assert pods["20-master.yaml"]["nodeSelector"] == {"mlink.node": "plc"}
    args = pods["20-master.yaml"]["containers"][0]["args"]
    assert "0x21=192.0.2.2:47001" in args and "0x23=127.0.0.1:47003" in args
    worker = pods["10-worker-0.yaml"]["containers"][0]["args"]
    assert worker[worker.index("--allow-master") + 1] == "192.0.2.1"


def test_an_unplaced_config_constrains_no_pod_and_reaches_each_by_its_services_name():
    manifests = k8s_manifests(load_config(QUICKSTART), QUICKSTART.read_text(encoding="utf-8"), project="qs")
    for pod in _pods(manifests).values():
        assert "nodeSelector" not in pod and "affinity" not in pod  # the scheduler spreads them
    service = manifests["15-station-21-service.yaml"]
    assert service["kind"] == "Service" and service["metadata"]["name"] == "qs-station-21"
    assert service["spec"]["clusterIP"] == "None"  # headless: the name is the node address of the pod
    assert service["spec"]["selector"] == {"mlink-sim/worker": "station-21", "app.kubernetes.io/instance": "qs"}
    master_service = manifests["25-master-service.yaml"]["spec"]
    assert master_service["publishNotReadyAddresses"] is True and "ports" not in master_service
    args = manifests["20-master.yaml"]["spec"]["template"]["spec"]["containers"][0]["args"]
    assert "0x21=qs-station-21:47001" in args
    slave = manifests["10-station-21.yaml"]["spec"]["template"]["spec"]["containers"][0]["args"]
    assert slave[slave.index("--allow-master") + 1] == "qs-master"  # resolved again until it resolves


def test_a_placed_config_has_no_services_unless_the_master_serves_a_port():
    assert not any(m["kind"] == "Service" for m in k8s_manifests(two_nodes(), TWO_NODES).values())
    manifests = k8s_manifests(two_nodes(), TWO_NODES, project="two", web_port=8080, control_port=8081)
    ports = manifests["25-master-service.yaml"]["spec"]["ports"]
    assert [(p["name"], p["port"]) for p in ports] == [("web", 8080), ("control", 8081)]
    pod = manifests["20-master.yaml"]["spec"]["template"]["spec"]
    args = pod["containers"][0]["args"]
    assert args[args.index("--web") + 1] == "0.0.0.0:8080" and args[args.index("--web-token-file") + 1].endswith("token")
    assert args[args.index("--control") + 1] == "0.0.0.0:8081"
    assert {"name": "token", "secret": {"secretName": "two-token"}} in pod["volumes"]


def test_the_master_waits_for_every_station_and_writes_its_report_on_its_node():
    pod = _pods(k8s_manifests(two_nodes(), TWO_NODES, project="two"))["20-master.yaml"]
    (wait,) = pod["initContainers"]
    script = wait["command"][2]
    assert "until mlink-health 192.0.2.2:47001 --station 0x21" in script
    assert "until mlink-health 127.0.0.1:47003 --station 0x23" in script
    reports = next(v for v in pod["volumes"] if v["name"] == "reports")
    assert "emptyDir" in reports and "/reports/report.json" in pod["containers"][0]["args"]
    command = pod["containers"][0]["command"]
    assert command[:2] == ["sh", "-c"] and "sleep 600; exit $code" in command[2]  # kept for kubectl cp
    no_hold = _pods(k8s_manifests(two_nodes(), TWO_NODES, report_hold=0))["20-master.yaml"]
    assert no_hold["containers"][0]["command"] == ["mlink-sim"]


def test_the_master_keeps_its_exit_code_after_the_hold(tmp_path):
    """The hold script run by a real shell: the master's exit code is the container's."""
    pod = _pods(k8s_manifests(two_nodes(), TWO_NODES, report_hold=1))["20-master.yaml"]
    script = pod["containers"][0]["command"][2]
    fake = tmp_path / "mlink-sim"
    fake.write_text("#!/bin/sh\nexit 3\n")
    fake.chmod(0o755)
    env = {**os.environ, "PATH": f"{tmp_path}{os.pathsep}{os.environ['PATH']}"}
    result = subprocess.run(["sh", "-c", script, "mlink-sim", "master"], env=env, capture_output=True, text=True,
                            timeout=30)  # fmt: skip
    assert result.returncode == 3 and "exited 3" in result.stderr


def test_the_workers_are_probed_with_the_cheap_probe():
    pod = _pods(k8s_manifests(two_nodes(), TWO_NODES))["10-station-23.yaml"]
    container = pod["containers"][0]
    for probe in ("readinessProbe", "livenessProbe"):
        assert container[probe]["exec"]["command"][:2] == ["mlink-health", "127.0.0.1:47003"]


def test_cli_writes_one_file_per_object(tmp_path, validate):
    out = tmp_path / "k8s"
    r = CliRunner().invoke(compose_cmd, [str(QUICKSTART), "--k8s", "-o", str(out), "--duration", "20s"])
    assert r.exit_code == 0, r.output
    files = sorted(p.name for p in out.iterdir())
    assert files == ["00-config.yaml", "10-station-21.yaml", "10-station-22.yaml", "10-station-23.yaml",
                     "15-station-21-service.yaml", "15-station-22-service.yaml", "15-station-23-service.yaml",
                     "20-master.yaml", "25-master-service.yaml"]  # fmt: skip
    for path in out.iterdir():
        text = path.read_text(encoding="utf-8")
        assert text.startswith("# Generated by `mlink-sim compose ") and "&id" not in text  # no YAML aliases
        validate(yaml.safe_load(text))
    assert "kubectl cp" in (out / "20-master.yaml").read_text(encoding="utf-8")
    job = yaml.safe_load((out / "20-master.yaml").read_text(encoding="utf-8"))
    assert "20s" in job["spec"]["template"]["spec"]["containers"][0]["args"]


def test_cli_unwritable_directory_exits_2(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    r = CliRunner().invoke(compose_cmd, [str(QUICKSTART), "--k8s", "-o", str(blocker / "k8s")])
    assert r.exit_code == 2 and "cannot write" in r.output and "Traceback" not in r.output


def test_object_names_follow_rfc_1123_whatever_the_network_is_called(validate):
    assert object_prefix("Line 2_Press") == "line-2-press"
    assert object_prefix("___") == "mlink"
    assert len(object_prefix("x" * 100)) == 40
    config = two_nodes().model_copy(update={"network": two_nodes().network.model_copy(update={"name": "My_Line"})})
    manifests = k8s_manifests(config, TWO_NODES)
    assert manifests["20-master.yaml"]["metadata"]["name"] == "my-line-master"
    for manifest in manifests.values():
        validate(manifest)


def test_real_time_files_say_why_they_run_as_root(tmp_path):
    path = tmp_path / "two.toml"
    path.write_text(TWO_NODES, encoding="utf-8")
    r = CliRunner().invoke(compose_cmd, [str(path), "--k8s", "-o", str(tmp_path / "k8s"), "--web", "8080"])
    assert r.exit_code == 0, r.output
    header = (tmp_path / "k8s" / "10-worker-0.yaml").read_text(encoding="utf-8").split("\napiVersion")[0]
    assert "SYS_NICE (SCHED_FIFO) and IPC_LOCK (mlockall) only" in header
    job = (tmp_path / "k8s" / "20-master.yaml").read_text(encoding="utf-8")
    assert "kubectl create secret generic two-token" in job


def test_cli_k8s_options_do_not_apply_elsewhere():
    for args, message in ((["--web", "8080"], "--web does not apply"), (["--stack", "--control", "1"], "--control"),
                          (["--report-hold", "5"], "--report-hold does not apply")):
        r = CliRunner().invoke(compose_cmd, [str(QUICKSTART), *args])
        assert r.exit_code == 2 and message in r.output, (args, r.output)


def _kubectl_reaches_a_server(kubectl: str) -> bool:
    result = subprocess.run([kubectl, "version", "--request-timeout=5s"], capture_output=True, text=True, timeout=30)
    return result.returncode == 0


@pytest.mark.parametrize("which", ["quickstart", "two-nodes"])
def test_kubectl_dry_run_accepts_the_manifests(tmp_path, which):
    """``kubectl apply --dry-run=client`` reads the objects as a cluster would; it asks an API server for the
    kinds it knows, so it runs only where one answers."""
    kubectl = shutil.which("kubectl")
    if kubectl is None:
        pytest.skip("kubectl is not installed (apt-get install -y kubernetes-client)")
    if not _kubectl_reaches_a_server(kubectl):
        pytest.skip("kubectl reaches no API server: `kubectl apply --dry-run=client` needs one for the kinds it maps")
    path = QUICKSTART if which == "quickstart" else tmp_path / "two.toml"
    if which == "two-nodes":
        path.write_text(TWO_NODES, encoding="utf-8")
    r = CliRunner().invoke(compose_cmd, [str(path), "--k8s", "-o", str(tmp_path / "k8s")])
    assert r.exit_code == 0, r.output
    result = subprocess.run([kubectl, "apply", "--dry-run=client", "-f", str(tmp_path / "k8s")], capture_output=True,
                            text=True, timeout=60)  # fmt: skip
    assert result.returncode == 0, result.stderr
