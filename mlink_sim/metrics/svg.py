"""Plots as inline SVG text, drawn here in Python for the HTML report (:mod:`mlink_sim.metrics.html`).

Static SVG rather than a JavaScript plotting library: the report is a CI artifact, and the viewers of artifacts
(a CI's file browser, a mail client, a sandboxed preview) often run no script at all; an SVG in the page shows in
each of them, prints, and needs no library vendored into every file. A plot is one ``<svg>`` element with its
axes, ticks, a legend and a ``<title>`` per series (the browser shows it on hover).

Two kinds: :func:`line_chart` (series over time, with numbered marks for actions and checks and shaded spans for
faults and the drive's regulation: mlink_sim.plots, the vocabulary the live page shares) and :func:`bar_chart` (the
RTT histogram's bins). A mark's number is printed in the plot, and the page lists what each number is, so a printed
or archived report needs no hover.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Sequence
from html import escape

__all__ = ["Series", "Mark", "Span", "line_chart", "bar_chart", "nice_ticks", "PALETTE"]

#: Series colours in order (readable on white and for the common colour-vision deficiencies).
PALETTE = ("#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#17becf", "#8c564b", "#e377c2")
_LEFT, _RIGHT, _TOP, _BOTTOM = 64, 16, 28, 40


@dataclasses.dataclass(frozen=True)
class Series:
    """One line (or set of points): *ys* over *xs*, None where there is no value (the line breaks there)."""

    label: str
    xs: Sequence[float]
    ys: Sequence[float | None]
    color: str = ""
    points: bool = False  #: dots instead of a line (events such as host stalls)
    dash: bool = False  #: a dashed line (a reference beside what follows it)


@dataclasses.dataclass(frozen=True)
class Mark:
    """A vertical line at *x* (an action, a check, a fault), with its *number* printed at its top (None: none) and
    its *label* on hover."""

    x: float
    label: str
    color: str = "#888"
    number: int | None = None
    kind: str = ""  #: its mlink_sim.plots.MARKS kind (``data-kind`` of its element)


@dataclasses.dataclass(frozen=True)
class Span:
    """A shaded band from *x0* to *x1* (a fault in force, the drive's regulation), of *band* (mlink_sim.plots.BANDS;
    ``data-band`` of its element)."""

    x0: float
    x1: float
    label: str
    color: str = "#f4c7c3"
    band: str = "fault"


def nice_ticks(lo: float, hi: float, count: int = 5) -> list[float]:
    """About *count* round tick values covering [lo, hi] (steps of 1, 2 or 5 × 10^n)."""
    if not (math.isfinite(lo) and math.isfinite(hi)):
        return [0.0]
    if hi <= lo:
        hi = lo + 1.0
    raw = (hi - lo) / max(count, 1)
    mag = 10 ** math.floor(math.log10(raw))
    step = next(m * mag for m in (1, 2, 5, 10) if m * mag >= raw)
    start = math.floor(lo / step) * step
    out = []
    v = start
    while True:  # up to the first tick at or above hi, so the plot's top is a tick
        out.append(round(v, 10))
        if v >= hi - step * 1e-9:
            return out
        v += step


def _fmt(v: float) -> str:
    if v == 0:
        return "0"
    if abs(v) >= 1000:
        return f"{v:,.0f}"
    return f"{v:.6g}"


def line_chart(title: str, series: Sequence[Series], *, y_label: str, x_label: str = "t (s)",
               marks: Sequence[Mark] = (), spans: Sequence[Span] = (), width: int = 860, height: int = 230,
               x_range: tuple[float, float] | None = None) -> str:
    """An SVG line chart of *series* with vertical *marks* and shaded *spans*; an empty chart says "no data"."""
    xs_all = [x for s in series for x, y in zip(s.xs, s.ys, strict=True) if y is not None]
    ys_all = [y for s in series for y in s.ys if y is not None]
    out = [_open(width, height, title)]
    if not xs_all:
        out.append(f'<text x="{width / 2}" y="{height / 2}" text-anchor="middle" class="muted">no data</text></svg>')
        return "".join(out)
    x0, x1 = x_range if x_range is not None else (min(xs_all), max(xs_all))
    if x1 <= x0:
        x1 = x0 + 1.0
    y0, y1 = min(0.0, min(ys_all)), max(ys_all)
    if y1 <= y0:
        y1 = y0 + 1.0
    yt = nice_ticks(y0, y1 * 1.05 if y1 > 0 else y1)
    y0, y1 = min(y0, yt[0]), max(y1, yt[-1])
    pw, ph = width - _LEFT - _RIGHT, height - _TOP - _BOTTOM

    def px(x: float) -> float:
        return round(_LEFT + (x - x0) / (x1 - x0) * pw, 1)

    def py(y: float) -> float:
        return round(_TOP + ph - (y - y0) / (y1 - y0) * ph, 1)

    for sp in spans:
        a, b = px(max(sp.x0, x0)), px(min(sp.x1, x1))
        if b >= a:
            out.append(f'<rect x="{a}" y="{_TOP}" width="{max(b - a, 1.0)}" height="{ph}" fill="{sp.color}" '
                       f'opacity="0.6" class="band" data-band="{escape(sp.band)}"><title>{escape(sp.label)}</title>'
                       "</rect>")
    out.append(_axes(width, height, [(py(v), _fmt(v)) for v in yt],
                     [(px(v), _fmt(v)) for v in nice_ticks(x0, x1, 8) if x0 <= v <= x1], x_label, y_label))
    if y0 < 0 < y1:
        out.append(f'<line x1="{_LEFT}" y1="{py(0.0)}" x2="{width - _RIGHT}" y2="{py(0.0)}" class="zero" '
                   'stroke="#777" stroke-width="1"/>')
    out.extend(_marks([m for m in marks if x0 <= m.x <= x1], px, _TOP + ph))
    for i, s in enumerate(series):
        color = s.color or PALETTE[i % len(PALETTE)]
        label = escape(s.label)
        if s.points:
            dots = "".join(f'<circle cx="{px(x)}" cy="{py(y)}" r="3"/>'
                           for x, y in zip(s.xs, s.ys, strict=True) if y is not None)
            out.append(f'<g fill="{color}" class="series"><title>{label}</title>{dots}</g>')
            continue
        for run in _runs(s.xs, s.ys):
            pts = " ".join(f"{px(x)},{py(y)}" for x, y in run)
            dash = ' stroke-dasharray="5,4"' if s.dash else ""
            out.append(f'<polyline fill="none" stroke="{color}" stroke-width="1.5"{dash} class="series" '
                       f'points="{pts}"><title>{label}</title></polyline>')
    out.append(_legend([(s.label, s.color or PALETTE[i % len(PALETTE)]) for i, s in enumerate(series)], width))
    out.append("</svg>")
    return "".join(out)


_MARK_ROWS = 3  # rows the numbered circles are staggered over where they would overlap
_MARK_R = 7


def _marks(marks: Sequence[Mark], px: Callable[[float], float], bottom: float) -> list[str]:
    """Each mark as a line with its number in a circle at its top; circles closer than two radii move down a row."""
    out = []
    last: list[float] = [-1e9] * _MARK_ROWS
    for m in sorted(marks, key=lambda m: m.x):
        x = px(m.x)
        row = next((r for r in range(_MARK_ROWS) if x - last[r] >= 2 * _MARK_R + 1), _MARK_ROWS - 1)
        last[row] = x
        y = _TOP + _MARK_R + 1 + row * (2 * _MARK_R + 2)
        label = escape(m.label)
        number = "" if m.number is None else (
            f'<circle cx="{x}" cy="{y}" r="{_MARK_R}" fill="{m.color}"/>'
            f'<text x="{x}" y="{y + 3}" text-anchor="middle" class="mark-n">{m.number}</text>')
        out.append(f'<g class="mark" data-kind="{escape(m.kind)}" data-n="{"" if m.number is None else m.number}">'
                   f"<title>{label}</title>"
                   f'<line x1="{x}" y1="{_TOP}" x2="{x}" y2="{bottom}" stroke="{m.color}" stroke-width="1" '
                   f'opacity="0.8"/>{number}</g>')
    return out


def bar_chart(title: str, bins: Sequence[Sequence[int]], *, x_label: str, y_label: str = "count",
              label_of: object = None, width: int = 860, height: int = 230) -> str:
    """An SVG bar chart of ``[[lower, upper, count], …]`` bins, one bar each, equal widths (the bins of the RTT
    histogram are log-spaced); *label_of* formats an edge (default: the number)."""
    out = [_open(width, height, title)]
    if not bins:
        out.append(f'<text x="{width / 2}" y="{height / 2}" text-anchor="middle" class="muted">no data</text></svg>')
        return "".join(out)
    fmt = label_of if callable(label_of) else _fmt
    top = max(b[2] for b in bins) or 1
    yt = nice_ticks(0, top * 1.05)
    y1 = max(yt[-1], top)
    pw, ph = width - _LEFT - _RIGHT, height - _TOP - _BOTTOM
    bw = pw / len(bins)
    every = max(1, math.ceil(len(bins) / 8))
    xticks = [(round(_LEFT + i * bw, 1), str(fmt(b[0]))) for i, b in enumerate(bins) if i % every == 0]
    out.append(_axes(width, height, [(round(_TOP + ph - v / y1 * ph, 1), _fmt(v)) for v in yt], xticks,
                     x_label, y_label))
    for i, (lo, hi, count) in enumerate(bins):
        h = count / y1 * ph
        out.append(f'<rect x="{round(_LEFT + i * bw + 0.5, 1)}" y="{round(_TOP + ph - h, 1)}" '
                   f'width="{round(max(bw - 1, 0.5), 1)}" height="{round(h, 1)}" fill="{PALETTE[0]}" class="bar">'
                   f"<title>{escape(f'{fmt(lo)} – {fmt(hi)}: {count}')}</title></rect>")
    out.append("</svg>")
    return "".join(out)


def _runs(xs: Sequence[float], ys: Sequence[float | None]) -> list[list[tuple[float, float]]]:
    """The stretches of a series without a gap (None)."""
    runs: list[list[tuple[float, float]]] = []
    cur: list[tuple[float, float]] = []
    for x, y in zip(xs, ys, strict=True):
        if y is None:
            if cur:
                runs.append(cur)
            cur = []
        else:
            cur.append((x, y))
    if cur:
        runs.append(cur)
    return runs


def _open(width: int, height: int, title: str) -> str:
    return (f'<svg viewBox="0 0 {width} {height}" width="100%" '
            f'role="img" aria-label="{escape(title)}" class="plot"><title>{escape(title)}</title>'
            f'<text x="{_LEFT}" y="16" class="plot-title">{escape(title)}</text>')


def _axes(width: int, height: int, yticks: list[tuple[float, str]], xticks: list[tuple[float, str]],
          x_label: str, y_label: str) -> str:
    base = height - _BOTTOM
    parts = [f'<g class="axes"><line x1="{_LEFT}" y1="{_TOP}" x2="{_LEFT}" y2="{base}"/>'
             f'<line x1="{_LEFT}" y1="{base}" x2="{width - _RIGHT}" y2="{base}"/>']
    for y, text in yticks:
        parts.append(f'<line x1="{_LEFT}" y1="{y}" x2="{width - _RIGHT}" y2="{y}" class="grid"/>'
                     f'<text x="{_LEFT - 4}" y="{y + 4}" text-anchor="end">{escape(text)}</text>')
    for x, text in xticks:
        parts.append(f'<line x1="{x}" y1="{base}" x2="{x}" y2="{base + 4}"/>'
                     f'<text x="{x}" y="{base + 16}" text-anchor="middle">{escape(text)}</text>')
    parts.append(f'<text x="{(width + _LEFT) / 2}" y="{height - 6}" text-anchor="middle">{escape(x_label)}</text>'
                 f'<text x="14" y="{(height - _BOTTOM + _TOP) / 2}" text-anchor="middle" '
                 f'transform="rotate(-90 14 {(height - _BOTTOM + _TOP) / 2})">{escape(y_label)}</text></g>')
    return "".join(parts)


def _legend(items: list[tuple[str, str]], width: int) -> str:
    parts = ['<g class="legend">']
    x = width - _RIGHT
    for label, color in reversed(items):
        w = 14 + 7 * len(label)
        x -= w + 12
        parts.append(f'<rect x="{x}" y="8" width="10" height="10" fill="{color}"/>'
                     f'<text x="{x + 14}" y="17">{escape(label)}</text>')
    parts.append("</g>")
    return "".join(parts)
