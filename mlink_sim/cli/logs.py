"""structlog set-up for the command line: key=value lines (or JSON with --log-json) on stderr
(:func:`mlink_sim._log.configure_logging`, shared with the pytest plugin's host process)."""

from __future__ import annotations

from .._log import configure_logging

__all__ = ["configure_logging"]
