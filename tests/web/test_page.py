"""The page in a real browser (Debian's chromium through Selenium) against a real network (``mlink-sim up
quickstart --web``): the stations reach phase 3, a stop from the page brings a drive to 0 Hz, a fault injected from
the page shows its alarm on the station's panel, a parameter is read from the page. Without chromium the tests are
skipped, saying why; in CI (``CI=true``) they fail instead."""

from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from .browser import attr, browser, control, find_browser, result, screenshots, until
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


def test_a_stop_from_the_page_brings_the_drive_to_0_hz(page: tuple[Any, Http]) -> None:
    session, _ = page
    control(session, "21H", "forward", speed="20")
    until(session, lambda s: (hz(s, "21H") or 0) > 5.0, 30, "21H above 5 Hz")
    assert attr(session, "21H", "running") == "true"
    control(session, "21H", "stop")
    until(session, lambda s: hz(s, "21H") == 0.0, 30, "21H at 0 Hz")
    assert result(session, "21H") == "stopping"


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


def test_the_page_is_shot_at_a_laptops_and_a_phones_width(page: tuple[Any, Http], tmp_path: Path) -> None:
    session, http = page
    wait_for(lambda: stations(http), 5)
    for shot in screenshots(session, tmp_path):
        assert shot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and shot.stat().st_size > 10_000
