"""EEPROM images are written atomically: a failed write leaves the old file intact."""

import os
from pathlib import Path

import pytest

from mlink_sim.aio.slave.state import atomic_write, eeprom_path, read_state
from mlink_sim.aio.run.supervisor import parse_workers, plan_workers, resolve_workers


def test_atomic_write_replaces_and_reads_back(tmp_path: Path) -> None:
    path = eeprom_path(tmp_path / "state", "si-t3", 0x21)
    assert path.name == "si-t3-21H.eeprom.json"
    assert read_state(path) is None
    atomic_write(path, b"one")
    atomic_write(path, b"two")
    assert read_state(path) == b"two"
    assert [p.name for p in path.parent.iterdir()] == [path.name]  # no temporary left behind


def test_atomic_write_failure_keeps_old_file(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    path = tmp_path / "img.json"
    atomic_write(path, b"old")

    def boom(src: str, dst: str) -> None:
        raise OSError("disk full")

    monkeypatch.setattr(os, "replace", boom)
    with pytest.raises(OSError):
        atomic_write(path, b"new")
    assert path.read_bytes() == b"old"
    assert [p.name for p in tmp_path.iterdir()] == ["img.json"]


def test_plan_workers_round_robin() -> None:
    assert plan_workers([1, 2, 3], None) == [[1], [2], [3]]
    assert plan_workers([1, 2, 3, 4, 5], 2) == [[1, 3, 5], [2, 4]]
    assert plan_workers([1, 2], 8) == [[1], [2]]


@pytest.mark.parametrize(("spec", "stations", "cpus", "expected"), [
    ("auto", 3, 2, 1),        # the quickstart on 2 CPUs: one slave process, a CPU left to the master's clock
    ("auto", 2, 2, None),     # two stations: one process each (kill-slave stops just one)
    (None, 62, 2, 1),
    ("auto", 3, 4, None),     # 4 CPUs: three slave processes and the master, one CPU each
    ("auto", 9, 4, 3),
    ("auto", 1, 1, None),
    ("station", 62, 2, None),
    (4, 62, 2, 4),
    ("4", 3, 2, 4),
])
def test_resolve_workers_auto_leaves_the_master_a_cpu(spec, stations, cpus, expected) -> None:
    assert resolve_workers(spec, stations, cpus) == expected


@pytest.mark.parametrize("bad", ["0", "-1", "two", "", 0, "1.5"])
def test_parse_workers_rejects_with_what_is_expected(bad) -> None:
    with pytest.raises(ValueError, match="expected a number of processes"):
        parse_workers(bad)
    assert parse_workers(" AUTO ") == "auto" and parse_workers(3) == 3 and parse_workers(None) == "auto"
