"""The impairment layer on explicit time (mlink_sim/impair): every stage, the pipeline's order, expiry, healing,
seeding and the realised loss rate (within ±10 % relative over 10,000 datagrams)."""

from __future__ import annotations

import pytest

from mlink_sim.impair import (ORDER, Direction, ImpairError, Impairment, ImpairmentLayer, Stage,
                              parse_impair_text)
from mlink_sim.wire import WireError, decode
from mlink_sim.wire.frame import DropReason, with_fcs

TO_ST, TO_M = Direction.TO_STATION, Direction.TO_MASTER
MS = 1_000_000


def datagram(station: int = 0x21, cycle: int = 0) -> bytes:
    return bytes([0x4D, 2, 1, station]) + cycle.to_bytes(4, "little") + (2 * MS).to_bytes(4, "little") \
        + bytes(32) + b"\x00\x00"


def run(layer: ImpairmentLayer, n: int, station: int = 0x21, direction: Direction = TO_ST,
        period: int = MS, start: int = 0) -> list[list[tuple[int, bytes]]]:
    return [layer.process(datagram(station, k), direction, station, start + k * period) for k in range(n)]


def test_idle_layer_is_inactive_and_passes_datagrams_unchanged() -> None:
    layer = ImpairmentLayer(seed=1)
    assert not layer.active
    d = datagram()
    assert layer.process(d, TO_ST, 0x21, 0) == [(0, d)]


@pytest.mark.parametrize("p", [0.01, 0.05, 0.2, 0.5])
def test_loss_rate_within_ten_percent_relative_over_10000_datagrams(p: float) -> None:
    layer = ImpairmentLayer(seed=7)
    layer.impair(Impairment(loss=p), 0x21, 0)
    lost = sum(not out for out in run(layer, 10_000))
    assert abs(lost / 10_000 - p) <= 0.1 * p
    assert layer.injected()[0x21]["drops"] == lost


def test_gilbert_elliott_bursts_have_the_mean_length_and_the_long_run_rate() -> None:
    layer = ImpairmentLayer(seed=3)
    layer.impair(Impairment(loss=0.05, burst=4), 0x21, 0)
    fates = [not out for out in run(layer, 200_000)]
    lost = sum(fates)
    bursts = sum(1 for i, f in enumerate(fates) if f and (i == 0 or not fates[i - 1]))
    assert abs(lost / len(fates) - 0.05) <= 0.1 * 0.05
    assert 3.6 <= lost / bursts <= 4.4


def test_corrupt_flips_one_bit_of_the_data_so_the_receiver_sees_a_bad_fcs() -> None:
    good = with_fcs(datagram()[:-2])
    decode(good)
    layer = ImpairmentLayer(seed=5)
    layer.impair(Impairment(corrupt=1.0), 0x21, 0)
    for k in range(50):
        [(delay, bad)] = layer.process(good, TO_ST, 0x21, k)
        assert delay == 0 and len(bad) == len(good) and bad[:12] == good[:12] and bad[-2:] == good[-2:]
        assert bin(int.from_bytes(bad, "big") ^ int.from_bytes(good, "big")).count("1") == 1
        with pytest.raises(WireError) as err:
            decode(bad)
        assert err.value.reason is DropReason.BAD_FCS
    assert layer.injected()[0x21]["corruptions"] == 50


def test_duplicate_delivers_twice_delay_and_jitter_stay_in_range() -> None:
    layer = ImpairmentLayer(seed=2)
    layer.impair(Impairment(duplicate=1.0, delay=300_000, jitter=200_000), 0x21, 0)
    for out in run(layer, 1000):
        assert len(out) == 2 and out[0][1] == out[1][1]  # the copy has its own jitter (delay after duplicate)
        assert all(100_000 <= delay <= 500_000 for delay, _ in out)
    counts = layer.injected()[0x21]
    assert counts["duplicates"] == 1000 and counts["delays"] == 2000


def test_reorder_holds_a_datagram_past_the_next_one_of_its_path() -> None:
    layer = ImpairmentLayer(seed=2)
    layer.impair(Impairment(reorder=1.0), 0x21, 0)
    outs = run(layer, 3, period=2 * MS)
    assert outs[0][0][0] == 1 * MS  # the path's interval is unknown at first: 1 ms
    assert outs[1][0][0] == outs[2][0][0] == 3 * MS  # 1.5 x the 2 ms interval: the next one overtakes it


def test_direction_and_station_select_the_path() -> None:
    layer = ImpairmentLayer(seed=1)
    layer.impair(Impairment(loss=1.0, direction="to-master"), 0x21, 0)
    assert layer.process(datagram(), TO_ST, 0x21, 0) != []
    assert layer.process(datagram(), TO_M, 0x21, 0) == []
    assert layer.process(datagram(0x22), TO_M, 0x22, 0) != []
    layer.impair(Impairment(loss=1.0), None, 0)  # every station, both ways
    assert layer.process(datagram(0x22), TO_ST, 0x22, 0) == []


def test_for_ends_the_impairment_and_heal_ends_it_early() -> None:
    events = []
    layer = ImpairmentLayer(seed=1, listener=lambda *e: events.append(e))
    name = layer.impair(Impairment(loss=1.0, for_ns=10 * MS), 0x21, 0)
    assert name == "loss-21H-1"
    assert layer.active and layer.process(datagram(), TO_ST, 0x21, 9 * MS) == []
    assert layer.process(datagram(), TO_ST, 0x21, 10 * MS) != []
    assert not layer.active
    assert events == [("start", 0x21, name, 0), ("start", 0x21, name, 0),
                      ("end", 0x21, name, 10 * MS), ("end", 0x21, name, 10 * MS)]
    every = layer.impair(Impairment(loss=1.0), None, 0)
    own = layer.impair(Impairment(loss=1.0), 0x22, 0)
    assert layer.heal(0x22, 1) == [own] and layer.active  # the every-station one stays
    assert layer.heal(None, 1) == [every] and not layer.active


def test_an_unnamed_impair_replaces_the_unnamed_one_a_named_one_stacks() -> None:
    """docs/faults.md, "Names": without a name a second impair of a station replaces the first; with one it stacks
    beside the others, and the same name again replaces that one."""
    layer = ImpairmentLayer(seed=1)
    first = layer.impair(Impairment(loss=1.0), 0x21, 0)
    second = layer.impair(Impairment(delay=MS), 0x21, 0)
    assert (first, second) == ("loss-21H-1", "delay-21H-1")
    assert [f["name"] for f in layer.faults()] == [second]  # the loss is gone
    assert layer.process(datagram(), TO_ST, 0x21, 0) == [(MS, datagram())]
    layer.impair(Impairment(loss=1.0, direction="to-master"), 0x21, 0, name="lossy")
    layer.impair(Impairment(duplicate=1.0, direction="to-station"), 0x21, 0, name="twice")
    assert [f["name"] for f in layer.faults()] == [second, "lossy", "twice"]
    assert len(layer.process(datagram(), TO_ST, 0x21, 1)) == 2 and layer.process(datagram(), TO_M, 0x21, 1) == []
    layer.impair(Impairment(loss=1.0), 0x21, 2)  # unnamed: replaces the unnamed delay only
    assert [f["name"] for f in layer.faults()] == ["lossy", "twice", "loss-21H-2"]
    layer.impair(Impairment(reorder=0.5), 0x22, 3, name="twice")  # the same name: moved, replaced
    listed = {f["name"]: f for f in layer.faults(now=3)}
    assert listed["twice"]["stations"] == [0x22] and listed["twice"]["describe"] == "reorder 50%"
    assert listed["lossy"]["direction"] == "to-master" and listed["lossy"]["given"] is True
    assert listed["loss-21H-2"]["given"] is False and listed["loss-21H-2"]["left_ns"] is None


def test_each_name_counts_what_it_injected_and_heal_ends_one_by_name() -> None:
    layer = ImpairmentLayer(seed=1)
    layer.impair(Impairment(loss=1.0, direction="to-station", for_ns=50 * MS), 0x21, 0, name="drop")
    layer.impair(Impairment(delay=MS), [0x21, 0x22], 0)
    run(layer, 5)
    run(layer, 3, station=0x22)
    listed = {f["name"]: f for f in layer.faults(now=10 * MS)}
    assert listed["drop"]["injected"] == {"drops": 5} and listed["drop"]["left_ns"] == 40 * MS
    assert listed["delay-all-1"]["injected"] == {"delays": 3} and listed["delay-all-1"]["stations"] == [0x21, 0x22]
    assert layer.injected() == {0x21: {"drops": 5}, 0x22: {"delays": 3}}
    assert layer.heal(None, 11 * MS, name="drop") == ["drop"]
    assert [f["name"] for f in layer.faults()] == ["delay-all-1"]
    assert layer.heal(0x21, 12 * MS, name="delay-all-1") == ["delay-all-1"]  # 21H's share of it
    assert layer.faults()[0]["stations"] == [0x22]
    assert "drop" not in layer.names and "delay-all-1" in layer.names


def test_a_second_impair_replaces_the_first_other_groups_stay() -> None:
    class Gate(Stage):
        order = ORDER["gate"]
        counter = "drops"

        def apply(self, items, path):
            path.count(self.counter, len(items))
            return []

    layer = ImpairmentLayer(seed=1)
    layer.impair(Impairment(loss=1.0), 0x21, 0)
    layer.impair(Impairment(delay=MS), 0x21, 0)
    assert layer.process(datagram(), TO_ST, 0x21, 0)[0][0] == MS
    layer.add("silence", 0x21, TO_M, [Gate()], 0, until=5 * MS, kind="gate")
    assert layer.process(datagram(), TO_M, 0x21, 1) == []
    assert [f["kind"] for f in layer.faults()] == ["impair", "gate"]
    assert layer.faults()[1]["injected"] == {"drops": 1}
    layer.heal(0x21, 2, groups=["impair"])
    assert [f["name"] for f in layer.faults()] == ["silence"]


def test_same_seed_same_fates_per_path_whatever_the_other_paths_do() -> None:
    def fates(seed: int, noise: bool) -> list[int]:
        layer = ImpairmentLayer(seed=seed)
        layer.impair(Impairment(loss=0.3, corrupt=0.2, duplicate=0.1, delay=100_000, jitter=50_000), None, 0)
        out = []
        for k in range(2000):
            if noise and k % 3 == 0:
                layer.process(datagram(0x22, k), TO_ST, 0x22, k * MS)
            out.append(hash(tuple(layer.process(datagram(0x21, k), TO_ST, 0x21, k * MS))))
        return out

    assert fates(11, False) == fates(11, True)
    assert fates(11, False) != fates(12, False)


@pytest.mark.parametrize("text, message", [
    ("loss=1.5", "loss: a probability is between 0 and 1"),
    ("loss=5%,burst=0.5", "burst: the mean length"),
    ("burst=3", "burst: needs loss"),
    ("delay=100us,jitter=200us", "jitter: at most the delay"),
    ("delay=3", "delay: expected a duration"),
    ("for=0s,loss=1", "for: expected a duration above 0"),
    ("direction=up,loss=1", "direction: expected"),
    ("lost=5%", "lost: unknown impairment field"),
    ("loss", "expected NAME=VALUE"),
    ("delay=0s", "nothing to do"),
    ("loss=0.9,burst=1", "needs bursts of at least"),
])
def test_bad_values_name_the_field(text: str, message: str) -> None:
    with pytest.raises(ImpairError, match=message):
        parse_impair_text(text)


def test_text_form() -> None:
    spec = parse_impair_text("loss=5%, burst=3, delay=300us, jitter=200us, duplicate=1%, reorder=0.01, corrupt=1%, "
                             "for=2s, direction=to-station")
    assert spec == Impairment(direction="to-station", loss=0.05, burst=3, delay=300_000, jitter=200_000,
                              duplicate=0.01, reorder=0.01, corrupt=0.01, for_ns=2_000_000_000)
    assert Impairment.from_fields(spec.as_fields() | {"for": "2s"}) == spec
