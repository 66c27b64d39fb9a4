"""mlink_sim.metrics.html and svg: the HTML report is one self-contained, well-formed page (no network: no
external src or href), with the verdict, every check beside the station's figures at its moment, an SVG per plot,
and every text from the report escaped."""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET
from html.parser import HTMLParser
from pathlib import Path

import pytest

from mlink_sim.metrics import NetworkMetrics
from mlink_sim.metrics.html import check_moments, render_html, tail_folded, verdict_of
from mlink_sim.metrics.svg import Series, line_chart, nice_ticks
from mlink_sim.metrics.trace import FIGURE_COLUMNS, TraceWriter, read_trace

META = {"config": "line.toml", "network": "line", "started": "2024-05-02T10:15:00+00:00", "duration_s": 3.0}


class Page(HTMLParser):
    """What a test needs of a page: the tags in order, every src/href, the text, whether the tags balance."""

    VOID = {"meta", "br", "img", "input", "link", "hr", "col", "area", "base", "source", "wbr"}
    SVG_LEAVES = {"line", "rect", "circle", "polyline", "path"}

    def __init__(self, text: str) -> None:
        super().__init__()
        self.tags: list[str] = []
        self.links: list[str] = []
        self.text: list[str] = []
        self.open: list[str] = []
        self.unbalanced: list[str] = []
        self.feed(text)
        self.close()

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        self.tags.append(tag)
        self.links += [v or "" for k, v in attrs if k in ("src", "href", "xlink:href", "action")]
        if tag not in self.VOID:
            self.open.append(tag)

    def handle_startendtag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        self.tags.append(tag)
        self.links += [v or "" for k, v in attrs if k in ("src", "href", "xlink:href", "action")]

    def handle_endtag(self, tag: str) -> None:
        if self.open and self.open[-1] == tag:
            self.open.pop()
        else:
            self.unbalanced.append(tag)

    def handle_data(self, data: str) -> None:
        self.text.append(data)


def _report(checks: list[tuple[float, str, bool, str | None]]) -> dict:
    m = NetworkMetrics(1_000_000)
    m.add_stations([0x21])
    for i in range(200):
        m.record_sent(0x21)
        m.record_rtt(0x21, 100_000 + 1_000 * i)
    for at, what, ok, cause in checks:
        m.record_check(at, what, ok, "output 12.00 Hz", cause, station=0x21)
    return m.report(meta=META)


def _trace(path: Path) -> None:
    w = TraceWriter(path)
    for k in range(300):
        row = dict.fromkeys(FIGURE_COLUMNS, "")
        row.update(address="0x21", name="21H", phase=3, running=True, reference_hz=30.0, output_hz=min(30, k / 10),
                   output_current_a=2.0, dc_bus_v=282.8)
        w.add((k / 100, "sample", *row.values(), "", ""))
    w.action(0.5, "fault", "silence for=200ms", "0x21")
    w.action(0.7, "fault-end", "silence for=200ms", "0x21")
    w.action(0.72, "recovered", "silence for=200ms: healthy 20.0 ms after its end", "0x21")
    w.close()


def test_the_page_is_self_contained_and_shows_verdict_checks_and_plots(tmp_path: Path) -> None:
    report = _report([(1.0, "1s station 21H: expect output-hz 30±0.5 Hz", False, "accelerating at C1-01 = 10.0 s"),
                      (2.5, "2.5s station 21H: expect running", True, None)])
    _trace(tmp_path / "t.csv")
    trace = read_trace(tmp_path / "t.csv", moments=check_moments(report))
    text = render_html(report, trace)
    page = Page(text)
    assert not page.unbalanced and not page.open
    assert page.links == []  # nothing to fetch: no src, no href
    assert "http://" not in text and "https://" not in text
    body = " ".join(page.text)
    assert "Failed: 1 check(s) failed; 1 check(s) held" in body
    for c in report["checks"]:
        assert c["what"] in body
    assert "accelerating at C1-01 = 10.0 s" in body
    assert "sample 1.0 s" in body  # the station's figures at the failed check's moment, from the trace
    assert page.tags.count("svg") == 5  # the RTT histogram and over time; frequency, current and DC bus of 21H
    assert "silence for=200ms: healthy 20.0 ms after its end" in body


def test_text_from_the_report_is_escaped() -> None:
    report = _report([(1.0, "<script>alert(1)</script>", False, "<b>x</b>")])
    text = render_html(report)
    assert "<script>" not in text and "&lt;script&gt;" in text
    assert "<b>x</b>" not in text


def test_the_verdict_follows_the_report() -> None:
    assert verdict_of(_report([(1.0, "a", True, None)])) == ("pass", "Passed: all checks held")
    assert verdict_of(_report([])) == ("pass", "Passed: run complete, no checks")
    interrupted = {**_report([(1.0, "a", True, None)])}
    interrupted["meta"] = {**interrupted["meta"], "interrupted": "SIGINT", "not_run": ["5s station 21H: do stop"]}
    assert verdict_of(interrupted) == ("stop", "Interrupted by SIGINT: 1 timeline step(s) not run; 1 check(s) held")


def test_a_chart_without_values_says_so_and_ticks_cover_the_range() -> None:
    assert "no data" in line_chart("empty", [Series("x", [0.0, 1.0], [None, None])], y_label="Hz")
    assert nice_ticks(0, 31.5) == [0, 10, 20, 30, 40]
    assert nice_ticks(-3, 2) == [-3, -2, -1, 0, 1, 2]


def test_host_stalls_are_plotted_by_process_and_listed() -> None:
    report = _report([])
    report["host"]["stall"].update(count=2, max=12_000_000, cycles=7, absorbed=6, lost=1)
    report["host"]["stalls"] = [
        {"process": "master", "at": 1_500_000_000, "duration": 12_000_000, "cycles": 6, "absorbed": True},
        {"process": "worker:0", "at": 2_000_000_000, "duration": 4_000_000, "cycles": 1, "absorbed": False}]
    text = render_html(report)
    page = Page(text)
    body = " ".join(page.text)
    assert "2 stall(s), longest 12ms, 7 cycle(s) delayed: 6 run late, 1 lost" in body
    assert page.tags.count("svg") == 2 and page.tags.count("circle") == 2  # the RTT histogram; the stalls
    assert "worker:0" in body and "1.500 s" in body


def test_a_few_outliers_are_one_last_bar_of_the_rtt_plot() -> None:
    bins = [[100, 119, 500], [119, 141, 400], [141, 168, 99], *([lo, lo + 1, 0] for lo in range(200, 210)),
            [300, 356, 1]]
    shown, note = tail_folded(bins)
    assert len(shown) == 6 and shown[-1] == [202, 356, 1] and sum(b[2] for b in shown) == 1000
    assert note == "The last bar holds the 1 round trip(s) from 202ns to 356ns."
    assert tail_folded(bins[:5]) == (bins[:5], "")  # nothing far out: every bin


def _svgs(text: str) -> dict[str, ET.Element]:
    """Each plot of the page by its title, parsed as XML (an inline SVG is well-formed XML)."""
    out = {}
    for chunk in re.findall(r"<svg .*?</svg>", text, re.S):
        svg = ET.fromstring(chunk)
        out[svg.get("aria-label")] = svg
    return out


def _x_of(svg: ET.Element, t: float, span: tuple[float, float]) -> float:
    """Where time *t* is on *svg*'s x axis (svg.py: left margin 64, right 16, width 860)."""
    return 64 + (t - span[0]) / (span[1] - span[0]) * (860 - 64 - 16)


def test_a_reverse_run_plots_below_0_hz_and_checks_and_actions_are_numbered_and_listed(tmp_path: Path) -> None:
    """What a person reads of one station: the output below the 0 Hz line while it runs in reverse; every action
    and check a numbered circle on each plot, the same numbers listed with what they are (a legend that prints);
    the drive's DC bus regulation shaded where the trace says it held; a time before 0 s said to be bring-up."""
    w = TraceWriter(tmp_path / "t.csv")
    w.action(-0.4, "control", 'impair {"loss":0.1}', "0x21")
    for k in range(301):
        t = k / 100
        row = dict.fromkeys(FIGURE_COLUMNS, "")
        out = 20.0 - 40.0 * min(1.0, t / 2)  # +20 Hz to -20 Hz
        row.update(address="0x21", name="21H", phase=3, running=True, direction="forward" if out >= 0 else "reverse",
                   reference_hz=-20.0, output_hz=round(out, 2), output_current_a=5.0, dc_bus_v=300.0,
                   regulation="stall-decel" if 0.5 <= t <= 1.2 and k % 7 else "", rtt_us=100.0)
        w.add((t, "sample", *row.values(), "", ""))
    w.action(0.2, "step", "0.2s station 21H: do run reverse 20 Hz", "0x21")
    w.action(2.5, "check", "ok 2.5s station 21H: expect output-hz 20±0.5 Hz: output 20.00 Hz", "0x21")
    w.action(2.6, "check", "FAIL 2.5s station 21H: expect no-alarm: alarm OV", "0x21")
    w.close()
    trace = read_trace(tmp_path / "t.csv")
    text = render_html(_report([]), trace)
    plots = _svgs(text)
    assert {"21H: frequency", "21H: output current", "21H: DC bus",
            "Round trips over time (each station's latest)"} <= set(plots)
    hz = plots["21H: frequency"]
    zero = hz.find(".//line[@class='zero']")
    assert zero is not None
    output = [pl for pl in hz.iter("polyline") if pl.findtext("title") == "output Hz"]
    ys = [float(p.split(",")[1]) for p in output[0].get("points").split()]
    assert min(ys) < float(zero.get("y1")) < max(ys)  # above the 0 Hz line, then below it
    for title in ("21H: frequency", "21H: output current", "21H: DC bus"):
        marks = plots[title].findall(".//g[@class='mark']")
        # printed in the plot; 1 (during bring-up) lies before the axis, in the list only
        assert [(m.get("data-n"), m.get("data-kind"), m.findtext("text")) for m in marks] == [
            ("2", "action", "2"), ("3", "check-ok", "3"), ("4", "check-fail", "4")]
        bands = plots[title].findall(".//rect[@data-band='stall-decel']")
        assert len(bands) == 1  # the hold's short gaps bridged (mlink_sim.plots.BRIDGE_S)
        x0, x1 = float(bands[0].get("x")), float(bands[0].get("x")) + float(bands[0].get("width"))
        assert x0 == pytest.approx(_x_of(hz, 0.5, (0.0, 3.0)), abs=1) and x1 == pytest.approx(
            _x_of(hz, 1.2, (0.0, 3.0)), abs=1)
    page = Page(text)
    body = " ".join(page.text)
    assert "-0.4 s (bring-up)  control: impair" in body
    assert "0.2 s  station 21H: do run reverse 20 Hz" in body
    assert "2.5 s  held: expect output-hz 20±0.5 Hz (output 20.00 Hz)" in body
    assert "2.6 s  FAILED: expect no-alarm (alarm OV)" in body
    assert "DC bus regulation (stall prevention, decel" in body
    listed = re.findall(r'<li data-n="(\d+)" data-kind="([\w-]+)">', text)
    assert listed == [("1", "action"), ("2", "action"), ("3", "check-ok"), ("4", "check-fail")]
    assert "-0.400 s (bring-up)" in body  # the actions table
