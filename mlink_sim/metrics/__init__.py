"""Run measurements: HDR latency histograms, the report document and ``--assert`` bounds on it.

Depends on ``hdrhistogram`` and the standard library only, and never reads a clock: times are passed in
(monotonic ns for latencies, seconds for CPU). Report fields and the expression grammar: docs/report.md.

>>> m = NetworkMetrics(cycle_ns=1_000_000)
>>> m.record_sent(0x21); m.record_rtt(0x21, 240_000)
>>> report = m.report(meta={"config": "net.toml", "started": "2024-01-01T00:00:00+00:00", "duration_s": 1.0})
>>> [r.message for r in check_all([parse_assertion("station[33].rtt.p99 < 500us")], report)]
['station[0x21].rtt.p99 < 500us ok: measured 240.1us']
"""

from .assertions import (
    Assertion,
    AssertionResult,
    AssertionSyntaxError,
    assertable_fields,
    check_all,
    parse_assertion,
    parse_assertions,
)
from ..units import format_ns
from .histogram import LatencyHistogram
from .network import NetworkMetrics, StationMetrics, station_key
from .report import REPORT_SCHEMA, SCHEMA_ID, build_report, dumps_report, host_info, write_report

__all__ = [
    "LatencyHistogram", "format_ns",
    "NetworkMetrics", "StationMetrics", "station_key",
    "REPORT_SCHEMA", "SCHEMA_ID", "build_report", "write_report", "dumps_report", "host_info",
    "Assertion", "AssertionResult", "AssertionSyntaxError", "parse_assertion", "parse_assertions", "check_all",
    "assertable_fields",
]
