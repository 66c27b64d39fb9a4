"""mlink_sim._accel: the compiled cores (mypyc) behave byte for byte as the pure-Python ones, the switch and the
report of which runs (docs/architecture.md, "Compiled cores (mypyc)").

The equivalence tests start two workers (tests/_accel_worker.py), one with ``MLINK_PURE=1`` and one with the
compiled modules, send both the same hypothesis-drawn inputs and compare their answers exactly (floats as repr,
bytes as hex). Without a compiled build they are skipped, unless ``MLINK_REQUIRE_COMPILED=1`` (scripts/test sets
it when the build compiled), which turns the skip into a failure.
"""

from __future__ import annotations

import hashlib
import importlib.machinery
import json
import os
import shutil
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mlink_sim import _accel

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent


def _env(pure: bool) -> dict[str, str]:
    return {**os.environ, "MLINK_PURE": "1" if pure else "0"}


class Worker:
    """tests/_accel_worker.py in a subprocess: one JSON request in, one JSON answer out."""

    def __init__(self, pure: bool) -> None:
        self.proc = subprocess.Popen([sys.executable, str(HERE / "_accel_worker.py")], env=_env(pure),
                                     stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, cwd=ROOT)
        hello = json.loads(self._line())
        self.mode, self.reason = hello["mode"], hello["reason"]

    def _line(self) -> str:
        assert self.proc.stdout is not None
        line = self.proc.stdout.readline()
        if not line:
            raise RuntimeError(f"the worker exited ({self.proc.wait()})")
        return line

    def ask(self, request: dict[str, Any]) -> Any:
        assert self.proc.stdin is not None
        self.proc.stdin.write(json.dumps(request) + "\n")
        self.proc.stdin.flush()
        return json.loads(self._line())

    def close(self) -> None:
        assert self.proc.stdin is not None
        self.proc.stdin.close()
        self.proc.wait(timeout=30)


@pytest.fixture(scope="module")
def sides() -> Iterator[tuple[Worker, Worker]]:
    pure, compiled = Worker(pure=True), Worker(pure=False)
    try:
        assert pure.mode == "pure"
        if compiled.mode != "compiled":
            message = f"the compiled cores are not available here: {compiled.reason}"
            if os.environ.get("MLINK_REQUIRE_COMPILED", "") not in ("", "0"):
                pytest.fail(message + " (MLINK_REQUIRE_COMPILED is set)")
            pytest.skip(message)
        yield pure, compiled
    finally:
        pure.close()
        compiled.close()


def same(sides: tuple[Worker, Worker], request: dict[str, Any]) -> Any:
    pure, compiled = sides
    a, b = pure.ask(request), compiled.ask(request)
    assert a == b, f"compiled and pure cores differ on {request}"
    return a


#: examples per equivalence test; MLINK_ACCEL_EXAMPLES=1000 for a longer search
_N = int(os.environ.get("MLINK_ACCEL_EXAMPLES", "25"))
_EQ = settings(max_examples=_N, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture],
               database=None)

# ---------------------------------------------------------------------------------------------- drive model
_steps = st.lists(st.tuples(
    st.integers(1_000, 50_000_000),                     # ns to the next command (1 µs .. 50 ms)
    st.booleans(), st.booleans(),                        # forward, reverse
    st.integers(0, 12_000),                              # frequency reference, 0.01 Hz (o1-03 = 0)
    st.booleans(), st.booleans(),                        # external baseblock, fault reset
    st.integers(-1_500, 1_500), st.integers(0, 1_500),  # torque reference / limit, 0.1 %
), min_size=1, max_size=60)
_loads = st.tuples(st.sampled_from(["inertia", "constant", "fan", "friction"]),
                   st.one_of(st.none(), st.floats(0.005, 2.0)), st.one_of(st.none(), st.floats(0.0, 40.0)),
                   st.one_of(st.none(), st.floats(0.0, 0.05)))
_a1000 = st.fixed_dictionaries({}, optional={
    "C1-01": st.integers(1, 300), "C1-02": st.integers(1, 300),  # accel / decel time, 0.1 s
    "C2-01": st.integers(0, 100), "C2-02": st.integers(0, 100),  # S-curve, 0.01 s
    "L3-04": st.integers(0, 2), "L3-01": st.integers(0, 1),     # stall prevention
    "b1-03": st.integers(0, 1),                                  # stop: ramp / coast
    "b3-01": st.integers(0, 1),                                  # speed search at start
    "d5-01": st.integers(0, 1),                                  # torque control
})


@given(load=_loads, params=_a1000, steps=_steps)
@_EQ
def test_drive_model_equal(sides, load, params, steps):
    same(sides, {"case": "drive", "family": "a1000", "load": load, "params": params, "steps": steps})


@given(load=_loads, steps=_steps)
@_EQ
def test_drive_model_v7_equal(sides, load, steps):
    same(sides, {"case": "drive", "family": "v7", "load": load, "params": {"n003": 1, "n004": 1}, "steps": steps})


# ---------------------------------------------------------------------------------------------- master and cards
@given(card=st.sampled_from(["si-t3", "si-t-v7", "si-et3"]), stations=st.integers(1, 3),
       cycles=st.integers(50, 400), seed=st.integers(0, 2**32), loss=st.sampled_from([0.0, 0.01, 0.05]),
       flip=st.sampled_from([0.0, 0.01, 0.05]),
       controls=st.lists(st.tuples(st.integers(1, 400), st.booleans(), st.integers(0, 6000)), max_size=4))
@settings(max_examples=max(1, _N * 3 // 5), deadline=None, database=None)
def test_exchange_equal(sides, card, stations, cycles, seed, loss, flip, controls):
    """Master core and cards over a lossy line that flips bits: every datagram both ways (sha256), the master's
    events and views and the cards' snapshots are the same."""
    same(sides, {"case": "exchange", "card": card, "stations": stations, "cycles": cycles, "seed": seed,
                 "loss": loss, "flip": flip, "controls": controls})


@given(card=st.sampled_from(["si-t3", "si-t-v7", "si-et3"]), data=st.binary(max_size=120))
@_EQ
def test_datagram_equal(sides, card, data):
    """Any bytes into a card in phase 3 and into the master: the same response, decode and counters."""
    same(sides, {"case": "datagram", "card": card, "data": data.hex()})


# ---------------------------------------------------------------------------------------------- the switch
def _probe(env: dict[str, str]) -> list[str]:
    code = ("import mlink_sim, mlink_sim._accel as a, mlink_sim.drive.integrate as m;"
            "print(a.MODE); print(a.describe()); print(m.__file__)")
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True, cwd=ROOT)
    return out.stdout.splitlines()


def test_mlink_pure_forces_the_source_modules():
    mode, line, path = _probe(_env(pure=True))
    assert (mode, line) == ("pure", "pure Python (MLINK_PURE is set)")
    assert path.endswith("integrate.py")


def test_the_compiled_modules_load_when_built():
    mode, line, path = _probe(_env(pure=False))
    if mode != "compiled":
        assert line.startswith("pure Python (")  # says why
        pytest.skip(f"not built here: {line}")
    assert line == f"compiled (mypyc, {len(_accel.COMPILED_MODULES)} modules; C, {len(_accel.C_EXTENSIONS)})"
    assert not path.endswith(".py")


def test_version_says_which_cores_run():
    out = subprocess.run([sys.executable, "-m", "mlink_sim", "--version"], env=_env(pure=True),
                         capture_output=True, text=True, check=True, cwd=ROOT)
    assert "cores: pure Python (MLINK_PURE is set)" in out.stdout


def test_pure_requested():
    assert not _accel.pure_requested({})
    assert not _accel.pure_requested({"MLINK_PURE": "0"})
    assert _accel.pure_requested({"MLINK_PURE": "1"})


#: compiled outside the sans-I/O cores (no socket, no wall clock either): the virtual clock's per-event path, a
#: slave worker's per-read path (its clock handed in), the metrics' recorder and the capture writer's per-datagram
#: loop
_PER_EXCHANGE = {"mlink_sim.aio.virtual.vqueue", "mlink_sim.aio.virtual.fabric", "mlink_sim.aio.slave.bus", "mlink_sim.metrics.histogram",
                 "mlink_sim.metrics.network", "mlink_sim.capture.pack"}


def test_compiled_modules_exist_and_are_cores():
    for name in _accel.COMPILED_MODULES:
        parts = name.split(".")
        assert parts[1] in ("wire", "drive", "cards", "master") or name in _PER_EXCHANGE, name
        assert ROOT.joinpath(*parts).with_suffix(".py").is_file(), name
    for name in _accel.C_EXTENSIONS:  # hand-written C, each from the .c file of its name, a core's helper
        assert name.split(".")[1] in ("wire", "drive", "cards", "master"), name
        assert _accel.source_of(name).is_file() and _accel.source_of(name).suffix == ".c", name


def test_an_install_without_a_compiler_runs_pure(tmp_path):
    """CC=/bin/false: the build says it falls back, the wheel installs and imports, and reports pure Python.
    Slow (a wheel build, ≈ 30 s): only with MLINK_TEST_NO_COMPILER=1 (scripts/test sets it)."""
    if os.environ.get("MLINK_TEST_NO_COMPILER", "") in ("", "0"):
        pytest.skip("set MLINK_TEST_NO_COMPILER=1 to build a wheel with CC=/bin/false")
    src = tmp_path / "src"  # a clean copy: no extension modules or C files of this tree's own build
    shutil.copytree(ROOT, src, symlinks=True, ignore=shutil.ignore_patterns(
        ".venv", ".git", "build", "*.so", "__pycache__", "*.egg-info", ".*_cache", ".hypothesis", "state"))
    env = {**os.environ, "CC": "/bin/false", "LDSHARED": "/bin/false"}
    env.pop("MLINK_PURE", None)
    wheels, site = tmp_path / "wheels", tmp_path / "site"
    build = subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "-v", "--disable-pip-version-check",
                            "-w", str(wheels), str(src)], env=env, capture_output=True, text=True)
    assert build.returncode == 0, build.stdout[-3000:] + build.stderr[-3000:]
    assert "the pure-Python modules will be used" in build.stdout + build.stderr
    wheel = next(wheels.glob("mlink_sim-*.whl"))
    subprocess.run([sys.executable, "-m", "pip", "install", "-q", "--no-deps", "--disable-pip-version-check",
                    "--target", str(site), str(wheel)], check=True, env=env)
    assert not list(site.rglob("*.so"))
    code = "import mlink_sim, mlink_sim._accel as a, mlink_sim.drive.integrate as m; print(a.describe(), m.__file__)"
    out = subprocess.run([sys.executable, "-c", code], env={**env, "PYTHONPATH": str(site)}, capture_output=True,
                         text=True, check=True, cwd=tmp_path)
    assert out.stdout.startswith("pure Python (not built"), out.stdout
    assert out.stdout.rstrip().endswith(str(site / "mlink_sim" / "drive" / "integrate.py")), out.stdout


def _fake_build(root: Path, names: tuple[str, ...], stamp: bool = True) -> None:
    """A package folder with a .py and an extension module for each of *names*, and the build's record."""
    lines = []
    for name in _accel.BUILT_MODULES:
        source = root.joinpath(*name.split(".")[1:]).with_suffix(".c" if name in _accel.C_EXTENSIONS else ".py")
        source.parent.mkdir(parents=True, exist_ok=True)
        source.write_text(f"# {name}\n")
        lines.append(f"{name} {hashlib.sha256(source.read_bytes()).hexdigest()}\n")
        if name in names:
            source.with_name(source.stem + importlib.machinery.EXTENSION_SUFFIXES[0]).write_bytes(b"")
    if stamp:
        (root / _accel.BUILD_STAMP).write_text("".join(lines))


@pytest.mark.parametrize("case, reason", [
    ("none", "not built (no C compiler or mypyc at install time, or MLINK_BUILD_PURE=1)"),
    ("part", f"partly built (1 of {len(_accel.BUILT_MODULES)} modules missing, e.g. {_accel.BUILT_MODULES[-1]})"),
    ("no stamp", "no record of what was built (_accel_build.txt missing; rebuild: pip install -e .)"),
    ("edited", "mlink_sim.cards.base changed after the build (rebuild: pip install -e .)"),
])
def test_why_the_cores_run_pure(tmp_path, monkeypatch, case, reason):
    names = {"none": (), "part": _accel.BUILT_MODULES[:-1]}.get(case, _accel.BUILT_MODULES)
    _fake_build(tmp_path, names, stamp=case != "no stamp")
    if case == "edited":
        (tmp_path / "cards" / "base.py").write_text("# changed\n")
    monkeypatch.setattr(_accel, "_PACKAGE_DIR", tmp_path)
    assert _accel._why_not_compiled() == reason
