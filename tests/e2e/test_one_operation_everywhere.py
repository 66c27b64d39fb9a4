"""One scenario driven through the four surfaces — the Python API (:class:`~mlink_sim.testing.RunningNetwork`), the
pytest plugin's fixture (here on the virtual clock), the command line (``mlink-sim control``) and the HTTP API (``up
--web``) — gives the same results: the same parameter written and entered (PRM_WR then CONFIG: the 1 s ramp takes
effect), the same output frequency after the run, the same refusals with the same kinds and messages (a speed
beyond E1-04, an A1000 name on the VS-606V7, a station the network does not have). Every surface performs the
operations of one table through one set of handlers (docs/control.md)."""

from __future__ import annotations

import json
import time
from collections.abc import Callable
from typing import Any

import pytest

from mlink_sim.operations import OpError
from mlink_sim.testing import RunningNetwork

from ..web.webnet import Http, up_with_web
from .conftest import run_cli

pytestmark = pytest.mark.e2e

Result = tuple[str, Any]  #: ("ok", what the scenario reads of the reply) or (error kind, message)


def _scenario(do: Callable[..., Result], wait: Callable[[float], None], output_hz: Callable[[], float]) -> list[Any]:
    """The scenario on one surface: *do(op, **args)* performs an operation, *wait* lets the network run."""
    out: list[Any] = [do("set-param", station="21H", param="C1-01", value=1.0),
                      do("get-param", station="21H", param="C1-01")]
    out.append(do("run", station="21H", hz=30.0))
    wait(1.2)  # at C1-01 = 1.0 s per E1-04 = 60 Hz, 30 Hz is reached after 0.5 s (10 s ramp: 3 Hz by then)
    out.append(("output", round(output_hz())))
    out += [do("run", station="21H", hz=450.0), do("get-param", station="22H", param="C1-01"),
            do("stop", station="99H"), do("stop", station="21H")]
    return out


def _param(reply: dict[str, Any]) -> Any:
    """What the scenario compares of a success: a parameter's row, else the station the reply is about."""
    if "param" in reply:
        return reply["param"]
    return {"address": reply["station"]["address"]}


def _python(net: Any) -> list[Any]:
    def do(op: str, **args: Any) -> Result:
        try:
            if op in ("set-param", "get-param"):
                value = getattr(net, op.replace("-", "_"))(**args)
                return "ok", {"name": value.name, "value": float(value), "unit": value.unit, "raw": value.raw,
                              "register": f"{value.register:04X}H", "text": value.text}
            return "ok", _param(getattr(net, op.replace("-", "_"))(**args))
        except OpError as exc:
            return exc.kind, str(exc)

    return _scenario(do, net.wait, lambda: net.output_hz(0x21))


@pytest.fixture(scope="module")
def python_result() -> list[Any]:
    with RunningNetwork("quickstart") as net:
        return _python(net)


@pytest.fixture(scope="module")
def web_network() -> Any:
    proc, url = up_with_web("--control", "127.0.0.1:0")
    control = proc.wait_line(__import__("re").compile(r"^control: (\S+:\d+) ")).group(1)
    yield Http(url), control
    proc.stop()


@pytest.mark.mlink_network("quickstart", clock="virtual")
def test_the_python_api_the_plugin_the_cli_and_http_agree(mlink_network, python_result, web_network) -> None:
    plugin = _python(mlink_network)
    http, control = web_network

    def cli(op: str, **args: Any) -> Result:
        argv = ["control", control, op, str(args.pop("station"))]
        if "param" in args:
            argv.append(args.pop("param"))
        if "value" in args:
            argv.append(str(args.pop("value")))
        argv += [x for k, v in args.items() for x in (f"--{k}", str(v))]
        reply = json.loads(run_cli(*argv).stdout)
        return ("ok", _param(reply)) if reply["ok"] else (reply["kind"], reply["error"])

    def web(op: str, **args: Any) -> Result:
        station = args.pop("station")
        if op == "get-param":
            status, body = http.get(f"api/stations/{station}/params/{args['param']}")
        elif op == "set-param":
            name = args.pop("param")
            status, body = http.request("PUT", f"api/stations/{station}/params/{name}", args)
        else:
            status, body = http.post(f"api/stations/{station}/{op}", args)
        return ("ok", _param(body)) if status == 200 else (body["kind"], body["error"])

    def cli_output() -> float:
        out = run_cli("control", control, "status").stdout
        return float(next(s for s in json.loads(out)["stations"] if s["address"] == "0x21")["output_hz"])

    through_cli = _scenario(cli, time.sleep, cli_output)
    through_web = _scenario(web, time.sleep, cli_output)
    assert python_result == plugin == through_cli == through_web
    written, read, run, output, too_fast, foreign, unknown, stop = python_result
    assert written == read == ("ok", {"name": "C1-01", "value": 1.0, "unit": "s", "raw": 10, "register": "0200H",
                                      "text": "1.0 s"})
    assert run[0] == stop[0] == "ok" and output == ("output", 30)
    assert too_fast == ("out_of_range", "hz: 450 Hz is outside 0…60 Hz, the maximum output frequency of station 21H "
                                        "(E1-04)")
    assert foreign[0] == "unknown_param" and "the VS-606V7's is n019" in foreign[1]
    assert unknown == ("unknown_station", "station 99H is not a station of this network (21H, 22H, 23H)")
