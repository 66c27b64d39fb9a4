"""The run report: its JSON Schema, an atomic writer and the host description.

The report document is produced by :meth:`mlink_sim.metrics.network.NetworkMetrics.report`; every field is
explained in ``docs/report.md``. :data:`REPORT_SCHEMA` is a JSON Schema (draft 2020-12). Each numeric leaf
carries an ``"x-kind"`` annotation (ignored by validators) that the ``--assert`` language reads to know what a
field is measured in:

* ``"time"``    – integer nanoseconds; assertions need a unit (``ns``, ``us``, ``µs``, ``ms``, ``s``).
* ``"count"``   – a plain integer; assertions take no unit.
* ``"percent"`` – a number in percent (CPU: of one core); ``%`` is optional in assertions.
* ``"ratio"``   – a fraction 0..1; a bare number is a fraction, ``1%`` means 0.01.
"""

from __future__ import annotations

import functools
import json
import os
import platform
from collections.abc import Mapping, Sequence
from typing import Any

from .. import _accel
from .._files import write_atomically

__all__ = ["REPORT_SCHEMA", "SCHEMA_ID", "INJECTED_KINDS", "build_report", "write_report", "dumps_report", "host_info"]

#: Value of the report's ``"schema"`` field. Bumped (``/2``) on any incompatible change of the document.
SCHEMA_ID = "mlink-sim/report/1"

_COUNT = {"type": "integer", "minimum": 0, "x-kind": "count"}
#: The report's ``station[…].injected`` keys (the fault injection counts under them, docs/faults.md); a new kind
#: of fault adds its name here and its stage counts under it.
INJECTED_KINDS: tuple[str, ...] = ("drops", "delays", "corruptions", "duplicates", "reorders",
                                   "silences", "skips", "wdt_freezes", "bad_commands", "drive_faults")
_INJECTED_HELP = {
    "drops": "datagrams dropped (loss)", "delays": "datagrams delivered later (delay, jitter)",
    "corruptions": "datagrams with a bit flipped after the FCS", "duplicates": "datagrams delivered twice",
    "reorders": "datagrams held back until the next one overtook them",
    "silences": "responses dropped (silence)", "skips": "commands the master did not send (skip-cycles)",
    "wdt_freezes": "commands sent with a frozen WDT count (freeze-wdt)",
    "bad_commands": "refused commands slipped in (bad-command)",
    "drive_faults": "load steps, locked rotors and mains losses applied to the drive",
}
_TIME = {"type": "integer", "minimum": 0, "x-kind": "time"}

REPORT_SCHEMA: dict[str, Any] = {
    "$schema": "https://json-schema.org/draft/2020-12/schema",
    "$id": "https://github.com/mlink-sim/mlink-sim/schemas/report-1.json",
    "title": "mlink-sim run report",
    "description": "Figures of one `mlink-sim up` run (docs/report.md).",
    "type": "object",
    "additionalProperties": False,
    "required": [
        "schema", "meta", "cycles", "missed", "missed_rate", "rtt", "lateness", "sent", "answered", "late",
        "missing", "reception_failures", "wdt_errors", "dropped", "cpu", "station", "checks", "assertions",
    ],
    "properties": {
        "schema": {"const": SCHEMA_ID},
        "meta": {"$ref": "#/$defs/meta"},
        "cycles": {**_COUNT, "description": "cycles due in the run: started + missed"},
        "missed": {**_COUNT, "description": "cycles whose start was skipped (loop blocked a whole period)"},
        "missed_rate": {
            "type": "number", "minimum": 0, "maximum": 1, "x-kind": "ratio",
            "description": "missed / cycles (0 when cycles is 0)",
        },
        "rtt": {"$ref": "#/$defs/histogram", "description": "command → response round trip, all stations"},
        "lateness": {"$ref": "#/$defs/histogram", "description": "cycle start minus its ideal start"},
        "sent": {**_COUNT, "description": "commands sent, all stations"},
        "answered": {**_COUNT, "description": "responses matched to a command (on time or late)"},
        "late": {**_COUNT, "description": "responses that arrived after their cycle's deadline"},
        "missing": {**_COUNT, "description": "commands never answered"},
        "reception_failures": {**_COUNT, "description": "reception failures counted by the slaves"},
        "wdt_errors": {**_COUNT, "description": "watchdog (WDT) errors counted by the slaves"},
        "dropped": {**_COUNT, "description": "datagrams dropped by the slaves (bad frames)"},
        "foreign_source": {**_COUNT, "description": "commands the slaves ignored: not from the station's master "
                                                    "(or from a source --allow-master does not name)"},
        "cpu": {"$ref": "#/$defs/cpu"},
        "station": {
            "type": "object",
            "description": "per station, keyed by address as '0x%02x'",
            "patternProperties": {"^0x[0-9a-f]{2}$": {"$ref": "#/$defs/station"}},
            "additionalProperties": False,
        },
        "host": {"$ref": "#/$defs/host"},
        "checks": {"type": "array", "items": {"$ref": "#/$defs/check"}},
        "assertions": {"type": "array", "items": {"$ref": "#/$defs/assertion"}},
    },
    "$defs": {
        "host": {
            "type": "object",
            "additionalProperties": False,
            "required": ["policy", "bound", "stall", "by_process", "stalls"],
            "description": "host stalls: how late each process's own loop and clock ran (metrics/stalls.py)",
            "properties": {
                "policy": {"enum": ["absorb", "strict"], "description": "the host-stall policy (docs/timing.md)"},
                "bound": {**_TIME, "description": "longest stall the policy absorbs (0 with strict)"},
                "stall": {"$ref": "#/$defs/stalls", "description": "every process together"},
                "by_process": {"type": "object", "additionalProperties": {"$ref": "#/$defs/stalls"}},
                "stalls": {"type": "array", "items": {"$ref": "#/$defs/stall_event"},
                           "description": "the longest 100 stalls, in time order"},
            },
        },
        "stalls": {
            "type": "object",
            "additionalProperties": False,
            "required": ["count", "total", "max", "cycles", "absorbed", "lost"],
            "properties": {
                "count": {**_COUNT, "description": "stalls"},
                "total": {**_TIME, "description": "their durations added up"},
                "max": {**_TIME, "description": "the longest"},
                "cycles": {**_COUNT, "description": "master cycles they delayed"},
                "absorbed": {**_COUNT, "description": "of those, run late (policy absorb, stall within bound)"},
                "lost": {**_COUNT, "description": "of those, skipped: the slaves saw them as lost"},
            },
        },
        "stall_event": {
            "type": "object",
            "additionalProperties": False,
            "required": ["process", "at", "duration", "cycles", "absorbed"],
            "properties": {
                "process": {"type": "string"},
                "at": {**_TIME, "description": "when the late wake-up was due, from the measured span's start"},
                "duration": {**_TIME}, "cycles": {**_COUNT}, "absorbed": {"type": "boolean"},
            },
        },
        "meta": {
            "type": "object",
            "required": ["config", "started", "duration_s", "cycle_ns"],
            "additionalProperties": True,
            "properties": {
                "config": {"type": "string", "description": "network configuration file as given"},
                "started": {"type": "string", "format": "date-time",
                            "description": "ISO 8601 wall time at which the measured span began"},
                "duration_s": {"type": "number", "minimum": 0, "description": "measured span in seconds"},
                "measured_from": {"enum": ["start", "bring-up done"],
                                  "description": "where the figures count from (up: --include-bringup = start)"},
                "cycle_ns": {"type": "integer", "minimum": 1, "description": "transmission cycle in ns"},
                "generation": {"type": "string",
                               "description": "the links in use, comma-separated: MECHATROLINK-I, -II, -III"},
                "stations": {"type": "integer", "minimum": 0, "description": "number of slave stations"},
                "host": {"type": "object",
                         "description": "host_info(): machine, interpreter, compiled or pure-Python cores"},
                "problems": {"type": "array", "items": {"type": "string"},
                             "description": "what went wrong outside the checks (stations not up, slaves exited)"},
                "interrupted": {"enum": [None, "SIGINT", "SIGTERM"],
                                "description": "the signal that ended the run early (up / master), else null"},
                "not_run": {"type": "array", "items": {"type": "string"},
                            "description": "timeline steps that never began (a signal or --duration ended the run)"},
            },
        },
        "histogram": {
            "type": "object",
            "additionalProperties": False,
            "required": ["count", "min", "p50", "p90", "p99", "p99_9", "max", "mean"],
            "properties": {
                "count": {**_COUNT, "description": "number of values"},
                "min": {**_TIME}, "p50": {**_TIME}, "p90": {**_TIME}, "p99": {**_TIME},
                "p99_9": {**_TIME}, "max": {**_TIME}, "mean": {**_TIME},
                "hdr": {"type": "string", "description": "HDR V2 compressed base64 histogram (optional)"},
                "bins": {"type": "array", "description": "the histogram to look at (top-level rtt): [lower, upper, "
                         "count] per bin, values in (lower, upper] ns, bins 2^(1/4) wide, contiguous",
                         "items": {"type": "array", "prefixItems": [_TIME, _TIME, _COUNT], "minItems": 3,
                                   "maxItems": 3}},
            },
        },
        "station": {
            "type": "object",
            "additionalProperties": False,
            "required": ["rtt", "sent", "answered", "late", "missing", "reception_failures", "wdt_errors",
                         "dropped"],
            "properties": {
                "rtt": {"$ref": "#/$defs/histogram"},
                "sent": {**_COUNT}, "answered": {**_COUNT}, "late": {**_COUNT}, "missing": {**_COUNT},
                "alarms": {**_COUNT, "description": "alarms and warnings the station raised, as the master saw them"},
                "reception_failures": {**_COUNT}, "wdt_errors": {**_COUNT}, "dropped": {**_COUNT},
                "foreign_source": {**_COUNT},
                "recovery": {"$ref": "#/$defs/histogram",
                             "description": "recovery times: a fault's end to phase 3 with no alarm (docs/faults.md)"},
                "injected": {"$ref": "#/$defs/injected"},
                "unrecovered": {**_COUNT, "description": "faults after which the station did not recover"},
            },
        },
        "injected": {
            "type": "object",
            "additionalProperties": {**_COUNT},
            "required": list(INJECTED_KINDS),
            "description": "what the fault injection did to the station's datagrams (docs/faults.md)",
            "properties": {name: {**_COUNT, "description": _INJECTED_HELP.get(name, name)}
                           for name in INJECTED_KINDS},
        },
        "cpu": {
            "type": "object",
            "additionalProperties": False,
            "required": ["master", "slaves", "by_process"],
            "properties": {
                "master": {"type": "number", "minimum": 0, "x-kind": "percent"},
                "slaves": {"type": "number", "minimum": 0, "x-kind": "percent"},
                "by_process": {
                    "type": "object",
                    "description": "percent of one core per role: 'master', 'slave:0x21', 'worker:1', ...",
                    "additionalProperties": {"type": "number", "minimum": 0},
                },
            },
        },
        "check": {
            "type": "object",
            "required": ["at", "what", "ok"],
            "additionalProperties": False,
            "properties": {
                "at": {"type": "number", "description": "seconds since the start of the run"},
                "what": {"type": "string"},
                "ok": {"type": "boolean"},
                "station": {"type": "string", "pattern": "^0x[0-9a-f]{2}$",
                            "description": "the station the check judged (the HTML report shows its figures then)"},
                "detail": {"type": "string"},
                "cause": {"type": "string", "description": "a failed check of the drive: what the drive model was "
                          "doing at that moment and why (docs/configuration.md, 'When a check fails')"},
            },
        },
        "assertion": {
            "type": "object",
            "required": ["text", "ok", "measured", "message"],
            "additionalProperties": False,
            "properties": {
                "text": {"type": "string", "description": "the expression, normalised"},
                "ok": {"type": "boolean"},
                "measured": {"type": ["number", "null"], "description": "in ns for times; null if absent"},
                "bound": {"type": "number", "description": "in ns for times"},
                "message": {"type": "string"},
            },
        },
    },
}


def build_report(metrics: Any, meta: dict[str, Any], assertions: Sequence[Any] = ()) -> dict[str, Any]:
    """The report of *metrics* (a ``NetworkMetrics``, a copy of a running network's) with *meta*, and *assertions*
    (parsed ``--assert`` expressions) evaluated into it."""
    from .assertions import check_all

    report = metrics.report(meta=meta)
    report["assertions"] = [r.as_dict() for r in check_all(list(assertions), report)] if assertions else []
    return report


def dumps_report(report: Mapping[str, Any]) -> str:
    """The report as JSON text (2-space indent, trailing newline). NaN/Infinity raise ValueError."""
    return json.dumps(report, indent=2, allow_nan=False, ensure_ascii=False) + "\n"


def write_report(path: str | os.PathLike[str], report: Mapping[str, Any]) -> None:
    """Write ``report`` as JSON to ``path`` atomically and durably (:func:`mlink_sim._files.write_atomically`).

    The document is serialised first, so a document that cannot be written fails before anything touches the
    disk. On any error an existing ``path`` is left untouched and no temporary file stays behind. The file gets
    the mode of the file it replaces, else 0644.
    """
    text = dumps_report(report)              # fails before anything touches the disk
    write_atomically(path, text)


def host_info() -> dict[str, Any]:
    """What the run ran on, for ``meta.host``. The first call takes many cycles' time (``platform.platform()`` reads the
    interpreter binary for its libc version), so it is made once and kept: a session calls it before the cycle
    starts, and a live report in the middle of a run then costs nothing here."""
    return dict(_host_info())


@functools.cache
def _host_info() -> dict[str, Any]:
    return {
        "name": platform.node(),
        "os": platform.platform(),
        "machine": platform.machine(),
        "cpus": os.cpu_count() or 0,
        "python": f"{platform.python_implementation()} {platform.python_version()}",
        "cores": _accel.describe(),  # compiled (mypyc) or pure-Python cores (docs/architecture.md)
    }
