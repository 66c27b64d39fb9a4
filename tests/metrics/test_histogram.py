"""mlink_sim.metrics.histogram: LatencyHistogram against hdrhistogram's own figures."""

from __future__ import annotations

import random

import pytest
from hdrh.histogram import HdrHistogram

from mlink_sim.metrics import LatencyHistogram
from mlink_sim.metrics.histogram import _LAYOUT, HIGHEST_NS, SUMMARY_KEYS, _index, _median_of_index

US = 1_000
MS = 1_000_000


def within(value: int, expected: float, rel: float = 1e-3) -> bool:
    """HDR precision: 3 significant digits → a figure is within 0.1 % of the value it stands for."""
    return abs(value - expected) <= rel * expected + 1


def filled(values) -> LatencyHistogram:
    h = LatencyHistogram()
    for v in values:
        h.record(v)
    return h


def test_inlined_index_equals_hdrh_index():
    ref = HdrHistogram(1, HIGHEST_NS, 3)
    probes = {0, 1, 2, 3, HIGHEST_NS}
    for k in range(35):
        probes.update({(1 << k) - 1, 1 << k, (1 << k) + 1})
    rnd = random.Random(7)
    probes.update(rnd.randrange(HIGHEST_NS) for _ in range(2000))
    for v in sorted(p for p in probes if p <= HIGHEST_NS):
        assert _index(v) == ref._counts_index_for(v), v


def test_closed_form_bucket_midpoint_equals_hdrh_for_every_index():
    for i in range(_LAYOUT.counts_len):
        assert _median_of_index(i) == _LAYOUT._hdr_median_equiv_value(_LAYOUT.get_value_from_index(i)), i


def test_copy_is_independent_and_sparse():
    h = LatencyHistogram()
    h.record(1_000)
    c = h.copy()
    c.record(2_000)
    assert (h.count, c.count) == (1, 2)
    assert sum(page is not None for page in h._pages) == 1  # one page of counts, not the whole array


def test_values_across_pages_merge_copy_and_travel_as_hdrh_counts_them():
    """The paged counts (one page per HDR bucket) against hdrh's flat array: values in many pages, the first page
    and the last index, merged into an empty histogram, into one with other pages, and into itself."""
    rnd = random.Random(11)
    values = [0, 1, 2047, 2048, HIGHEST_NS, HIGHEST_NS + 5] + [rnd.randrange(HIGHEST_NS) >> rnd.randrange(34)
                                                              for _ in range(3000)]
    ref = HdrHistogram(1, HIGHEST_NS, 3)
    for v in values:
        ref.record_value(min(v, HIGHEST_NS))
    a, b = filled(values[::2]), filled(values[1::2])
    merged = LatencyHistogram.merged([a, b])
    assert [list(p) for p in merged.to_pairs()] == [[i, c] for i, c in enumerate(ref.counts) if c]
    twice = merged.copy()
    twice.merge(twice)
    assert twice.count == 2 * merged.count == 2 * len(values)
    assert LatencyHistogram.from_pairs(merged.to_pairs()) == merged
    assert LatencyHistogram.decode(merged.encode()) == merged
    assert merged.count_at_most(2047) == sum(1 for v in values if v <= 2047)


def test_uniform_1_to_1000_us():
    s = filled(range(1 * US, 1001 * US, US)).summary()
    assert s["count"] == 1000
    assert within(s["min"], 1 * US)
    assert within(s["p50"], 500 * US)
    assert within(s["p90"], 900 * US)
    assert within(s["p99"], 990 * US)
    assert within(s["p99_9"], 999 * US)
    assert within(s["max"], 1000 * US)
    assert within(s["mean"], 500.5 * US)
    assert set(s) == set(SUMMARY_KEYS) and all(isinstance(v, int) for v in s.values())


def test_summary_equals_hdrh_figures():
    rnd = random.Random(3)
    values = [int(rnd.lognormvariate(12, 1)) for _ in range(5000)] + [0, 5, 2 * MS]
    h = filled(values)
    ref = HdrHistogram(1, HIGHEST_NS, 3)
    for v in values:
        ref.record_value(v)
    s = h.summary()
    assert s["count"] == ref.get_total_count()
    assert s["min"] == ref.get_min_value()
    assert s["max"] == ref.get_max_value()
    for key, p in (("p50", 50), ("p90", 90), ("p99", 99), ("p99_9", 99.9)):
        assert s[key] == ref.get_value_at_percentile(p), key
    assert s["mean"] == round(ref.get_mean_value())
    assert h.percentile(75) == ref.get_value_at_percentile(75)
    assert h.percentile(0) == ref.get_value_at_percentile(0)
    assert h.to_hdr().equals(ref)


def test_single_value_and_empty():
    assert LatencyHistogram().summary() == dict.fromkeys(SUMMARY_KEYS, 0)
    assert LatencyHistogram().percentile(99) == 0
    assert LatencyHistogram().count == 0
    s = filled([250 * US]).summary()
    assert s["count"] == 1
    assert all(within(s[k], 250 * US) for k in SUMMARY_KEYS if k != "count")


def test_out_of_range_values_are_clamped_not_lost():
    h = filled([-5, -10**12, 20 * 10**9, 10**15])
    s = h.summary()
    assert s["count"] == 4
    assert s["min"] == 0
    assert within(s["max"], HIGHEST_NS)


def test_merge_equals_recording_everything_in_one():
    rnd = random.Random(11)
    a_vals = [rnd.randrange(50 * US, 400 * US) for _ in range(3000)]
    b_vals = [rnd.randrange(300 * US, 2 * MS) for _ in range(1000)]
    a, b = filled(a_vals), filled(b_vals)
    b_before = b.summary()
    a.merge(b)
    assert a == filled(a_vals + b_vals)
    assert a.summary() == filled(a_vals + b_vals).summary()
    assert b.summary() == b_before                       # other unchanged
    assert LatencyHistogram.merged([filled(a_vals), b]) == a


def test_merge_into_empty_keeps_min():
    # HdrHistogram.add() takes min(self.get_min_value(), ...) where an empty histogram's min reads 0.
    h = LatencyHistogram()
    h.merge(filled([300 * US, 400 * US]))
    assert within(h.summary()["min"], 300 * US)
    h.merge(LatencyHistogram())
    assert within(h.summary()["min"], 300 * US)


def test_merge_with_itself_doubles():
    h = filled([1 * US, 2 * US])
    h.merge(h)
    assert h.count == 4


@pytest.mark.parametrize("values", [[], [0], [1, 999, 1000, 123456789], list(range(0, 10 * MS, 997))])
def test_encode_decode_round_trip(values):
    h = filled(values)
    blob = h.encode()
    assert isinstance(blob, str) and blob.startswith("HISTF")
    back = LatencyHistogram.decode(blob)
    assert back == h
    assert back.summary() == h.summary()
    assert LatencyHistogram.decode(blob.encode("ascii")) == h


def test_blob_is_standard_hdr():
    h = filled([100 * US, 200 * US, 300 * US])
    ref = HdrHistogram.decode(h.encode())
    assert ref.get_total_count() == 3
    assert ref.get_value_at_percentile(50) == h.summary()["p50"]


@pytest.mark.parametrize("blob", ["", "not base64!", "SElTVEZBQUFB", "HISTFAAAACB4nJNpmSzMwMBgzgABMBoEmADw"])
def test_decode_garbage_is_value_error(blob):
    with pytest.raises(ValueError):
        LatencyHistogram.decode(blob)


def test_decode_other_layout_is_value_error():
    other = HdrHistogram(1, 60 * 10**9, 2)
    other.record_value(1000)
    with pytest.raises(ValueError, match="another layout"):
        LatencyHistogram.decode(other.encode())


def test_reset_and_copy():
    h = filled([1, 2, 3])
    c = h.copy()
    h.reset()
    assert h.count == 0 and c.count == 3


def test_count_at_most_counts_the_values_up_to_a_bound():
    h = filled([100 * US, 999 * US, 1 * MS, 1_002 * US, 5 * MS])
    assert h.count_at_most(1 * MS) == 3  # 1.002 ms lies in another bucket than 1 ms (0.1 % resolution)
    assert h.count_at_most(99 * US) == 0 and h.count_at_most(HIGHEST_NS) == 5
    assert h.count_at_most(-1) == 0 and LatencyHistogram().count_at_most(1 * MS) == 0


def test_a_page_of_counts_gives_the_collector_nothing_to_traverse() -> None:
    """The counts' pages hold no object references (arrays, not lists of 1 024 ints), so a garbage collection in the
    master does not walk every count of every page (mlink_sim/metrics/histogram.py, module docstring)."""
    import gc

    h = LatencyHistogram()
    for ns in (3, 150_000, 300_000, 600_000, 2_000_000):
        h.record(ns)
    pages = [page for page in h._pages if page is not None]
    assert len(pages) >= 4
    assert all(len(gc.get_referents(page)) <= 1 for page in pages)  # at most its type
    assert h.copy() == h and LatencyHistogram.merged([h, h]).count == 10


def test_bins_count_every_value_in_contiguous_quarter_octave_bins():
    h = LatencyHistogram()
    values = [50_000 + 37 * k for k in range(5000)] + [4_900_000] + [3]
    for v in values:
        h.record(v)
    bins = h.bins()
    assert sum(c for _, _, c in bins) == len(values)
    assert bins[0][:2] == [0, 8] and bins[0][2] == 1  # 3 ns: the first bin, (0, 8]
    assert all(a[1] == b[0] for a, b in zip(bins, bins[1:]))  # contiguous, empty bins between included
    assert all(round(hi / lo, 2) in (1.18, 1.19, 1.2) for lo, hi, _ in bins[1:] if lo >= 1000)  # 2^(1/4) wide
    top = next(b for b in bins if b[0] < 4_900_000 <= b[1])
    assert top[2] == 1 and bins[-1] is top
    other = LatencyHistogram()
    other.record(60_000)
    assert other.bins()[0][:2] in [b[:2] for b in bins]  # the edges of two histograms line up
    assert LatencyHistogram().bins() == []
