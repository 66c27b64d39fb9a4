"""What ``mlink-sim watch`` shows, as a terminal shows it (rendered by pyte): one line per station, direction and
command, its rate, the last value with names and units, the changed fields in reverse video, at 60 columns every
line's station, command and rate on the screen; rows seen last kept when the screen is short."""

from __future__ import annotations

import io
from pathlib import Path

import pytest

from mlink_sim.capture import CaptureFile, Datagram
from mlink_sim.capture.watch import WatchTable, frame_fields
from mlink_sim.cli.frame_names import FrameNames
from mlink_sim.cli.speed_units import SpeedUnits
from mlink_sim.cli.watch import WatchScreen, render
from mlink_sim.wire import Frame, Kind, Link, M2Status, describe, encode, ml2

from tests.aio.present.test_status_screen import _Terminal as StatusTerminal

from .timed import T0, write_timed_capture

A, B = ("192.0.2.1", 40000), ("192.0.2.33", 47001)


class _Terminal(StatusTerminal):
    """The live status tests' pyte terminal, read line by line and by its reverse-video characters."""

    def lines(self) -> list[str]:
        return [line.rstrip() for line in self.screen.display]

    def reversed_text(self, row: int) -> str:
        """The characters of screen line *row* shown in reverse video."""
        line = self.screen.buffer[row]
        return "".join(line[x].data for x in range(self.screen.columns) if line[x].reverse)


def _table() -> WatchTable:
    units = SpeedUnits()
    return WatchTable(FrameNames(), lambda link, station: units.of(link, station).hz, on_note=units.learn)


def _answer(cycle: int, hz_counts: int, status: int) -> Datagram:
    data = encode(Frame(Link.ML2, Kind.RESPONSE, 0x21, cycle, 2_000_000,
                        ml2.M2Response(ml2.InvCtlResponse(output_freq=hz_counts), 0, status, 0, ml2.Nop(), 0)))
    return Datagram(T0 + cycle * 2_000_000, B, A, data)


def _show(table: WatchTable, columns: int, rows: int) -> _Terminal:
    term = _Terminal(columns, rows)
    screen = WatchScreen(term, size=(columns, rows))
    screen.start()
    width, height = screen.dimensions()
    screen.show(render(table, width, height, "stdin"))
    screen.stop()
    return term


def test_fields_name_bits_and_give_hz() -> None:
    d = describe(encode_decode(ml2.M2Command(ml2.InvCtl(signals=1, speed_ref=3000), 0, ml2.Nop())))
    fields = dict(frame_fields(d, lambda raw: raw * 0.01))
    assert fields["ref"] == "30.00 Hz" and fields["signals"] == "FORWARD"
    assert list(dict(frame_fields(d, lambda raw: raw * 0.01)))[:2] == ["ref", "signals"]  # the telling ones first
    r = describe(encode_decode(ml2.M2Response(ml2.InvCtlResponse(output_freq=2998), 0xE6,
                                              int(M2Status.ALM | M2Status.REMOTE), 0, ml2.Nop(), 4)))
    fields = dict(frame_fields(r, lambda raw: raw * 0.01))
    assert fields["out"] == "29.98 Hz" and fields["status"] == "ALM|REMOTE"
    assert fields["alarm"] == "E6H COMM_ERROR" and fields["substatus"] == "SUBCMDRDY"
    assert "cycle" not in fields and "rwdt" not in fields  # they change with every datagram: the rate says so


def encode_decode(message: object) -> Frame:
    from mlink_sim.wire import decode

    kind = Kind.COMMAND if isinstance(message, ml2.M2Command) else Kind.RESPONSE
    return decode(encode(Frame(Link.ML2, kind, 0x21, 1, 2_000_000, message)))


def test_rows_rates_and_the_fields_that_changed(tmp_path: Path) -> None:
    table = _table()
    for d in CaptureFile(write_timed_capture(tmp_path / "timed.pcapng")):
        table.add(d)
    table.refresh()
    rows = {(r.station, r.kind, r.command): r for r in table.sorted_rows()}
    assert set(rows) == {(0x21, "cmd", "INV_CTL"), (0x21, "rsp", "INV_CTL"), (0x23, "cmd", "PRM_RD"),
                         (0x23, "rsp", "PRM_RD")}
    inv = rows[(0x21, "rsp", "INV_CTL")]
    assert inv.count == 12 and table.rejected == 1 and "bad FCS" in table.last_rejection
    # 12 answers in the 22.2 ms the capture spans: its rate over that time, the window being shorter than 1 s
    assert inv.rate(table.now_ns, table.start_ns) == pytest.approx(12 / 0.0222, rel=1e-3)
    assert dict(inv.fields)["out"] == "26.40 Hz"  # 4400 counts × the note's 0.006 Hz
    assert dict(rows[(0x23, "rsp", "PRM_RD")].fields)["param"] == "C1-02 (0201H) = 1.0 s"
    assert inv.changed(table.now_ns) == set()  # the first screen: nothing came before to differ from
    table.add(_answer(50, 4500, int(M2Status.CMDRDY | M2Status.REMOTE)))
    table.refresh()
    assert inv.changed(table.now_ns) == {"out"}


def test_the_screen_at_60_columns_keeps_station_command_rate_and_marks_changes(tmp_path: Path) -> None:
    table = _table()
    for d in CaptureFile(write_timed_capture(tmp_path / "timed.pcapng")):
        table.add(d)
    table.refresh()
    table.add(_answer(50, 4500, int(M2Status.CMDRDY | M2Status.REMOTE | M2Status.RUNX)))
    term = _show(table, 60, 24)
    lines = term.lines()
    assert lines[0].startswith("watch stdin  ") and "31 datagrams  1 rejected" in lines[0]
    assert lines[1].split()[:4] == ["ADDR", "DIR", "COMMAND", "RATE"]
    rsp = next(i for i, line in enumerate(lines) if line.startswith("21H  rsp INV_CTL"))
    assert lines[rsp].split()[3].endswith("/s") and "out=27.00 Hz" in lines[rsp]
    marked = term.reversed_text(rsp)  # the output frequency and the status changed, nothing else
    assert marked.startswith("out=27.00 Hzstatus=CMDRDY|RUNX|") and "output_current" not in marked
    assert any(line.startswith("23H  rsp PRM_RD") for line in lines)
    assert any(line.startswith("last rejected: bad FCS") for line in lines)
    assert all(len(line) <= 60 for line in lines)


def test_a_short_screen_keeps_the_rows_seen_last(tmp_path: Path) -> None:
    table = _table()
    for d in CaptureFile(write_timed_capture(tmp_path / "timed.pcapng")):
        table.add(d)
    term = _show(table, 60, 7)  # header, headings, 3 rows, the sum-up line, the last-rejected line
    lines = term.lines()
    assert any(line.startswith("21H  rsp INV_CTL") for line in lines)  # the last datagram is a 21H answer
    assert any("row(s) idle longest not shown" in line for line in lines)
    assert len([line for line in lines if line]) <= 6


def test_plain_text_off_a_terminal(tmp_path: Path) -> None:
    table = _table()
    for d in CaptureFile(write_timed_capture(tmp_path / "timed.pcapng")):
        table.add(d)
    out = io.StringIO()
    screen = WatchScreen(out)
    screen.start()
    width, height = screen.dimensions()
    screen.show(render(table, width, height, "timed.pcapng", stations=frozenset({0x23})))
    text = out.getvalue()
    assert "23H  cmd PRM_RD" in text and "21H" not in text.split("\n", 2)[2]
