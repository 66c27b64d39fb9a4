"""Debian's chromium driven by Selenium, for the page's tests and for the screenshots of docs/web.md.

    python -m tests.web.browser docs/images      # (from the repository's root) writes web-laptop.png, web-phone.png,
                                                 # report-station.png and report-rtt.png

The browser runs headless with a fresh profile, offline (``SE_OFFLINE``: Selenium fetches no driver; chromium
reaches nothing but the page's server)."""

from __future__ import annotations

import os
import shutil
import sys
import tempfile
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

LAPTOP = (1280, 860)
PHONE = (390, 844)
_FLAGS = ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
          "--disable-component-update", "--no-first-run", "--disable-sync", "--disable-dev-shm-usage",
          "--hide-scrollbars", "--force-device-scale-factor=1")


def find_browser() -> tuple[str, str] | str:
    """(chromium, chromedriver), or why they cannot be used."""
    try:
        import selenium  # noqa: F401
    except ImportError:
        return "selenium is not installed (pip install -e '.[test]')"
    chromium = shutil.which("chromium") or shutil.which("chromium-browser")
    driver = shutil.which("chromedriver")
    if chromium is None or driver is None:
        return "Debian's chromium and chromium-driver are not installed (.ci/run installs them)"
    return chromium, driver


@contextmanager
def browser(chromium: str, driver: str, size: tuple[int, int] = LAPTOP) -> Iterator[Any]:
    """A headless chromium with a fresh profile, its window *size*; quit on exit."""
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    os.environ["SE_OFFLINE"] = "true"
    with tempfile.TemporaryDirectory(prefix="mlink-chromium-") as profile:
        options = webdriver.ChromeOptions()
        options.binary_location = chromium
        for flag in (*_FLAGS, f"--user-data-dir={profile}", f"--window-size={size[0]},{size[1]}"):
            options.add_argument(flag)
        session = webdriver.Chrome(options=options, service=Service(executable_path=driver))
        try:
            session.set_page_load_timeout(30)
            yield session
        finally:
            session.quit()


def panel(session: Any, name: str) -> Any:
    """The panel of station *name* (``21H``)."""
    from selenium.webdriver.common.by import By

    return session.find_element(By.ID, f"station-{name}")


def attr(session: Any, name: str, key: str) -> str:
    return str(panel(session, name).get_attribute(f"data-{key}") or "")


def until(session: Any, check: Any, timeout: float = 30.0, what: str = "") -> Any:
    from selenium.webdriver.support.ui import WebDriverWait

    return WebDriverWait(session, timeout, poll_frequency=0.1).until(lambda s: check(s), what)


def control(session: Any, station: str, action: str, **fields: str) -> None:
    """On *station*'s panel: fill the inputs *fields* (by name), then press the button *action*."""
    from selenium.webdriver.common.by import By

    node = panel(session, station)
    details = node.find_element(By.CSS_SELECTOR, "details.controls")
    if not details.get_attribute("open"):
        details.find_element(By.TAG_NAME, "summary").click()
    for field, value in fields.items():
        box = node.find_element(By.CSS_SELECTOR, f"input[name='{field}']")
        box.clear()
        box.send_keys(value)
    button = node.find_element(By.CSS_SELECTOR, f"button[data-act='{action}']")
    session.execute_script("arguments[0].scrollIntoView({block: 'center'})", button)
    button.click()


def result(session: Any, name: str) -> str:
    from selenium.webdriver.common.by import By

    return str(panel(session, name).find_element(By.CSS_SELECTOR, ".ctl-result").text)


def screenshots(session: Any, out: Path) -> list[Path]:
    """The page as it is, at a laptop's and a phone's width: ``web-laptop.png`` (the whole page, up to 1,600
    pixels high), ``web-phone.png`` (the first screen) in *out*."""
    out.mkdir(parents=True, exist_ok=True)
    shots = []
    for label, (width, height) in (("laptop", LAPTOP), ("phone", PHONE)):
        session.set_window_size(width, height)
        if label == "laptop":
            whole = session.execute_script("return document.documentElement.scrollHeight")
            session.set_window_size(width, min(1600, max(height, int(whole))))
        session.execute_script("window.scrollTo(0, 0)")
        time.sleep(1.0)  # the plots follow the new width (ResizeObserver) and redraw
        path = out / f"web-{label}.png"
        session.save_screenshot(str(path))
        shots.append(path)
    session.set_window_size(*LAPTOP)
    return shots


def _docs_shots(out: Path) -> int:
    """The quickstart with every drive running, one reversing (its deceleration held by the DC bus), one delayed by a
    named impairment and one tripped (lock-rotor: oC), shot; then the quickstart's HTML report (report_shots)."""
    from .webnet import Http, stations, up_with_web, wait_for

    found = find_browser()
    if isinstance(found, str):
        print(found, file=sys.stderr)
        return 2
    net, url = up_with_web(realtime=True)  # the cycle held against the browser beside it
    try:
        http = Http(url)
        wait_for(lambda: all(row["phase"] == 3 for row in stations(http)), 30, "every station in phase 3")
        with browser(*found) as session:
            session.get(url)
            for name in ("21H", "22H", "23H"):
                http.post(f"api/stations/{name}/run", {"direction": "forward", "hz": 30.0})
            time.sleep(8)
            http.post("api/stations/21H/run", {"direction": "reverse", "hz": 20.0})
            http.post("api/stations/22H/impair", {"spec": "delay=300us,jitter=100us", "name": "slow-link"})
            time.sleep(6)
            http.post("api/stations/23H/fault", {"spec": "lock-rotor"})
            time.sleep(3)
            control(session, "22H", "read", name="n019")
            until(session, lambda s: "n019 =" in result(s, "22H"), 20, "the parameter read")
            for path in screenshots(session, out):
                print(path)
            for path in report_shots(session, out):
                print(path)
    finally:
        net.stop()
    return 0


def report_shots(session: Any, out: Path) -> list[Path]:
    """The quickstart's HTML report (``mlink-sim up quickstart --clock virtual --report-html``) at a laptop's width:
    ``report-station.png`` (station 21H: its plots, marks and legend), ``report-rtt.png`` (the round trips)."""
    import subprocess

    from selenium.webdriver.common.by import By

    with tempfile.TemporaryDirectory(prefix="mlink-report-") as tmp:
        html = Path(tmp) / "report.html"
        subprocess.run([sys.executable, "-m", "mlink_sim", "up", "quickstart", "--clock", "virtual", "--no-status",
                        "--report-html", str(html)], check=True, capture_output=True, timeout=120)
        session.set_window_size(*LAPTOP)
        session.get(html.as_uri())
        shots = []
        for name, css in (("report-station", "section.station-plots"), ("report-rtt", "div.pair")):
            element = session.find_element(By.CSS_SELECTOR, css)
            tall = session.execute_script("return arguments[0].getBoundingClientRect().height", element)
            session.set_window_size(LAPTOP[0], min(3000, int(tall) + 200))  # the whole element in view
            session.execute_script("arguments[0].scrollIntoView()", element)
            time.sleep(0.3)
            path = out / f"{name}.png"
            element.screenshot(str(path))
            shots.append(path)
        session.set_window_size(*LAPTOP)
    return shots


if __name__ == "__main__":
    sys.exit(_docs_shots(Path(sys.argv[1] if len(sys.argv) > 1 else "docs/images")))
