"""The operations table (mlink_sim.operations): each operation declared once, its requests read by one rule per
argument kind, with one message per mistake; the text a user reads of stations, LEDs, alarms and events."""

from __future__ import annotations

import keyword
import re

import pytest

from mlink_sim.operations import (ENDPOINTS, ERROR_KINDS, OPERATIONS, OpError, alarm_text, check_speed, event_text,
                                  leds_text, operation, parse_request, request_of, served_by, station_text)
from mlink_sim.web.openapi import path_args


def test_every_operation_is_declared_whole() -> None:
    for op in OPERATIONS.values():
        names = [a.name for a in op.args]
        assert len(names) == len(set(names)), op.name
        assert all(a.python.isidentifier() and not keyword.iskeyword(a.python) for a in op.args)
        assert op.endpoints and op.endpoints <= set(ENDPOINTS), op.name
        assert op.summary.endswith((".", "?")) and "\n" not in op.summary, op.name
        if op.http is not None:
            method, path = op.http
            assert method in ("GET", "POST", "PUT") and path.startswith("/api/")
            assert set(path_args(op)) <= set(names), op.name
            assert "network" in op.endpoints
        if op.timeline:
            assert "network" in op.endpoints and op.acts
    assert served_by("slave") and served_by("proxy") and "ping" in {op.name for op in served_by("proxy")}


def test_a_request_is_read_by_its_arguments_kinds() -> None:
    run = operation("run")
    assert parse_request(run, {"op": "run", "station": "21H", "hz": "30", "id": "r1"}) == {
        "station": 0x21, "hz": 30.0, "direction": "forward"}
    assert parse_request(run, {"station": 33, "hz": 12.5, "direction": "Reverse"})["direction"] == "reverse"
    set_param = operation("set-param")
    assert parse_request(set_param, {"station": "0x22", "param": "n019", "value": "24H"}) == {
        "station": 0x22, "param": "n019", "value": "24H", "eeprom": False}
    assert parse_request(set_param, {"station": "0x22", "param": "n019", "value": "3.5"})["value"] == 3.5
    assert parse_request(operation("heal"), {})["station"] is None  # every station
    assert parse_request(operation("impair"), {"station": "all", "loss": "5%", "for": 2})["for_"] == "2000000000ns"


@pytest.mark.parametrize(("name", "request_", "kind", "message"), [
    ("run", {"station": "21H", "speed_hz": 30}, "bad_request",
     "run: unknown field(s) speed_hz (it takes: station, hz, direction)"),
    ("run", {"station": "21H"}, "bad_request", "run: hz is missing (a frequency reference in Hz"),
    ("run", {"station": "21X", "hz": 3}, "bad_request",
     "station: expected a station address such as 0x21 or 21H, got '21X'"),
    ("run", {"station": "21H", "hz": True}, "bad_request", "hz: expected a number, got True"),
    ("run", {"station": "21H", "hz": -5}, "out_of_range", "hz: a frequency reference is 0 Hz or more"),
    ("run", {"station": "21H", "hz": 5, "direction": "to-master"}, "bad_request",
     "direction: expected 'forward' or 'reverse', got 'to-master'"),
    ("impair", {"station": "21H", "spec": "loss=5%", "direction": "forward"}, "bad_request",
     "direction: expected 'to-station', 'to-master' or 'both', got 'forward'"),
    ("impair", {"station": "21H"}, "bad_request", "impair: nothing to do"),
    ("impair", {"station": "21H", "loss": 2}, "bad_request", "impair: loss: a probability is between 0 and 1"),
    ("fault", {"station": "21H", "spec": "silence"}, "bad_request", 'fault: for: required, e.g. for = "200ms"'),
    ("fault", {"station": "21H", "spec": "silence,for=1s", "do": "load"}, "bad_request", "not both"),
    ("set-param", {"station": "21H", "param": "C1 01", "value": 1}, "bad_request", "param: expected a parameter"),
    ("set-param", {"station": "21H", "param": "C1-01", "value": [1]}, "bad_request", "value: expected the"),
    ("set-param", {"station": "21H", "param": "C1-01", "value": 1, "eeprom": "yes"}, "bad_request",
     "eeprom: expected true or false"),
    ("status", {"since": -1}, "bad_request", "since: expected a whole number 0 or more, got -1"),
    ("release", {"station": "21H", "handle": 0}, "bad_request", "handle: expected a whole number 1 or more"),
])
def test_every_mistake_has_its_kind_and_one_line(name: str, request_: dict, kind: str, message: str) -> None:
    with pytest.raises(OpError) as err:
        parse_request(operation(name), request_)
    assert err.value.kind == kind and message in str(err.value) and "\n" not in str(err.value)
    assert err.value.as_reply() == {"ok": False, "error": str(err.value), "kind": kind}


def test_an_unknown_operation_names_the_known_ones() -> None:
    with pytest.raises(OpError, match=r"unknown op 'teleport' \(known: network, status"):
        operation("teleport")
    with pytest.raises(ValueError, match="not one of"):
        OpError("broken", "no such kind")
    assert ERROR_KINDS[0] == "bad_request"


def test_request_of_spells_a_python_call_as_a_control_request() -> None:
    assert request_of("impair", station=0x21, spec=None, loss=0.1, for_=2.0) == {
        "op": "impair", "station": 0x21, "loss": 0.1, "for": 2.0}
    with pytest.raises(OpError, match="unknown argument"):
        request_of("stop", station=0x21, hz=3)


def test_one_speed_rule_names_the_station_and_its_parameter() -> None:
    assert check_speed(60.0, 0x21, 60.0, "E1-04") == 60.0
    with pytest.raises(OpError) as err:
        check_speed(450.0, 0x22, 60.0, "n011")
    assert err.value.kind == "out_of_range"
    assert str(err.value) == ("hz: 450 Hz is outside 0…60 Hz, the maximum output frequency of station 22H (n011)")


def test_what_a_user_reads() -> None:
    assert station_text("0x21") == "21H" and station_text(34) == "22H" and station_text("all") == "all"
    assert leds_text({"RUN": "on", "ERR": "off", "TX": "blink", "RX": "on"}) == "RUN ERR- TX* RX"
    assert alarm_text({"code": "E6H", "name": "COMM_ERROR"}) == "COMM_ERROR (E6H)"
    assert alarm_text({"code": None, "name": "D_ALM"}) == "D_ALM" and alarm_text(None) == "ok"
    cleared = event_text({"seq": 3, "at_s": 1.5, "kind": "alarm", "station": "0x22", "code": None, "name": None,
                          "source": "comm", "cleared": True})
    assert cleared == "   1.500 s  alarm  22H COMM_ALM cleared" and "None" not in cleared
    raised = event_text({"seq": 4, "at_s": -0.2, "kind": "alarm", "station": "0x21", "code": "E6H",
                         "name": "COMM_ERROR", "source": "alarm"})
    assert raised.endswith("21H COMM_ERROR (E6H) (bring-up)") and "-0.200 s" in raised  # before the timeline's 0 s
    step = event_text({"seq": 5, "at_s": 0.2, "kind": "step", "describe": "0.2s all stations: do run forward 30 Hz"})
    assert step.endswith("step   0.2s all stations: do run forward 30 Hz")
    assert not re.search(r"0x[0-9a-f]{2}", event_text({"at_s": 0, "kind": "action", "station": "0x23",
                                                        "describe": "stop"}))
