"""mlink_sim.plots: the one plotting vocabulary of the HTML report and the live page holds the drive's regulation
states by their names (drive.activity.REGULATION), a colour and a legend for every mark and band, and is what the
web server serves the page (``/plots.json``)."""

from __future__ import annotations

import json

from mlink_sim.drive.activity import REGULATION
from mlink_sim.metrics.trace import FIGURE_COLUMNS
from mlink_sim.plots import BANDS, MARKS, REGULATION_BANDS, STATION_PLOTS, mark_kind, vocabulary


def test_the_bands_are_the_drives_regulation_states_and_the_faults() -> None:
    assert REGULATION_BANDS == tuple(name for _, name, _, _ in REGULATION)
    assert set(BANDS) == {*REGULATION_BANDS, "fault"}
    for entry in (*BANDS.values(), *MARKS.values()):
        assert entry["color"].startswith("#") and entry["label"]


def test_each_plotted_series_is_a_figure_the_trace_records() -> None:
    keys = [s["key"] for plot in STATION_PLOTS for s in plot["series"]]
    assert keys == ["reference_hz", "output_hz", "output_current_a", "dc_bus_v"]
    assert set(keys) <= set(FIGURE_COLUMNS)


def test_a_trace_action_is_marked_by_its_kind() -> None:
    assert mark_kind("check", "ok 3s station 21H: expect running: running=True") == "check-ok"
    assert mark_kind("check", "FAIL 3s station 21H: expect running: running=False") == "check-fail"
    assert mark_kind("step", "0.2s all stations: do run forward 30 Hz") == "action"
    assert mark_kind("impair-start", "loss-21H-1: loss 5%") == "fault"
    assert mark_kind("fault-end", "silence-21H-1: silence for=200ms") is None  # a band's edge, not a mark


def test_the_vocabulary_is_json_and_the_web_server_serves_it() -> None:
    from aiohttp.test_utils import TestClient, TestServer

    from mlink_sim.web.api import Control
    from mlink_sim.web.server import build_app

    assert json.loads(json.dumps(vocabulary())) == vocabulary()

    async def fetch() -> dict:
        async with TestClient(TestServer(build_app(Control("127.0.0.1", 9), background=None))) as client:
            response = await client.get("/plots.json")
            assert response.status == 200
            return await response.json()

    import asyncio

    assert asyncio.run(fetch()) == vocabulary()
