"""The trace's sample rows are the station figures (aio/present/figures.py) flattened into the trace's columns
(docs/report.md, "Traces"): one column per figure, the alarm as code and name, the warnings and LEDs as text."""

from __future__ import annotations

from mlink_sim.aio.present.figures import FIGURE_FIELDS
from mlink_sim.aio.present.trace import _row
from mlink_sim.metrics.trace import FIGURE_COLUMNS, TRACE_COLUMNS


def test_every_station_figure_has_its_trace_column() -> None:
    flattened = [c for f in FIGURE_FIELDS if f != "led_colors"
                 for c in (("alarm_code", "alarm_name") if f == "alarm" else (f,))]
    assert tuple(flattened) == FIGURE_COLUMNS


def test_a_sample_row_flattens_the_alarm_warnings_and_leds() -> None:
    fig = dict.fromkeys(FIGURE_FIELDS)
    fig.update(address="0x23", name="23H", alarm={"code": "COMM_ALM 8H", "name": "FCS_ERROR"},
               warnings=["D_WAR", "WDT_WARNING"], leds={"R/E": "on", "CON": "on", "LK1": "blink", "LK2": "off"},
               output_hz=29.5, running=True)
    row = dict(zip(TRACE_COLUMNS, _row(1.25, fig), strict=True))
    assert row["t_s"] == 1.25 and row["kind"] == "sample" and row["address"] == "0x23"
    assert (row["alarm_code"], row["alarm_name"]) == ("COMM_ALM 8H", "FCS_ERROR")
    assert row["warnings"] == "D_WAR|WDT_WARNING" and row["leds"] == "R/E CON LK1* LK2-"
    assert row["output_hz"] == 29.5 and row["running"] is True and row["event"] == row["detail"] == ""
    fig.update(alarm={"code": None, "name": "D_ALM"}, warnings=[], leds={})
    row = dict(zip(TRACE_COLUMNS, _row(2.0, fig), strict=True))
    assert (row["alarm_code"], row["alarm_name"], row["warnings"], row["leds"]) == ("", "D_ALM", "", "")
