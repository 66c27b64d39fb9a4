"""``--control-token TOKEN`` / ``--control-token-file FILE``: the token of a control endpoint (docs/faults.md, "Who can
reach a station"). An endpoint bound to anything but a loopback address requires one (a usage error otherwise);
``mlink-sim control`` sends it."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import click

from .inputs import InputError

__all__ = ["control_token_options", "control_token", "endpoint_token"]


def control_token_options(fn: Callable[..., Any]) -> Callable[..., Any]:
    """Adds ``--control-token`` and ``--control-token-file`` (parameters ``control_token``, ``control_token_file``)."""
    fn = click.option("--control-token-file", "control_token_file", metavar="FILE",
                      type=click.Path(dir_okay=False),
                      help="Read the control token from FILE (its first line; keeps it off the command line).")(fn)
    fn = click.option("--control-token", "control_token", metavar="TOKEN",
                      help="The token every control request carries; required to bind --control to an address "
                           "other than loopback.")(fn)
    return fn


def control_token(token: str | None, token_file: str | None, flag: str = "--control-token") -> str | None:
    """The token from ``--control-token`` or ``--control-token-file`` (None: neither); a usage error (exit 2, one
    line: :class:`~mlink_sim.cli.inputs.InputError`) for both, an unreadable file or an empty token. *flag*: the
    option's name in the messages (``--web-token``: the same rules)."""
    if token is not None and token_file is not None:
        raise InputError(f"give {flag} or {flag}-file, not both")
    if token_file is not None:
        try:
            lines = Path(token_file).read_text(encoding="utf-8").splitlines()
        except (OSError, UnicodeDecodeError) as exc:
            raise InputError(f"{flag}-file: cannot read {token_file}: "
                             f"{getattr(exc, 'strerror', None) or exc}") from None
        token = lines[0].strip() if lines else ""
        if not token:
            raise InputError(f"{flag}-file: {token_file} holds no token")
    if token is not None and not token.strip():
        raise InputError(f"{flag}: an empty token")
    return token


def endpoint_token(control: tuple[str, int] | None, token: str | None, token_file: str | None) -> str | None:
    """The token of a control endpoint bound at *control* (None: no endpoint): binding anything but a loopback
    address without one is a usage error."""
    from ..aio.control.token import is_loopback

    value = control_token(token, token_file)
    if control is not None and value is None and not is_loopback(control[0]):
        raise InputError(f"--control {control[0]}:{control[1]} is reachable from other hosts: give "
                         "--control-token or --control-token-file (or bind 127.0.0.1)")
    return value
