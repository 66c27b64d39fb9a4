"""``mlink-sim compose --k8s -o DIR``: every manifest validates against the Kubernetes schemas offline
(kubernetes-validate) and means what docs/testbeds.md ("More than one machine") says: a Deployment per slave
worker, the master as a Job, hostNetwork, Guaranteed QoS with whole CPUs, SYS_NICE/IPC_LOCK, the config's
placement."""

from __future__ import annotations

import os

import pytest
import yaml
from click.testing import CliRunner

from mlink_sim.cli.compose import compose_cmd
from mlink_sim.config import load_config
from mlink_sim.testbed.k8s import HOSTNAME_KEY, k8s_manifests, object_prefix

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

    def check(manifest):
        kubernetes_validate.validate(manifest, KUBERNETES_VERSION, strict=True)  # its schemas ship with the package

    return check


def _pods(manifests):
    return {name: m["spec"]["template"]["spec"] for name, m in manifests.items() if m["kind"] != "ConfigMap"}


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


def test_every_pod_is_guaranteed_with_whole_cpus_on_the_hosts_network_with_real_time_rights():
    pods = _pods(k8s_manifests(two_nodes(), TWO_NODES))
    for name, pod in pods.items():
        assert pod["hostNetwork"] is True and pod["dnsPolicy"] == "ClusterFirstWithHostNet", name
        for container in _containers(pod):
            res = container["resources"]
            assert res["requests"] == res["limits"], name  # Guaranteed QoS: every container, init ones too
            assert res["requests"]["cpu"].isdigit(), name  # whole CPUs: the static CPU manager's exclusive ones
        main = pod["containers"][0]
        assert main["securityContext"]["capabilities"]["add"] == ["SYS_NICE", "IPC_LOCK"]
        assert "--cpus" not in main["args"]  # the kubelet chooses the CPUs
    assert pods["10-worker-0.yaml"]["containers"][0]["resources"]["limits"]["cpu"] == "2"  # cpus = [0, 1]
    assert pods["20-master.yaml"]["containers"][0]["resources"]["limits"]["cpu"] == "1"


def test_placement_is_the_configs_node_selector():
    pods = _pods(k8s_manifests(two_nodes(), TWO_NODES))
    assert pods["10-worker-0.yaml"]["nodeSelector"] == {"mlink.node": "rack-b"}
    assert pods["10-station-23.yaml"]["nodeSelector"] == {"mlink.node": "plc"}
    assert pods["20-master.yaml"]["nodeSelector"] == {"mlink.node": "plc"}
    args = pods["20-master.yaml"]["containers"][0]["args"]
    assert "0x21=192.0.2.2:47001" in args and "0x23=127.0.0.1:47003" in args
    worker = pods["10-worker-0.yaml"]["containers"][0]["args"]
    assert worker[worker.index("--allow-master") + 1] == "192.0.2.1"


def test_an_unplaced_config_keeps_every_pod_on_one_node_by_pod_affinity():
    pods = _pods(k8s_manifests(load_config(QUICKSTART), QUICKSTART.read_text(encoding="utf-8"), project="qs"))
    for pod in pods.values():
        assert "nodeSelector" not in pod
        (term,) = pod["affinity"]["podAffinity"]["requiredDuringSchedulingIgnoredDuringExecution"]
        assert term == {"labelSelector": {"matchLabels": {"app.kubernetes.io/instance": "qs"}},
                        "topologyKey": HOSTNAME_KEY}  # fmt: skip


def test_the_master_waits_for_every_station_and_writes_its_report_on_its_node():
    pod = _pods(k8s_manifests(two_nodes(), TWO_NODES, project="two"))["20-master.yaml"]
    (wait,) = pod["initContainers"]
    script = wait["command"][2]
    assert "until mlink-health 192.0.2.2:47001 --station 0x21" in script
    assert "until mlink-health 127.0.0.1:47003 --station 0x23" in script
    reports = next(v for v in pod["volumes"] if v["name"] == "reports")
    assert reports["hostPath"] == {"path": "/var/lib/mlink-sim/two", "type": "DirectoryOrCreate"}
    assert "/reports/report.json" in pod["containers"][0]["args"]


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
                     "20-master.yaml"]  # fmt: skip
    for path in out.iterdir():
        text = path.read_text(encoding="utf-8")
        assert text.startswith("# Generated by `mlink-sim compose ") and "&id" not in text  # no YAML aliases
        validate(yaml.safe_load(text))
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
