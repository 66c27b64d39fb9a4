"""One poller of the network's ``status`` operation, shared by every HTTP client (docs/web.md, "What the page
costs the network").

The poller asks the control endpoint for ``status`` at most every *interval* (0.1 s: 10 Hz), and only while someone
wants it: an open event stream (``GET /api/events``), or a ``GET /api/status`` in the last *linger* seconds. Each
answer is handed to every event stream (status, then the network's new events: phase changes, alarms, timeline steps,
check results), and a ``GET /api/status`` gets the latest answer if it is younger than *interval*, else waits for the
next one. However many pages are open, the network answers one query per interval.

The events come with a sequence number; the poller asks for those after the last it has (``since``), and keeps the
last :data:`KEEP_EVENTS` so that a page opened late shows what happened before it.

Touches: the control endpoint (through the ``query`` function it is given); nothing else.
"""

from __future__ import annotations

import asyncio
from collections import deque
from collections.abc import Awaitable, Callable
from typing import Any

from .._log import get_logger

__all__ = ["Feed", "KEEP_EVENTS", "Message"]

log = get_logger("mlink_sim.web")

#: the network's events a new event stream is given first (the newest this many)
KEEP_EVENTS = 200
#: messages an event stream may have waiting before it misses some (a client that does not read)
_BACKLOG = 256

#: what an event stream receives: (SSE event name, JSON-able data); ``status``, ``event``, ``error``, or
#: ``end`` (None) when the server stops
Message = tuple[str, Any]
Query = Callable[..., Awaitable[dict[str, Any] | None]]


class Feed:
    """The status poller and its fan-out to event streams and status requests."""

    def __init__(self, query: Query, *, interval: float = 0.1, linger: float = 2.0, timeout: float = 1.0) -> None:
        self._query = query
        self.interval = interval
        self.linger = linger
        self.timeout = timeout
        self.latest: dict[str, Any] | None = None  #: the last status (without its events)
        self.latest_at = float("-inf")  #: when it came (the loop's clock)
        self.events: deque[dict[str, Any]] = deque(maxlen=KEEP_EVENTS)
        self.polls = 0  #: status queries sent (the tests read it: one poller, whatever the clients)
        self.error: dict[str, str] | None = None  #: why the last poll got no status (None: it got one)
        self._seq: int | None = None
        self._streams: set[asyncio.Queue[Message]] = set()
        self._waiters: list[asyncio.Future[dict[str, Any] | None]] = []
        self._wanted_until = float("-inf")
        self._task: asyncio.Task[None] | None = None

    @property
    def streams(self) -> int:
        return len(self._streams)

    async def status(self) -> dict[str, Any] | None:
        """The network's status, at most *interval* old (None: the endpoint did not answer; :attr:`error` says
        why)."""
        loop = asyncio.get_running_loop()
        if self.latest is not None and loop.time() - self.latest_at < self.interval:
            return self.latest
        waiter: asyncio.Future[dict[str, Any] | None] = loop.create_future()
        self._waiters.append(waiter)
        self._wanted_until = loop.time() + self.linger
        self._ensure_polling()
        return await waiter

    def subscribe(self) -> asyncio.Queue[Message]:
        """A new event stream's queue: the kept events and the latest status first, then every poll's."""
        queue: asyncio.Queue[Message] = asyncio.Queue(_BACKLOG)
        for event in self.events:
            queue.put_nowait(("event", event))
        if self.latest is not None:
            queue.put_nowait(("status", self.latest))
        self._streams.add(queue)
        self._ensure_polling()
        return queue

    def unsubscribe(self, queue: asyncio.Queue[Message]) -> None:
        self._streams.discard(queue)

    def close(self) -> None:
        """End every event stream (the server stops) and the poller."""
        for queue in self._streams:
            if queue.full():
                queue.get_nowait()
            _offer(queue, ("end", None))
        self._streams.clear()
        if self._task is not None:
            self._task.cancel()
        for waiter in self._waiters:
            if not waiter.done():
                waiter.set_result(None)
        self._waiters.clear()

    def _wanted(self) -> bool:
        return bool(self._streams or self._waiters) or asyncio.get_running_loop().time() < self._wanted_until

    def _ensure_polling(self) -> None:
        if self._task is None or self._task.done():
            self._task = asyncio.get_running_loop().create_task(self._poll())

    async def _poll(self) -> None:
        loop = asyncio.get_running_loop()
        while self._wanted():
            began = loop.time()
            fields = {} if self._seq is None else {"since": self._seq}
            self.polls += 1
            reply = await self._query("status", timeout=self.timeout, **fields)
            self._take(reply, loop.time())
            await asyncio.sleep(max(0.0, self.interval - (loop.time() - began)))

    def _take(self, reply: dict[str, Any] | None, now: float) -> None:
        if reply is None or not reply.get("ok"):
            error = ({"error": "the network's control endpoint did not answer", "kind": "no_answer"} if reply is None
                     else {"error": str(reply.get("error")), "kind": str(reply.get("kind") or "bad_request")})
            if error != self.error:
                log.warning("status_unanswered", **error)
                self._publish(("error", error))
            self.error = error
            self._resolve(None)
            return
        self.error = None
        events = reply.get("events") or []
        status = {k: v for k, v in reply.items() if k not in ("ok", "events")}
        if isinstance(reply.get("seq"), int):
            self._seq = reply["seq"]
        for event in events:
            self.events.append(event)
            self._publish(("event", event))
        self.latest, self.latest_at = status, now
        self._publish(("status", status))
        self._resolve(status)

    def _resolve(self, status: dict[str, Any] | None) -> None:
        waiters, self._waiters = self._waiters, []
        for waiter in waiters:
            if not waiter.done():
                waiter.set_result(status)

    def _publish(self, message: Message) -> None:
        for queue in self._streams:
            _offer(queue, message)


def _offer(queue: asyncio.Queue[Message], message: Message) -> None:
    """Put *message* on a stream's queue; a client that lets :data:`_BACKLOG` messages wait misses this one."""
    try:
        queue.put_nowait(message)
    except asyncio.QueueFull:
        pass
