"""The control endpoint (mlink_sim.aio.control.endpoint) over real UDP on 127.0.0.1: requests read by the operations
table before a handler sees them, operations that answer later, replies in parts, a repeated request id acting once,
error kinds. The endpoint under test serves the proxy's operations (impair, heal, faults) with handlers of the test's
own."""

from __future__ import annotations

import asyncio
import json
from typing import Any

import pytest

from mlink_sim.aio.control.endpoint import ControlServer, Encoded, encode_reply, query_control
from mlink_sim.operations import OpError


def _handlers(**given: Any) -> dict[str, Any]:
    """The proxy's three operations, those not *given* answering nothing in particular."""
    return {"impair": lambda **a: {}, "heal": lambda **a: {"ended": 0}, "faults": dict, **given}


def _serve(handlers: dict[str, Any], scenario: Any) -> Any:
    async def main() -> Any:
        server = ControlServer(_handlers(**handlers), "proxy")
        _, port = await server.start("127.0.0.1", 0)
        try:
            return await scenario(port)
        finally:
            server.close()

    return asyncio.run(main())


def test_an_operation_answering_later_does_not_hold_up_the_others():
    gate: dict[str, asyncio.Event] = {}

    def slow() -> Any:
        async def later() -> dict[str, Any]:
            await gate["open"].wait()
            return {"value": 5}
        return later()

    async def scenario(port: int) -> None:
        gate["open"] = asyncio.Event()
        pending = asyncio.ensure_future(query_control("127.0.0.1", port, "faults", timeout=5))
        assert await query_control("127.0.0.1", port, "ping", timeout=2) == {"ok": True}  # answered meanwhile
        assert not pending.done()
        gate["open"].set()
        assert await pending == {"ok": True, "value": 5}

    _serve({"faults": slow}, scenario)


def test_a_reply_its_operation_encoded_itself_is_sent_as_it_is_now_or_later():
    text = '{"ok":true,"stations":[{"address":"0x21"}],"seq":3}'

    def later(station: Any = None, name: Any = None) -> Any:
        async def encoded() -> Encoded:
            await asyncio.sleep(0)
            return Encoded(text)
        return encoded()

    async def scenario(port: int) -> None:
        assert await query_control("127.0.0.1", port, "faults", timeout=2) == json.loads(text)
        assert await query_control("127.0.0.1", port, "heal", timeout=2) == json.loads(text)

    _serve({"faults": lambda: Encoded(text), "heal": later}, scenario)
    assert encode_reply(Encoded(text)) == [text.encode()]


def test_a_repeated_request_id_acts_once_and_gets_the_same_answer():
    calls: list[int] = []

    def act(station: Any = None, name: Any = None) -> Any:
        calls.append(1)

        async def later() -> dict[str, Any]:
            await asyncio.sleep(0.2)
            return {"n": len(calls)}
        return later()

    async def scenario(port: int) -> None:
        first, second = await asyncio.gather(
            query_control("127.0.0.1", port, "heal", timeout=3, id="r1"),
            query_control("127.0.0.1", port, "heal", timeout=3, id="r1"))  # a repeat while the first is pending
        third = await query_control("127.0.0.1", port, "heal", timeout=3, id="r1")
        assert first == second == third == {"ok": True, "n": 1}
        assert await query_control("127.0.0.1", port, "heal", timeout=3, id="r2") == {"ok": True, "n": 2}

    _serve({"heal": act}, scenario)
    assert len(calls) == 2


def test_a_reply_larger_than_a_datagram_comes_in_parts_and_is_put_together():
    big = {"rows": [{"i": i, "text": "x" * 40 + '"quoted" \\ é'} for i in range(5000)]}
    parts = encode_reply({"ok": True, **big})
    assert len(parts) >= 5 and all(len(p) <= 60_000 for p in parts)

    async def scenario(port: int) -> None:
        assert await query_control("127.0.0.1", port, "faults", timeout=5) == {"ok": True, **big}

    _serve({"faults": lambda: big}, scenario)


def test_requests_are_read_by_the_table_and_errors_carry_their_kind():
    seen: list[Any] = []

    def refuse(station: Any = None, name: Any = None) -> dict[str, Any]:
        raise OpError("refused", "station 21H is in phase 1")

    def crash() -> Any:
        async def later() -> dict[str, Any]:
            raise RuntimeError("gone")
        return later()

    def impair(**args: Any) -> dict[str, Any]:
        seen.append(args)
        return {}

    async def scenario(port: int) -> None:
        ask = lambda op, **f: query_control("127.0.0.1", port, op, timeout=3, **f)  # noqa: E731
        assert await ask("heal") == {"ok": False, "error": "station 21H is in phase 1", "kind": "refused"}
        assert (await ask("faults"))["kind"] == "unavailable"
        unknown = await ask("nope")
        assert unknown["kind"] == "bad_request" and "unknown op 'nope'" in unknown["error"]
        elsewhere = await ask("run", station="21H", hz=30)
        assert elsewhere["kind"] == "bad_request" and "answered by a network, not by this proxy" in elsewhere["error"]
        assert await ask("impair", station="21H", loss=0.1, speed=3) == {
            "ok": False, "kind": "bad_request", "error": "impair: unknown field(s) speed (it takes: station, spec, "
            "name, loss, burst, delay, jitter, duplicate, reorder, corrupt, direction, for)"}
        assert (await ask("impair", station="22X"))["kind"] == "bad_request"
        assert await ask("impair", station="21H", loss="5%", **{"for": "2s"}) == {"ok": True}

    _serve({"heal": refuse, "faults": crash, "impair": impair}, scenario)
    assert seen == [{"station": 0x21, "spec": None, "name": None, "loss": "5%", "burst": None, "delay": None, "jitter": None,
                     "duplicate": None, "reorder": None, "corrupt": None, "direction": None, "for_": "2000000000ns"}]


def test_a_request_that_is_not_json_gets_a_bad_request():
    server = ControlServer(_handlers(), "proxy")
    reply = server.handle(b"{not json")
    assert isinstance(reply, dict) and reply["kind"] == "bad_request"
    assert json.dumps(reply)


def test_an_endpoint_must_serve_every_operation_the_table_gives_it():
    with pytest.raises(ValueError, match="missing \\['heal'\\]"):
        ControlServer({"impair": lambda **a: {}, "faults": dict}, "proxy")
    with pytest.raises(ValueError, match="not in the table for it \\['run'\\]"):
        ControlServer(_handlers(run=lambda **a: {}), "proxy")
