"""``mlink-sim report REPORT.json --html FILE [--trace TRACE.csv]``: the HTML report of a finished run.

The same page as ``up --report-html`` writes (:mod:`mlink_sim.metrics.html`), from a report written with
``--report``; the trace is the one given, else the one the report names (``meta.trace``: as written, else beside
the report). docs/report.md, "The HTML report".
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import click

from .inputs import InputError, report_path

__all__ = ["report_cmd", "load_report", "load_trace_for"]


def load_report(path: str) -> dict[str, Any]:
    """The run report at *path*; :class:`InputError` (one line, exit 2) if it cannot be read or is not one."""
    try:
        text = Path(path).read_text(encoding="utf-8")
    except OSError as exc:
        raise InputError(f"{path}: cannot read the report: {exc.strerror or exc}") from None
    except UnicodeDecodeError:
        raise InputError(f"{path}: not a report of mlink-sim (not UTF-8 text)") from None
    try:
        report = json.loads(text)
    except ValueError as exc:
        raise InputError(f"{path}: not a report of mlink-sim (invalid JSON: {exc})") from None
    if not (isinstance(report, dict) and str(report.get("schema", "")).startswith("mlink-sim/report/")
            and isinstance(report.get("meta"), dict) and isinstance(report.get("checks", []), list)):
        raise InputError(f"{path}: not a report of mlink-sim (no \"schema\": \"mlink-sim/report/…\" with its "
                         "\"meta\"; write one with 'mlink-sim up CONFIG --report FILE')")
    return report


def load_trace_for(report: dict[str, Any], report_file: str, given: str | None) -> Any:
    """The trace for *report*: *given* (a bad one is an :class:`InputError`), else the one ``meta.trace`` names,
    found as written or beside *report_file* (a note on stderr and None when it is not there)."""
    from ..metrics.html import check_moments
    from ..metrics.trace import TraceError, read_trace

    moments = check_moments(report)
    if given is not None:
        try:
            return read_trace(given, moments=moments)
        except TraceError as exc:
            raise InputError(f"--trace: {exc}") from None
    named = report["meta"].get("trace")
    if not isinstance(named, str) or not named:
        return None
    for candidate in (Path(named), Path(report_file).parent / Path(named).name):
        if candidate.is_file():
            try:
                return read_trace(candidate, moments=moments)
            except TraceError as exc:
                click.echo(f"mlink-sim report: note: {exc}; the page has no traces", err=True)
                return None
    click.echo(f"mlink-sim report: note: the trace the report names ({named}) is not there; the page has no "
               "traces (--trace FILE gives one)", err=True)
    return None


@click.command("report")
@click.argument("report_file", metavar="REPORT.json", type=click.Path(dir_okay=False))
@click.option("--html", "html_path", required=True, metavar="FILE", type=click.Path(dir_okay=False),
              help="Write the HTML report here (one self-contained file).")
@click.option("--trace", "trace_path", metavar="TRACE.csv", type=click.Path(dir_okay=False),
              help="The run's trace (default: the one the report names in meta.trace).")
def report_cmd(report_file: str, html_path: str, trace_path: str | None) -> None:
    """Write the HTML report of a finished run from its JSON report (--report) and trace (--trace)."""
    from ..metrics.html import write_html

    out = report_path(html_path, "--html", "report.html")
    report = load_report(report_file)
    trace = load_trace_for(report, report_file, trace_path)
    assert out is not None
    try:
        write_html(out, report, trace)
    except OSError as exc:
        raise InputError(f"--html {html_path}: {exc.strerror or exc}") from None
    click.echo(f"{out}: the HTML report of {report_file}" + (f" with the trace {trace.path}" if trace else ""))
