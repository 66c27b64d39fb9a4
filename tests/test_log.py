"""mlink_sim._log: quiet as a library; once configured, key=value lines on the standard error the process has at
each write."""

from __future__ import annotations

import io
import logging
import sys

import pytest
import structlog

from mlink_sim._log import configure_logging, get_logger


@pytest.fixture
def unconfigured():
    structlog.reset_defaults()
    yield
    structlog.reset_defaults()


def test_a_library_logger_prints_nothing_until_logging_is_configured(unconfigured, capsys) -> None:
    get_logger("mlink_sim.test").warning("quiet", n=1)
    assert capsys.readouterr() == ("", "")


def test_lines_follow_the_current_stderr_after_the_stream_it_was_configured_with_is_closed(
        unconfigured, monkeypatch) -> None:
    first = io.StringIO()
    monkeypatch.setattr(sys, "stderr", first)
    configure_logging(level="info")
    first.close()  # as a test runner's capture, or an application that swaps its streams
    second = io.StringIO()
    monkeypatch.setattr(sys, "stderr", second)
    get_logger("mlink_sim.test", station="21H").warning("still_written", n=2)
    line = second.getvalue()
    assert "still_written" in line and "station=21H" in line and "n=2" in line


def test_the_level_filters(unconfigured, monkeypatch) -> None:
    out = io.StringIO()
    monkeypatch.setattr(sys, "stderr", out)
    configure_logging(level="warning")
    log = get_logger("mlink_sim.test")
    log.info("below")
    log.warning("above")
    assert "above" in out.getvalue() and "below" not in out.getvalue()
    assert logging.getLogger("mlink_sim").handlers  # the package's NullHandler stays for stdlib users
