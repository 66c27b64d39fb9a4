"""mlink_sim.metrics.trace: the trace CSV's writer (header at once, whole lines through a bounded buffer) and its
reader (bounded samples per station, the figures at given moments, a torn last line, not a trace)."""

from __future__ import annotations

import csv
from pathlib import Path

import pytest

from mlink_sim.metrics.trace import FIGURE_COLUMNS, TRACE_COLUMNS, TraceError, TraceWriter, read_trace


def _sample(t: float, address: str = "0x21", hz: float = 0.0) -> tuple[object, ...]:
    figures = dict.fromkeys(FIGURE_COLUMNS, "")
    figures.update(address=address, name=f"{int(address, 16):02X}H", phase=3, connected=True, running=True,
                   output_hz=hz, reference_hz=30.0, output_current_a=2.5, dc_bus_v=282.8)
    return (t, "sample", *figures.values(), "", "")


def _rows(path: Path) -> list[list[str]]:
    with path.open(newline="") as f:
        return list(csv.reader(f))


def test_the_header_is_on_disk_before_any_row_and_rows_follow_in_whole_lines(tmp_path: Path) -> None:
    path = tmp_path / "t.csv"
    w = TraceWriter(path, buffer_rows=3)
    assert _rows(path) == [list(TRACE_COLUMNS)]
    w.add(_sample(0.0))
    w.add(_sample(0.01))
    assert len(_rows(path)) == 1  # buffered
    w.add(_sample(0.02))  # the buffer is full: written
    assert len(_rows(path)) == 4 and path.read_text().endswith("\n")
    w.action(0.025, "step", "0.025s station 21H: do stop", "0x21")
    w.flush()
    last = dict(zip(TRACE_COLUMNS, _rows(path)[-1], strict=True))
    assert last["kind"] == "action" and last["event"] == "step" and last["address"] == "0x21"
    assert last["output_hz"] == "" and last["detail"] == "0.025s station 21H: do stop"
    w.close()
    w.close()  # idempotent


def test_the_reader_thins_each_station_to_max_points_and_keeps_every_action(tmp_path: Path) -> None:
    path = tmp_path / "t.csv"
    w = TraceWriter(path)
    for k in range(1000):
        w.add_many([_sample(k / 100, "0x21", hz=k / 100), _sample(k / 100, "0x22")])
        if k % 100 == 0:
            w.action(k / 100, "control", f"stop {k}")
    w.close()
    trace = read_trace(path, max_points=100)
    st = trace.stations["0x21"]
    assert st.samples == 1000 and 50 <= len(st.t) <= 100 and st.stride == 16
    assert st.t[:2] == [0.0, st.stride / 100] and st.series["output_hz"][1] == st.stride / 100
    assert len(trace.actions) == 10 and trace.actions[0]["detail"] == "stop 0"
    assert trace.span == (0.0, 9.99) and not trace.torn


def test_the_reader_gives_each_station_its_last_sample_at_or_before_a_moment(tmp_path: Path) -> None:
    path = tmp_path / "t.csv"
    w = TraceWriter(path)
    for k in range(10):
        w.add_many([_sample(k / 10, "0x21", hz=k), _sample(k / 10, "0x22", hz=-k)])
    w.close()
    trace = read_trace(path, moments={"0x21": [0.3, 0.35, 5.0], "0x22": [0.0], "0x23": [0.5]})
    assert trace.at[("0x21", 0.3)]["output_hz"] == "3"
    assert trace.at[("0x21", 0.35)]["output_hz"] == "3"
    assert trace.at[("0x21", 5.0)]["output_hz"] == "9"  # after the last sample: the last one
    assert trace.at[("0x22", 0.0)]["output_hz"] == "0"
    assert ("0x23", 0.5) not in trace.at  # no such station in the trace


def test_a_killed_runs_torn_last_line_is_skipped(tmp_path: Path) -> None:
    path = tmp_path / "t.csv"
    w = TraceWriter(path)
    w.add_many([_sample(0.0), _sample(0.01)])
    w.close()
    with path.open("a") as f:
        f.write("0.02,sample,0x21,21H,si-t3")  # what a SIGKILL in the middle of a write leaves
    trace = read_trace(path)
    assert trace.torn and trace.stations["0x21"].samples == 2


@pytest.mark.parametrize("content", ["", "a,b,c\n1,2,3\n", "t_s,kind\n", "\xff\xfe garbage"])
def test_a_file_that_is_not_a_trace_is_a_trace_error(tmp_path: Path, content: str) -> None:
    path = tmp_path / "x.csv"
    path.write_text(content, encoding="latin-1")
    with pytest.raises(TraceError, match="not a trace of mlink-sim"):
        read_trace(path)
    with pytest.raises(TraceError, match="No such file"):
        read_trace(tmp_path / "missing.csv")
