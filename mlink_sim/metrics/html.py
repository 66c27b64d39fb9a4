"""The HTML report (``--report-html FILE``, ``mlink-sim report REPORT.json --html FILE``): one self-contained file.

From a run report (docs/report.md) and, where there is one, its trace (:mod:`mlink_sim.metrics.trace`): the
verdict; each check with the station's figures at that moment (its last trace sample at or before the check's
time); the ``--assert`` bounds; the RTT histogram (the report's ``rtt.bins``) beside the round trips over time, and
the per-station round trips; per station its reference and output frequency (signed: a reverse run below 0 Hz),
output current and DC bus voltage over time, with the actions and checks as numbered marks listed under the plots,
and the faults and the drive's regulation (stall prevention, the torque limit) shaded, in the plotting vocabulary
the live page shares (:mod:`mlink_sim.plots`); the faults injected against their recovery times; the host stalls;
the actions.

Self-contained: inline CSS and inline SVG (:mod:`mlink_sim.metrics.svg`, why no script: there), no ``src`` or
``href`` that leaves the file, so it opens from disk, from a CI's artifacts or a mail with no network. Text from
the report and the trace is escaped. Written atomically (:func:`write_html`).
"""

from __future__ import annotations

import os
import re
from collections.abc import Mapping, Sequence
from html import escape
from typing import Any

from .._files import write_atomically
from ..plots import BANDS, BEFORE_ZERO, MARKS, STATION_PLOTS, TIME_LABEL, mark_kind
from ..units import format_ns
from .svg import Mark, Series, Span, bar_chart, line_chart
from .trace import StationTrace, Trace

__all__ = ["render_html", "write_html", "verdict_of", "check_moments", "tail_folded"]

_CSS = """
body{font:14px/1.45 system-ui,-apple-system,"Segoe UI",Roboto,sans-serif;margin:0 auto;max-width:1100px;
padding:12px 16px;color:#222}
h1{font-size:22px;margin:8px 0}h2{font-size:18px;margin:28px 0 8px;border-bottom:1px solid #ddd}
h3{font-size:15px;margin:16px 0 4px}
table{border-collapse:collapse;margin:6px 0;font-size:13px}td,th{border:1px solid #ddd;padding:3px 7px;
text-align:left;vertical-align:top}th{background:#f5f5f5}td.n{text-align:right;font-variant-numeric:tabular-nums}
.verdict{font-size:20px;font-weight:600;padding:10px 14px;border-radius:6px;margin:10px 0}
.pass{background:#e3f4e1;color:#1d5e1a}.fail{background:#fbe3e1;color:#8a1c13}.stop{background:#fdf1d6;color:#6b4b00}
.ok{color:#1d6e1a;font-weight:600}.bad{color:#a11b10;font-weight:600}.muted{color:#777;fill:#777}
svg.plot{max-width:100%;height:auto;margin:4px 0;font-size:11px}svg .axes line{stroke:#999}
svg .grid{stroke:#eee}svg text{fill:#333}svg .plot-title{font-weight:600;font-size:12px}
svg text.mark-n{fill:#fff;font-weight:700;font-size:9px}
.scroll{overflow-x:auto}code{font-size:12px}
.pair{display:grid;grid-template-columns:1fr 1fr;gap:8px}@media (max-width:800px){.pair{grid-template-columns:1fr}}
ol.marks{list-style:none;padding:0;margin:4px 0 12px;columns:2 360px;font-size:12px}
ol.marks li{break-inside:avoid;margin:1px 0}
.n{display:inline-block;min-width:16px;padding:0 3px;border-radius:8px;color:#fff;font-size:10px;font-weight:700;
text-align:center;margin-right:4px}.sw{display:inline-block;width:12px;height:10px;margin:0 3px 0 10px;opacity:.6}
.n,.sw,svg{-webkit-print-color-adjust:exact;print-color-adjust:exact}
@media print{.pair{grid-template-columns:1fr}h3{break-after:avoid}svg.plot{break-inside:avoid}}
"""
#: Numbered marks drawn per station at most; the rest are in the actions table.
MAX_MARKS = 99

#: Figures shown beside a check (trace columns) and their headings.
_AT_CHECK = (("phase", "phase"), ("running", "run"), ("direction", "dir"), ("reference_hz", "ref Hz"),
             ("output_hz", "out Hz"), ("output_current_a", "A"), ("dc_bus_v", "DC bus V"),
             ("alarm_name", "alarm"))
_FAULT_START = {"fault": "fault-end", "impair-start": "impair-end"}


def verdict_of(report: Mapping[str, Any]) -> tuple[str, str]:
    """``(css class, sentence)`` of the run's outcome as the report records it: interrupted, failed (a check, an
    assertion, a station that never came up) or passed."""
    meta = report.get("meta", {})
    checks = report.get("checks", [])
    asserts = report.get("assertions", [])
    failed = sum(not c.get("ok") for c in checks) + sum(not a.get("ok") for a in asserts)
    held = len(checks) + len(asserts) - failed
    unreached = sum("did not reach" in p for p in meta.get("problems", []))
    parts = []
    if failed:
        parts.append(f"{failed} check(s) failed")
    if unreached:
        parts.append(f"{unreached} station(s) did not come up")
    if meta.get("not_run"):
        parts.append(f"{len(meta['not_run'])} timeline step(s) not run")
    held_text = f"{held} check(s) held" if held else "none held" if failed else "no checks"
    if meta.get("interrupted"):
        return "stop", f"Interrupted by {meta['interrupted']}: " + "; ".join(parts + [held_text])
    if failed or unreached:
        return "fail", "Failed: " + "; ".join(parts + [held_text])
    return "pass", "Passed: " + ("all checks held" if held else "run complete, no checks") + (
        f" ({'; '.join(parts)})" if parts else "")


def check_moments(report: Mapping[str, Any]) -> dict[str, list[float]]:
    """``{"0x21": [3.0, …]}``: the moments the report's checks judged each station (for ``read_trace``)."""
    out: dict[str, list[float]] = {}
    for c in report.get("checks", []):
        if c.get("station"):
            out.setdefault(c["station"], []).append(float(c["at"]))
    return out


def write_html(path: str | os.PathLike[str], report: Mapping[str, Any], trace: Trace | None = None) -> None:
    """Write the HTML report of *report* (and *trace*) to *path*, atomically (``_files.write_atomically``)."""
    write_atomically(path, render_html(report, trace))


def render_html(report: Mapping[str, Any], trace: Trace | None = None) -> str:
    """The HTML report as one string (see the module docstring)."""
    meta = report.get("meta", {})
    name = meta.get("network") or meta.get("config") or "run"
    cls, sentence = verdict_of(report)
    body = [
        f"<h1>mlink-sim report: {_e(name)}</h1>",
        f'<div class="verdict {cls}" id="verdict">{_e(sentence)}</div>',
        _overview(report),
        _checks(report, trace),
        _assertions(report),
        _rtt(report, trace),
        _traces(trace),
        _faults(report, trace),
        _stalls(report),
        _actions(trace),
        _run_notes(report, trace),
    ]
    return ("<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
            "<meta name=\"viewport\" content=\"width=device-width,initial-scale=1\">"
            f"<title>mlink-sim report: {_e(name)}</title><style>{_CSS}</style></head><body>"
            + "\n".join(part for part in body if part) + "</body></html>\n")


def _e(value: Any) -> str:
    return escape("" if value is None else str(value))


def _table(head: Sequence[str], rows: Sequence[Sequence[str]], numeric: Sequence[int] = ()) -> str:
    """A table of already-escaped cells; columns *numeric* right-aligned."""
    th = "".join(f"<th>{h}</th>" for h in head) if any(head) else ""
    trs = "".join("<tr>" + "".join(f'<td class="n">{c}</td>' if i in numeric else f"<td>{c}</td>"
                                   for i, c in enumerate(row)) + "</tr>" for row in rows)
    return f'<div class="scroll"><table>{f"<tr>{th}</tr>" if th else ""}{trs}</table></div>'


def _ns(value: Any) -> str:
    return format_ns(value) if isinstance(value, int | float) else "–"


def _overview(report: Mapping[str, Any]) -> str:
    meta = report.get("meta", {})
    rtt = report.get("rtt", {})
    host = meta.get("host", {}) if isinstance(meta.get("host"), dict) else {}
    rows = [
        ("config", _e(meta.get("config"))),
        ("started", _e(meta.get("started"))),
        ("measured", f"{_e(meta.get('duration_s'))} s from {_e(meta.get('measured_from', 'start'))}"),
        ("clock", _e(meta.get("clock", "real")) + (f", seed {_e(meta.get('seed'))}" if "seed" in meta else "")),
        ("network", f"{_e(meta.get('stations'))} station(s), {_e(meta.get('generation', ''))}, cycle "
                    f"{_ns(meta.get('cycle_ns'))}"),
        ("round trip", f"p50 {_ns(rtt.get('p50'))}, p99 {_ns(rtt.get('p99'))}, max {_ns(rtt.get('max'))} "
                       f"({_e(rtt.get('count', 0))} responses)"),
        ("cycles", f"{_e(report.get('cycles'))} due, {_e(report.get('missed'))} missed; "
                   f"{_e(report.get('missing'))} answers missing, {_e(report.get('late'))} late"),
        ("stations saw", f"{_e(report.get('reception_failures'))} reception failures, "
                         f"{_e(report.get('wdt_errors'))} WDT errors, {_e(report.get('dropped'))} dropped"),
        ("host", _e(", ".join(str(host[k]) for k in ("name", "os", "python", "cores") if host.get(k)))),
    ]
    return "<h2>Run</h2>" + _table(("", ""), [(f"<b>{k}</b>", v) for k, v in rows])


def _checks(report: Mapping[str, Any], trace: Trace | None) -> str:
    checks = report.get("checks", [])
    if not checks:
        return "<h2>Checks</h2><p class=\"muted\">The timeline has no checks.</p>"
    note = ("" if trace is not None else
            '<p class="muted">No trace: the drive\'s figures at each check need one (--trace, --report-html).</p>')
    rows = []
    for c in checks:
        state = trace.at.get((c.get("station", ""), float(c["at"]))) if trace is not None else None
        figures = [_e(state.get(col)) if state else "–" for col, _ in _AT_CHECK]
        when = f"{float(c['at']):g} s" + (f" <span class=\"muted\">(sample {_e(state['t_s'])} s)</span>"
                                          if state else "")
        ok = '<span class="ok">ok</span>' if c.get("ok") else '<span class="bad">FAIL</span>'
        why = _e(c.get("detail", "")) + (f"<br><i>{_e(c['cause'])}</i>" if c.get("cause") else "")
        rows.append((ok, when, _e(c.get("what")), why, *figures))
    return ("<h2>Checks</h2>" + note + _table(("", "at", "check", "seen (and why)", *(h for _, h in _AT_CHECK)),
                                               rows, numeric=range(7, 11)))


def _assertions(report: Mapping[str, Any]) -> str:
    asserts = report.get("assertions", [])
    if not asserts:
        return ""
    rows = [('<span class="ok">ok</span>' if a.get("ok") else '<span class="bad">FAIL</span>',
             f"<code>{_e(a.get('text'))}</code>", _e(a.get("message"))) for a in asserts]
    return "<h2>Assertions</h2>" + _table(("", "bound", "result"), rows)


def tail_folded(bins: Sequence[Sequence[int]], keep: float = 0.999, room: int = 4) -> tuple[list[list[int]], str]:
    """*bins* for the plot: when the bins past the one that holds *keep* of the values are more than *room*, they
    are one last bar (a few outliers would squeeze the body of the histogram into a corner); and a sentence saying
    so."""
    total = sum(b[2] for b in bins)
    running = 0
    cumulative = []
    for b in bins:
        running += b[2]
        cumulative.append(running)
    i = next((k for k, c in enumerate(cumulative) if c >= keep * total), len(bins) - 1)
    if len(bins) - 1 - i <= room:
        return [list(b) for b in bins], ""
    cut = i + 1 + room // 2
    tail = bins[cut:]
    n = sum(b[2] for b in tail)
    return ([*(list(b) for b in bins[:cut]), [tail[0][0], tail[-1][1], n]],
            f"The last bar holds the {n} round trip(s) from {format_ns(tail[0][0])} to {format_ns(tail[-1][1])}.")


def _rtt(report: Mapping[str, Any], trace: Trace | None = None) -> str:
    rtt = report.get("rtt", {})
    bins, folded = tail_folded(rtt.get("bins") or [])
    over_time = _rtt_over_time(trace)
    width = _HALF if over_time else 860  # side by side: each at half the width, its text as large
    chart = bar_chart(f"Round trips, all stations ({rtt.get('count', 0)})", bins, x_label="round trip",
                      label_of=format_ns, width=width)
    if not bins and rtt.get("count"):
        chart = '<p class="muted">This report has no histogram bins (written by an older version).</p>'
    chart = f'<div class="pair"><div>{chart}</div><div>{over_time}</div></div>' if over_time else chart
    if folded:
        chart += f'<p class="muted">{_e(folded)}</p>'
    rows = []
    for key, st in sorted(report.get("station", {}).items()):
        h = st.get("rtt", {})
        rows.append((f"{int(key, 16):02X}H", *(_ns(h.get(k)) for k in ("p50", "p99", "max")),
                     *(_e(st.get(k)) for k in ("sent", "answered", "missing", "late", "reception_failures",
                                                "wdt_errors", "alarms"))))
    return ("<h2>Round trips</h2>" + chart
            + _table(("station", "p50", "p99", "max", "sent", "answered", "missing", "late", "reception failures",
                      "WDT errors", "alarms"), rows, numeric=range(1, 11)))


_RTT_LINES = 8  # stations drawn one line each at most; more: the worst of them at each moment
_HALF = 540  # the width of each of two plots side by side


def _rtt_over_time(trace: Trace | None) -> str:
    """Each station's latest round trip over the run (the trace's ``rtt_us``), faults and impairments shaded; over
    :data:`_RTT_LINES` stations, the worst at each moment."""
    if trace is None or not trace.stations:
        return ""
    stations = sorted(trace.stations.items())
    if len(stations) <= _RTT_LINES:
        series = [Series(f"{int(a, 16):02X}H", st.t, st.series["rtt_us"]) for a, st in stations]
    else:
        steps = [(st.t[-1] - st.t[0]) / (len(st.t) - 1) for _, st in stations if len(st.t) > 1]
        step = max(steps) if steps and max(steps) > 0 else 1.0
        worst: dict[float, float] = {}
        for _, st in stations:
            for t, v in zip(st.t, st.series["rtt_us"], strict=True):
                if v is not None:
                    k = round(round(t / step) * step, 6)
                    worst[k] = max(worst.get(k, v), v)
        xs = sorted(worst)
        series = [Series(f"worst of {len(stations)} stations", xs, [worst[x] for x in xs])]
    spans = [sp for a, _ in stations for sp in _fault_spans(trace, a, only_own=True)]
    return line_chart("Round trips over time (each station's latest)", series, y_label="µs", x_label=TIME_LABEL,
                      spans=spans, x_range=trace.span, width=_HALF)


def _fault_spans(trace: Trace, address: str, *, only_own: bool = False) -> list[Span]:
    """The faults and impairments in force on *address* (and, unless *only_own*, on every station) as spans."""
    spans: list[Span] = []
    open_: dict[tuple[str, str], list[tuple[float, str]]] = {}
    end = trace.span[1] if trace.span else 0.0
    color, what = BANDS["fault"]["color"], BANDS["fault"]["label"]
    for a in trace.actions:
        if a["address"] != address and (only_own or a["address"] != ""):
            continue
        ev = a["event"]
        if ev in _FAULT_START:
            open_.setdefault((_FAULT_START[ev], a["address"]), []).append((a["t_s"], a["detail"]))
        elif ev in _FAULT_START.values() and open_.get((ev, a["address"])):
            t0, detail = open_[(ev, a["address"])].pop(0)
            spans.append(Span(t0, a["t_s"], f"{what}: {detail}, {t0:g}–{a['t_s']:g} s", color))
    for starts in open_.values():
        spans.extend(Span(t0, end, f"{what}: {detail}, from {t0:g} s (not ended)", color) for t0, detail in starts)
    return spans


def _marks(trace: Trace, address: str) -> tuple[list[Mark], int]:
    """The actions and checks on *address* (or on every station) as marks numbered in time order; how many more
    there were than :data:`MAX_MARKS`."""
    marks: list[Mark] = []
    more = 0
    for a in trace.actions:
        if a["address"] not in ("", address):
            continue
        kind = mark_kind(a["event"], a["detail"])
        if kind is None:
            continue
        if len(marks) == MAX_MARKS:
            more += 1
            continue
        label = f"{_when(a['t_s'])}  {_mark_text(a['event'], a['detail'])}"
        marks.append(Mark(a["t_s"], label, MARKS[kind]["color"], len(marks) + 1, kind))
    return marks, more


_CHECK = re.compile(r"(ok|FAIL) (?:[\d.]+s (?:station [0-9A-F]{2}H|all stations): )?(.*)", re.S)
_STEP = re.compile(r"[\d.]+s (.*)", re.S)


def _mark_text(event: str, detail: str) -> str:
    """What a numbered mark stands for, without what its place says already (its time, its station)."""
    if event == "check" and (m := _CHECK.fullmatch(detail)):
        what, _, seen = m.group(2).partition(": ")
        return f"{'held' if m.group(1) == 'ok' else 'FAILED'}: {what}" + (f" ({seen})" if seen else "")
    if event == "step" and (m := _STEP.fullmatch(detail)):
        return m.group(1)
    return f"{event}: {detail}"


def _regulation_spans(st: StationTrace) -> list[Span]:
    return [Span(t0, t1, f"{BANDS[state]['label']}, {t0:g}–{t1:g} s", BANDS[state]["color"], state)
            for t0, t1, state in st.bands if state in BANDS]


def _when(t: float) -> str:
    """A trace time as the page writes it; before the timeline's 0 s: said to be bring-up."""
    return f"{t:g} s" + (f" ({BEFORE_ZERO})" if t < 0 else "")


def _traces(trace: Trace | None) -> str:
    if trace is None:
        return ""
    if not trace.stations:
        return "<h2>Stations over time</h2><p class=\"muted\">The trace has no samples.</p>"
    out = [f"<h2>Stations over time</h2><p class=\"muted\">From the trace <code>{_e(trace.path)}</code>. Numbered: "
           "the actions and checks, listed under each station's plots; shaded: faults and impairments in force and "
           "the drive's own regulation (stall prevention, the torque limit). A reverse run is below 0 Hz.</p>"]
    x_range = trace.span
    for address, st in sorted(trace.stations.items()):
        marks, more = _marks(trace, address)
        spans = _fault_spans(trace, address) + _regulation_spans(st)
        label = f"{int(address, 16):02X}H"
        label += f" ({st.name})" if st.name and st.name != label else ""
        thinned = f" (every {st.stride}th of {st.samples} samples)" if st.stride > 1 else ""
        out.append(f"<section class=\"station-plots\"><h3 id=\"station-{_e(address)}\">Station {_e(label)}"
                   f"{_e(thinned)}</h3>")
        for plot in STATION_PLOTS:
            series = [Series(sr["label"], st.t, st.series[sr["key"]], sr["color"], dash=bool(sr.get("dash")))
                      for sr in plot["series"]]
            out.append(line_chart(f"{label}: {plot['title']}", series, y_label=plot["unit"], x_label=TIME_LABEL,
                                  marks=marks, spans=spans, x_range=x_range))
        out.append(_legend(marks, more, spans) + "</section>")
    return "".join(out)


def _legend(marks: Sequence[Mark], more: int, spans: Sequence[Span]) -> str:
    """What each number and each shade of a station's plots is, as text, so that it prints."""
    items = "".join(f'<li data-n="{m.number}" data-kind="{_e(m.kind)}"><span class="n" style="background:'
                    f'{m.color}">{m.number}</span>{_e(m.label)}</li>' for m in marks)
    out = f'<ol class="marks">{items}</ol>' if items else ""
    if more:
        out += f'<p class="muted">{more} more action(s) and check(s): the actions table below.</p>'
    shades = [b for b in dict.fromkeys(sp.band for sp in spans) if b in BANDS]
    if shades:
        out += '<p class="bands">shaded:' + "".join(
            f'<span class="sw" style="background:{BANDS[b]["color"]}"></span>{_e(BANDS[b]["label"])}'
            for b in shades) + "</p>"
    return out


def _faults(report: Mapping[str, Any], trace: Trace | None) -> str:
    stations = report.get("station", {})
    rows = []
    for key, st in sorted(stations.items()):
        rec = st.get("recovery") or {}
        injected = ", ".join(f"{n} {k}" for k, n in (st.get("injected") or {}).items() if n)
        if rec.get("count") or st.get("unrecovered") or injected:
            rows.append((f"{int(key, 16):02X}H", _e(rec.get("count", 0)), _ns(rec.get("p50")), _ns(rec.get("max")),
                         _e(st.get("unrecovered", 0)), _e(injected or "–")))
    episodes = []
    if trace is not None:
        starts: dict[str, list[dict[str, Any]]] = {}
        for a in trace.actions:
            if a["event"] == "fault":
                starts.setdefault(a["address"], []).append({"start": a, "end": None, "outcome": None})
            elif a["event"] in ("fault-end", "recovered", "unrecovered"):
                slot = "end" if a["event"] == "fault-end" else "outcome"
                ep = next((e for e in starts.get(a["address"], []) if e[slot] is None), None)
                if ep is not None:
                    ep[slot] = a
        for address, eps in sorted(starts.items()):
            for ep in eps:
                end, outcome = ep["end"], ep["outcome"]
                rows_outcome = ('<span class="muted">not settled</span>' if outcome is None else
                                f'<span class="{"ok" if outcome["event"] == "recovered" else "bad"}">'
                                f'{_e(outcome["event"])}</span> {_e(outcome["detail"])}')
                episodes.append((f"{int(address, 16):02X}H" if address else "all", f"{ep['start']['t_s']:g} s",
                                 f"{end['t_s']:g} s" if end else "–", _e(ep["start"]["detail"]), rows_outcome))
    if not rows and not episodes:
        return "<h2>Faults and recovery</h2><p class=\"muted\">No fault was injected.</p>"
    out = ["<h2>Faults and recovery</h2>"]
    if episodes:
        out.append(_table(("station", "began", "ended", "fault", "recovery"), episodes))
    if rows:
        out.append(_table(("station", "recoveries", "p50", "max", "unrecovered", "injected"), rows,
                          numeric=range(1, 5)))
    return "".join(out)


def _stalls(report: Mapping[str, Any]) -> str:
    host = report.get("host")
    if not host:
        return ""
    st = host.get("stall", {})
    bound = f"absorbs up to {_ns(host.get('bound'))}" if host.get("policy") == "absorb" else "strict"
    out = [f"<h2>Host stalls</h2><p>{_e(st.get('count', 0))} stall(s), longest {_ns(st.get('max'))}, "
           f"{_e(st.get('cycles', 0))} cycle(s) delayed: {_e(st.get('absorbed', 0))} run late, "
           f"{_e(st.get('lost', 0))} lost (policy {_e(bound)}).</p>"]
    events = host.get("stalls") or []
    if events:
        by: dict[str, list[dict[str, Any]]] = {}
        for ev in events:
            by.setdefault(str(ev.get("process")), []).append(ev)
        series = [Series(proc, [e["at"] / 1e9 for e in evs], [e["duration"] / 1e6 for e in evs], points=True)
                  for proc, evs in sorted(by.items())]
        out.append(line_chart("Host stalls: when and how long", series, y_label="ms"))
        rows = [(_e(e.get("process")), f"{e['at'] / 1e9:.3f} s", _ns(e.get("duration")), _e(e.get("cycles")),
                 "run late" if e.get("absorbed") else "lost") for e in events]
        out.append(_table(("process", "at", "duration", "cycles", ""), rows, numeric=(1, 2, 3)))
    return "".join(out)


def _actions(trace: Trace | None) -> str:
    if trace is None or not trace.actions:
        return ""
    rows = [(f"{a['t_s']:.3f} s" + (f" ({BEFORE_ZERO})" if a["t_s"] < 0 else ""),
             f"{int(a['address'], 16):02X}H" if a["address"] else "all", _e(a["event"]), _e(a["detail"]))
            for a in trace.actions]
    more = (f"<p class=\"muted\">{trace.actions_dropped} more action(s) in the trace are not shown.</p>"
            if trace.actions_dropped else "")
    return "<h2>Actions</h2>" + _table(("at", "station", "event", "what"), rows, numeric=(0,)) + more


def _run_notes(report: Mapping[str, Any], trace: Trace | None) -> str:
    meta = report.get("meta", {})
    notes = [*(f"problem: {p}" for p in meta.get("problems", [])), *(f"not run: {s}" for s in meta.get("not_run", []))]
    if trace is not None and trace.torn:
        notes.append("the trace ends in a partial line (the run was killed); it was read up to there")
    if not notes:
        return ""
    return "<h2>Notes</h2><ul>" + "".join(f"<li>{_e(n)}</li>" for n in notes) + "</ul>"
