"""The control endpoints' token: a slave's stats/fault endpoint and a run's or a proxy's ``--control`` answer only
requests that carry it (docs/faults.md, "Who can reach a station").

An endpoint on a loopback address needs none (only this host reaches it); one bound anywhere else is refused without
a token (``--control-token`` / ``--control-token-file``, a usage error). The token travels in each request's JSON
object (``"token"``), is compared in constant time (:func:`hmac.compare_digest`), and a request without it, or with
another, is counted (:attr:`ControlToken.refused`) and not answered: a scanner learns nothing, not even that
something listens.

Touches: nothing (the endpoints call it).
"""

from __future__ import annotations

import hmac
import ipaddress
from typing import Any

__all__ = ["ControlToken", "is_loopback"]


def is_loopback(host: str) -> bool:
    """*host* is a loopback address (127.0.0.0/8, ::1) or ``localhost``; a wildcard, another address or another
    name is not."""
    if host.lower() == "localhost":
        return True
    try:
        return ipaddress.ip_address(host.strip("[]").partition("%")[0]).is_loopback
    except ValueError:
        return False


class ControlToken:
    """Admits the requests that carry *token* (None: every request)."""

    def __init__(self, token: str | None = None) -> None:
        self._token = None if token is None else token.encode()
        self.refused = 0  #: requests without the token, or with another (not answered)

    @property
    def required(self) -> bool:
        return self._token is not None

    def admits(self, request: Any) -> bool:
        """Whether *request* (the decoded JSON, any type) carries the token; counts it in :attr:`refused` if not."""
        if self._token is None:
            return True
        given = request.get("token") if isinstance(request, dict) else None
        if isinstance(given, str) and hmac.compare_digest(given.encode(), self._token):
            return True
        self.refused += 1
        return False
