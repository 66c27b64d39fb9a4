"""``mlink-sim web`` against a network running with ``--control`` (as in a container or on another machine), the
token that any address other than loopback requires, the web server's process ending with the run, and ``master
--web`` for a master whose slave runs elsewhere."""

from __future__ import annotations

import re
import subprocess
import urllib.error
import urllib.request

import pytest

from .webnet import MLINK, Http, Proc, check_response, stations, up_with_control, up_with_web, wait_for, web_server

pytestmark = pytest.mark.e2e


def test_web_serves_a_network_through_its_tokened_control_endpoint_and_needs_its_own_token_off_loopback(
        tmp_path) -> None:
    token_file = tmp_path / "web-token"
    token_file.write_text("s3cret-web\n")
    net, control = up_with_control("--control-token", "ctl-token")
    try:
        web, url = web_server("--control", control, "--control-token", "ctl-token", "--listen", "0.0.0.0:0",
                              "--web-token-file", str(token_file))
        try:
            url = url.replace("0.0.0.0", "127.0.0.1")
            status, body = Http(url).get("api/status")
            assert (status, body["kind"]) == (401, "unauthorized")
            check_response("/api/status", "get", status, body)
            status, body = Http(url, token="wrong").get("api/network")
            assert status == 401
            http = Http(url, token="s3cret-web")
            wait_for(lambda: all(row["phase"] == 3 for row in stations(http)), 30, "every station in phase 3")
            status, body = http.get("api/network")
            check_response("/api/network", "get", status, body)
            assert body["name"] == "quickstart"
            with urllib.request.urlopen(url, timeout=10) as r:  # the page itself holds no data of the network
                assert r.status == 200 and b"<title>mlink-sim</title>" in r.read()
        finally:
            assert web.stop() == 130
    finally:
        net.stop()


def test_web_with_another_control_token_says_the_endpoint_does_not_answer() -> None:
    net, control = up_with_control("--control-token", "ctl-token")
    try:
        web, url = web_server("--control", control, "--control-token", "not-it", "--listen", "127.0.0.1:0")
        try:
            web.wait_line(re.compile("does not answer"), 10)
            status, body = Http(url).get("api/network")
            assert (status, body["kind"]) == (503, "no_answer")
            check_response("/api/network", "get", status, body)
        finally:
            web.stop()
    finally:
        net.stop()


@pytest.mark.parametrize(("args", "message"), [
    (["web", "--control", "127.0.0.1:1", "--listen", "0.0.0.0:0"], "--listen 0.0.0.0:0 is reachable from other "
                                                                     "hosts: give --web-token"),
    (["web", "--control", "127.0.0.1:1", "--listen", "nowhere"], "--listen 'nowhere'"),
    (["up", "quickstart", "--web", "0.0.0.0:0"], "--web 0.0.0.0:0 is reachable from other hosts"),
    (["up", "quickstart", "--web-token", "x"], "--web-token is the token of the page's server"),
    (["up", "quickstart", "--clock", "virtual", "--web", "0"], "--web shows a network on the wall clock"),
])
def test_a_web_option_that_cannot_be_used_is_a_usage_error(args: list[str], message: str) -> None:
    r = subprocess.run([*MLINK, *args], capture_output=True, text=True, timeout=60)
    assert r.returncode == 2, r.stderr
    assert message in r.stderr and "Traceback" not in r.stderr


def test_the_web_server_of_up_ends_with_the_run() -> None:
    net, url = up_with_web()
    http = Http(url)
    wait_for(lambda: http.get("api/status")[0] == 200, 30, "the status")
    net.stop()
    with pytest.raises(urllib.error.URLError):
        urllib.request.urlopen(url, timeout=5)


ONE_STATION = """
[network]
name = "one"
transmission_cycle = "2ms"

[[station]]
address = 0x21
card = "si-t3"
link = "ML2"
"""


def test_master_web_serves_a_master_whose_slave_runs_elsewhere(tmp_path) -> None:
    config = tmp_path / "one.toml"
    config.write_text(ONE_STATION)
    slave = Proc("slave", "--card", "si-t3", "--station", "21H", "--listen", "127.0.0.1:0",
                 "--allow-master", "127.0.0.1")
    try:
        port = slave.wait_line(re.compile(r"0x21@127\.0\.0\.1:(\d+)")).group(1)  # its log's "ready" line
        master = Proc("master", str(config), "--endpoint", f"0x21=127.0.0.1:{port}", "--no-timeline",
                      "--duration", "600s", "--no-status", "--no-realtime", "--web", "127.0.0.1:0")
        try:
            url = master.wait_line(re.compile(r"^web: (http://\S+)")).group(1)
            http = Http(url)
            rows = wait_for(lambda: [s for s in stations(http) if s["phase"] == 3], 30, "phase 3")
            assert [s["name"] for s in rows] == ["21H"]
            status, body = http.get("api/stations/21H/params/C1-01")
            check_response("/api/stations/{station}/params/{param}", "GET", status, body)
            assert status == 200 and body["param"]["unit"] == "s"  # read through the master from the slave
        finally:
            master.stop()
    finally:
        slave.stop()
