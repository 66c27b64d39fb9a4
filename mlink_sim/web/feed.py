"""One poller of the network's ``status`` operation, shared by every HTTP client (docs/web.md, "What the page
costs the network").

The poller asks the control endpoint for ``status`` at most every *interval* (0.1 s: 10 Hz) while someone wants it:
an open event stream (``GET /api/events``), or a ``GET /api/status`` in the last *linger* seconds; and, with
*background*, every *background* seconds (0.5 s) while nobody does, so that a page opened later has the minute before
it. Each answer is handed to every event stream (status, then the network's new events: phase changes, alarms,
timeline steps, check results), and a ``GET /api/status`` gets the latest answer if it is younger than *interval*,
else waits for the next one. However many pages are open, the network answers one query per interval.

The events come with a sequence number; the poller asks for those after the last it has (``since``), and keeps the
last :data:`KEEP_EVENTS` so that a page opened late shows what happened before it. It keeps each station's plotted
figures (:data:`HISTORY_FIELDS`) of the last :data:`HISTORY_S` seconds too, a bounded ring of the answers: a new event
stream begins with them (``history``), so its plots start full.

Touches: the control endpoint (through the ``query`` function it is given); nothing else.
"""

from __future__ import annotations

import asyncio
from collections import deque
from collections.abc import Awaitable, Callable
from typing import Any

from .._log import get_logger

__all__ = ["Feed", "KEEP_EVENTS", "HISTORY_S", "HISTORY_FIELDS", "Message"]

log = get_logger("mlink_sim.web")

#: the network's events a new event stream is given first (the newest this many)
KEEP_EVENTS = 200
#: messages an event stream may have waiting before it misses some (a client that does not read)
_BACKLOG = 256
#: the seconds of status answers a new event stream is given first (the page's plots: the last minute)
HISTORY_S = 60.0
#: the figures of each station the history keeps (docs/control.md, "Station figures": what the page plots)
HISTORY_FIELDS = ("reference_hz", "output_hz", "output_current_a", "dc_bus_v", "regulation", "rtt_p99_us", "missed")

#: what an event stream receives: (SSE event name, JSON-able data); ``status``, ``event``, ``error``, or
#: ``end`` (None) when the server stops
Message = tuple[str, Any]
Query = Callable[..., Awaitable[dict[str, Any] | None]]


class Feed:
    """The status poller and its fan-out to event streams and status requests."""

    def __init__(self, query: Query, *, interval: float = 0.1, linger: float = 2.0, timeout: float = 1.0,
                 background: float | None = None) -> None:
        self._query = query
        self.interval = interval
        self.background = background  #: the poll's period while nobody looks (None: no poll then)
        self.linger = linger
        self.timeout = timeout
        self.latest: dict[str, Any] | None = None  #: the last status (without its events)
        self.latest_at = float("-inf")  #: when it came (the loop's clock)
        self.events: deque[dict[str, Any]] = deque(maxlen=KEEP_EVENTS)
        #: (elapsed_s, {station: its HISTORY_FIELDS}) of the answers of the last HISTORY_S seconds
        self.history: deque[tuple[float, dict[str, tuple[Any, ...]]]] = deque()
        self.polls = 0  #: status queries sent (the tests read it: one poller, whatever the clients)
        self.error: dict[str, str] | None = None  #: why the last poll got no status (None: it got one)
        self._seq: int | None = None
        self._streams: set[asyncio.Queue[Message]] = set()
        self._waiters: list[asyncio.Future[dict[str, Any] | None]] = []
        self._wanted_until = float("-inf")
        self._task: asyncio.Task[None] | None = None
        self._idle: asyncio.Future[None] | None = None  # the background's wait, while it lasts

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

    def start(self) -> None:
        """Poll from now on, every *background* seconds while nobody looks (the server's start)."""
        if self.background is not None:
            self._ensure_polling()

    def history_message(self) -> dict[str, Any]:
        """The kept answers as columns: ``{"fields": HISTORY_FIELDS, "t": [elapsed_s …], "stations": {"0x21":
        [[a field's values …] …]}}`` (a station missing from an answer: nulls there)."""
        times = [t for t, _ in self.history]
        keys = list(dict.fromkeys(k for _, rows in self.history for k in rows))
        blank = (None,) * len(HISTORY_FIELDS)
        stations = {k: [list(col) for col in zip(*(rows.get(k, blank) for _, rows in self.history), strict=True)]
                    for k in keys}
        return {"fields": list(HISTORY_FIELDS), "t": times, "stations": stations}

    def subscribe(self) -> asyncio.Queue[Message]:
        """A new event stream's queue: the kept history (the plots' last minute), the kept events and the latest
        status first, then every poll's."""
        queue: asyncio.Queue[Message] = asyncio.Queue(_BACKLOG)
        if self.history:
            queue.put_nowait(("history", self.history_message()))
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

    def _watched(self) -> bool:
        return bool(self._streams or self._waiters) or asyncio.get_running_loop().time() < self._wanted_until

    def _wanted(self) -> bool:
        return self.background is not None or self._watched()

    def _ensure_polling(self) -> None:
        if self._task is None or self._task.done():
            self._task = asyncio.get_running_loop().create_task(self._poll())
        elif self._idle is not None and not self._idle.done():
            self._idle.set_result(None)  # someone looks now: the next poll at once, not after the background's wait

    async def _poll(self) -> None:
        loop = asyncio.get_running_loop()
        while self._wanted():
            began = loop.time()
            fields = {} if self._seq is None else {"since": self._seq}
            self.polls += 1
            reply = await self._query("status", timeout=self.timeout, **fields)
            self._take(reply, loop.time())
            if self._watched() or self.background is None:
                await asyncio.sleep(max(0.0, self.interval - (loop.time() - began)))
                continue
            idle = self._idle = loop.create_future()
            try:
                await asyncio.wait_for(idle, max(0.0, self.background - (loop.time() - began)))
            except TimeoutError:
                pass
            finally:
                self._idle = None

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
        self._remember(status)
        self.latest, self.latest_at = status, now
        self._publish(("status", status))
        self._resolve(status)

    def _remember(self, status: dict[str, Any]) -> None:
        """Keep *status*'s plotted figures in the history; what is older than :data:`HISTORY_S` goes (and all of it
        when the network's time went back: another run on the same endpoint)."""
        t = status.get("elapsed_s")
        if not isinstance(t, int | float):
            return
        history = self.history
        if history and t < history[-1][0]:
            history.clear()
        history.append((float(t), {str(row.get("address")): tuple(row.get(f) for f in HISTORY_FIELDS)
                                   for row in status.get("stations") or () if isinstance(row, dict)}))
        while history and history[0][0] < t - HISTORY_S:
            history.popleft()

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
