"""The trace of a run (``--trace FILE.csv``): each station's figures at a fixed interval, and the actions taken.

One CSV file, one header line (:data:`TRACE_COLUMNS`), then rows of two kinds, told apart by the ``kind`` column
(docs/report.md, "Traces"):

* ``sample``: one station's figures at ``t_s`` (the station figures of the run's status, flattened: the alarm as
  ``alarm_code`` and ``alarm_name``, the warnings and LEDs as text); ``event`` and ``detail`` are empty;
* ``action``: something done to the network or seen happen at ``t_s``: a timeline step, a control request, an
  impairment's or a fault's start and end, a recovery, a check; ``address`` is empty for one on the whole network,
  the figure columns are empty, ``event`` names it and ``detail`` says what it was.

One file rather than two keeps a run's trace one artifact that a report names once (``meta.trace``), and a
reader that wants one kind filters on one column.

:class:`TraceWriter` holds rows in a bounded buffer and writes them in whole lines, when the buffer is full and
whenever :meth:`TraceWriter.flush` is called (the sampler does so about once a second): the file has its header
from the start and grows by whole lines, so a run ended by a signal, or killed, leaves a CSV that reads up to its
last flush (:func:`read_trace` skips a torn last line). A trace is a stream, not a state file: it is not written
through ``write_atomically``.

:func:`read_trace` reads a trace back for the HTML report in bounded memory: at most ``max_points`` samples per
station are kept (every 2nd, 4th … once there are more), the actions up to :data:`MAX_ACTIONS`, each station's
bands of regulation (from every sample, up to :data:`MAX_BANDS`) and each station's full figures at the moments
asked for (the checks' times).
"""

from __future__ import annotations

import csv
import dataclasses
import os
from collections.abc import Iterable, Mapping, Sequence
from typing import IO, Any

from ..plots import BRIDGE_S

__all__ = ["TRACE_COLUMNS", "FIGURE_COLUMNS", "PLOT_COLUMNS", "ACTION_EVENTS", "MAX_ACTIONS", "MAX_BANDS", "TraceWriter",
           "Trace", "StationTrace", "TraceError", "read_trace"]

#: A station's figures in a ``sample`` row, in order: the station figures of ``aio/present/figures.py`` flattened (the
#: alarm as code and name; without the LED colours), docs/report.md.
FIGURE_COLUMNS: tuple[str, ...] = (
    "address", "name", "card", "link", "phase", "connected", "alarm_code", "alarm_name", "warnings", "leds",
    "running", "direction", "reference_hz", "output_hz", "output_current_a", "dc_bus_v", "motor_speed_rpm",
    "regulation", "rtt_us", "rtt_p50_us", "rtt_p99_us", "missed", "late",
)
#: The header of a trace.
TRACE_COLUMNS: tuple[str, ...] = ("t_s", "kind", *FIGURE_COLUMNS, "event", "detail")
#: The numeric figures :func:`read_trace` keeps per sample for the plots.
PLOT_COLUMNS: tuple[str, ...] = ("reference_hz", "output_hz", "output_current_a", "dc_bus_v", "motor_speed_rpm",
                                 "phase", "rtt_us")
#: :func:`read_trace` keeps this many bands of the drive's regulation per station; more are counted.
MAX_BANDS = 2_000
#: The ``event`` of an ``action`` row.
ACTION_EVENTS: dict[str, str] = {
    "step": "a timeline action began (its description)",
    "control": "a control request changed the run (the operation and its fields)",
    "impair-start": "a network impairment began (impair)",
    "impair-end": "a network impairment ended (heal, its 'for' ran out)",
    "fault": "a station, master or drive fault began",
    "fault-end": "that fault ended",
    "recovered": "the station was healthy again after a fault (the recovery time)",
    "unrecovered": "the station was not healthy again within a minute of a fault's end",
    "check": "a timeline check was judged (ok or FAIL, what was seen)",
}
#: :func:`read_trace` keeps this many actions; more are counted (``Trace.actions_dropped``).
MAX_ACTIONS = 5_000

_T, _KIND, _ADDRESS = 0, 1, 2
_EVENT, _DETAIL = len(TRACE_COLUMNS) - 2, len(TRACE_COLUMNS) - 1
_PLOT_INDEX = tuple(TRACE_COLUMNS.index(c) for c in PLOT_COLUMNS)
_REGULATION = TRACE_COLUMNS.index("regulation")
_BLANK_FIGURES = ("",) * (len(FIGURE_COLUMNS) - 1)  # an action row's figures after its address


class TraceWriter:
    """Writes a trace to *path*: the header at once, then rows through a buffer of at most *buffer_rows* rows.

    :meth:`add` takes a full ``sample`` row (``t_s, "sample", *figures, "", ""``, as :data:`TRACE_COLUMNS`);
    :meth:`action` builds an ``action`` row. ``OSError`` from opening *path* reaches the caller (a bad path is a
    usage error there); later write errors are kept in :attr:`error` and stop the trace, not the run."""

    def __init__(self, path: str | os.PathLike[str], *, buffer_rows: int = 4096) -> None:
        self.path = os.fspath(path)
        self.buffer_rows = buffer_rows
        self.rows = 0  #: rows written or buffered so far
        self.error: str | None = None
        self._pending: list[Sequence[Any]] = []
        self._file: IO[str] | None = open(self.path, "w", newline="", encoding="utf-8")  # noqa: SIM115 - closed by close()
        self._csv = csv.writer(self._file, lineterminator="\n")
        self._csv.writerow(TRACE_COLUMNS)
        self._file.flush()

    def add(self, row: Sequence[Any]) -> None:
        """One ``sample`` row (written with the next flush)."""
        pending = self._pending
        pending.append(row)
        if len(pending) >= self.buffer_rows:
            self.flush()

    def add_many(self, rows: Iterable[Sequence[Any]]) -> None:
        """Several rows at once (a sampling instant's stations)."""
        pending = self._pending
        pending.extend(rows)
        if len(pending) >= self.buffer_rows:
            self.flush()

    def action(self, t_s: float, event: str, detail: str = "", address: str = "") -> None:
        """An ``action`` row: *event* (one of :data:`ACTION_EVENTS`) at *t_s*, on station *address* (``"0x21"``;
        empty: the whole network)."""
        self.add((round(t_s, 6), "action", address, *_BLANK_FIGURES, event, detail))

    def flush(self) -> None:
        """Write the buffered rows as whole lines and hand them to the operating system."""
        pending = self._pending
        if not pending:
            return
        self.rows += len(pending)
        if self._file is not None:
            try:
                self._csv.writerows(pending)
                self._file.flush()
            except OSError as exc:  # a full disk: the trace ends here, the run goes on
                self.error = f"{self.path}: {exc.strerror or exc}"
                self._close_file()
        pending.clear()

    def close(self) -> None:
        """Flush and close. Idempotent."""
        self.flush()
        self._close_file()

    def _close_file(self) -> None:
        if self._file is not None:
            try:
                self._file.close()
            except OSError as exc:
                self.error = self.error or f"{self.path}: {exc.strerror or exc}"
            self._file = None


class TraceError(ValueError):
    """A file that is not a trace (no trace header), or one that cannot be read."""


@dataclasses.dataclass
class StationTrace:
    """One station's samples as :func:`read_trace` kept them: ``t`` in s, and per :data:`PLOT_COLUMNS` a list of
    floats (None where the figure was empty); ``stride``: every how many samples one was kept."""

    address: str
    name: str = ""
    t: list[float] = dataclasses.field(default_factory=list)
    series: dict[str, list[float | None]] = dataclasses.field(
        default_factory=lambda: {c: [] for c in PLOT_COLUMNS})
    stride: int = 1
    samples: int = 0  #: samples in the file
    #: ``(start, end, state)``: where the drive's regulation held it (a ``regulation`` state; every sample, not the
    #: thinned ones), a gap under :data:`mlink_sim.plots.BRIDGE_S` bridged
    bands: list[tuple[float, float, str]] = dataclasses.field(default_factory=list)
    bands_dropped: int = 0
    _open: dict[str, list[float]] = dataclasses.field(default_factory=dict, repr=False)  # state -> [start, last]

    @property
    def regulating(self) -> bool:
        """A band is open (its state seen lately)."""
        return bool(self._open)

    def regulated(self, t: float, text: str) -> None:
        """The sample at *t* had the regulation *text* (``stall-decel|torque-limit``; empty: none)."""
        states = text.split("|") if text else ()
        for state, span in list(self._open.items()):
            if state not in states and t - span[1] > BRIDGE_S:
                self._close(state)
        for state in states:
            seen = self._open.get(state)
            if seen is None:
                self._open[state] = [t, t]
            else:
                seen[1] = t

    def close_bands(self) -> None:
        for state in list(self._open):
            self._close(state)
        self.bands.sort()

    def _close(self, state: str) -> None:
        start, end = self._open.pop(state)
        if len(self.bands) < MAX_BANDS:
            self.bands.append((start, end, state))
        else:
            self.bands_dropped += 1


@dataclasses.dataclass
class Trace:
    """A trace read back (:func:`read_trace`)."""

    path: str
    stations: dict[str, StationTrace]
    actions: list[dict[str, Any]]  #: ``{"t_s", "address", "event", "detail"}`` in time order
    actions_dropped: int
    #: (address, moment) -> that station's figures (column -> text) in its last sample at or before the moment
    at: dict[tuple[str, float], dict[str, str]]
    span: tuple[float, float] | None  #: first and last ``t_s`` of a sample
    torn: bool = False  #: the file ended in a partial line (the run was killed), which was skipped


def _num(text: str) -> float | None:
    if not text:
        return None
    try:
        return float(text)
    except ValueError:
        return 1.0 if text == "True" else 0.0 if text == "False" else None


def read_trace(path: str | os.PathLike[str], *, max_points: int = 2000,
               moments: Mapping[str, Iterable[float]] | None = None) -> Trace:
    """Read the trace at *path* (:class:`TraceError` if it is not one, or unreadable): per station at most
    *max_points* samples (evenly thinned), the actions, and each station's figures at *moments*
    (``{"0x21": [3.0, 7.0]}``: its last sample at or before each)."""
    path = os.fspath(path)
    wanted = {a: sorted(set(ts)) for a, ts in (moments or {}).items()}
    stations: dict[str, StationTrace] = {}
    actions: list[dict[str, Any]] = []
    dropped = 0
    at: dict[tuple[str, float], dict[str, str]] = {}
    last: dict[str, list[str]] = {}  # each station's latest sample (full row), for the moments
    nxt: dict[str, int] = dict.fromkeys(wanted, 0)
    first = end = None
    torn = False
    width = len(TRACE_COLUMNS)
    try:
        with open(path, newline="", encoding="utf-8") as f:
            reader = csv.reader(f)
            header = next(reader, None)
            if header is None or tuple(header[:2]) != ("t_s", "kind") or tuple(header) != TRACE_COLUMNS:
                raise TraceError(f"{path}: not a trace of mlink-sim (its first line is not the trace header: "
                                 f"{','.join(TRACE_COLUMNS[:4])},…)")
            for row in reader:
                if len(row) != width:
                    torn = True  # only a killed run's last line can be short
                    continue
                try:
                    t = float(row[_T])
                except ValueError:
                    torn = True
                    continue
                if row[_KIND] == "action":
                    if len(actions) < MAX_ACTIONS:
                        actions.append({"t_s": t, "address": row[_ADDRESS], "event": row[_EVENT],
                                        "detail": row[_DETAIL]})
                    else:
                        dropped += 1
                    continue
                address = row[_ADDRESS]
                st = stations.get(address)
                if st is None:
                    st = stations[address] = StationTrace(address, row[_ADDRESS + 1])
                first = t if first is None else first
                end = t
                if row[_REGULATION] or st.regulating:
                    st.regulated(t, row[_REGULATION])
                times = wanted.get(address)
                if times is not None:
                    i = nxt[address]
                    while i < len(times) and times[i] < t:
                        if address in last:
                            at[(address, times[i])] = dict(zip(TRACE_COLUMNS, last[address], strict=True))
                        i += 1
                    nxt[address] = i
                    last[address] = row
                if st.samples % st.stride == 0:
                    st.t.append(t)
                    for col, i in zip(PLOT_COLUMNS, _PLOT_INDEX, strict=True):
                        st.series[col].append(_num(row[i]))
                    if len(st.t) > max_points:
                        st.t = st.t[::2]
                        st.series = {c: v[::2] for c, v in st.series.items()}
                        st.stride *= 2
                st.samples += 1
    except OSError as exc:
        raise TraceError(f"{path}: {exc.strerror or exc}") from None
    except (UnicodeDecodeError, csv.Error) as exc:
        raise TraceError(f"{path}: not a trace of mlink-sim ({exc})") from None
    for address, times in wanted.items():
        for moment in times[nxt.get(address, 0):]:
            if address in last:
                at[(address, moment)] = dict(zip(TRACE_COLUMNS, last[address], strict=True))
    for st in stations.values():
        st.close_bands()
    actions.sort(key=lambda a: a["t_s"])
    span = None if first is None or end is None else (first, end)
    return Trace(path, stations, actions, dropped, at, span, torn)
