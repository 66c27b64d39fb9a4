"""Checks of command-line input made before anything starts: each problem is one line naming the file, option or
field and what was expected, and exit status 2, so that a user fixes the input before a run rather than reading a
traceback from the middle of one."""

from __future__ import annotations

import os
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import click

from ..config import Config, ConfigError, load_config, resolve_config_path

__all__ = ["InputError", "load_checked", "report_path", "assertions", "check_stations"]


class InputError(click.ClickException):
    """A usage or configuration problem: ``mlink-sim: <one line>`` on stderr, exit 2."""

    exit_code = 2

    def show(self, file: Any = None) -> None:
        click.echo(f"mlink-sim: {self.format_message()}", err=True)


def load_checked(text: str) -> tuple[Config, Path]:
    """The config at *text* (a path, or the name of a shipped example) and the file it was read from."""
    try:
        return load_config(text), resolve_config_path(text)
    except ConfigError as exc:
        raise InputError(str(exc)) from None


def report_path(text: str | None, flag: str = "--report", example: str = "report.json") -> Path | None:
    """``--report`` (or another output file *flag*: ``--trace``, ``--report-html``, ``--html``): a file in a
    folder that exists and can be written, so the run does not end in an error after its whole length."""
    if text is None:
        return None
    p = Path(text)
    folder = p.parent
    if not folder.is_dir():
        raise InputError(f"{flag} {text}: folder {str(folder)!r} does not exist; create it or write elsewhere")
    if p.is_dir():
        raise InputError(f"{flag} {text}: is a folder, expected a file name such as {p / example}")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise InputError(f"{flag} {text}: folder {str(folder)!r} is not writable")
    return p


def assertions(texts: Iterable[str], stations: Iterable[int]) -> list[Any]:
    """``--assert``: parsed, each ``station[N]`` a station of the config (docs/report.md)."""
    from ..metrics import AssertionSyntaxError, parse_assertion

    known = list(stations)
    out = []
    for text in texts:
        try:
            out.append(parse_assertion(text, stations=known))
        except AssertionSyntaxError as exc:
            raise InputError(f"--assert {text!r}: {exc}") from None
    return out


def check_stations(option: str, addresses: Iterable[int], config: Config, source: str) -> None:
    """Every address given with *option* is a station of *config* (read from *source*)."""
    known = {st.address for st in config.station}
    for address in addresses:
        if address not in known:
            names = ", ".join(f"{a:02X}H" for a in sorted(known))
            raise InputError(f"{option} {address:02X}H: not a station of {source} (stations: {names})")
