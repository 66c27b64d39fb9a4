"""Read-only views of a report for tests: latencies in **seconds**, counters as ints.

>>> m = MetricsView({"rtt": {"count": 2, "min": 1000, "p50": 250_000, "p90": 0, "p99": 400_000, "p99_9": 0,
...                          "max": 400_000, "mean": 0}, "missed": 0, "station": {}})
>>> m.rtt.p99, m.rtt.p99_ns, m.missed
(0.0004, 400000, 0)
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Mapping
from typing import Any

from ..units import format_ns

__all__ = ["Latency", "MetricsView", "StationMetricsView", "ReportChecks", "HostView", "StallsView"]

_LATENCY_KEYS = ("min", "p50", "p90", "p99", "p99_9", "max", "mean")


class Latency:
    """One latency histogram's summary: ``.p99`` in seconds, ``.p99_ns`` in ns, ``.count`` responses/cycles."""

    __slots__ = ("_d",)

    def __init__(self, summary: Mapping[str, Any]) -> None:
        self._d = dict(summary)

    @property
    def count(self) -> int:
        return int(self._d.get("count", 0))

    def __getattr__(self, name: str) -> float | int:
        if name.endswith("_ns") and name[:-3] in _LATENCY_KEYS:
            return int(self._d.get(name[:-3], 0))
        if name in _LATENCY_KEYS:
            return int(self._d.get(name, 0)) / 1e9
        raise AttributeError(f"latency has no field {name!r} (fields: {', '.join(_LATENCY_KEYS)}, count; "
                             "add _ns for nanoseconds)")

    def as_dict(self) -> dict[str, Any]:
        """The summary as in the report (ns)."""
        return dict(self._d)

    def __repr__(self) -> str:
        if not self.count:
            return "Latency(empty)"
        return (f"Latency(count={self.count}, p50={format_ns(self._d['p50'])}, p99={format_ns(self._d['p99'])}, "
                f"max={format_ns(self._d['max'])})")


class _Counters:
    __slots__ = ("_d",)

    def __init__(self, d: Mapping[str, Any]) -> None:
        self._d = d

    def __getattr__(self, name: str) -> Any:
        try:
            value = self._d[name]
        except KeyError:
            raise AttributeError(f"no field {name!r} (fields: {', '.join(sorted(self._d))})") from None
        if isinstance(value, Mapping) and "p50" in value:
            return Latency(value)
        return value


class StationMetricsView(_Counters):
    """One station's figures: ``rtt`` (:class:`Latency`), ``sent``, ``answered``, ``late``, ``missing``,
    ``reception_failures``, ``wdt_errors``, ``dropped``."""

    def __repr__(self) -> str:
        return f"StationMetricsView(rtt={self.rtt!r}, missing={self.missing}, late={self.late})"


class _Stations(Mapping[int, StationMetricsView]):
    def __init__(self, d: Mapping[str, Any]) -> None:
        self._d = d

    @staticmethod
    def _key(station: int | str) -> str:
        if isinstance(station, str):
            station = int(station.rstrip("Hh"), 16) if station.upper().endswith("H") else int(station, 0)
        return f"0x{station:02x}"

    def __getitem__(self, station: int | str) -> StationMetricsView:
        try:
            return StationMetricsView(self._d[self._key(station)])
        except KeyError:
            raise KeyError(f"no station {station!r} in this network (stations: {', '.join(self._d)})") from None

    def __iter__(self) -> Iterator[int]:
        return (int(k, 16) for k in self._d)

    def __len__(self) -> int:
        return len(self._d)


class StallsView:
    """Host stalls (docs/report.md, ``host``): ``count``, ``cycles``, ``absorbed``, ``lost`` as ints; ``total`` and
    ``max`` in seconds (``total_ns``, ``max_ns`` in ns)."""

    __slots__ = ("_d",)

    def __init__(self, d: Mapping[str, Any]) -> None:
        self._d = dict(d)

    def __getattr__(self, name: str) -> float | int:
        if name in ("total", "max"):
            return int(self._d.get(name, 0)) / 1e9
        if name in ("total_ns", "max_ns"):
            return int(self._d.get(name[:-3], 0))
        if name in ("count", "cycles", "absorbed", "lost"):
            return int(self._d.get(name, 0))
        raise AttributeError(f"stalls have no field {name!r} (count, total, max, cycles, absorbed, lost)")

    def __repr__(self) -> str:
        return f"StallsView(count={self.count}, max={self.max_ns / 1e6:.1f} ms, lost={self.lost})"


class HostView:
    """The report's ``host`` section: ``policy``, ``bound`` (s), ``stall`` and ``by_process[name]``
    (:class:`StallsView`), ``stalls`` (the events as in the report)."""

    __slots__ = ("_d",)

    def __init__(self, d: Mapping[str, Any]) -> None:
        self._d = d

    policy = property(lambda self: self._d.get("policy", "strict"))
    bound = property(lambda self: int(self._d.get("bound", 0)) / 1e9)
    stall = property(lambda self: StallsView(self._d.get("stall", {})))
    by_process = property(lambda self: {p: StallsView(v) for p, v in self._d.get("by_process", {}).items()})
    stalls = property(lambda self: list(self._d.get("stalls", [])))


class MetricsView(_Counters):
    """A report snapshot (docs/report.md) for assertions in tests.

    ``rtt`` and ``lateness`` are :class:`Latency` (seconds; ``_ns`` for ns); ``cycles``, ``missed``,
    ``missed_rate``, ``sent``, ``answered``, ``late``, ``missing``, ``reception_failures``, ``wdt_errors``,
    ``dropped``, ``cpu`` as in the report; ``station[0x21]`` one station; ``host`` the host stalls
    (:class:`HostView`); ``report`` the whole document."""

    def __init__(self, report: Mapping[str, Any]) -> None:
        super().__init__(report)

    @property
    def report(self) -> Mapping[str, Any]:
        return self._d

    @property
    def station(self) -> _Stations:
        return _Stations(self._d.get("station", {}))

    @property
    def host(self) -> HostView:
        """Host stalls: ``net.metrics.host.stall.max`` in seconds (docs/report.md, ``host``)."""
        return HostView(self._d.get("host", {}))

    def __repr__(self) -> str:
        return (f"MetricsView(cycles={self._d.get('cycles')}, missed={self._d.get('missed')}, "
                f"rtt={Latency(self._d.get('rtt', {}))!r})")


class ReportChecks:
    """``metrics`` and ``check`` for a network handle with ``report()`` and ``config`` (both clocks' harnesses)."""

    config: Any
    report: Callable[[], dict[str, Any]]  #: the handle's own: the live report (the final one once stopped)

    @property
    def metrics(self) -> MetricsView:
        """Live figures (a fresh report, slave counters included): ``net.metrics.rtt.p99`` in seconds."""
        return MetricsView(self.report())

    def check(self, *expressions: str) -> list[Any]:
        """Evaluate ``--assert`` expressions (docs/report.md) on the live figures; ``AssertionError`` naming every
        broken bound and its measured value. A malformed expression raises ``AssertionSyntaxError``."""
        from ..metrics import check_all, parse_assertions

        parsed = parse_assertions(expressions, stations=[st.address for st in self.config.station])
        results = check_all(parsed, self.report())
        failed = [r for r in results if not r.ok]
        if failed:
            raise AssertionError("; ".join(r.message for r in failed))
        return results
