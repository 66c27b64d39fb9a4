"""The Dockerfile without a Docker engine: its instructions, its build context, and its HEALTHCHECK command run
through /bin/sh exactly as the engine would run it, with mlink-health made as the Dockerfile makes it."""

from __future__ import annotations

import json
import os
import re
import shutil
import socket
import subprocess
import sys
import time
import tomllib
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
DOCKERFILE = REPO / "Dockerfile"
DOCKERIGNORE = REPO / ".dockerignore"
BIN = Path(sys.executable).parent


def _instructions() -> list[tuple[str, str]]:
    """(INSTRUCTION, arguments) with continuation lines joined and comments dropped."""
    text = re.sub(r"\\\n", " ", DOCKERFILE.read_text(encoding="utf-8"))
    out = []
    for line in text.splitlines():
        line = line.strip()
        if line and not line.startswith("#"):
            word, _, rest = line.partition(" ")
            out.append((word.upper(), rest.strip()))
    return out


def _healthcheck_shell() -> str:
    [args] = [a for ins, a in _instructions() if ins == "HEALTHCHECK"]
    return args.split(" CMD ", 1)[1].strip()


def test_base_stages_user_install_entrypoint():
    ins = _instructions()
    words = [w for w, _ in ins]
    assert ins[0] == ("ARG", "BASE=python:3.11-slim")  # before the first FROM: both stages may use it
    assert [a for w, a in ins if w == "FROM"] == ["${BASE} AS build", "${BASE}"]
    runs = " ".join(a for w, a in ins if w == "RUN")
    assert "pip install --no-index --find-links /tmp/deps -r /tmp/deps/requirements.txt" in runs  # WHEELS set
    assert "pip install --no-index --no-deps /tmp/project/mlink_sim-*.whl" in runs
    assert "pip install /tmp/src" in runs  # WHEELS empty: from source with the index
    assert ("COPY", "--from=build /opt/mlink-sim /opt/mlink-sim") in ins
    users = [a for w, a in ins if w == "USER"]
    assert users and users[-1] not in ("root", "0", "0:0")
    assert words.index("USER") < words.index("ENTRYPOINT")
    assert ("ENTRYPOINT", '["mlink-sim"]') in ins
    assert "EXPOSE" not in words  # UDP ports come from the command


def test_healthcheck_asks_the_station():
    [args] = [a for ins, a in _instructions() if ins == "HEALTHCHECK"]
    for flag in ("--interval=", "--timeout=", "--start-period=", "--retries="):
        assert flag in args
    assert _healthcheck_shell().count("mlink-health ") == 1 and "mlink-sim" not in _healthcheck_shell()


def test_build_context_has_what_the_dockerfile_copies_and_not_the_host_state():
    pyproject = tomllib.loads((REPO / "pyproject.toml").read_text())
    copied = []
    for word, args in _instructions():
        if word == "COPY" and not args.startswith("--from="):
            copied += [src for src in args.split()[:-1] if not src.startswith("${")]  # ${WHEELS:+…}: optional
    assert pyproject["project"]["readme"] in copied  # setuptools needs the readme to build
    for src in copied:
        assert (REPO / src).exists(), src
    ignored = {line.strip() for line in DOCKERIGNORE.read_text().splitlines() if line.strip()}
    assert {".venv", ".git", "**/__pycache__", ".pytest_cache"} <= ignored
    assert not set(copied) & ignored


def _mlink_health(bin_dir: Path) -> Path:
    """/opt/mlink-sim/bin/mlink-health as the Dockerfile's RUN writes it: our interpreter with -IS as the shebang,
    the directory of health.py first on sys.path (so its .pyc is used), then its main()."""
    [run] = [a for w, a in _instructions() if w == "RUN" and "mlink-health" in a]
    assert "printf '#!/opt/mlink-sim/bin/python3 -IS\\nimport sys\\nsys.path[0] = \"%s\"" in run
    assert "from health import main\\nsys.exit(main())" in run and "site-packages/mlink_sim/testbed >" in run
    path = bin_dir / "mlink-health"
    path.write_text(f"#!{sys.executable} -IS\nimport sys\nsys.path[0] = \"{REPO / 'mlink_sim' / 'testbed'}\"\n"
                    "from health import main\nsys.exit(main())\n")
    path.chmod(0o755)
    return path


def _run_healthcheck(env: dict[str, str], bin_dir: Path) -> subprocess.CompletedProcess[str]:
    sh = shutil.which("sh")
    if sh is None:
        pytest.skip("no /bin/sh")
    _mlink_health(bin_dir)
    full = {"PATH": f"{bin_dir}{os.pathsep}{os.environ.get('PATH', '')}", "MLINK_PROBE_TARGET": "",
            "MLINK_PROBE_STATION": "", "MLINK_PROBE_ARGS": "", **env}  # fmt: skip
    return subprocess.run([sh, "-c", _healthcheck_shell()], env=full, capture_output=True, text=True, timeout=30)


def test_healthcheck_passes_when_no_target_is_set(tmp_path):
    assert _run_healthcheck({}, tmp_path).returncode == 0


def test_healthcheck_fails_when_the_station_does_not_answer(tmp_path):
    env = {"MLINK_PROBE_STATION": "0x21", "MLINK_PROBE_ARGS": "--link ml2 --frame-size 32 --timeout 0.3"}
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:  # a bound port that never answers
        s.bind(("127.0.0.1", 0))
        env["MLINK_PROBE_TARGET"] = f"127.0.0.1:{s.getsockname()[1]}"
        result = _run_healthcheck(env, tmp_path)
        assert result.returncode == 1, result.stderr
        assert "no valid NOP answer" in result.stderr


@pytest.mark.e2e
def test_healthcheck_passes_against_a_live_station(tmp_path):
    if not (BIN / "mlink-sim").exists():
        pytest.skip(f"mlink-sim is not installed next to {sys.executable}")
    proc = subprocess.Popen([str(BIN / "mlink-sim"), "slave", "--card", "si-t3", "--station", "0x21", "--listen",
                             "127.0.0.1:0", "--ready-json"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert proc.stdout is not None
        line = proc.stdout.readline()
        assert line, proc.stderr.read() if proc.stderr else ""
        port = json.loads(line)["stations"][0]["port"]
        t0 = time.monotonic()
        result = _run_healthcheck({"MLINK_PROBE_TARGET": f"127.0.0.1:{port}", "MLINK_PROBE_STATION": "0x21",
                                   "MLINK_PROBE_ARGS": "--link ml2 --frame-size 32"}, tmp_path)
        assert result.returncode == 0, result.stderr
        assert "answered (ml2 32-byte)" in result.stdout
        assert time.monotonic() - t0 < 5
    finally:
        proc.terminate()
        proc.wait(timeout=10)
