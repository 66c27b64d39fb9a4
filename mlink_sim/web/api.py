"""The HTTP side of the control operations: the client of the run's control endpoint and the mapping of an
operation's error ``kind`` to an HTTP status (:data:`~.openapi.STATUS_OF_KIND`).

Every answer of the API that is not a success is ``{"error": "one line", "kind": K}`` with a 4xx status; a control
endpoint that does not answer is 503 (``kind`` ``no_answer``), the only status of the 5xx class the server gives.

Touches: one UDP socket per request to the control endpoint (:func:`~mlink_sim.aio.control.endpoint.query_control`).
"""

from __future__ import annotations

from typing import Any

from ..aio.control.endpoint import query_control
from .openapi import STATUS_OF_KIND

__all__ = ["ApiError", "Control"]


class ApiError(Exception):
    """A request the API answers with *status* and ``{"error": message, "kind": kind}``."""

    def __init__(self, status: int, kind: str, message: str) -> None:
        super().__init__(message)
        self.status = status
        self.kind = kind
        self.message = message.splitlines()[0] if message else kind

    def body(self) -> dict[str, str]:
        return {"error": self.message, "kind": self.kind}


class Control:
    """The run's control endpoint at *host*:*port* (with its *token*, if it has one)."""

    def __init__(self, host: str, port: int, token: str | None = None) -> None:
        self.host = "127.0.0.1" if host in ("0.0.0.0", "") else "::1" if host == "::" else host
        self.port = port
        self.token = token

    @property
    def where(self) -> str:
        return f"[{self.host}]:{self.port}" if ":" in self.host else f"{self.host}:{self.port}"

    async def query(self, op: str, timeout: float = 1.0, **fields: Any) -> dict[str, Any] | None:
        """The reply to *op* as it came (``ok`` true or false), None when the endpoint did not answer in time."""
        return await query_control(self.host, self.port, op, timeout=timeout, token=self.token, **fields)

    async def ask(self, op: str, timeout: float = 2.0, **fields: Any) -> dict[str, Any]:
        """The reply's fields (without ``ok``); :class:`ApiError` for an error reply (its ``kind`` → the status of
        :data:`STATUS_OF_KIND`; an operation error without one is a 400) or no answer in time (503)."""
        reply = await self.query(op, timeout=timeout, **fields)
        if reply is None:
            raise ApiError(503, "no_answer", f"the network's control endpoint {self.where} did not answer '{op}' "
                                             f"within {timeout:g}s (is the run still going?)")
        if not reply.get("ok"):
            kind = reply.get("kind")
            if kind not in STATUS_OF_KIND:
                kind = "bad_request"
            raise ApiError(STATUS_OF_KIND[kind], kind, str(reply.get("error") or f"'{op}' was refused"))
        return {k: v for k, v in reply.items() if k != "ok"}
