"""The control operations (mlink_sim.aio.run.ops) on a network of the virtual clock: a status of 62 stations
stays one datagram, is built a few stations at a time, and reads the events; the report so far; parameters."""

from __future__ import annotations

import inspect
import json
from pathlib import Path
from typing import Any

import pytest

from mlink_sim.aio.run.control import OpError
from mlink_sim.aio.run.embed import VirtualNetwork
from mlink_sim.aio.run.events import RunLog
from mlink_sim.aio.run.ops import STATIONS_PER_STEP, RunOps

ROOT = Path(__file__).resolve().parents[3]
ML3_62 = ROOT / "mlink_sim" / "examples" / "ml3-62-max.toml"


def _ops(net: VirtualNetwork) -> tuple[RunOps, dict[str, Any]]:
    session = net.session
    log = RunLog(next(iter(session.masters.values())).now_ns)
    for master in session.masters.values():
        log.watch(master)
    ops = RunOps(session, log, in_thread=False)
    return ops, ops.ops()


def _ask(net: VirtualNetwork, op: Any, **request: Any) -> dict[str, Any]:
    """*op*'s reply to *request*, asked in the network's loop (as the endpoint asks it)."""
    async def go() -> dict[str, Any]:
        reply = op(request)
        return await reply if inspect.isawaitable(reply) else reply

    return net.call(go())


def test_a_status_of_62_stations_is_built_in_steps_and_fits_a_datagram():
    with VirtualNetwork(ML3_62, seed=1, bring_up=False) as net:
        ops, table = _ops(net)
        net.call(net.session.bring_up(10))
        for i in range(70):
            ops.log.add("action", station="0x21", describe=f"a long enough description of action number {i}")
        assert len(ops.figures.by_address) > STATIONS_PER_STEP  # built in steps
        status = _ask(net, table["status"])
        events = list(status["events"])
        while True:  # the rest, 64 at a time
            more = _ask(net, table["status"], since=events[-1]["seq"])["events"]
            if not more:
                break
            events += more
    assert len(status["stations"]) == 62 and all(s["phase"] == 3 for s in status["stations"])
    assert len(status["events"]) == 64 and status["seq"] == status["events"][-1]["seq"]
    assert len(json.dumps({"ok": True, **status}, separators=(",", ":"))) < 60_000
    assert [e["seq"] for e in events] == list(range(1, len(events) + 1))
    phases = {e["station"] for e in events if e["kind"] == "phase" and e["state"] == "phase3"}
    assert len(phases) == 62  # bring-up, as the master saw it
    assert sum(e["kind"] == "action" for e in events) == 70


def test_the_report_so_far_and_parameters_by_name():
    with VirtualNetwork("quickstart", seed=2) as net:
        ops, table = _ops(net)
        net.advance(0.5)
        report = _ask(net, table["report"])["report"]
        assert report["meta"]["clock"] == "virtual" and report["rtt"]["count"] > 0
        wrote = _ask(net, table["param"], station="21H", name="C1-02", value=4.5)
        assert wrote["param"] == {"name": "C1-02", "value": 4.5, "unit": "s", "raw": 45, "register": "0201H",
                                  "text": "4.5 s"}  # SI-T3 Table 8: C1-02 at 0201H, 0.1 s
        assert net.prm_rd(0x21, "C1-02") == 4.5
        with pytest.raises(OpError) as err:
            _ask(net, table["param"], station="0x22", name="C1-01")  # an A1000 name on a VS-606V7
        assert err.value.kind == "unknown_param"
        with pytest.raises(OpError) as err:
            _ask(net, table["param"], station="0x23", name="C1-01", value=-1)
        assert err.value.kind == "out_of_range"
