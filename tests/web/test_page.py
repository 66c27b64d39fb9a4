"""The page in a real browser (Debian's chromium through Selenium) against a real network (``mlink-sim up
quickstart --web``): the stations reach phase 3, the time axis reads in seconds at any window, a stop from the page
brings a drive to 0 Hz, a reverse run reads below 0 Hz, actions are numbered on the plots and listed, a fault
injected from the page shows its alarm on the station's panel, a parameter is read from the page, and a page opened
later starts with the last minute plotted. Without chromium the tests are skipped, saying why; in CI (``CI=true``)
they fail instead."""

from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from .browser import attr, browser, control, find_browser, panel, result, screenshots, until
from .webnet import Http, stations, up_with_web, wait_for

pytestmark = pytest.mark.e2e

NAMES = ("21H", "22H", "23H")


@pytest.fixture(scope="module")
def page() -> Iterator[tuple[Any, Http]]:
    found = find_browser()
    if isinstance(found, str):
        if os.environ.get("CI", "").lower() == "true":
            pytest.fail(f"{found}; CI must run the page's tests")
        pytest.skip(found)
    net, url = up_with_web()
    try:
        http = Http(url)
        with browser(*found) as session:
            session.get(url)
            yield session, http
    finally:
        net.stop()


def hz(session: Any, name: str) -> float | None:
    text = attr(session, name, "output-hz")
    return float(text) if text else None


def test_every_station_reaches_phase_3_on_its_panel(page: tuple[Any, Http]) -> None:
    session, _ = page
    until(session, lambda s: all(attr(s, n, "phase") == "3" for n in NAMES), 30, "phase 3 on every panel")
    assert session.title == "quickstart – mlink-sim"


def ticks(session: Any, name: str) -> list[float]:
    """The numbers under the time axis of *name*'s frequency plot as drawn (the page records them: data-x-ticks)."""
    text = attr(session, name, "x-ticks")
    return [float(v) for v in text.split()] if text else []


def assert_seconds(values: list[float]) -> None:
    """Ticks that read as a time axis: at least two, each written once, increasing evenly."""
    assert len(values) >= 2 and values == sorted(set(values)), values
    steps = {round(b - a, 6) for a, b in zip(values, values[1:])}
    assert len(steps) == 1, values


def test_the_time_axis_reads_in_seconds_however_short_the_window(page: tuple[Any, Http]) -> None:
    """The first seconds after bring-up (a window of a second or two: ticks 0.2 or 0.5 s apart) and later."""
    session, _ = page
    until(session, lambda s: len(ticks(s, "21H")) >= 2, 30, "ticks under 21H's plot")
    assert_seconds(ticks(session, "21H"))
    assert session.execute_script("return document.querySelector('#station-21H .plot-hz').textContent") != ""


def test_a_stop_from_the_page_brings_the_drive_to_0_hz(page: tuple[Any, Http]) -> None:
    session, _ = page
    control(session, "21H", "forward", speed="20")
    until(session, lambda s: (hz(s, "21H") or 0) > 5.0, 30, "21H above 5 Hz")
    assert attr(session, "21H", "running") == "true"
    control(session, "21H", "stop")
    until(session, lambda s: hz(s, "21H") == 0.0, 30, "21H at 0 Hz")
    assert result(session, "21H") == "stopping"


def test_a_reverse_run_reads_below_0_hz_and_each_action_is_a_numbered_mark_listed_under_the_plots(
        page: tuple[Any, Http]) -> None:
    from selenium.webdriver.common.by import By

    session, _ = page
    control(session, "22H", "reverse", speed="10")
    until(session, lambda s: (hz(s, "22H") or 0) < -5.0, 30, "22H below -5 Hz")
    listed = until(session, lambda s: [li.text for li in panel(s, "22H").find_elements(By.CSS_SELECTOR,
                                                                                        ".st-marks li")], 10)
    assert any("run reverse 10 Hz" in text for text in listed), listed
    numbers = [li.get_attribute("data-n") for li in panel(session, "22H").find_elements(By.CSS_SELECTOR,
                                                                                         ".st-marks li")]
    assert numbers == sorted(numbers, key=int) and int(attr(session, "22H", "marks")) >= len(numbers)
    control(session, "22H", "stop")


def test_a_fault_injected_from_the_page_shows_its_alarm_on_the_panel(page: tuple[Any, Http]) -> None:
    session, http = page
    control(session, "23H", "forward", speed="20")
    until(session, lambda s: (hz(s, "23H") or 0) > 5.0, 30, "23H above 5 Hz")
    control(session, "23H", "fault", fault="lock-rotor")
    alarm = until(session, lambda s: attr(s, "23H", "alarm"), 30, "an alarm on 23H's panel")
    assert alarm == next(row for row in stations(http) if row["name"] == "23H")["alarm"]["name"]
    assert attr(session, "21H", "alarm") == ""


def test_a_parameter_is_read_from_the_page(page: tuple[Any, Http]) -> None:
    session, _ = page
    control(session, "22H", "read", name="n019")  # the config sets n019 (acceleration time 1) = 2.0 s
    text = until(session, lambda s: result(s, "22H") if "=" in result(s, "22H") else "", 20, "the value")
    assert text.startswith(("n019 = 2 s", "n019 = 2.0 s")), text


def test_a_page_opened_later_starts_with_the_last_minute_plotted(page: tuple[Any, Http]) -> None:
    """The server keeps the last minute of status answers, polled while nobody looks; a page opened later plots
    them at once, not from the moment it opened."""
    session, http = page
    wait_for(lambda: http.get("api/status")[1]["elapsed_s"] > 15, 30)
    session.get(http.base)  # opened again: a new page, a new event stream
    until(session, lambda s: attr(s, "23H", "plot-points") not in ("", "0"), 10, "23H's plot filled")
    span = float(attr(session, "23H", "plot-to")) - float(attr(session, "23H", "plot-from"))
    assert span > 10, span  # the seconds before it opened, plotted within a few seconds of opening
    assert_seconds(ticks(session, "21H"))


def test_the_page_is_shot_at_a_laptops_and_a_phones_width(page: tuple[Any, Http], tmp_path: Path) -> None:
    session, http = page
    wait_for(lambda: stations(http), 5)
    for shot in screenshots(session, tmp_path):
        assert shot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and shot.stat().st_size > 10_000
