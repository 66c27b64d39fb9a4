"""benchmarks.micro.virtual: its run and floor helpers on a short span (no timing asserted)."""

from __future__ import annotations

from benchmarks.micro import virtual


def test_run_is_the_up_code_path_on_the_virtual_clock():
    report = virtual.run(virtual.QUICKSTART, seed=2, duration_ns=300_000_000)
    assert report["meta"]["clock"] == "virtual" and report["meta"]["seed"] == 2
    assert report["meta"]["wall"]["simulated_s"] >= 0.3 and report["cycles"] >= 149


def test_floor_times_the_cores_and_their_card_share():
    total, cards = virtual.floor(virtual.QUICKSTART, 0.2)
    assert total > 0 and 0 < cards <= total * 1.5  # the cards' share is timed inside the total (clock granularity)
