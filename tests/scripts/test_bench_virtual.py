"""scripts/bench_virtual.py: its run and floor helpers on a short span (no timing asserted)."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def bench():  # noqa: ANN201 - a script, loaded as a module
    spec = importlib.util.spec_from_file_location("mlink_bench_virtual", ROOT / "scripts" / "bench_virtual.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules["mlink_bench_virtual"] = module
    spec.loader.exec_module(module)
    yield module
    del sys.modules["mlink_bench_virtual"]


def test_run_is_the_up_code_path_on_the_virtual_clock(bench):
    report = bench.run(bench.QUICKSTART, seed=2, duration_ns=300_000_000)
    assert report["meta"]["clock"] == "virtual" and report["meta"]["seed"] == 2
    assert report["meta"]["wall"]["simulated_s"] >= 0.3 and report["cycles"] >= 149


def test_floor_times_the_cores_and_their_card_share(bench):
    total, cards = bench.floor(bench.QUICKSTART, 0.2)
    assert total > 0 and 0 < cards <= total * 1.5  # the cards' share is timed inside the total (clock granularity)
