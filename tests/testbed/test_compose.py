"""``mlink-sim compose``: the document validates against the Compose Specification schema and means what
docs/testbeds.md says (one container per station, a master gated on their health, read-only config, report
volume); the checked-in docker-compose.yml is the generator's output for configs/quickstart.toml."""

from __future__ import annotations

import json
import os
import shlex
import shutil
import subprocess
from pathlib import Path

import pytest
import yaml
from click.testing import CliRunner

from mlink_sim.cli.compose import compose_cmd
from mlink_sim.config import load_config
from mlink_sim.testbed import health
from mlink_sim.testbed.compose import (
    CONFIG_IN_CONTAINER,
    HEALTH_PORTABLE,
    HEALTH_START,
    probe_argv,
    compose_document,
    config_source_for,
    project_name,
    render_compose,
    service_name,
)

REPO = Path(__file__).resolve().parents[2]
SCHEMA_IN_SHARED = Path("shared") / "schemas" / "compose-spec.json"


def _schema_path() -> Path:
    """``../shared/schemas/compose-spec.json`` beside the checkout: the checkout as given (a symlinked clone keeps
    its own parent), as resolved, and the working directory's parent (CI runs from the clone's root)."""
    unresolved = Path(os.path.abspath(__file__)).parents[2]
    for base in (unresolved.parent, REPO.parent, Path.cwd().parent):
        if (base / SCHEMA_IN_SHARED).is_file():
            return base / SCHEMA_IN_SHARED
    return REPO.parent / SCHEMA_IN_SHARED


SCHEMA = _schema_path()
CONFIGS = sorted((REPO / "configs").glob("*.toml"))
QUICKSTART = REPO / "configs" / "quickstart.toml"
CHECKED_IN = REPO / "docker-compose.yml"
REGENERATE = "mlink-sim compose configs/quickstart.toml -o docker-compose.yml"


@pytest.fixture(scope="module")
def validator():
    if not SCHEMA.is_file():
        pytest.skip(f"Compose Specification schema not found at {SCHEMA} (../shared/schemas/compose-spec.json)")
    jsonschema = pytest.importorskip("jsonschema", reason="jsonschema is a test dependency: pip install -e '.[test]'")
    schema = json.loads(SCHEMA.read_text(encoding="utf-8"))
    # the file declares draft-07 (as "https://json-schema.org/draft-07/schema", a URL jsonschema does not know)
    jsonschema.Draft7Validator.check_schema(schema)
    return jsonschema.Draft7Validator(schema)


def _errors(validator, document) -> list[str]:
    return [f"{'/'.join(map(str, e.absolute_path))}: {e.message}" for e in validator.iter_errors(document)]


def test_configs_exist():
    assert QUICKSTART in CONFIGS and len(CONFIGS) >= 2


@pytest.mark.parametrize("path", CONFIGS, ids=lambda p: p.stem)
def test_document_validates_against_compose_spec(validator, path):
    config = load_config(path)
    text = render_compose(config, path, REPO / "compose.yaml", command="mlink-sim compose x")
    document = yaml.safe_load(text)  # what docker compose reads: the YAML, not our dict
    assert _errors(validator, document) == []
    # with every option set too
    full = compose_document(config, image="registry.example/mlink-sim:1.0", station_port=40000, report_dir="/out",
                            duration="20s", asserts=("rtt.p99 < 2ms", "missed == 0"), start_interval=True)
    assert _errors(validator, full) == []


def test_the_schema_rejects_what_compose_would_reject(validator):
    doc = compose_document(load_config(QUICKSTART))
    doc["services"]["master"]["depends_on"]["station-21"]["condition"] = "healthy"
    doc["services"]["station-22"]["healthcheck"]["interval"] = 2  # must be a duration string
    errors = _errors(validator, doc)
    assert len(errors) >= 1 and any("depends_on" in e or "station-22" in e for e in errors)


@pytest.mark.parametrize("path", CONFIGS, ids=lambda p: p.stem)
def test_one_service_per_station_plus_master_gated_on_health(path):
    config = load_config(path)
    doc = compose_document(config, config_source="./net.toml")
    names = [service_name(st.address) for st in config.station]
    assert list(doc["services"]) == [*names, "master"]
    assert len(set(names)) == len(names)
    master = doc["services"]["master"]
    assert master["depends_on"] == {n: {"condition": "service_healthy"} for n in names}
    assert master["restart"] == "no"
    assert doc["networks"] == {"mlink": {"driver": "bridge"}}
    for svc in doc["services"].values():
        assert svc["networks"] == ["mlink"]
        assert svc["image"] == "mlink-sim:latest"


def _probe_in(test: list[str]) -> list[str]:
    """The ``mlink-health …`` argv of a CMD healthcheck."""
    assert test[0] == "CMD"
    return test[1:]


def test_station_service_listens_on_all_addresses_and_is_probed():
    config = load_config(QUICKSTART)
    doc = compose_document(config, station_port=47001)
    for st in config.station:
        svc = doc["services"][service_name(st.address)]
        cmd = svc["command"]
        assert cmd[:5] == ["slave", "--config", CONFIG_IN_CONTAINER, "--only", f"0x{st.address:02X}"]
        assert cmd[cmd.index("--endpoint") + 1] == f"0x{st.address:02X}=0.0.0.0:47001"
        assert cmd[cmd.index("--host-stalls") + 1] == "absorb"  # the master is ours: docs/timing.md
        assert cmd[cmd.index("--allow-master") + 1] == "master"  # only the master's container changes a station
        probe = _probe_in(svc["healthcheck"]["test"])
        assert probe == probe_argv(st, 47001)
        assert probe[:2] == ["mlink-health", "127.0.0.1:47001"]
        assert probe[probe.index("--station") + 1] == f"0x{st.address:02X}"
        assert probe[probe.index("--link") + 1] == st.link.name.lower()
        assert probe[probe.index("--frame-size") + 1] == str(st.frame_size)
        hc = svc["healthcheck"]
        assert {"interval", "timeout", "retries", "start_period"} <= set(hc)
        assert "start_interval" not in hc  # docker-compose 1.29 rejects it
    # quickstart: 0x23 is the SI-ET3 on MECHATROLINK-III with 64-byte frames
    probe = _probe_in(doc["services"]["station-23"]["healthcheck"]["test"])
    assert probe[probe.index("--link") + 1 :][:3] == ["ml3", "--frame-size", "64"]


def test_master_command_reaches_every_station_by_service_name():
    config = load_config(QUICKSTART)
    doc = compose_document(config, duration="20s", asserts=("rtt.p99 < 2ms", "missed == 0"), report_dir="/out")
    cmd = doc["services"]["master"]["command"]
    assert cmd[:2] == ["master", CONFIG_IN_CONTAINER]
    endpoints = [cmd[i + 1] for i, a in enumerate(cmd) if a == "--endpoint"]
    assert endpoints == ["0x21=station-21:47001", "0x22=station-22:47001", "0x23=station-23:47001"]
    assert cmd[cmd.index("--report") + 1] == "/out/report.json"
    assert "--no-status" in cmd
    assert cmd[cmd.index("--duration") + 1] == "20s"
    assert [cmd[i + 1] for i, a in enumerate(cmd) if a == "--assert"] == ["rtt.p99 < 2ms", "missed == 0"]


def test_config_mounted_read_only_everywhere_and_report_on_named_volume():
    config = load_config(QUICKSTART)
    doc = compose_document(config, config_source="./configs/quickstart.toml")
    ro = {"type": "bind", "source": "./configs/quickstart.toml", "target": CONFIG_IN_CONTAINER, "read_only": True}
    for svc in doc["services"].values():
        assert ro in svc["volumes"]
    master_volumes = doc["services"]["master"]["volumes"]
    assert {"type": "volume", "source": "reports", "target": "/reports"} in master_volumes
    assert doc["volumes"] == {"reports": {}}
    for name, svc in doc["services"].items():
        if name != "master":
            assert all(v.get("read_only") for v in svc["volumes"]), "stations write nothing"


def test_document_is_deterministic_and_key_order_fixed():
    config = load_config(QUICKSTART)
    a = render_compose(config, QUICKSTART, CHECKED_IN, command=REGENERATE)
    b = render_compose(load_config(QUICKSTART), QUICKSTART, CHECKED_IN, command=REGENERATE)
    assert a == b
    doc = yaml.safe_load(a)
    assert list(doc) == ["services", "networks", "volumes"]  # no top-level name: docker-compose 1.29 rejects it
    assert "docker compose -p quickstart -f THIS_FILE up" in a


def test_project_name_is_a_valid_compose_name(tmp_path):
    text = QUICKSTART.read_text().replace('name = "quickstart"', 'name = "My Test Bench #1"')
    (tmp_path / "n.toml").write_text(text)
    assert project_name(load_config(tmp_path / "n.toml").network.name) == "my-test-bench-1"
    assert "-p my-test-bench-1 " in render_compose(load_config(tmp_path / "n.toml"), tmp_path / "n.toml")


def test_realtime_master_is_root_with_sys_nice_and_a_budget_only_on_request(validator):
    config = load_config(QUICKSTART)
    plain = compose_document(config)
    assert not {"user", "cap_add", "cpu_rt_runtime"} & set(plain["services"]["master"])
    rt = compose_document(config, realtime_budget_us=400000)
    master = rt["services"]["master"]
    assert master["user"] == "0:0" and master["cap_add"] == ["SYS_NICE", "IPC_LOCK"]
    assert master["cpu_rt_runtime"] == 400000
    for name, svc in rt["services"].items():  # the stations keep the image's non-root user
        if name != "master":
            assert "user" not in svc and "cap_add" not in svc
    assert "cpu_rt_runtime" not in compose_document(config, realtime_budget_us=0)["services"]["master"]
    assert _errors(validator, rt) == []
    with pytest.raises(ValueError, match="budget"):
        compose_document(config, realtime_budget_us=-1)


def test_health_timing_portable_by_default_start_interval_on_request():
    config = load_config(QUICKSTART)
    portable = compose_document(config)["services"]["station-21"]["healthcheck"]
    fast = compose_document(config, start_interval=True)["services"]["station-21"]["healthcheck"]
    assert {k: v for k, v in portable.items() if k != "test"} == HEALTH_PORTABLE.as_compose()
    assert {k: v for k, v in fast.items() if k != "test"} == HEALTH_START.as_compose()
    assert fast["start_interval"] == "1s" and fast["interval"] == "30s"
    assert fast["test"] == portable["test"]


def test_dollar_signs_survive_compose_interpolation():
    doc = compose_document(load_config(QUICKSTART), asserts=("rtt.p99 < $LIMIT",))
    assert "rtt.p99 < $$LIMIT" in doc["services"]["master"]["command"]


def test_bad_options_are_value_errors():
    config = load_config(QUICKSTART)
    with pytest.raises(ValueError, match="port"):
        compose_document(config, station_port=0)
    with pytest.raises(ValueError, match="absolute"):
        compose_document(config, report_dir="reports")


def test_config_source_is_relative_under_the_compose_files_directory_else_absolute(tmp_path):
    (tmp_path / "configs").mkdir()
    cfg = tmp_path / "configs" / "n.toml"
    cfg.touch()
    assert config_source_for(cfg, tmp_path / "compose.yaml") == "./configs/n.toml"
    (tmp_path / "out").mkdir()
    assert config_source_for(cfg, tmp_path / "out" / "compose.yaml") == str(cfg)  # not ../: absolute
    assert config_source_for(cfg, None) == str(cfg)  # stdout: where it lands is not known


def test_a_compose_file_runs_from_any_directory(tmp_path, monkeypatch):
    """The file written to stdout and saved elsewhere, read by Compose from another working directory: the config's
    mount still names the config."""
    cfg = tmp_path / "configs" / "n.toml"
    cfg.parent.mkdir()
    cfg.write_text(QUICKSTART.read_text(encoding="utf-8"), encoding="utf-8")
    monkeypatch.chdir(tmp_path / "configs")
    r = CliRunner().invoke(compose_cmd, ["n.toml"])
    assert r.exit_code == 0, r.output
    (tmp_path / "elsewhere").mkdir()
    (tmp_path / "elsewhere" / "compose.yaml").write_text(r.output, encoding="utf-8")
    monkeypatch.chdir(tmp_path)
    doc = yaml.safe_load(r.output)
    assert doc["services"]["master"]["volumes"][0]["source"] == str(cfg)
    compose = shutil.which("docker-compose")
    if compose is None:
        return
    out = subprocess.run([compose, "-f", "elsewhere/compose.yaml", "config"], capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    assert yaml.safe_load(out.stdout)["services"]["master"]["volumes"][0]["source"] == str(cfg)


def test_checked_in_docker_compose_yml_is_up_to_date():
    assert CHECKED_IN.is_file(), f"missing {CHECKED_IN}; run: {REGENERATE}"
    fresh = render_compose(load_config(QUICKSTART), QUICKSTART, CHECKED_IN, command=REGENERATE)
    assert CHECKED_IN.read_text(encoding="utf-8") == fresh, f"docker-compose.yml is stale; run: {REGENERATE}"


def test_checked_in_file_validates(validator):
    assert _errors(validator, yaml.safe_load(CHECKED_IN.read_text(encoding="utf-8"))) == []


# -- the commands in the document parse with the real CLI (the contract with slave/master/probe) ----------


def _parse(cmd, args):
    ctx = cmd.make_context(cmd.name, list(args), resilient_parsing=False)
    return ctx.params


def test_service_commands_parse_with_the_cli():
    from mlink_sim.cli.network import master_cmd
    from mlink_sim.cli.probe import probe_cmd
    from mlink_sim.cli.slave import slave_cmd

    doc = compose_document(load_config(QUICKSTART), duration="20s", asserts=("missed == 0",))
    for name, svc in doc["services"].items():
        command = svc["command"]
        if name == "master":
            assert command[0] == "master"
            params = _parse(master_cmd, command[1:])
            assert params["status"] is False and params["report"] == "/reports/report.json"
            assert len(params["endpoints"]) == 3
        else:
            assert command[0] == "slave"
            params = _parse(slave_cmd, command[1:])
            assert params["config_path"] == CONFIG_IN_CONTAINER
            assert params["only"] == "0x" + name.removeprefix("station-").upper()
            probe = _probe_in(svc["healthcheck"]["test"])
            assert probe[0] == "mlink-health"
            host, port, station, attempts, _ = health._parse(probe[1:])
            assert (host, port, station) == ("127.0.0.1", 47001, int(params["only"], 16))
            assert len(attempts) == 1
            # the same options mean the same to `mlink-sim probe`
            _parse(probe_cmd, probe[1:])


# -- the CLI -----------------------------------------------------------------------------------------------


def test_cli_writes_stdout(monkeypatch):
    monkeypatch.chdir(REPO)
    result = CliRunner().invoke(compose_cmd, ["configs/quickstart.toml"])
    assert result.exit_code == 0, result.output
    doc = yaml.safe_load(result.output)
    assert doc["services"]["station-21"]["volumes"][0]["source"] == str(REPO / "configs" / "quickstart.toml")


def test_cli_regenerates_the_checked_in_file_byte_for_byte(monkeypatch, tmp_path):
    # the same command line, run in a copy of the tree, gives the same bytes
    (tmp_path / "configs").mkdir()
    (tmp_path / "configs" / "quickstart.toml").write_bytes(QUICKSTART.read_bytes())
    monkeypatch.chdir(tmp_path)
    result = CliRunner().invoke(compose_cmd, shlex.split(REGENERATE)[2:])
    assert result.exit_code == 0, result.output
    assert (tmp_path / "docker-compose.yml").read_text(encoding="utf-8") == CHECKED_IN.read_text(encoding="utf-8")


def test_cli_writes_file_atomically_with_options(tmp_path):
    out = tmp_path / "sub" / "compose.yaml"
    out.parent.mkdir()
    result = CliRunner().invoke(compose_cmd, [str(QUICKSTART), "-o", str(out), "--image", "example/mlink:2",
                                              "--port", "40001", "--duration", "5s", "--assert", "missed == 0",
                                              "--realtime-master", "300000"])
    assert result.exit_code == 0, result.output
    assert sorted(p.name for p in out.parent.iterdir()) == ["compose.yaml"]  # no temp file left behind
    doc = yaml.safe_load(out.read_text())
    assert doc["services"]["master"]["image"] == "example/mlink:2"
    assert "0x21=station-21:40001" in doc["services"]["master"]["command"]
    source = doc["services"]["station-21"]["volumes"][0]["source"]
    assert (out.parent / source).resolve() == QUICKSTART.resolve()
    assert "--port 40001" in out.read_text().splitlines()[0]
    assert "--realtime-master 300000" in out.read_text().splitlines()[0]
    assert doc["services"]["master"]["cpu_rt_runtime"] == 300000


def test_cli_bad_config_exits_2_with_the_config_error(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text('[network]\ntransmission_cycle = "2ms"\n[[station]]\naddress = 0x21\ncard = "si-t9"\n')
    result = CliRunner().invoke(compose_cmd, [str(bad)])
    assert result.exit_code == 2
    assert "mlink-sim compose:" in result.output and "bad.toml" in result.output and "card" in result.output
    assert "Traceback" not in result.output


def test_cli_missing_config_exits_2(tmp_path):
    result = CliRunner().invoke(compose_cmd, [str(tmp_path / "nope.toml")])
    assert result.exit_code == 2
    assert "no such file" in result.output


@pytest.mark.parametrize("args", [["--duration", "soon"], ["--report-dir", "relative"], ["--port", "0"]])
def test_cli_bad_option_exits_2(args):
    result = CliRunner().invoke(compose_cmd, [str(QUICKSTART), *args])
    assert result.exit_code == 2, result.output


def test_cli_unwritable_output_exits_2(tmp_path):
    result = CliRunner().invoke(compose_cmd, [str(QUICKSTART), "-o", str(tmp_path / "missing-dir" / "c.yaml")])
    assert result.exit_code == 2
    assert "cannot write" in result.output


# -- the Compose implementations themselves (when installed; `config` needs no engine) ------------------------


def _compose_config(argv: list[str], document: dict, tmp_path: Path) -> subprocess.CompletedProcess[str]:
    (tmp_path / "quickstart.toml").write_bytes(QUICKSTART.read_bytes())
    path = tmp_path / "compose.yaml"
    path.write_text(yaml.safe_dump(document, sort_keys=False))
    return subprocess.run([*argv, "-p", "mlinktest", "-f", str(path), "config", "-q"], capture_output=True, text=True,
                          timeout=60, cwd=tmp_path)  # fmt: skip


def test_docker_compose_1_29_accepts_the_file_and_rejects_start_interval(tmp_path):
    """Debian's docker-compose 1.29 validates against its own schema: no top-level name, no start_interval."""
    if shutil.which("docker-compose") is None:
        pytest.skip("docker-compose is not installed (apt-get install -y docker-compose)")
    config = load_config(QUICKSTART)
    ok = _compose_config(["docker-compose"], compose_document(config, config_source="./quickstart.toml"), tmp_path)
    assert ok.returncode == 0, ok.stderr
    fast = compose_document(config, config_source="./quickstart.toml", start_interval=True)
    rejected = _compose_config(["docker-compose"], fast, tmp_path)
    assert rejected.returncode != 0 and "start_interval" in rejected.stderr
    named = {"name": "quickstart", **compose_document(config, config_source="./quickstart.toml")}
    assert _compose_config(["docker-compose"], named, tmp_path).returncode != 0
    realtime = compose_document(config, config_source="./quickstart.toml", realtime_budget_us=400000)
    accepted = _compose_config(["docker-compose"], realtime, tmp_path)
    assert accepted.returncode == 0, accepted.stderr


def test_compose_v2_accepts_both_timings(tmp_path):
    docker = shutil.which("docker")
    if docker is None or subprocess.run([docker, "compose", "version"], capture_output=True).returncode != 0:
        pytest.skip("Compose v2 (the docker compose plugin) is not installed")
    config = load_config(QUICKSTART)
    for start_interval in (False, True):
        doc = compose_document(config, config_source="./quickstart.toml", start_interval=start_interval)
        result = _compose_config([docker, "compose"], doc, tmp_path)
        assert result.returncode == 0, result.stderr
