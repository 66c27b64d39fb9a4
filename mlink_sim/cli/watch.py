"""``mlink-sim watch SOURCE``: a running network's frames as python-can's ``can.viewer`` shows a CAN bus, one line
per station, direction and command with its rate and its last value decoded, the fields that changed
highlighted (:mod:`mlink_sim.capture.watch`), in a rich ``Live`` screen fitted to the terminal (60 columns keep
every row).

SOURCE is a pcapng stream: ``-`` reads standard input (``mlink-sim up … --capture - | mlink-sim watch -``; also
``tcpdump -U -w - …``), a FILE is followed as a ``--capture FILE`` writes it (every 250 ms) until Ctrl-C
(``--no-follow``: read to its end, show the last screen). Why a stream and not a request to the control endpoint:
docs/capture.md, "Watching the wire".

Ends with 0 at the end of the stream (the recorder ended: the pipe closed) or when the output is closed, 130 on
Ctrl-C, 2 when SOURCE is not a capture.
"""

from __future__ import annotations

import os
import queue
import sys
import threading
import time
from typing import Any, TextIO

import click

from .decode import card_names
from .params import ADDR

__all__ = ["watch_cmd", "WatchScreen", "render"]

_END = object()  #: the reader's last item: the stream ended
#: how often the screen is redrawn on a terminal, and how often plain frames are printed elsewhere (s)
TTY_INTERVAL_S, PLAIN_INTERVAL_S = 0.25, 5.0
_MARK = "reverse"  #: the style of a changed field


def _head(table: Any, source: str, now_ns: int) -> str:
    elapsed = max(0.0, (now_ns - (table.start_ns or now_ns)) / 1e9)
    rate = sum(r.rate(now_ns, table.start_ns) for r in table.rows.values()) if table.start_ns is not None else 0.0
    return (f"watch {source}  {elapsed:.1f} s  {rate:.0f}/s  {table.datagrams} datagrams  "
            f"{table.rejected} rejected")


def render(table: Any, width: int, height: int | None, source: str, now_ns: int | None = None,
           stations: frozenset[int] = frozenset()) -> list[Any]:
    """The screen as rich ``Text`` lines, each at most *width* columns: the header, the column headings, one
    line per row of *table* (of *stations*, when given; the changed fields in :data:`_MARK`), the latest note; at
    most *height* lines: when the rows do not fit, those seen last stay and the others are summed up in a line."""
    from rich.text import Text

    now = table.now_ns if now_ns is None else now_ns
    table.refresh()
    rows = [r for r in table.sorted_rows() if not stations or r.station in stations]
    counts = width >= 80
    name_w = max([len("COMMAND"), *(len(r.command) for r in rows)])
    lead = f"{'ADDR':4} {'DIR':3} {'COMMAND':{name_w}} " + (f"{'COUNT':>7} " if counts else "") + f"{'RATE':>7}  "
    lines = [Text(_head(table, source, now), no_wrap=True, overflow="ellipsis"),
             Text(lead + "LAST (changed: highlighted)", no_wrap=True, overflow="ellipsis")]
    tail = []
    if table.notes:
        tail.append(Text(f"# {table.notes[-1]}", no_wrap=True, overflow="ellipsis"))
    if table.last_rejection:
        tail.append(Text(f"last rejected: {table.last_rejection}", no_wrap=True, overflow="ellipsis"))
    hidden = 0
    if height is not None:
        room = max(1, height - len(lines) - len(tail))
        if len(rows) > room:  # the rows seen last stay, in their order; the idle ones are summed up
            keep = {id(r) for r in sorted(rows, key=lambda r: r.last_ns, reverse=True)[: room - 1]}
            hidden = len(rows) - len(keep)
            rows = [r for r in rows if id(r) in keep]
    body = []
    for r in rows:
        rate = f"{r.rate(now, table.start_ns):.0f}/s"
        text = Text(f"{r.station:02X}H  {r.kind} {r.command:{name_w}} " + (f"{r.count:7} " if counts else "")
                    + f"{rate:>7}  ", no_wrap=True, overflow="ellipsis")
        changed = r.changed(now)
        for i, (name, value) in enumerate(r.fields):
            if i:
                text.append(" ")
            text.append(f"{name}={value}", style=_MARK if name in changed else "")
        body.append(text)
    if hidden:
        body.append(Text(f"… {hidden} row(s) idle longest not shown: a taller terminal or --station shows them"))
    out = [*lines, *body, *tail]
    for line in out:
        line.truncate(width, overflow="ellipsis")
    return out[:height] if height is not None else out


class WatchScreen:
    """Where the screens go: a rich ``Live`` display on a terminal (*file*; *size*, its columns and rows, where
    they are not the terminal's own: tests), else plain text every :data:`PLAIN_INTERVAL_S` and at the end."""

    def __init__(self, file: TextIO | None = None, size: tuple[int, int] | None = None) -> None:
        self.file = file or sys.stdout
        self.tty = self.file.isatty()
        self.size = size
        self.interval = TTY_INTERVAL_S if self.tty else PLAIN_INTERVAL_S
        self._live: Any = None
        self._console: Any = None

    def start(self) -> None:
        """On a terminal, open the ``Live`` display (its console cut to *size* where given)."""
        if self.tty:
            from rich.console import Console
            from rich.live import Live

            columns, rows = self.size or (None, None)
            console = Console(file=self.file, width=columns, height=rows, highlight=False, markup=False, emoji=False)
            self._live = Live(console=console, auto_refresh=False, vertical_overflow="crop")
            self._console = console
            self._live.start()

    def dimensions(self) -> tuple[int, int | None]:
        """Columns and rows to draw in (rows None off a terminal: every row, 120 columns)."""
        if self._console is not None:
            return int(self._console.size.width), int(self._console.size.height) - 1  # a row free: no scrolling
        return 120, None

    def show(self, lines: list[Any]) -> None:
        if self._live is not None:
            from rich.console import Group

            self._live.update(Group(*lines), refresh=True)
            return
        self.file.write("\n".join(line.plain for line in lines) + "\n\n")
        self.file.flush()

    def stop(self) -> None:
        if self._live is not None:
            self._live.stop()
            self._live = None


def _reader(source: Any, out: queue.SimpleQueue[Any]) -> None:
    """Put every datagram of *source* on *out*, then :data:`_END` (or the error that ended it)."""
    from ..capture import CaptureError

    try:
        for d in source:
            out.put(d)
    except CaptureError as exc:
        out.put(exc)
        return
    out.put(_END)


def _watch(source_name: str, source: Any, table: Any, screen: WatchScreen, stations: frozenset[int],
           live: bool) -> int:
    """Feed the table from a reader thread and redraw until the stream ends; the exit status."""
    from ..capture import CaptureError

    items: queue.SimpleQueue[Any] = queue.SimpleQueue()
    threading.Thread(target=_reader, args=(source, items), name="mlink-watch-reader", daemon=True).start()
    screen.start()
    last_add, shown_at, status = time.monotonic(), float("-inf"), 0
    ended = drawn = False

    def draw(now: int) -> None:
        nonlocal shown_at, drawn
        width, height = screen.dimensions()
        screen.show(render(table, width, height, source_name, now, stations))
        shown_at, drawn = time.monotonic(), True

    try:
        while not ended:
            deadline = time.monotonic() + screen.interval
            while True:
                try:
                    item = items.get(timeout=max(0.0, deadline - time.monotonic()))
                except queue.Empty:
                    break
                if item is _END or isinstance(item, CaptureError):
                    ended = True
                    if isinstance(item, CaptureError):
                        click.echo(f"mlink-sim watch: {item}", err=True)
                        status = 1 if table.datagrams else 2
                    break
                table.add(item)
                drawn = False
                last_add = time.monotonic()
            now = table.now_ns + (int((time.monotonic() - last_add) * 1e9) if live and not ended else 0)
            if status != 2 and (ended or time.monotonic() - shown_at >= screen.interval * 0.9):
                draw(now)
    finally:
        if not drawn and table.datagrams:  # Ctrl-C between two screens: the last one, as it stands
            draw(table.now_ns)
        screen.stop()
    return status


@click.command("watch")
@click.argument("source", metavar="SOURCE")
@click.option("--station", "stations", multiple=True, type=ADDR, help="Show only this station's rows (repeatable).")
@click.option("--card", "cards", multiple=True, metavar="[ADDR=]CARD",
              help="The card of a station, for parameter names and units (as decode --card); default: the "
                   "capture's notes, and the link.")
@click.option("--follow/--no-follow", default=True, show_default=True,
              help="A FILE: keep reading as it grows (a running --capture FILE), until Ctrl-C; --no-follow: read it "
                   "to its end and show the last screen.")
def watch_cmd(source: str, stations: tuple[int, ...], cards: tuple[str, ...], follow: bool) -> None:
    """Show a capture's frames live, one line per station, direction and command: rate, last value with names and
    units, changed fields highlighted. SOURCE: '-' (a pcapng stream on stdin: mlink-sim up … --capture - |
    mlink-sim watch -) or a FILE being written by --capture. Exit 0 at the end of the stream, 130 on Ctrl-C."""
    from ..capture import CaptureFile
    from ..capture.watch import WatchTable
    from .speed_units import SpeedUnits

    names = card_names(cards)
    if source != "-" and not os.path.exists(source):
        hint = (" (watch reads a pcapng stream, not a control endpoint: run the network with --capture - and pipe "
                "it, mlink-sim up … --capture - | mlink-sim watch -)" if ":" in source else "")
        raise click.BadParameter(f"{source!r}: no such file{hint}", param_hint="SOURCE")
    units = SpeedUnits()
    table = WatchTable(names, lambda link, station: units.of(link, station).hz, on_note=units.learn)
    live = source == "-" or follow
    capture = CaptureFile(source, follow=(lambda: True) if source != "-" and follow else None)
    shown = "stdin" if source == "-" else source
    try:
        status = _watch(shown, capture, table, WatchScreen(), frozenset(stations), live)
    except BrokenPipeError:  # the output was closed (| head): that reader has what it wanted
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        status = 0
    sys.exit(status)
