"""The live status of ``mlink-sim up`` / ``master``: a header (elapsed / total, p99, missed, the current timeline
step) over one line per station (phase, run state, frequency, alarms, last RTT).

On a terminal it is one frame redrawn in place by rich's ``Live``, cut to the terminal's width and height (lines
end in "…", stations that do not fit are summed up in a last line), so frames never pile up however small the
window. When stdout is not a terminal, the same lines are printed as plain text every few seconds.

The header's fields are :data:`STATUS_FIELDS`, one ``(label, value)`` entry each: adding a figure to the status
is adding one line there.

Touches: the terminal (stdout) only; reads the network's views and metrics.
"""

from __future__ import annotations

import shutil
import sys
import textwrap
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, TextIO

from ...config import Config, format_ns
from ...operations import alarm_text, station_name
from ...wire import Link
from .figures import run_direction

__all__ = ["StatusInfo", "STATUS_FIELDS", "COLUMNS", "LEGEND", "WorstP99", "LiveStatus", "render_lines", "station_cells",
           "station_line", "fit", "aligned", "SummaryWriter"]


@dataclass(frozen=True)
class StatusInfo:
    """What one frame of the status shows; :data:`STATUS_FIELDS` read it."""

    config: Config
    net: Any  #: the running network (``NetworkApi``): ``view(address)``
    metrics: Any  #: the run's ``NetworkMetrics`` (counters as of now)
    scales: dict[int, Any]  #: Hz converters of the stations (``scenario.SpeedScale``)
    elapsed_s: float
    total_s: float | None  #: the run's planned length (None: until Ctrl-C)
    step: str | None  #: the timeline step begun last
    p99_ns: int | None  #: the highest RTT p99 among the stations (:class:`WorstP99`)


def _elapsed(i: StatusInfo) -> str:
    return f"{i.elapsed_s:.1f}" + (f"/{i.total_s:.1f}" if i.total_s is not None else "") + " s"


#: The header's fields in order: ``(label, value of a StatusInfo)``. One line per field.
STATUS_FIELDS: tuple[tuple[str, Callable[[StatusInfo], str]], ...] = (
    ("", _elapsed),
    ("p99", lambda i: format_ns(i.p99_ns) if i.p99_ns else "-"),
    ("missed", lambda i: str(i.metrics.missed)),
    ("stalls", lambda i: i.metrics.stalls.brief()),
    ("step", lambda i: i.step or "-"),
)


class WorstP99:
    """The highest RTT p99 among the stations, refreshed *per_step* stations at a time, in turn.

    A network-wide p99 merges every station's histogram, a few thousand buckets each: tens of 1 ms cycles per
    refresh on a large line, where one station's p99 is about one cycle (docs/performance.md, "Live status and
    traces"), so the status refreshes a couple of stations per frame and shows the worst of the latest figures."""

    def __init__(self, per_step: int = 2) -> None:
        self.per_step = per_step
        self._p99: dict[int, int] = {}
        self._next = 0

    def step(self, metrics: Any) -> int | None:
        stations = sorted(metrics.stations)
        for _ in range(min(self.per_step, len(stations))):
            address = stations[self._next % len(stations)]
            self._next += 1
            self._p99[address] = metrics.stations[address].rtt.percentile(99)
        values = [v for v in self._p99.values() if v]
        return max(values) if values else None


_RUN_STATE = {"forward": "FWD", "reverse": "REV", None: "stop"}

#: The headings of the station lines, over their columns (:func:`station_cells`).
COLUMNS = ("ADDR", "CARD", "LINK", "PHASE", "RUN", "OUTPUT", "RTT", "STATE")

#: What the terms of the status mean: one line at 120 columns, wrapped between its items on a narrower terminal;
#: ``up --help`` says the same at length.
LEGEND = ("P1/P2/P3: phase (answers/connected/cyclic)", "ok: no alarm", "missed: cycles skipped",
          "stalls: host stalls (longest)")

#: Below this width the columns are separated by one space instead of two, and the header may take two lines.
NARROW = 100


def station_cells(st: Any, view: Any, hz: float) -> tuple[str, ...]:
    """One station's :data:`COLUMNS`: ``("21H", "SI-T3", "ML2", "P3", "FWD", "30.00 Hz", "0.21 ms", "ok")``."""
    link: Link = st.link
    run_state = _RUN_STATE[run_direction(link, view.status)]
    if view.fault or view.alarm or view.comm_alm or view.cmd_alm:
        code = (f"{view.alarm:02X}H" if view.alarm else f"COMM_ALM {view.comm_alm:X}H" if view.comm_alm
                else f"CMD_ALM {view.cmd_alm:X}H" if view.cmd_alm else None)
        alarm = alarm_text({"code": code, "name": view.alarm_name})
    elif view.warning:
        alarm = f"warn {view.alarm_name or ''}".strip()
    else:
        alarm = "ok"
    rtt = f"{view.rtt_ns / 1e6:.2f} ms" if view.rtt_ns is not None else "-"
    phase = f"P{view.phase}" if view.phase else view.state.value
    return (station_name(st.address), st.profile.label, link.name, phase, run_state, f"{hz:.2f} Hz", rtt, alarm)


def station_line(st: Any, view: Any, hz: float) -> str:
    """``  21H si-t3  ML2  P3  FWD  30.00 Hz  0.21 ms  ok``: one station on its own (no column widths)."""
    return "  " + "  ".join(station_cells(st, view, hz))


def _table(rows: list[tuple[str, ...]], gap: int) -> list[str]:
    return aligned(rows, gap, {COLUMNS.index("OUTPUT"), COLUMNS.index("RTT")})


def aligned(rows: list[tuple[str, ...]], gap: int, right: set[int]) -> list[str]:
    """*rows* (the headings first) as aligned columns *gap* spaces apart; the columns *right* (figures)
    right-aligned, the last column (free text) not padded."""
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    out = []
    for r in rows:
        cells = [c.rjust(w) if i in right else c.ljust(w) for i, (c, w) in enumerate(zip(r[:-1], widths))]
        out.append(" " * gap + (" " * gap).join([*cells, r[-1]]))
    return out


def _wrap_fields(first: str, fields: Sequence[str], width: int | None, sep: str = "  ") -> list[str]:
    """*first*, then *fields* joined by *sep* on as few lines of *width* as hold them whole (a field is never
    split; continuation lines indented by two spaces); width None: one line."""
    lines = [first]
    for text in fields:
        if width is None or len(lines[-1]) + len(sep) + len(text) <= width:
            lines[-1] += (sep if lines[-1] else "") + text
        else:
            lines.append("  " + text)
    return lines


def render_lines(info: StatusInfo, width: int | None = None) -> list[str]:
    """The header, the legend, the column headings, then one line per station, laid out for a terminal *width*
    columns wide (None: not a terminal, the wide layout). Below :data:`NARROW` columns the padding goes first:
    one space between columns, the header's fields over two lines where one does not hold them, so that the
    step, the longest stall and every RTT stay on the screen."""
    narrow = width is not None and width < NARROW
    fields = [f"{label} {value(info)}".strip() for label, value in STATUS_FIELDS]
    name = info.config.network.name
    header = _wrap_fields(name, fields, width)
    legend = _wrap_fields("  " + LEGEND[0], LEGEND[1:], width, " · ")
    rows: list[tuple[str, ...]] = [COLUMNS]
    for st in info.config.station:
        view = info.net.view(st.address)
        try:
            hz = info.scales[st.address].to_hz(view.output_freq)
        except Exception:  # noqa: BLE001 - a display must never stop the run
            hz = float("nan")
        rows.append(station_cells(st, view, hz))
    return [*header, *legend, *_table(rows, 1 if narrow else 2)]


def fit(lines: list[str], height: int) -> list[str]:
    """At most *height* lines: the stations that do not fit are summed up in the last one."""
    height = max(1, height)
    if len(lines) <= height:
        return lines
    keep = lines[: height - 1] if height > 1 else []
    return [*keep, f"  … {len(lines) - len(keep)} more line(s): a taller terminal shows them"][-height:]


class LiveStatus:
    """Where the frames go: a rich ``Live`` display on a terminal, else plain lines every ``interval`` s."""

    def __init__(self, file: TextIO | None = None, size: tuple[int, int] | None = None) -> None:
        """*size*: ``(columns, rows)`` of the terminal, when it is not the one *file* is (tests); default: asked."""
        self.file = file or sys.stdout
        self.tty = self.file.isatty()
        self.size = size
        self.interval = 0.5 if self.tty else 5.0
        self._live: Any = None
        self._console: Any = None
        self._shown = float("-inf")  #: wall time of the last frame

    def start(self) -> None:
        if not self.tty:
            return
        from rich.console import Console
        from rich.live import Live

        width, height = self.size or (None, None)
        self._console = Console(file=self.file, highlight=False, markup=False, emoji=False, width=width,
                                height=height)
        # Log lines on the same terminal go above the frame instead of through it.
        self._live = Live(console=self._console, auto_refresh=False, transient=False, vertical_overflow="crop",
                          redirect_stdout=False, redirect_stderr=sys.stderr.isatty())
        self._live.start()

    def show(self, lines: list[str], *, force: bool = False) -> None:
        """Draw one frame (a terminal) or print it (anything else); at most one per ``interval`` of wall time
        unless *force*d (on the virtual clock, ``interval`` of simulated time may pass much faster)."""
        now = time.monotonic()
        if not force and now - self._shown < self.interval * 0.9:
            return
        self._shown = now
        if self._live is None:
            self.file.write("\n".join(lines) + "\n")
            self.file.flush()
            return
        from rich.console import Group
        from rich.text import Text

        height = self._console.size.height
        # One row is kept free: a frame as tall as the window would scroll it and leave a copy behind.
        rows = fit(lines, height - 1)
        self._live.update(Group(*(Text(line, no_wrap=True, overflow="ellipsis") for line in rows)), refresh=True)

    @property
    def width(self) -> int | None:
        """The terminal's width in columns, for :func:`render_lines`; None when the status is not on a terminal."""
        if not self.tty:
            return None
        if self._console is not None:
            return int(self._console.size.width)
        return self.size[0] if self.size else shutil.get_terminal_size().columns

    def stop(self, lines: list[str] | None = None) -> None:
        """Show the last frame (if given) and leave it on the screen."""
        if lines is not None:
            self.show(lines, force=True)
        if self._live is not None:
            self._live.stop()
            self._live = None


class SummaryWriter:
    """A text file whose lines are wrapped to *width* columns (continuation lines indented under the line's own
    indent and four spaces more): the run's final summary on a terminal. Width None: lines pass unchanged."""

    def __init__(self, file: TextIO, width: int | None) -> None:
        self.file = file
        self.width = width
        self._pending = ""

    @classmethod
    def for_terminal(cls, file: TextIO) -> SummaryWriter:
        """Wrapped to the terminal's width when *file* is a terminal, else unchanged."""
        return cls(file, shutil.get_terminal_size().columns if file.isatty() else None)

    def write(self, text: str) -> int:
        self._pending += text
        *whole, self._pending = self._pending.split("\n")
        for line in whole:
            self.file.write("\n".join(self._wrap(line)) + "\n")
        return len(text)

    def _wrap(self, line: str) -> list[str]:
        if self.width is None or len(line) <= self.width:
            return [line]
        indent = " " * (len(line) - len(line.lstrip(" ")))
        return textwrap.wrap(line, self.width, subsequent_indent=indent + "    ", break_on_hyphens=False) or [line]

    def flush(self) -> None:
        if self._pending:
            self.file.write(self._pending)
            self._pending = ""
        self.file.flush()
