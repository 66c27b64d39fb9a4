"""The control endpoint of a running ``mlink-sim up`` or ``mlink-sim proxy`` (``--control HOST:PORT``): one JSON
object per UDP datagram each way, the same shape as a slave's stats endpoint (aio/slave/server.py). docs/faults.md,
"While it runs".

    → {"op": "impair", "station": "0x21", "impair": "loss=10%,for=2s"}        (or the fields: "loss": 0.1, …)
    ← {"ok": true, "impairment": {"loss": 0.1, "for": "2000000000ns"}}
    → {"op": "heal", "station": "all"}
    ← {"ok": true, "ended": 2}
    → {"op": "faults"}
    ← {"ok": true, "faults": [...], "injected": {"0x21": {"drops": 12}}}
    ← {"ok": false, "error": "loss: a probability is between 0 and 1 …", "kind": "bad_request"}

An error reply's ``kind`` says what went wrong (:data:`ERROR_KINDS`: ``bad_request``, ``unknown_station``,
``unknown_param``, ``out_of_range``, ``refused``, ``unavailable``). An operation may answer later (a coroutine: a
parameter read through the master); the endpoint keeps answering others meanwhile, and one still unanswered after
:data:`ASYNC_LIMIT_S` gets an ``unavailable`` error. A request carrying an ``"id"`` seen among the last
:data:`REMEMBERED` is answered with the first reply (waiting for it if needed) without acting again: a client repeats
a request whose reply UDP lost. A reply larger than one datagram is sent in parts (``{"ok": true, "part": 0,
"parts": 3, "data": "<base64 of a piece of the JSON>"}``), which :func:`query_control` puts together.

A request carries the endpoint's token (``"token": "…"``) when it has one: without it, or with another, it is counted
and not answered (:mod:`mlink_sim.aio.slave.token`; an endpoint bound to anything but a loopback address must have
one).

The operations are a table (:func:`impairment_ops`); another kind of fault adds its own entries
(:mod:`mlink_sim.aio.run.faults`, :mod:`mlink_sim.aio.run.ops`). A client:
:func:`query_control` (``mlink-sim control``; the network run asks the slave workers' stats endpoints with it too).

Touches: one UDP socket of its own (the endpoint, or the client's); the operations act on the run through the table
they are given.
"""

from __future__ import annotations

import asyncio
import base64
import inspect
import json
from collections import OrderedDict
from collections.abc import Awaitable, Callable
from typing import Any

from ..._log import get_logger
from ..slave.token import ControlToken
from ..transport.udp import DatagramEndpoint, open_endpoint

__all__ = ["ControlServer", "Encoded", "Op", "OpError", "ERROR_KINDS", "ASYNC_LIMIT_S", "REMEMBERED", "QUIET", "impairment_ops",
           "query_control"]

log = get_logger("mlink_sim.control")

#: An operation: the request (a dict) -> the reply's fields (``ok`` is added), or an awaitable of them;
#: :class:`OpError` (or ValueError, TypeError, KeyError: ``bad_request``) -> an error reply.
Op = Callable[[dict[str, Any]], "Reply | Awaitable[Reply]"]
#: The kinds of an error reply, in the order of the HTTP statuses a web server maps them to (400, 404, 404, 422,
#: 409, 409).
ERROR_KINDS = ("bad_request", "unknown_station", "unknown_param", "out_of_range", "refused", "unavailable")
ASYNC_LIMIT_S = 10.0  #: an operation that answers later gets this long
REMEMBERED = 64  #: request ids remembered (their replies), for requests UDP made a client repeat
QUIET = ("status", "network", "report", "faults", "recovery")  #: operations that only read: not logged
_MAX_REPLY = 60_000
_PART = 44_000  #: bytes of the JSON reply per part: 58,668 in base64, a part stays one datagram


class Encoded:
    """A reply its operation encoded itself: the JSON text of the whole reply, ``"ok"`` included. An operation
    whose reply is large encodes it a part at a time with the loop free in between (a 62-station ``status``:
    :mod:`.ops`), where one ``json.dumps`` of the whole would hold the cycle for a quarter of a millisecond."""

    __slots__ = ("text",)

    def __init__(self, text: str) -> None:
        self.text = text

    def decode(self) -> dict[str, Any]:
        reply: dict[str, Any] = json.loads(self.text)
        return reply


#: A reply as the endpoint sends it: its fields, or the text an operation encoded itself
Reply = dict[str, Any] | Encoded


class OpError(ValueError):
    """An operation's refusal: one line and its :data:`ERROR_KINDS` entry."""

    def __init__(self, kind: str, message: str) -> None:
        assert kind in ERROR_KINDS, kind
        super().__init__(message)
        self.kind = kind


def _error(exc: BaseException) -> dict[str, Any]:
    return {"ok": False, "error": str(exc) or type(exc).__name__,
            "kind": exc.kind if isinstance(exc, OpError) else "bad_request"}


def impairment_ops(target: Any) -> dict[str, Op]:
    """``impair``, ``heal`` and ``faults`` on *target*: anything with ``impair(station, spec)``, ``heal(station)``
    and an ``impairments`` layer (a :class:`~mlink_sim.aio.run.session.NetworkSession`, the proxy)."""
    from ...impair import as_impairment, target_station
    from ...metrics.network import station_key

    def impair(request: dict[str, Any]) -> dict[str, Any]:
        fields = {k: v for k, v in request.items() if k not in ("op", "station", "impair", "id")}
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

    def __init__(self, ops: dict[str, Op], token: str | None = None, quiet: tuple[str, ...] = QUIET) -> None:
        self.ops = dict(ops)
        self.quiet = frozenset(quiet)  #: operations not logged (read-only ones a page asks many times a second)
        self.token = ControlToken(token)
        self._endpoint: DatagramEndpoint | None = None
        #: request id -> its reply, or the future of a reply still to come (the last REMEMBERED ids)
        self._replies: OrderedDict[Any, Reply | asyncio.Future[Reply]] = OrderedDict()
        self._tasks: set[asyncio.Task[Any]] = set()

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
        for task in list(self._tasks):
            task.cancel()

    def handle(self, data: bytes) -> Reply | asyncio.Future[Reply] | None:
        """The reply to one request (never raises): a dict, a future of one (an operation that answers later,
        within :data:`ASYNC_LIMIT_S`), or None for a request without the token (not answered). A request with an
        ``"id"`` already seen gets that request's reply, and does not act again."""
        try:
            request = json.loads(data)
        except (ValueError, UnicodeDecodeError):
            request = None
        if not self.token.admits(request):
            if self.token.refused == 1 or self.token.refused & (self.token.refused - 1) == 0:
                log.warning("control_refused", reason="no token or a wrong one", refused=self.token.refused)
            return None
        if isinstance(request, dict):
            request.pop("token", None)  # admitted: the operations see their own fields only
        if not isinstance(request, dict) or not isinstance(request.get("op"), str):
            return {"ok": False, "kind": "bad_request", "error": "expected a JSON object with 'op' (one of: "
                                                                 f"{', '.join(sorted([*self.ops, 'ping']))})"}
        rid = request.get("id")
        if isinstance(rid, (str, int)) and not isinstance(rid, bool):
            known = self._replies.get(rid)
            if known is not None:
                return known
            reply = self._act(request)
            self._replies[rid] = reply
            while len(self._replies) > REMEMBERED:
                self._replies.popitem(last=False)
            return reply
        return self._act(request)

    def _act(self, request: dict[str, Any]) -> Reply | asyncio.Future[Reply]:
        op = request["op"]
        if op == "ping":
            return {"ok": True}
        fn = self.ops.get(op)
        if fn is None:
            return {"ok": False, "kind": "bad_request",
                    "error": f"unknown op {op!r} (known: {', '.join(sorted([*self.ops, 'ping']))})"}
        try:
            reply = fn(request)
        except (ValueError, TypeError, KeyError) as exc:
            return _error(exc)
        if op not in self.quiet:
            log.info("control", op=op, request={k: v for k, v in request.items() if k not in ("op", "token")})
        if isinstance(reply, Encoded):
            return reply
        if not inspect.isawaitable(reply):
            return {"ok": True, **reply}
        return self._later(op, reply)

    def _later(self, op: str, pending: Awaitable[Reply]) -> asyncio.Future[Reply]:
        """The future reply of an operation that answers later (bounded by :data:`ASYNC_LIMIT_S`)."""
        loop = asyncio.get_running_loop()
        fut: asyncio.Future[Reply] = loop.create_future()

        async def finish() -> None:
            try:
                result = await asyncio.wait_for(pending, ASYNC_LIMIT_S)
                reply: Reply = result if isinstance(result, Encoded) else {"ok": True, **result}
            except TimeoutError:
                reply = {"ok": False, "kind": "unavailable",
                         "error": f"{op}: no answer within {ASYNC_LIMIT_S:g} s"}
            except (ValueError, TypeError, KeyError) as exc:
                reply = _error(exc)
            except Exception as exc:  # noqa: BLE001 - the endpoint answers, whatever the operation met
                log.warning("control_failed", op=op, error=repr(exc))
                reply = {"ok": False, "kind": "unavailable", "error": f"{op}: {exc}"}
            if not fut.done():
                fut.set_result(reply)

        task = loop.create_task(finish())
        self._tasks.add(task)
        task.add_done_callback(self._tasks.discard)
        return fut

    def _on_datagram(self, data: bytes, addr: Any) -> None:
        reply = self.handle(data)
        if reply is None:
            return
        if isinstance(reply, (dict, Encoded)):
            self._send(reply, addr)
            return

        def done(fut: asyncio.Future[Reply]) -> None:
            if not fut.cancelled():
                self._send(fut.result(), addr)

        reply.add_done_callback(done)

    def _send(self, reply: Reply, addr: Any) -> None:
        if self._endpoint is None:
            return
        for payload in encode_reply(reply):
            self._endpoint.sendto(payload, addr)


def encode_reply(reply: Reply) -> list[bytes]:
    """*reply* as the datagrams that carry it: one, or the parts of a larger one (the JSON in pieces of
    :data:`_PART` bytes, base64, ``part``/``parts`` numbered)."""
    payload = (reply.text if isinstance(reply, Encoded) else json.dumps(reply, separators=(",", ":"))).encode()
    if len(payload) <= _MAX_REPLY:
        return [payload]
    pieces = [payload[i:i + _PART] for i in range(0, len(payload), _PART)]
    return [json.dumps({"ok": True, "part": i, "parts": len(pieces), "data": base64.b64encode(piece).decode()},
                       separators=(",", ":")).encode() for i, piece in enumerate(pieces)]


async def query_control(host: str, port: int, op: str = "stats", timeout: float = 1.0, token: str | None = None,
                        **fields: Any) -> dict[str, Any] | None:
    """Ask a control endpoint (a slave process's stats endpoint, a run's or a proxy's ``--control``) the operation
    *op* (*fields* go into the request, and *token* where the endpoint has one): its JSON reply (put together from
    its parts where it came in several), or None when it does not answer in time (an endpoint answers no request
    without its token)."""
    if token is not None:
        fields["token"] = token
    loop = asyncio.get_running_loop()
    fut: asyncio.Future[bytes] = loop.create_future()
    parts: dict[int, bytes] = {}

    def on_datagram(data: bytes, addr: Any) -> None:
        if fut.done():
            return
        try:
            head = json.loads(data) if data[:1] == b"{" and b'"parts"' in data[:80] else None
        except ValueError:
            head = None
        if not isinstance(head, dict) or not isinstance(head.get("parts"), int):
            fut.set_result(data)
            return
        try:
            parts[int(head["part"])] = base64.b64decode(head["data"])
        except (KeyError, TypeError, ValueError):
            return
        if len(parts) == head["parts"]:
            fut.set_result(b"".join(parts[i] for i in sorted(parts)))

    ep = await open_endpoint(on_datagram, "::" if ":" in host else "0.0.0.0", 0)
    try:
        ep.sendto(json.dumps({"op": op, **fields}).encode(), (host, port))
        data = await asyncio.wait_for(fut, timeout)
        reply = json.loads(data)
        return reply if isinstance(reply, dict) else None
    except (TimeoutError, ValueError):
        return None
    finally:
        ep.close()
