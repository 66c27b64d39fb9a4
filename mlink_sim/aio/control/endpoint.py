"""The control endpoint of a running network (``up``/``master --control``), a standalone slave (``slave
--control``) or the impairing proxy (``proxy --control``): one JSON object per UDP datagram each way, answered by the
operations of :data:`mlink_sim.operations.OPERATIONS` this endpoint serves (docs/control.md, "The requests").

    → {"op": "impair", "station": "21H", "impair": "loss=10%,for=2s"}        (or the fields: "loss": 0.1, …)
    ← {"ok": true, "impairment": {"loss": 0.1, "for": "2000000000ns"}, "describe": "loss 10%, for 2s"}
    → {"op": "set-param", "station": "21H", "param": "C1-01", "value": 5.0, "id": "w1"}
    ← {"ok": false, "error": "hz: 250 Hz is outside 0…60 Hz, the maximum output frequency of station 21H (E1-04)",
       "kind": "out_of_range"}

Every request is read by the table (:func:`~mlink_sim.operations.parse_request`): a field the operation does not
take, a missing argument or a value of the wrong kind is refused here, before the operation's handler sees it, with
the same message the other surfaces give. An error reply's ``kind`` is one of
:data:`~mlink_sim.operations.ERROR_KINDS`. An operation may answer later (an awaitable: a parameter read through the
master); the endpoint keeps answering others meanwhile, and one still unanswered after :data:`ASYNC_LIMIT_S` gets an
``unavailable`` error. A request carrying an ``"id"`` seen among the last :data:`REMEMBERED` is answered with the first
reply (waiting for it if needed) without acting again: a client repeats a request whose reply UDP lost. A reply
larger than one datagram is sent in parts (``{"ok": true, "part": 0, "parts": 3, "data": "<base64 of a piece of the
JSON>"}``), which :func:`query_control` puts together.

A request carries the endpoint's token (``"token": "…"``) when it has one: without it, or with another, it is counted
and not answered (:mod:`.token`; an endpoint bound to anything but a loopback address must have one).

Touches: one UDP socket of its own (the endpoint, or the client's); the operations act through the handlers given.
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
from ...operations import ENDPOINTS, OpError, Operation, operation, parse_request, served_by
from .token import ControlToken
from ..transport.udp import DatagramEndpoint, open_endpoint

__all__ = ["ControlServer", "Encoded", "Handler", "ASYNC_LIMIT_S", "REMEMBERED", "encode_reply", "perform",
           "query_control"]

log = get_logger("mlink_sim.control")

#: An operation's handler: its arguments by their Python names (as :func:`~mlink_sim.operations.parse_request` reads
#: them) -> the reply's fields (``ok`` is added), or an awaitable of them; :class:`~mlink_sim.operations.OpError` ->
#: an error reply of its kind.
Handler = Callable[..., "Reply | Awaitable[Reply]"]
ASYNC_LIMIT_S = 10.0  #: an operation that answers later gets this long
REMEMBERED = 64  #: request ids remembered (their replies), for requests UDP made a client repeat
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


def _error(exc: BaseException) -> dict[str, Any]:
    if isinstance(exc, OpError):
        return exc.as_reply()
    return {"ok": False, "error": str(exc) or type(exc).__name__, "kind": "bad_request"}


async def perform(handlers: dict[str, Handler], request: dict[str, Any]) -> dict[str, Any]:
    """*request* (a control request: ``op`` and its fields) performed in this process by *handlers*, read as the
    endpoint reads it: its reply's fields (``ok`` left out), or :class:`~mlink_sim.operations.OpError`. The Python
    API and the pytest plugin's host act through it, so they behave as a control request does."""
    op = operation(request.get("op", ""))
    if op.name not in handlers:
        raise OpError("unavailable", f"{op.name!r} is not answered here")
    reply = handlers[op.name](**parse_request(op, request))
    if inspect.isawaitable(reply):
        reply = await asyncio.wait_for(reply, ASYNC_LIMIT_S)
    if isinstance(reply, Encoded):
        reply = reply.decode()
    return {k: v for k, v in reply.items() if k != "ok"}


class ControlServer:
    """Answers the control requests of *endpoint* (one of :data:`~mlink_sim.operations.ENDPOINTS`) with *handlers*
    (operation name -> :data:`Handler`; ``ping`` is answered here); with *token*, only the requests that carry it
    (:class:`~.token.ControlToken`). Every operation the table gives *endpoint* must have a handler, but those
    *absent* names (operations this endpoint's run cannot serve, e.g. ``kill-slave`` without slave processes:
    answered ``unavailable``)."""

    def __init__(self, handlers: dict[str, Handler], endpoint: str, token: str | None = None,
                 absent: dict[str, str] | None = None) -> None:
        self.endpoint = endpoint
        self.served = {op.name: op for op in served_by(endpoint)}
        self.absent = dict(absent or {})
        missing = sorted(set(self.served) - set(handlers) - set(self.absent) - {"ping"})
        extra = sorted(set(handlers) - set(self.served))
        if missing or extra:
            raise ValueError(f"the {endpoint} endpoint's handlers do not match the operations table: "
                             f"missing {missing or 'none'}, not in the table for it {extra or 'none'}")
        self.handlers = dict(handlers)
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
            return {"ok": False, "kind": "bad_request", "error": f"expected a JSON object with 'op' (one of: "
                                                                 f"{', '.join(self.served)})"}
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

    def _operation(self, name: str) -> Operation:
        op = self.served.get(name)
        if op is not None:
            return op
        try:
            known = operation(name)
        except OpError:
            raise OpError("bad_request", f"unknown op {name!r} (this {self.endpoint} answers: "
                                         f"{', '.join(self.served)})") from None
        where = " or ".join(f"a {e}" for e in ENDPOINTS if e in known.endpoints)
        raise OpError("bad_request", f"{name!r} is answered by {where}, not by this {self.endpoint} (it answers: "
                                     f"{', '.join(self.served)})")

    def _act(self, request: dict[str, Any]) -> Reply | asyncio.Future[Reply]:
        try:
            op = self._operation(request["op"])
            if op.name == "ping":
                return {"ok": True}
            if op.name in self.absent:
                raise OpError("unavailable", self.absent[op.name])
            args = parse_request(op, request)
            reply = self.handlers[op.name](**args)
        except (ValueError, TypeError, KeyError) as exc:
            return _error(exc)
        if op.acts:
            log.info("control", op=op.name, request={k: v for k, v in request.items() if k not in ("op", "token")})
        if isinstance(reply, Encoded):
            return reply
        if not inspect.isawaitable(reply):
            return {"ok": True, **reply}
        return self._later(op.name, reply)

    def _later(self, op: str, pending: Awaitable[Reply]) -> asyncio.Future[Reply]:
        """The future reply of an operation that answers later (bounded by :data:`ASYNC_LIMIT_S`)."""
        loop = asyncio.get_running_loop()
        fut: asyncio.Future[Reply] = loop.create_future()
        work = asyncio.ensure_future(pending)  # under way at once: a close cancels it, never leaves it unawaited
        self._tasks.add(work)
        work.add_done_callback(self._tasks.discard)

        async def finish() -> None:
            try:
                result = await asyncio.wait_for(work, ASYNC_LIMIT_S)
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
                        decode: Callable[[bytes], Awaitable[Any]] | None = None,
                        **fields: Any) -> dict[str, Any] | None:
    """Ask a control endpoint (a slave process's stats endpoint, a run's or a proxy's ``--control``) the operation
    *op* (*fields* go into the request, and *token* where the endpoint has one): its JSON reply (put together from
    its parts where it came in several), or None when it does not answer in time (an endpoint answers no request
    without its token). *decode*: what reads the reply's JSON, when it is not ``json.loads`` at once (the master
    reads a slave's stats in a cycle's slack: :meth:`~mlink_sim.aio.run.session.NetworkSession.refresh_slave_stats`)."""
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
        reply = json.loads(data) if decode is None else await decode(data)
        return reply if isinstance(reply, dict) else None
    except (TimeoutError, ValueError):
        return None
    finally:
        ep.close()
