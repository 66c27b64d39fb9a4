"""The network's operations (mlink_sim.aio.control.network) on a network of the virtual clock, asked as the control
endpoint asks them (``perform``: the request read by the table, then the handler): a status of 62 stations stays one
datagram, is built a few stations at a time, and reads the events; the report so far; parameters."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

from mlink_sim.aio.control.endpoint import perform
from mlink_sim.aio.control.network import STATIONS_PER_STEP
from mlink_sim.aio.run.embed import VirtualNetwork
from mlink_sim.operations import OpError

ROOT = Path(__file__).resolve().parents[3]
ML3_62 = ROOT / "mlink_sim" / "examples" / "ml3-62-max.toml"


def _ask(net: VirtualNetwork, op: str, **request: Any) -> dict[str, Any]:
    """*op*'s reply to *request*, asked in the network's loop as the endpoint asks it."""
    return net.call(perform(net.ops.handlers(), {"op": op, **request}))


def test_a_status_of_62_stations_is_built_in_steps_and_fits_a_datagram():
    with VirtualNetwork(ML3_62, seed=1, bring_up=False) as net:
        ops = net.ops
        net.call(net.session.bring_up(10))
        for i in range(70):
            ops.log.add("action", station="0x21", describe=f"a long enough description of action number {i}")
        assert len(ops.figures.by_address) > STATIONS_PER_STEP  # built in steps
        status = _ask(net, "status")
        events = list(status["events"])
        while True:  # the rest, 64 at a time
            more = _ask(net, "status", since=events[-1]["seq"])["events"]
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
        net.advance(0.5)
        report = _ask(net, "report")["report"]
        assert report["meta"]["clock"] == "virtual" and report["rtt"]["count"] > 0
        wrote = _ask(net, "set-param", station="21H", param="C1-02", value=4.5)
        assert wrote["param"] == {"name": "C1-02", "value": 4.5, "unit": "s", "raw": 45, "register": "0201H",
                                  "text": "4.5 s"}  # SI-T3 Table 8: C1-02 at 0201H, 0.1 s
        assert net.prm_rd(0x21, "C1-02") == 4.5
        with pytest.raises(OpError) as err:
            _ask(net, "get-param", station="0x22", param="C1-01")  # an A1000 name on a VS-606V7
        assert err.value.kind == "unknown_param"
        with pytest.raises(OpError) as err:
            _ask(net, "set-param", station="0x23", param="C1-01", value=-1)
        assert err.value.kind == "out_of_range"


def test_a_drive_fault_is_the_alarm_and_alarm_clear_clears_it():
    """A locked rotor trips oC (07H: SI-T3 Table 26; on the SI-ET3 read with ALM_RD, Tables 16/17); the SI-ET3's R/E
    lights red (Table 4), the SI-T3's ERR stays off (Table 3: communication errors only); ALM_CLR (SI-T3 Table 15)
    clears it once the fault has gone, and the events say so."""
    from mlink_sim.faults import fault_from_fields

    with VirtualNetwork("quickstart", seed=2) as net:
        for station in ("0x21", "0x23"):
            _ask(net, "run", station=station, direction="forward", hz=40.0)
        net.advance(3.0)
        for address in (0x21, 0x23):
            net.call(net.session.net.fault(address, fault_from_fields("lock-rotor", {"for": "0.5s"})))
        net.advance(2.0)
        tripped = {s["address"]: s for s in _ask(net, "status")["stations"]}
        assert tripped["0x21"]["alarm"] == tripped["0x23"]["alarm"] == {"code": "07H", "name": "OC"}
        assert tripped["0x21"]["leds"]["ERR"] == "off" and tripped["0x23"]["led_colors"]["R/E"] == "red"
        for station in ("0x21", "0x23"):
            _ask(net, "stop", station=station)
        net.advance(1.0)
        for station in ("0x21", "0x23"):
            assert _ask(net, "alarm-clear", station=station)["station"]["alarm"] is None
        net.advance(0.1)
        status = _ask(net, "status")
    assert all(s["alarm"] is None for s in status["stations"])
    alarms = [(e["station"], e.get("cleared", False)) for e in status["events"] if e["kind"] == "alarm"]
    assert alarms == [("0x21", False), ("0x23", False), ("0x21", True), ("0x23", True)]
    assert [e["describe"] for e in status["events"] if e["kind"] == "action"][-2:] == ["alarm clear (ALM_CLR)"] * 2
