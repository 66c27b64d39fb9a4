"""The control endpoint (mlink_sim.aio.run.control) over real UDP on 127.0.0.1: operations that answer later,
replies in parts, a repeated request id acting once, error kinds."""

from __future__ import annotations

import asyncio
import json
from typing import Any

from mlink_sim.aio.run.control import ControlServer, Encoded, OpError, encode_reply, query_control


def _serve(ops: dict[str, Any], scenario: Any) -> Any:
    async def main() -> Any:
        server = ControlServer(ops)
        _, port = await server.start("127.0.0.1", 0)
        try:
            return await scenario(port)
        finally:
            server.close()

    return asyncio.run(main())


def test_an_operation_answering_later_does_not_hold_up_the_others():
    gate: dict[str, asyncio.Event] = {}

    def slow(request: dict[str, Any]) -> Any:
        async def later() -> dict[str, Any]:
            await gate["open"].wait()
            return {"value": 5}
        return later()

    async def scenario(port: int) -> None:
        gate["open"] = asyncio.Event()
        pending = asyncio.ensure_future(query_control("127.0.0.1", port, "slow", timeout=5))
        assert await query_control("127.0.0.1", port, "ping", timeout=2) == {"ok": True}  # answered meanwhile
        assert not pending.done()
        gate["open"].set()
        assert await pending == {"ok": True, "value": 5}

    _serve({"slow": slow}, scenario)


def test_a_reply_its_operation_encoded_itself_is_sent_as_it_is_now_or_later():
    text = '{"ok":true,"stations":[{"address":"0x21"}],"seq":3}'

    def later(request: dict[str, Any]) -> Any:
        async def encoded() -> Encoded:
            await asyncio.sleep(0)
            return Encoded(text)
        return encoded()

    async def scenario(port: int) -> None:
        assert await query_control("127.0.0.1", port, "now", timeout=2) == json.loads(text)
        assert await query_control("127.0.0.1", port, "later", timeout=2) == json.loads(text)

    _serve({"now": lambda request: Encoded(text), "later": later}, scenario)
    assert encode_reply(Encoded(text)) == [text.encode()]


def test_a_repeated_request_id_acts_once_and_gets_the_same_answer():
    calls: list[int] = []

    def act(request: dict[str, Any]) -> Any:
        calls.append(1)

        async def later() -> dict[str, Any]:
            await asyncio.sleep(0.2)
            return {"n": len(calls)}
        return later()

    async def scenario(port: int) -> None:
        first, second = await asyncio.gather(
            query_control("127.0.0.1", port, "act", timeout=3, id="r1"),
            query_control("127.0.0.1", port, "act", timeout=3, id="r1"))  # a repeat while the first is pending
        third = await query_control("127.0.0.1", port, "act", timeout=3, id="r1")
        assert first == second == third == {"ok": True, "n": 1}
        assert await query_control("127.0.0.1", port, "act", timeout=3, id="r2") == {"ok": True, "n": 2}

    _serve({"act": act}, scenario)
    assert len(calls) == 2


def test_a_reply_larger_than_a_datagram_comes_in_parts_and_is_put_together():
    big = {"rows": [{"i": i, "text": "x" * 40 + '"quoted" \\ é'} for i in range(5000)]}
    parts = encode_reply({"ok": True, **big})
    assert len(parts) >= 5 and all(len(p) <= 60_000 for p in parts)

    async def scenario(port: int) -> None:
        assert await query_control("127.0.0.1", port, "big", timeout=5) == {"ok": True, **big}

    _serve({"big": lambda request: big}, scenario)


def test_errors_carry_their_kind():
    def refuse(request: dict[str, Any]) -> dict[str, Any]:
        raise OpError("refused", "station 21H is in phase 1")

    def crash(request: dict[str, Any]) -> Any:
        async def later() -> dict[str, Any]:
            raise RuntimeError("gone")
        return later()

    async def scenario(port: int) -> None:
        ask = lambda op, **f: query_control("127.0.0.1", port, op, timeout=3, **f)  # noqa: E731
        assert await ask("refuse") == {"ok": False, "error": "station 21H is in phase 1", "kind": "refused"}
        assert (await ask("bad"))["kind"] == "bad_request"  # ValueError: a bad request
        assert (await ask("crash"))["kind"] == "unavailable"
        unknown = await ask("nope")
        assert unknown["kind"] == "bad_request" and "unknown op 'nope'" in unknown["error"]

    def bad(request: dict[str, Any]) -> dict[str, Any]:
        raise ValueError("speed_hz: expected a number")

    _serve({"refuse": refuse, "bad": bad, "crash": crash}, scenario)


def test_a_request_that_is_not_json_gets_a_bad_request():
    server = ControlServer({})
    reply = server.handle(b"{not json")
    assert isinstance(reply, dict) and reply["kind"] == "bad_request"
    assert json.dumps(reply)
