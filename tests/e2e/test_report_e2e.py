"""Traces and the HTML report end to end (docs/report.md, "Traces", "The HTML report"): ``up`` with ``--trace``
and ``--report-html`` on the virtual clock and on the real one (processes on loopback, port 0), ``mlink-sim report
REPORT.json --html`` giving the same page, a run ended by SIGINT leaving a readable trace; bad input is exit 2."""

from __future__ import annotations

import csv
import json
import signal
import subprocess
import time
from html.parser import HTMLParser
from pathlib import Path

import pytest

from mlink_sim.metrics.trace import TRACE_COLUMNS, read_trace

from .conftest import MLINK, assert_held, run_cli

pytestmark = pytest.mark.e2e

#: Two stations (an SI-T3 on ML-II and an SI-ET3 on ML-III) ramping to 30 Hz in 1 s (C1-01 = 1.0 s per 60 Hz:
#: 0.5 s), a silence on one, checks before and after.
LINE = """
[network]
name = "line"
transmission_cycle = "2ms"

[[station]]
address = 0x21
card = "si-t3"
link = "ML2"
params = { "b1-01" = 3, "b1-02" = 3, "C1-01" = 1.0, "C1-02" = 1.0 }

[[station]]
address = 0x23
card = "si-et3"
link = "ML3"
params = { "b1-01" = 3, "b1-02" = 3, "C1-01" = 1.0, "C1-02" = 1.0 }

[[timeline]]
at = "0.1s"
do = "run"
direction = "forward"
hz = 30.0

[[timeline]]
at = "1.2s"
expect = "output-hz"
output_hz = 30.0

[[timeline]]
at = "1.4s"
station = 0x21
do = "silence"
for = "100ms"

[[timeline]]
at = "1.5s"
station = 0x21
expect = "recovered"
within = "500ms"  # the wall clock's: generous, so that a host stall of tens of ms within the bound passes (docs/ci.md)

[[timeline]]
at = "2s"
expect = "running"
"""


class _Page(HTMLParser):
    def __init__(self, text: str) -> None:
        super().__init__()
        self.tags: list[str] = []
        self.links: list[str] = []
        self.text: list[str] = []
        self.feed(text)
        self.close()

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        self.tags.append(tag)
        self.links += [v or "" for k, v in attrs if k in ("src", "href", "xlink:href")]

    def handle_data(self, data: str) -> None:
        self.text.append(data)


def _samples(path: Path) -> tuple[list[str], dict[str, list[dict[str, str]]], list[dict[str, str]]]:
    with path.open(newline="") as f:
        rows = list(csv.reader(f))
    by: dict[str, list[dict[str, str]]] = {}
    actions = []
    for row in rows[1:]:
        r = dict(zip(rows[0], row, strict=True))
        (by.setdefault(r["address"], []) if r["kind"] == "sample" else actions).append(r)
    return rows[0], by, actions


def _check_page(text: str, report: dict, stations: int) -> str:
    page = _Page(text)
    body = " ".join(page.text)
    assert page.links == [] and "http://" not in text and "https://" not in text
    stalls = 1 if report.get("host", {}).get("stalls") else 0  # a busy host's stalls have a plot of their own
    # the RTT histogram and the round trips over time; Hz, current, DC bus per station
    assert page.tags.count("svg") == 2 + 3 * stations + stalls
    for c in report["checks"]:
        assert c["what"] in body
    return body


def test_a_virtual_run_traces_each_station_at_the_interval_and_writes_the_html_report(tmp_path: Path) -> None:
    cfg, trace, report, html = tmp_path / "line.toml", tmp_path / "t.csv", tmp_path / "r.json", tmp_path / "r.html"
    cfg.write_text(LINE)
    r = run_cli("up", str(cfg), "--clock", "virtual", "--no-status", "--duration", "2.5s", "--trace", str(trace),
                "--trace-interval", "20ms", "--report", str(report), "--report-html", str(html))
    assert r.returncode == 0 and "all checks held" in r.stdout, r.stdout + r.stderr
    assert f"trace: {trace}" in r.stdout and f"HTML report: {html}" in r.stdout
    header, by, actions = _samples(trace)
    assert tuple(header) == TRACE_COLUMNS
    assert set(by) == {"0x21", "0x23"}
    for address, rows in by.items():
        times = [float(x["t_s"]) for x in rows]
        assert len(rows) == 126 and times[0] == 0.0 and times[-1] == 2.5  # 0 … 2.5 s every 20 ms
        assert all(round(b - a, 6) == 0.02 for a, b in zip(times, times[1:]))
        assert float(rows[0]["output_hz"]) == 0.0
        ramp = [float(x["output_hz"]) for x in rows if 0.1 < float(x["t_s"]) < 0.6]
        assert ramp == sorted(ramp) and 0 < ramp[len(ramp) // 2] < 30  # rising: C1-01 = 1 s per 60 Hz
        steady = [x for x in rows if 1.0 <= float(x["t_s"]) <= 1.3]
        assert all(float(x["output_hz"]) == float(x["reference_hz"]) == 30.0 for x in steady), address
        assert all(x["running"] == "True" and x["direction"] == "forward" and x["phase"] == "3" for x in steady)
        assert all(250 < float(x["dc_bus_v"]) < 400 and float(x["output_current_a"]) > 0 for x in steady)
    events = [(a["event"], a["address"]) for a in actions]
    assert ("step", "") in events and ("fault", "0x21") in events and ("fault-end", "0x21") in events
    assert ("recovered", "0x21") in events
    assert sum(e == "check" for e, _ in events) == 5
    silence = next(a for a in actions if a["event"] == "fault")
    assert float(silence["t_s"]) == 1.4 and silence["detail"] == "silence-21H-1: silence for=100ms"

    written = json.loads(report.read_text())
    assert written["meta"]["trace"] == str(trace) and written["meta"]["trace_interval_ns"] == 20_000_000
    assert written["rtt"]["bins"] and sum(b[2] for b in written["rtt"]["bins"]) == written["rtt"]["count"]
    assert {c["station"] for c in written["checks"]} == {"0x21", "0x23"}
    text = html.read_text()
    body = _check_page(text, written, stations=2)
    assert "Passed: all checks held" in body and "silence for=100ms" in body

    again = tmp_path / "again.html"
    r = run_cli("report", str(report), "--html", str(again))  # the trace the report names
    assert r.returncode == 0, r.stderr
    assert again.read_text() == text
    r = run_cli("report", str(report), "--html", str(again), "--trace", str(trace))
    assert r.returncode == 0 and again.read_text() == text


def test_the_quickstart_trace_reads_a_reverse_run_below_0_hz_and_names_the_dc_bus_regulation(tmp_path: Path) -> None:
    """The quickstart reverses 21H from +30 Hz to -20 Hz at 3.2 s: the CSV's output and reference are signed (the
    direction column says the same in words), and the deceleration held by the DC bus (stall prevention, L3-04) is
    in its regulation column while the bus holds its level."""
    trace = tmp_path / "t.csv"
    r = run_cli("up", "quickstart", "--clock", "virtual", "--no-status", "--trace", str(trace))
    assert r.returncode == 0, r.stdout + r.stderr
    _, by, _ = _samples(trace)
    a = by["0x21"]
    late = [x for x in a if 6.5 <= float(x["t_s"]) <= 7.0]
    assert all(float(x["output_hz"]) == -20.0 and float(x["reference_hz"]) == -20.0 for x in late)
    assert all(x["direction"] == "reverse" for x in late)
    early = [x for x in a if 2.0 <= float(x["t_s"]) <= 3.0]
    assert all(float(x["output_hz"]) == 30.0 and x["direction"] == "forward" for x in early)
    held = [float(x["t_s"]) for x in a if "stall-decel" in x["regulation"]]
    assert held and 3.5 < held[0] < 4.2 and 5.0 < held[-1] < 5.6
    assert all(float(x["dc_bus_v"]) > 360 for x in a if "stall-decel" in x["regulation"])
    assert all(float(x["output_hz"]) >= 0 for x in by["0x22"])  # 22H runs forward only
    assert all(x["rtt_us"] and float(x["rtt_us"]) > 0 for x in a if x["phase"] == "3")


def test_report_html_alone_records_a_temporary_trace_for_its_plots(tmp_path: Path) -> None:
    cfg, html, report = tmp_path / "line.toml", tmp_path / "r.html", tmp_path / "r.json"
    cfg.write_text(LINE)
    r = run_cli("up", str(cfg), "--clock", "virtual", "--no-status", "--duration", "2.5s", "--report-html",
                str(html), "--report", str(report))
    assert r.returncode == 0, r.stdout + r.stderr
    written = json.loads(report.read_text())
    assert "trace" not in written["meta"]
    body = _check_page(html.read_text(), written, stations=2)
    assert "Stations over time" in body
    assert sorted(p.name for p in tmp_path.iterdir()) == ["line.toml", "r.html", "r.json"]


def test_a_real_clock_run_traces_control_requests_and_its_report_opens_offline(tmp_path: Path) -> None:
    cfg, trace, html, report = tmp_path / "line.toml", tmp_path / "t.csv", tmp_path / "r.html", tmp_path / "r.json"
    cfg.write_text(LINE)
    up = subprocess.Popen([*MLINK, "up", str(cfg), "--no-status", "--duration", "6s", "--trace", str(trace),
                           "--report-html", str(html), "--report", str(report), "--control", "127.0.0.1:0"],
                          stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert up.stderr is not None
        control = None
        for _ in range(50):
            line = up.stderr.readline()
            if line.startswith("control: "):
                control = line.split()[1]
                break
        assert control, "no control endpoint announced"
        time.sleep(1.0)
        r = run_cli("control", control, "impair", "0x23", "delay=100us,for=300ms", "--timeout", "6")
        assert r.returncode == 0, r.stdout + r.stderr
        r = run_cli("param", "set", control, "0x21", "C1-02=1.5")  # answered later, through the master
        assert r.returncode == 0, r.stdout + r.stderr
        r = run_cli("param", "get", control, "0x21", "C1-02")  # reads only: no row
        assert r.returncode == 0, r.stdout + r.stderr
        out, err = up.communicate(timeout=90)
    finally:  # a failed step leaves no network running beside the rest of the suite
        if up.poll() is None:
            up.kill()
            up.communicate()
    assert_held(subprocess.CompletedProcess(up.args, up.returncode, out, err))
    header, by, actions = _samples(trace)
    assert tuple(header) == TRACE_COLUMNS and set(by) == {"0x21", "0x23"}
    for rows in by.values():  # every 10 ms on the wall clock, give or take the loop's lateness
        assert 400 <= len(rows) <= 602
        assert [float(x["output_hz"]) for x in rows if 1.0 <= float(x["t_s"]) <= 1.3] != []
        assert all(float(x["output_hz"]) == 30.0 for x in rows if 1.0 <= float(x["t_s"]) <= 1.3)
    events = {(a["event"], a["address"]) for a in actions}
    assert {("control", "0x23"), ("impair-start", "0x23"), ("impair-end", "0x23")} <= events
    impair, param = (a for a in actions if a["event"] == "control")
    assert impair["detail"].startswith("impair ") and "delay=100us,for=300ms" in impair["detail"]
    assert param["address"] == "0x21" and param["detail"].startswith("set-param ") and '"value":1.5' in param["detail"]
    _check_page(html.read_text(), json.loads(report.read_text()), stations=2)


def test_a_run_ended_by_sigint_leaves_a_readable_trace_and_an_html_report(tmp_path: Path) -> None:
    cfg, trace, html = tmp_path / "line.toml", tmp_path / "t.csv", tmp_path / "r.html"
    cfg.write_text(LINE)
    up = subprocess.Popen([*MLINK, "up", str(cfg), "--no-status", "--duration", "60s", "--trace", str(trace),
                           "--report-html", str(html)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    end = time.monotonic() + 30
    while time.monotonic() < end and (not trace.exists() or trace.stat().st_size < 20_000):
        time.sleep(0.2)
    up.send_signal(signal.SIGINT)
    out, err = up.communicate(timeout=60)
    assert up.returncode == 130, out + err
    read = read_trace(trace)
    assert not read.torn and read.stations["0x21"].samples > 50
    assert "Interrupted by SIGINT" in " ".join(_Page(html.read_text()).text)


@pytest.mark.parametrize("content, message", [
    (None, "cannot read the report: No such file"),
    ("{", "not a report of mlink-sim (invalid JSON"),
    ('{"schema": "x"}', "not a report of mlink-sim (no \"schema\""),
    ("\udcff", "not a report of mlink-sim"),
])
def test_report_of_an_unreadable_or_invalid_file_is_one_line_and_exit_2(tmp_path: Path, content: str | None,
                                                                        message: str) -> None:
    path = tmp_path / "r.json"
    if content is not None:
        path.write_bytes(content.encode("utf-8", "surrogateescape"))
    r = run_cli("report", str(path), "--html", str(tmp_path / "r.html"))
    assert r.returncode == 2 and message in r.stderr, r.stderr
    assert len(r.stderr.strip().splitlines()) == 1 and "Traceback" not in r.stderr
    assert not (tmp_path / "r.html").exists()


def test_bad_trace_options_are_exit_2_before_the_run(tmp_path: Path) -> None:
    (tmp_path / "r.json").write_text(json.dumps({"schema": "mlink-sim/report/1", "meta": {}, "checks": []}))
    cases = [
        (["up", "quickstart", "--trace-interval", "0"], "--trace-interval '0': expected a duration from 1ms"),
        (["up", "quickstart", "--trace-interval", "soon"], "expected a duration"),
        (["up", "quickstart", "--trace", str(tmp_path / "no" / "t.csv")], "--trace"),
        (["master", "quickstart", "--report-html", str(tmp_path)], "--report-html"),
        (["report", str(tmp_path / "r.json"), "--html", str(tmp_path / "x.html"), "--trace", str(tmp_path / "r.json")],
         "--trace: " + str(tmp_path / "r.json") + ": not a trace of mlink-sim"),
    ]
    for args, message in cases:
        r = run_cli(*args)
        assert r.returncode == 2 and message in r.stderr, (args, r.stderr)
        assert "Traceback" not in r.stderr
