"""Latency histogram: an HDR histogram of nanosecond values, 1 ns .. 10 s at 3 significant digits.

:class:`LatencyHistogram` uses :class:`hdrh.histogram.HdrHistogram` (package ``hdrhistogram``) for its layout,
its percentile rules and the HDR compressed transport form, but records into its own *paged* copy of the HDR
counts array: one page of 1 024 counts per HDR bucket (a power of two of values), allocated when a value first
falls in it. Real latencies fill two to four pages, so copying, merging and summarising touch a few thousand
counts instead of 25 600, and a live report does not stall the cycle. ``HdrHistogram.record_value`` costs
about a microsecond a call in CPython (``bin()`` based leading-zero count, ctypes counters, min/max bookkeeping); the
inlined index computation and two list indexings below cost about 40 ns compiled (docs/report.md, "Cost on the
recording path"). The counts are indexed lists of pages, not a ``dict`` keyed by index: a dict's lookups (hash
probe, a compare of two int objects, a second lookup to store) for every answer are a visible share of a large
network's master CPU (docs/performance.md, "Garbage collection").
The pages are ``array.array("q")``, not lists: an array holds no object references, so a garbage collection
visits it in one step instead of 1 024 (``tp_traverse`` visits only its type). As lists, the few hundred pages a
62-station master fills after a reset are young containers of 1 024 references each, and the first collections
of the measuring window traverse them all, each in the middle of a cycle, for milliseconds (docs/performance.md,
"Garbage collection").
Summaries are computed from the non-zero buckets with HdrHistogram's own index ⇄ value functions (tests check
they equal the library's figures); the counts are copied into an ``HdrHistogram`` only to encode it or for
:meth:`LatencyHistogram.to_hdr`.

Index computation (same as ``HdrHistogram._counts_index_for`` for ``lowest_trackable_value == 1``, i.e.
``unit_magnitude == 0``; a test checks equality over the whole range)::

    bucket = bit_length(v | sub_bucket_mask) - (sub_bucket_half_count_magnitude + 1)
    index  = ((bucket + 1) << sub_bucket_half_count_magnitude) + (v >> bucket) - sub_bucket_half_count

Values are integers in nanoseconds. Negative values are recorded as 0, values above 10 s as 10 s (so a count
is never lost; ``max`` then reads 10 s).
"""

from __future__ import annotations

import math
from array import array
from collections.abc import Iterable

from hdrh.histogram import HdrHistogram

from ..units import format_ns

__all__ = ["LatencyHistogram", "LOWEST_NS", "HIGHEST_NS", "SIGNIFICANT_DIGITS", "SUMMARY_KEYS", "BINS_PER_OCTAVE"]

LOWEST_NS = 1
HIGHEST_NS = 10_000_000_000          # 10 s
SIGNIFICANT_DIGITS = 3

#: Keys of :meth:`LatencyHistogram.summary`, in report order. All values are ns except ``count``.
SUMMARY_KEYS: tuple[str, ...] = ("count", "min", "p50", "p90", "p99", "p99_9", "max", "mean")
_PERCENTILES = {"p50": 50.0, "p90": 90.0, "p99": 99.0, "p99_9": 99.9}
#: :meth:`LatencyHistogram.bins`: bins a factor 2^(1/4) (19 %) wide, so 50 µs .. 5 ms takes 27 bins.
BINS_PER_OCTAVE = 4
_FIRST_BIN = 3 * BINS_PER_OCTAVE  # its upper edge is 8 ns: from there on the rounded edges differ


def _new_hdr() -> HdrHistogram:
    return HdrHistogram(LOWEST_NS, HIGHEST_NS, SIGNIFICANT_DIGITS)


# A reference histogram that stays empty: the layout constants of the counts array are read from it, and its
# index ⇄ value functions (get_value_from_index, get_highest_equivalent_value, ...) serve every summary.
_LAYOUT = _new_hdr()
_COUNTS_LEN: int = _LAYOUT.counts_len                          # 25 600
_SUB_MASK: int = _LAYOUT.sub_bucket_mask                       # 2047
_SHIFT: int = _LAYOUT.sub_bucket_half_count_magnitude          # 10
_HALF: int = _LAYOUT.sub_bucket_half_count                     # 1024
_BITS: int = _SHIFT + 1                                        # 11
# The counts' pages (see the module docstring): page p holds indices p·1024 … p·1024 + 1023, one HDR bucket
# each (a bucket of the layout is _HALF = 1024 indices wide, from the second on; the first, 0 … 2047, is pages 0
# and 1), so that all 25 600 indices are covered by 25 pages.
_PAGE: int = _HALF                                              # 1024 counts per page
_PAGES: int = _COUNTS_LEN // _PAGE                              # 25
# record() has these constants inlined (a global lookup each would be a visible share of its cost).
assert _LAYOUT.unit_magnitude == 0 and (_SUB_MASK, _BITS, _SHIFT, _HALF) == (2047, 11, 10, 1024)
assert _PAGES * _PAGE == _COUNTS_LEN
_ZERO_PAGE = array("q", bytes(8 * _PAGE))  # copied for each new page: 1 024 zero counts


def _new_page() -> array[int]:
    """A page of :data:`_PAGE` zero counts, which a garbage collection visits in one step (module docstring)."""
    return array("q", _ZERO_PAGE)


def _index(ns: int) -> int:
    """Counts-array index of ``ns`` (reference implementation of the inlined code in ``record``)."""
    b = (ns | _SUB_MASK).bit_length() - _BITS
    return ((b + 1) << _SHIFT) + (ns >> b) - _HALF


assert _index(HIGHEST_NS) < _COUNTS_LEN  # the largest value recorded has its page


def _edge(k: int) -> int:
    """The upper edge of bin *k* of :meth:`LatencyHistogram.bins`, in ns."""
    return round(2 ** (k / BINS_PER_OCTAVE))


def _median_of_index(index: int) -> int:
    """``_LAYOUT._hdr_median_equiv_value(_LAYOUT.get_value_from_index(index))`` in closed form (~10× faster;
    a test checks equality over every index): the bucket's lowest value plus half its width."""
    bucket = (index >> _SHIFT) - 1
    sub = (index & (_HALF - 1)) + _HALF
    if bucket < 0:
        sub -= _HALF
        bucket = 0
    return (sub << bucket) + ((1 << bucket) >> 1)


class LatencyHistogram:
    """HDR histogram of nanosecond latencies (1 ns .. 10 s, 3 significant digits, i.e. ≤ 0.1 % quantisation).

    >>> h = LatencyHistogram()
    >>> for us in range(1, 1001):
    ...     h.record(us * 1000)
    >>> s = h.summary()
    >>> s["count"], s["p50"] // 1000
    (1000, 500)
    """

    __slots__ = ("_pages",)

    def __init__(self) -> None:
        # the HdrHistogram counts array in pages of 1 024 counts (None: no value there yet; module docstring)
        self._pages: list[array[int] | None] = [None] * _PAGES

    # ------------------------------------------------------------------ hot path
    def record(self, ns: int) -> None:
        """Count one value in nanoseconds (an ``int``). Negative → 0, above 10 s → 10 s. About 40 ns compiled."""
        if ns < 0:
            ns = 0
        elif ns > 10_000_000_000:
            ns = 10_000_000_000
        b = (ns | 2047).bit_length() - 11
        i = ((b + 1) << 10) + (ns >> b) - 1024
        pages = self._pages
        page = pages[i >> 10]
        if page is None:
            page = pages[i >> 10] = _new_page()
        page[i & 1023] += 1

    def _add(self, i: int, c: int) -> None:
        """*c* more in counts-array index *i* (0 ≤ i < 25 600)."""
        pages = self._pages
        page = pages[i // _PAGE]
        if page is None:
            page = pages[i // _PAGE] = _new_page()
        page[i % _PAGE] += c

    # ------------------------------------------------------------------ queries
    @property
    def count(self) -> int:
        """Number of recorded values."""
        return sum(sum(page) for page in self._pages if page is not None)

    def __len__(self) -> int:
        return self.count

    def count_at_most(self, ns: int) -> int:
        """Number of recorded values ≤ ``ns``, to the histogram's resolution (a value in ``ns``'s own bucket,
        at most 0.1 % above it, counts as well)."""
        top = _index(min(max(ns, 0), HIGHEST_NS))
        return sum(c for i, c in self._nonzero() if i <= top)

    def to_hdr(self) -> HdrHistogram:
        """A new :class:`hdrh.histogram.HdrHistogram` holding these counts (milliseconds), for anything the summary
        does not give (other percentiles, iterators, ``output_percentile_distribution``)."""
        h = _new_hdr()
        nonzero = self._nonzero()
        for i, c in nonzero:
            h.counts[i] = c
        if nonzero:
            h.set_internal_tacking_values(nonzero[0][0], nonzero[-1][0], sum(c for _, c in nonzero))
        return h

    def _nonzero(self) -> list[tuple[int, int]]:
        """``(index, count)`` of the non-zero counts, by index."""
        out: list[tuple[int, int]] = []
        for p, page in enumerate(self._pages):
            if page is not None:
                base = p * _PAGE
                out.extend((base + j, c) for j, c in enumerate(page) if c)
        return out

    def percentile(self, p: float) -> int:
        """Value at percentile ``p`` (0..100) in ns, as ``HdrHistogram.get_value_at_percentile``; 0 when empty."""
        return self._percentiles(self._nonzero(), (p,))[0]

    def percentiles(self, ps: tuple[float, ...]) -> list[int]:
        """The values at each percentile of *ps* in ns (as :meth:`percentile`), from one scan of the buckets."""
        return self._percentiles(self._nonzero(), ps)

    @staticmethod
    def _percentiles(nonzero: list[tuple[int, int]], ps: tuple[float, ...]) -> list[int]:
        """HdrHistogram's percentile rule over the non-zero buckets: the first bucket whose cumulative count
        reaches ``max(1, int(p/100 * total + 0.5))``, reported as the bucket's highest equivalent value."""
        total = sum(c for _, c in nonzero)
        if not total:
            return [0] * len(ps)
        out = []
        for p in ps:
            target = max(int(min(p, 100.0) * total / 100 + 0.5), 1)
            running = 0
            for i, c in nonzero:
                running += c
                if running >= target:
                    v = _LAYOUT.get_value_from_index(i)
                    out.append(int(_LAYOUT.get_highest_equivalent_value(v) if p else
                                   _LAYOUT.get_lowest_equivalent_value(v)))
                    break
        return out

    def summary(self) -> dict[str, int]:
        """``{"count", "min", "p50", "p90", "p99", "p99_9", "max", "mean"}``, ints in ns; all 0 when empty.

        Same figures as the wrapped ``HdrHistogram`` gives (a test checks it), computed from the non-zero
        buckets only (a small fraction of the library's time): percentiles and ``max`` are the highest value of their
        bucket, ``min`` the lowest, ``mean`` the mean of bucket midpoints (all within 0.1 % of the values).
        """
        nonzero = self._nonzero()
        if not nonzero:
            return dict.fromkeys(SUMMARY_KEYS, 0)
        total = sum(c for _, c in nonzero)
        lo, hi = nonzero[0][0], nonzero[-1][0]
        out = {"count": total, "min": int(_LAYOUT.get_value_from_index(lo))}
        out.update(zip(_PERCENTILES, self._percentiles(nonzero, tuple(_PERCENTILES.values()))))
        out["max"] = int(_LAYOUT.get_highest_equivalent_value(_LAYOUT.get_value_from_index(hi)))
        weighted = sum(c * _median_of_index(i) for i, c in nonzero)
        out["mean"] = round(weighted / total)
        return out

    def bins(self) -> list[list[int]]:
        """The histogram a person can look at: ``[[lower_ns, upper_ns, count], …]``, contiguous from the bin of the
        smallest value to that of the largest (empty bins between them included), each bin a factor
        2^(1/:data:`BINS_PER_OCTAVE`) wide: the edges are ``round(2 ** (k / 4))`` ns, so bins of two histograms line
        up; the first bin, ``(0, 8]`` ns, holds everything below (where rounded edges would repeat). A value counts in the bin whose range ``(lower, upper]`` holds its HDR bucket's midpoint; ``[]`` when
        empty."""
        counts: dict[int, int] = {}
        for i, c in self._nonzero():
            mid = _median_of_index(i)
            k = max(math.ceil(math.log2(mid) * BINS_PER_OCTAVE), _FIRST_BIN) if mid > 1 else _FIRST_BIN
            while _edge(k) < mid:  # the float log may land one bin low at an edge
                k += 1
            while k > _FIRST_BIN and _edge(k - 1) >= mid:
                k -= 1
            counts[k] = counts.get(k, 0) + c
        if not counts:
            return []
        return [[_edge(k - 1) if k > _FIRST_BIN else 0, _edge(k), counts.get(k, 0)]
                for k in range(min(counts), max(counts) + 1)]

    # ------------------------------------------------------------------ combining and transport
    def merge(self, other: LatencyHistogram) -> None:
        """Add ``other``'s counts to this histogram (``other`` is unchanged)."""
        pages = self._pages
        for p, theirs in enumerate(list(other._pages)):
            if theirs is not None:
                mine = pages[p]
                if mine is None:
                    pages[p] = array("q", theirs)
                else:
                    pages[p] = array("q", [a + b for a, b in zip(mine.tolist(), theirs.tolist())])

    @classmethod
    def merged(cls, histograms: Iterable[LatencyHistogram]) -> LatencyHistogram:
        """A new histogram holding the sum of ``histograms``."""
        out = cls()
        for h in histograms:
            out.merge(h)
        return out

    def reset(self) -> None:
        self._pages = [None] * _PAGES

    def copy(self) -> LatencyHistogram:
        out = LatencyHistogram()
        out._pages = [None if page is None else array("q", page) for page in self._pages]
        return out

    def to_pairs(self) -> list[list[int]]:
        """``[[index, count], …]`` of the non-zero buckets: a cheap JSON form between processes of this package
        (for anything else use the standard :meth:`encode`)."""
        return [[i, c] for i, c in self._nonzero()]

    @classmethod
    def from_pairs(cls, pairs: Iterable[Iterable[int]]) -> LatencyHistogram:
        """Rebuild from :meth:`to_pairs`; ``ValueError`` for an index outside the layout or a negative count."""
        out = cls()
        for pair in pairs:
            i, c = (int(x) for x in pair)
            if not 0 <= i < _COUNTS_LEN or c < 0:
                raise ValueError(f"bad histogram bucket {pair!r}")
            out._add(i, c)
        return out

    def encode(self) -> str:
        """HDR V2 compressed, base64 form (``HISTF...``), an ASCII string safe to put in JSON."""
        return self.to_hdr().encode().decode("ascii")

    @classmethod
    def decode(cls, blob: str | bytes) -> LatencyHistogram:
        """Rebuild a histogram from :meth:`encode`'s output.

        Raises :class:`ValueError` for anything that is not an HDR blob of this histogram's range and precision
        (callers receiving blobs from other processes turn that into a counted drop).
        """
        try:
            h = HdrHistogram.decode(blob.encode("ascii") if isinstance(blob, str) else blob)
        except Exception as exc:  # noqa: BLE001 - hdrh raises TypeError, binascii/zlib errors, its own exceptions
            raise ValueError(f"not an HDR histogram blob: {type(exc).__name__}: {exc}") from None
        if (h.lowest_trackable_value, h.highest_trackable_value, h.significant_figures) != (
            LOWEST_NS, HIGHEST_NS, SIGNIFICANT_DIGITS,
        ) or h.counts_len != _COUNTS_LEN:
            raise ValueError(
                "HDR histogram of another layout: "
                f"range {h.lowest_trackable_value}..{h.highest_trackable_value}, {h.significant_figures} digits "
                f"(expected {LOWEST_NS}..{HIGHEST_NS}, {SIGNIFICANT_DIGITS} digits)"
            )
        out = cls()
        for i, c in enumerate(h.counts[:_COUNTS_LEN]):
            if c:
                out._add(i, int(c))
        return out

    def __eq__(self, other: object) -> bool:
        return isinstance(other, LatencyHistogram) and self._nonzero() == other._nonzero()

    __hash__ = None  # type: ignore[assignment]   # mutable

    def __repr__(self) -> str:
        s = self.summary()
        return f"LatencyHistogram(count={s['count']}, p50={format_ns(s['p50'])}, max={format_ns(s['max'])})"

