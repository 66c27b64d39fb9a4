"""The control endpoint of a running ``mlink-sim up`` or ``mlink-sim proxy`` (``--control HOST:PORT``): one JSON
object per UDP datagram each way, the same shape as a slave's stats endpoint (aio/slave/server.py). docs/faults.md,
"While it runs".

    → {"op": "impair", "station": "0x21", "impair": "loss=10%,for=2s"}        (or the fields: "loss": 0.1, …)
    ← {"ok": true, "impairment": {"loss": 0.1, "for": "2000000000ns"}}
    → {"op": "heal", "station": "all"}
    ← {"ok": true, "ended": 2}
    → {"op": "faults"}
    ← {"ok": true, "faults": [...], "injected": {"0x21": {"drops": 12}}}
    ← {"ok": false, "error": "loss: a probability is between 0 and 1 …"}

A request carries the endpoint's token (``"token": "…"``) when it has one: without it, or with another, it is counted
and not answered (:mod:`mlink_sim.aio.slave.token`; an endpoint bound to anything but a loopback address must have
one).

The operations are a table (:func:`impairment_ops`); another kind of fault adds its own entries. A client:
:func:`query_control` (``mlink-sim control``; the network run asks the slave workers' stats endpoints with it too).

Touches: one UDP socket of its own (the endpoint, or the client's); the operations act on the run through the table
they are given.
"""

from __future__ import annotations

import asyncio
import json
from collections.abc import Callable
from typing import Any

from ..._log import get_logger
from ..slave.token import ControlToken
from ..transport.udp import DatagramEndpoint, open_endpoint

__all__ = ["ControlServer", "Op", "impairment_ops", "query_control"]

log = get_logger("mlink_sim.control")

#: An operation: the request (a dict) -> the reply's fields (``ok`` is added); ValueError -> an error reply.
Op = Callable[[dict[str, Any]], dict[str, Any]]
_MAX_REPLY = 60_000


def impairment_ops(target: Any) -> dict[str, Op]:
    """``impair``, ``heal`` and ``faults`` on *target*: anything with ``impair(station, spec)``, ``heal(station)``
    and an ``impairments`` layer (a :class:`~mlink_sim.aio.run.session.NetworkSession`, the proxy)."""
    from ...impair import as_impairment, target_station
    from ...metrics.network import station_key

    def impair(request: dict[str, Any]) -> dict[str, Any]:
        fields = {k: v for k, v in request.items() if k not in ("op", "station", "impair")}
        spec = as_impairment(request.get("impair"), fields)
        target.impair(target_station(request.get("station", "all")), spec)
        return {"impairment": spec.as_fields(), "describe": spec.describe()}

    def heal(request: dict[str, Any]) -> dict[str, Any]:
        return {"ended": target.heal(target_station(request.get("station", "all")))}

    def faults(request: dict[str, Any]) -> dict[str, Any]:
        layer = target.impairments
        return {"faults": [{**f, "station": f["station"] if f["station"] == "all" else station_key(f["station"])}
                           for f in layer.faults()],
                "injected": {station_key(a): c for a, c in layer.injected().items()}}

    return {"impair": impair, "heal": heal, "faults": faults}


class ControlServer:
    """Answers control requests with the operations of *ops* (plus ``ping``); with *token*, only those that carry it
    (:class:`~mlink_sim.aio.slave.token.ControlToken`)."""

    def __init__(self, ops: dict[str, Op], token: str | None = None) -> None:
        self.ops = dict(ops)
        self.token = ControlToken(token)
        self._endpoint: DatagramEndpoint | None = None

    async def start(self, host: str, port: int) -> tuple[str, int]:
        """Listen on *host*:*port* (0: any free port); returns where."""
        self._endpoint = await open_endpoint(self._on_datagram, host, port)
        return self._endpoint.local_address

    @property
    def address(self) -> tuple[str, int] | None:
        return None if self._endpoint is None else self._endpoint.local_address

    def close(self) -> None:
        if self._endpoint is not None:
            self._endpoint.close()
            self._endpoint = None

    def handle(self, data: bytes) -> dict[str, Any] | None:
        """The reply to one request (never raises); None for a request without the token (not answered)."""
        try:
            request = json.loads(data)
        except (ValueError, UnicodeDecodeError):
            request = None
        if not self.token.admits(request):
            if self.token.refused == 1 or self.token.refused & (self.token.refused - 1) == 0:
                log.warning("control_refused", reason="no token or a wrong one", refused=self.token.refused)
            return None
        if not isinstance(request, dict) or not isinstance(request.get("op"), str):
            return {"ok": False, "error": "expected a JSON object with 'op' (one of: "
                                          f"{', '.join(sorted([*self.ops, 'ping']))})"}
        op = request["op"]
        if op == "ping":
            return {"ok": True}
        fn = self.ops.get(op)
        if fn is None:
            return {"ok": False, "error": f"unknown op {op!r} (known: {', '.join(sorted([*self.ops, 'ping']))})"}
        try:
            reply = fn(request)
        except (ValueError, TypeError, KeyError) as exc:
            return {"ok": False, "error": str(exc)}
        log.info("control", op=op, request={k: v for k, v in request.items() if k not in ("op", "token")})
        return {"ok": True, **reply}

    def _on_datagram(self, data: bytes, addr: Any) -> None:
        reply = self.handle(data)
        if reply is None:
            return
        payload = json.dumps(reply, separators=(",", ":")).encode()
        if len(payload) > _MAX_REPLY:
            payload = json.dumps({"ok": False, "error": "reply too large for one datagram"}).encode()
        if self._endpoint is not None:
            self._endpoint.sendto(payload, addr)


async def query_control(host: str, port: int, op: str = "stats", timeout: float = 1.0, token: str | None = None,
                        **fields: Any) -> dict[str, Any] | None:
    """Ask a control endpoint (a slave process's stats endpoint, a run's or a proxy's ``--control``) the operation
    *op* (*fields* go into the request, and *token* where the endpoint has one): its JSON reply, or None when it
    does not answer in time (an endpoint answers no request without its token)."""
    if token is not None:
        fields["token"] = token
    loop = asyncio.get_running_loop()
    fut: asyncio.Future[bytes] = loop.create_future()

    def on_datagram(data: bytes, addr: Any) -> None:
        if not fut.done():
            fut.set_result(data)

    ep = await open_endpoint(on_datagram, "::" if ":" in host else "0.0.0.0", 0)
    try:
        ep.sendto(json.dumps({"op": op, **fields}).encode(), (host, port))
        data = await asyncio.wait_for(fut, timeout)
        return json.loads(data)
    except (TimeoutError, ValueError):
        return None
    finally:
        ep.close()
