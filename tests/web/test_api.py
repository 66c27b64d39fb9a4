"""The HTTP API of ``mlink-sim up --web`` against a real network (the quickstart: slave processes, the master, the
web server in a process of its own): every answer is validated against the OpenAPI 3.1 document it serves."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import pytest
from openapi_spec_validator import validate as validate_spec

from .webnet import DOC, Http, by_name, check_response, component, stations, up_with_web, wait_for

pytestmark = pytest.mark.e2e


@pytest.fixture(scope="module")
def http() -> Iterator[Http]:
    proc, url = up_with_web()
    client = Http(url)
    try:
        wait_for(lambda: client.get("api/status")[0] == 200 and all(
            row["phase"] == 3 for row in stations(client)), 30, "every station in phase 3")
        yield client
    finally:
        proc.stop()


def test_the_openapi_document_is_valid_openapi_3_1_and_served_as_it_is_kept() -> None:
    validate_spec(DOC)
    assert DOC["openapi"].startswith("3.1")


def test_the_served_document_is_the_packaged_one(http: Http) -> None:
    status, body = http.get("api/openapi.json")
    assert (status, body) == (200, DOC)


def test_the_network_names_its_stations_cards_links_and_frame_sizes(http: Http) -> None:
    status, body = http.get("api/network")
    check_response("/api/network", "get", status, body)
    assert body["name"] == "quickstart" and body["cycle"] == "2ms"
    assert [(s["name"], s["card"], s["link"], s["frame_size"]) for s in body["stations"]] == [
        ("21H", "si-t3", "ML2", 32), ("22H", "si-t-v7", "ML2", 32), ("23H", "si-et3", "ML3", 64)]


def test_the_status_gives_every_station_its_figures(http: Http) -> None:
    status, body = http.get("api/status")
    check_response("/api/status", "get", status, body)
    rows = by_name(body["stations"])
    assert set(rows) == {"21H", "22H", "23H"}
    assert all(row["connected"] and row["alarm"] is None for row in rows.values())
    assert set(rows["23H"]["leds"]) == {"R/E", "CON", "LK1", "LK2"}  # SI-ET3 Table 4
    assert set(rows["21H"]["leds"]) == {"RUN", "ERR", "TX", "RX"}  # SI-T3 Table 3


def test_run_then_stop_a_station_by_either_address_notation(http: Http) -> None:
    status, body = http.post("api/stations/0x21/run", {"direction": "forward", "hz": 20.0})
    check_response("/api/stations/{station}/run", "post", status, body)
    assert body["station"]["name"] == "21H"
    wait_for(lambda: (by_name(stations(http))["21H"]["output_hz"] or 0) > 5.0, 20, "21H above 5 Hz")
    assert by_name(stations(http))["21H"]["direction"] == "forward"
    status, body = http.post("api/stations/21H/stop")
    check_response("/api/stations/{station}/stop", "post", status, body)
    wait_for(lambda: by_name(stations(http))["21H"]["output_hz"] == 0.0, 20, "21H at 0 Hz")


def test_a_parameter_reads_and_writes_back_in_its_unit(http: Http) -> None:
    status, body = http.get("api/stations/21H/params/C1-01")  # the config sets C1-01 = 2.0 s
    check_response("/api/stations/{station}/params/{param}", "get", status, body)
    assert (body["param"]["name"], body["param"]["value"], body["param"]["unit"]) == ("C1-01", 2.0, "s")
    status, body = http.request("PUT", "api/stations/0x23/params/C1-02", {"value": 3.0, "eeprom": False})
    check_response("/api/stations/{station}/params/{param}", "put", status, body)
    assert body["param"]["value"] == 3.0
    status, body = http.get("api/stations/23h/params/C1-02")
    assert (status, body["param"]["value"]) == (200, 3.0)


def test_faults_impairments_and_heal_are_taken_and_answered_as_documented(http: Http) -> None:
    status, body = http.post("api/stations/22H/fault", {"spec": "silence,for=100ms"})
    check_response("/api/stations/{station}/fault", "post", status, body)
    assert status == 200, body
    assert body["describe"].startswith("silence")
    status, body = http.post("api/stations/21H/impair", {"spec": "loss=5%,for=1s"})
    check_response("/api/stations/{station}/impair", "post", status, body)
    assert status == 200, body
    status, body = http.post("api/stations/all/heal")
    check_response("/api/stations/{station}/heal", "post", status, body)
    assert status == 200, body
    assert body["ended"] >= 1
    status, body = http.post("api/stations/22H/alarm-clear")
    check_response("/api/stations/{station}/alarm-clear", "post", status, body)


def test_named_impairments_are_listed_and_healed_one_by_one_over_http(http: Http) -> None:
    """docs/faults.md, "Names", through the HTTP API: a named impairment stacks beside an unnamed one; GET
    /api/faults lists both with what each injected; heal with a name ends that one only."""
    status, body = http.post("api/stations/21H/impair", {"spec": "delay=100us", "name": "slow"})
    assert (status, body["name"]) == (200, "slow"), body
    status, body = http.post("api/stations/21H/impair", {"spec": "duplicate=1%"})
    assert status == 200 and body["name"].startswith("duplicate-21H-"), body
    unnamed = body["name"]
    wait_for(lambda: {f["name"]: f for f in http.get("api/faults")[1]["faults"]}.get("slow", {}).get("injected"), 5)
    status, body = http.get("api/faults")
    check_response("/api/faults", "get", status, body)
    listed = {f["name"]: f for f in body["faults"]}
    assert set(listed) == {"slow", unnamed} and listed["slow"]["stations"] == ["0x21"]
    assert listed["slow"]["injected"]["delays"] > 0 and listed["slow"]["given"] and not listed[unnamed]["given"]
    status, body = http.post("api/stations/all/heal", {"name": "slow"})
    assert (status, body) == (200, {"ended": 1, "names": ["slow"]})
    assert [f["name"] for f in http.get("api/faults")[1]["faults"]] == [unnamed]
    status, body = http.post("api/stations/all/heal", {"name": "slow"})
    assert (status, body["kind"]) == (400, "bad_request") and "no impairment or fault is called 'slow'" in body["error"]
    status, body = http.post("api/stations/21H/heal")
    assert body["names"] == [unnamed]
    # a drive fault by name, on the slave worker's drive: listed, then released by heal
    status, body = http.post("api/stations/23H/fault", {"spec": "load,torque=1", "name": "heavy"})
    assert (status, body["name"]) == (200, "heavy"), body
    listed = {f["name"]: f for f in http.get("api/faults")[1]["faults"]}
    assert listed["heavy"]["kind"] == "fault" and listed["heavy"]["injected"] == {"drive_faults": 1}
    assert http.post("api/stations/23H/heal", {"name": "heavy"})[1]["names"] == ["heavy"]
    assert http.get("api/faults")[1]["faults"] == []


def test_the_report_is_the_report_of_the_run_so_far(http: Http) -> None:
    status, body = http.get("api/report")
    check_response("/api/report", "get", status, body)
    assert body["meta"]["network"] == "quickstart"


def test_the_event_stream_delivers_status_and_the_networks_events(http: Http) -> None:
    http.post("api/stations/21H/stop")  # an action: logged as an event while the stream is open
    messages = http.events(lambda ms: {name for name, _ in ms} >= {"status", "event"}
                           and sum(name == "status" for name, _ in ms) >= 3)
    for name, data in messages:
        component({"status": "Status", "event": "Event", "error": "Error", "history": "History"}[name]).validate(data)
    kinds = {data["kind"] for name, data in messages if name == "event"}
    assert "phase" in kinds  # the bring-up's phase changes come first
    assert [d["stations"][0]["name"] for n, d in messages if n == "status"][0] == "21H"


BAD: list[tuple[str, str, Any, dict[str, str] | None, int, str]] = [
    ("GET", "api/stations/99H/params/C1-01", None, None, 404, "unknown_station"),
    ("GET", "api/stations/21H/params/X9-99", None, None, 404, "unknown_param"),
    ("GET", "api/stations/21X/params/C1-01", None, None, 400, "bad_request"),
    ("GET", "api/stations/21H/params/C1%2001", None, None, 400, "bad_request"),
    ("PUT", "api/stations/21H/params/C1-01", {"value": 9999.0}, None, 422, "out_of_range"),
    ("PUT", "api/stations/21H/params/C1-01", {"value": True}, None, 400, "bad_request"),
    ("PUT", "api/stations/21H/params/C1-01", {"value": 1, "colour": "red"}, None, 400, "bad_request"),
    ("POST", "api/stations/21H/run", {"direction": "up"}, None, 400, "bad_request"),
    ("POST", "api/stations/21H/run", {"hz": 1e6}, None, 422, "out_of_range"),
    ("POST", "api/stations/0x99/stop", {}, None, 404, "unknown_station"),
    ("POST", "api/stations/21H/fault", {"spec": "melt,for=1s"}, None, 400, "bad_request"),
    ("POST", "api/stations/21H/fault", {}, None, 400, "bad_request"),
    ("POST", "api/stations/21H/impair", {"station": "22H", "spec": "loss=5%"}, None, 400, "bad_request"),
]


@pytest.mark.parametrize(("method", "path", "body", "headers", "code", "kind"), BAD,
                         ids=[f"{m} {p} {b}" for m, p, b, *_ in BAD])
def test_a_bad_request_gets_a_4xx_with_a_one_line_reason(http: Http, method: str, path: str, body: Any,
                                                         headers: dict[str, str] | None, code: int,
                                                         kind: str) -> None:
    status, answer = http.request(method, path, body, headers=headers)
    assert (status, answer["kind"]) == (code, kind), answer
    template = "/" + path.replace("99H", "{station}").replace("21X", "{station}").replace("0x99", "{station}")
    template = template.replace("21H", "{station}").replace("X9-99", "{param}").replace("C1%2001", "{param}")
    template = template.replace("C1-01", "{param}")
    check_response(template, method, status, answer)
    assert "\n" not in answer["error"]


def test_a_form_post_is_refused_so_that_another_site_cannot_send_one(http: Http) -> None:
    status, body = http.request("POST", "api/stations/21H/stop", raw=b"x=1",
                                content_type="application/x-www-form-urlencoded")
    assert (status, body["kind"]) == (415, "unsupported_media_type")
    check_response("/api/stations/{station}/stop", "post", status, body)


def test_a_request_under_a_name_other_than_loopback_is_refused_without_a_token(http: Http) -> None:
    status, body = http.get("api/status", headers={"Host": "mlink.example:8080"})
    assert (status, body["kind"]) == (403, "forbidden")


def test_an_unknown_route_or_method_is_a_4xx_in_json(http: Http) -> None:
    assert http.get("api/nothing")[0] == 404
    status, body = http.request("DELETE", "api/network")
    assert (status, body["kind"]) == (405, "method_not_allowed")


def test_the_page_and_its_files_are_served_offline(http: Http) -> None:
    import urllib.request

    with urllib.request.urlopen(http.base, timeout=10) as r:
        page = r.read().decode()
    assert "static/vendor/uplot/uPlot.iife.min.js" in page and "static/app.js" in page
    assert "http" not in page.replace("http://HOST:PORT", "")  # nothing from another server
    for path in ("static/app.js", "static/app.css", "static/vendor/uplot/uPlot.iife.min.js",
                 "static/vendor/uplot/LICENSE"):
        with urllib.request.urlopen(http.base + path, timeout=10) as r:
            assert r.status == 200 and r.read()
