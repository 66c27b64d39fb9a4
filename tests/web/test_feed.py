"""The status poller: one query to the network at a time, whatever the number of clients, and its answer handed to
every event stream and every status request (the query is a stand-in the test answers by hand: no clock)."""

from __future__ import annotations

import asyncio
from typing import Any

from mlink_sim.web import Feed
from mlink_sim.web.feed import HISTORY_FIELDS


class HandAnswered:
    """A ``status`` query the test answers: each call waits until :meth:`answer`."""

    def __init__(self) -> None:
        self.calls: list[dict[str, Any]] = []
        self.pending: list[asyncio.Future[dict[str, Any] | None]] = []

    async def __call__(self, op: str, timeout: float = 1.0, **fields: Any) -> dict[str, Any] | None:
        self.calls.append({"op": op, **fields})
        fut: asyncio.Future[dict[str, Any] | None] = asyncio.get_running_loop().create_future()
        self.pending.append(fut)
        return await fut

    def answer(self, reply: dict[str, Any] | None) -> None:
        self.pending.pop(0).set_result(reply)


async def settle() -> None:
    for _ in range(5):
        await asyncio.sleep(0)


def status(seq: int, events: list[dict[str, Any]] | None = None) -> dict[str, Any]:
    return {"ok": True, "elapsed_s": 1.0, "step": None, "stalls": {}, "stations": [], "events": events or [],
            "seq": seq}


async def test_many_clients_share_one_status_query() -> None:
    query = HandAnswered()
    feed = Feed(query, interval=3600.0)  # one poll, then a long wait: the test sees each query
    streams = [feed.subscribe() for _ in range(5)]
    readers = [asyncio.ensure_future(feed.status()) for _ in range(5)]
    await settle()
    assert len(query.calls) == 1 and query.calls[0] == {"op": "status"}
    query.answer(status(3, [{"seq": 3, "at_s": 0.5, "kind": "phase"}]))
    await settle()
    assert [r.result()["seq"] for r in readers] == [3] * 5
    for stream in streams:
        assert [stream.get_nowait()[0] for _ in range(2)] == ["event", "status"]
    assert len(query.calls) == 1
    feed.close()


async def test_the_next_query_asks_for_the_events_after_the_last_one_seen() -> None:
    query = HandAnswered()
    feed = Feed(query, interval=0.0)
    stream = feed.subscribe()
    await settle()
    query.answer(status(7))
    await settle()
    assert query.calls[1] == {"op": "status", "since": 7}
    feed.close()
    assert ("end", None) in [stream.get_nowait() for _ in range(stream.qsize())]


async def test_a_stream_opened_late_gets_the_history_the_kept_events_and_the_latest_status_first() -> None:
    query = HandAnswered()
    feed = Feed(query, interval=3600.0)
    first = asyncio.ensure_future(feed.status())
    await settle()
    query.answer(status(2, [{"seq": 1, "at_s": 0.1, "kind": "step"}, {"seq": 2, "at_s": 0.2, "kind": "check"}]))
    await first
    late = feed.subscribe()
    got = [late.get_nowait() for _ in range(late.qsize())]
    assert [name for name, _ in got] == ["history", "event", "event", "status"]
    assert [data["seq"] for name, data in got if name == "event"] == [1, 2]
    feed.close()


def _answer(t: float, out_hz: float) -> dict[str, Any]:
    row = {"address": "0x21", "reference_hz": -20.0, "output_hz": out_hz, "output_current_a": 5.0, "dc_bus_v": 300.0,
           "regulation": [], "rtt_p99_us": 120.0, "missed": 0}
    return {**status(1), "elapsed_s": t, "stations": [row]}


async def test_the_last_minute_of_answers_is_kept_as_columns_and_polled_while_nobody_looks() -> None:
    """A page opened late starts with full plots: the poller asks in the background (every *background* s) and keeps
    the answers of the last HISTORY_S seconds; a clock that went back (another run) starts it afresh."""
    query = HandAnswered()
    feed = Feed(query, interval=3600.0, background=3600.0)
    feed.start()
    await settle()
    assert len(query.calls) == 1  # nobody looks, yet it asks
    for k in range(70):
        feed._take({"ok": True, **_answer(float(k), -float(k % 20))}, float(k))
    kept = feed.history_message()
    assert kept["t"] == [float(k) for k in range(9, 70)]  # the last 60 s
    assert kept["fields"] == list(HISTORY_FIELDS)
    columns = dict(zip(kept["fields"], kept["stations"]["0x21"], strict=True))
    assert columns["output_hz"][:3] == [-9.0, -10.0, -11.0] and len(columns["dc_bus_v"]) == 61
    feed._take({"ok": True, **_answer(0.5, 0.0)}, 71.0)
    assert feed.history_message()["t"] == [0.5]
    feed.close()


async def test_an_endpoint_that_does_not_answer_is_said_once_to_the_streams() -> None:
    query = HandAnswered()
    feed = Feed(query, interval=0.0)
    stream = feed.subscribe()
    for _ in range(3):
        await settle()
        query.answer(None)
    await settle()
    errors = [m for m in (stream.get_nowait() for _ in range(stream.qsize())) if m[0] == "error"]
    assert errors == [("error", {"error": "the network's control endpoint did not answer", "kind": "no_answer"})]
    assert feed.error is not None and feed.error["kind"] == "no_answer"
    feed.close()


async def test_without_clients_the_poller_stops_asking() -> None:
    query = HandAnswered()
    feed = Feed(query, interval=0.0, linger=0.0)
    stream = feed.subscribe()
    await settle()
    feed.unsubscribe(stream)
    query.answer(status(1))
    await settle()
    assert len(query.calls) == 1 and not query.pending
    feed.close()
