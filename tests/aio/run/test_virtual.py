"""The virtual-clock driver (mlink_sim.aio.run.virtual_session, mlink_sim.aio.run.embed): the real master, cards and
report on simulated time over the in-memory network, deterministic for a seed."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from mlink_sim import _accel
from mlink_sim.aio.run.embed import VirtualNetwork
from mlink_sim.aio.run.virtual_session import without_wall_clock
from mlink_sim.cards.base import SLOW
from mlink_sim.config import load_config
from mlink_sim.master import StationAlarmError
from mlink_sim.master.core import MasterCore
from mlink_sim.metrics import REPORT_SCHEMA

ROOT = Path(__file__).resolve().parents[3]
QUICKSTART = ROOT / "configs" / "quickstart.toml"
C1_01 = 0x0200  # SI-T3 Tables 8/9: C1-01 acceleration time 1 at register 0200H (0.1 s units)
US = 1_000


def _config(tmp_path: Path, network_extra: str) -> Path:
    text = QUICKSTART.read_text().replace('transmission_cycle = "2ms"', 'transmission_cycle = "2ms"\n' + network_extra)
    path = tmp_path / "net.toml"
    path.write_text(text)
    return path


def _run_two_seconds(seed: int, impair: str | None = None) -> dict:
    with VirtualNetwork(QUICKSTART, seed=seed) as net:
        net.run(0x21, hz=30)
        net.run(0x23, hz=10, direction="reverse")
        if impair:
            net.advance(0.5)
            net.impair("all", impair)
        net.advance(2.0)
    assert net.final_report is not None
    return without_wall_clock(net.final_report)


def test_bring_up_and_the_master_api_work_as_on_the_real_clock():
    with VirtualNetwork(QUICKSTART) as net:
        assert {v.phase for v in net.views().values()} == {3}
        assert net.now < 0.1  # bring-up takes a few cycles of simulated time
        assert net.prm_rd(0x21, C1_01) == 20  # 2.0 s, as the config sets it
        with pytest.raises(StationAlarmError) as err:
            net.prm_rd(0x21, 0x7FFF)  # no such register: A.94 (SI-T3 Table 23)
        assert err.value.code == 0x94
        net.prm_wr(0x21, C1_01, 35)
        net.send_config(0x21)  # CONFIG: enter the written value (SI-T3 Table 12)
        assert net.prm_rd(0x21, C1_01) == 35
        assert net.alm_rd(0x21) is not None
        net.run(0x21, hz=30)
        net.advance(3.0)
        assert net.running(0x21) and net.output_hz(0x21) == pytest.approx(30, abs=0.1)
        assert net.station(0x21).snapshot().drive.output_hz == pytest.approx(30, abs=0.1)  # the slave side
        net.stop(0x21)
        net.advance(5.0)
        assert not net.running(0x21) and net.output_hz(0x21) < 0.5


def test_rtts_come_from_the_network_model(tmp_path):
    with VirtualNetwork(_config(tmp_path, 'latency = "300us"\njitter = "0us"')) as net:
        net.advance(1.0)
        rtt = net.report()["rtt"]
    assert 1497 <= rtt["count"] <= 1500  # 3 stations, 500 cycles; the last cycle's answers may be in flight
    assert rtt["min"] == pytest.approx(600 * US, rel=1e-3) and rtt["max"] == pytest.approx(600 * US, rel=1e-3)
    with VirtualNetwork(QUICKSTART) as net:  # defaults: 50 us ± 10 us each way
        net.advance(1.0)
        rtt = net.report()["rtt"]
    assert 80 * US * 0.999 <= rtt["min"] < rtt["max"] <= 120 * US * 1.001


def test_the_report_says_which_clock_made_it_and_fits_the_schema():
    jsonschema = pytest.importorskip("jsonschema")
    with VirtualNetwork(QUICKSTART, seed=4) as net:
        net.advance(0.5)
        report = net.report()
    jsonschema.validate(report, REPORT_SCHEMA)
    meta = report["meta"]
    assert meta["clock"] == "virtual" and meta["seed"] == 4
    assert meta["network_model"] == {"latency_ns": 50_000, "jitter_ns": 10_000}
    assert meta["duration_s"] == pytest.approx(0.5, abs=0.003)
    assert meta["wall"]["speedup"] > 0
    assert report["missed"] == 0 and report["lateness"]["max"] == 0  # the virtual cycle is never late


def test_same_seed_same_report_and_another_seed_differs_only_in_the_drawn_delays():
    a, b = _run_two_seconds(7), _run_two_seconds(7)
    assert json.dumps(a, sort_keys=True) == json.dumps(b, sort_keys=True)
    c = _run_two_seconds(8)

    def without_rtt(report):
        out = {k: v for k, v in report.items() if k != "rtt"}
        out["station"] = {k: {f: v for f, v in s.items() if f != "rtt"} for k, s in report["station"].items()}
        out["meta"] = {k: v for k, v in report["meta"].items() if k != "seed"}
        return out

    assert c["rtt"] != a["rtt"]
    assert without_rtt(c) == without_rtt(a)


def test_same_seed_same_report_with_impairments_and_another_seed_draws_other_faults():
    """docs/faults.md: every draw of the impairment layer comes from the seed."""
    impair = "loss=3%,corrupt=1%,duplicate=1%,reorder=0.5%,delay=300us,jitter=200us,for=1s"
    a, b = _run_two_seconds(5, impair), _run_two_seconds(5, impair)
    assert json.dumps(a, sort_keys=True) == json.dumps(b, sort_keys=True)
    injected = a["station"]["0x21"]["injected"]
    assert all(injected[k] > 0 for k in ("drops", "corruptions", "duplicates", "delays"))
    assert a["station"]["0x21"]["reception_failures"] > 0
    c = _run_two_seconds(6, impair)
    assert c["station"] != a["station"]


@pytest.mark.skipif(_accel.MODE == "compiled", reason="counts by wrapping core methods, which compiled (mypyc) classes "
                    "refuse; runs in CI's pure pass (MLINK_PURE=1), tests/test_accel.py pins the two")
def test_the_real_time_fast_paths_carry_the_cyclic_traffic(monkeypatch):
    counts = {"card_fast": 0, "card_slow": 0, "master_fast": 0}
    from mlink_sim.cards.ml2_card import Ml2Station
    from mlink_sim.cards.si_et3 import SiEt3

    def counting(cls):
        original = cls._fast_receive

        def wrapper(self, dg, source, now):
            out = original(self, dg, source, now)
            counts["card_slow" if out is SLOW else "card_fast"] += 1
            return out

        monkeypatch.setattr(cls, "_fast_receive", wrapper)

    counting(Ml2Station)
    counting(SiEt3)
    original_response = MasterCore._fast_response

    def fast_response(self, datagram, now):
        taken = original_response(self, datagram, now)
        counts["master_fast"] += bool(taken)
        return taken

    monkeypatch.setattr(MasterCore, "_fast_response", fast_response)
    with VirtualNetwork(QUICKSTART) as net:
        net.advance(1.0)
    assert counts["card_fast"] > 1400 and counts["master_fast"] > 1400  # ~500 cycles × 3 stations
    assert counts["card_slow"] < 100  # bring-up and the odd request only


def test_step_is_one_transmission_cycle_and_a_snapshot_shows_both_sides():
    with VirtualNetwork(QUICKSTART) as net:
        before = net.report()["cycles"]
        first = net.snapshot()
        t0 = net.now_ns
        net.step()
        assert net.now_ns - t0 == 2_000_000
        assert net.report()["cycles"] == before + 1
        snap = net.snapshot()
        assert snap.cycle == first.cycle + 1 and snap.t_s == pytest.approx(first.t_s + 0.002)
        assert set(snap.views) == set(snap.stations) == {0x21, 0x22, 0x23}
        assert snap.views[0x21].phase == snap.stations[0x21].phase == 3


def test_a_killed_station_comes_back_after_half_a_second():
    with VirtualNetwork(QUICKSTART) as net:
        assert net.kill_slave(0x22)
        assert net.station(0x22) is None
        net.advance(0.3)
        assert not net.view(0x22).at_target
        net.advance(3.0)
        assert net.view(0x22).at_target and net.station(0x22) is not None
        assert any("22H was killed" in p for p in net.session.problems)
        assert net.report()["station"]["0x22"]["missing"] > 0


def test_the_timeline_runs_on_simulated_time_and_its_checks_reach_the_report():
    with VirtualNetwork(QUICKSTART) as net:
        checks = net.run_timeline()
        assert net.now == pytest.approx(10.008, abs=0.01)  # the last step at 10 s after bring-up
    assert checks and all(c.ok for c in checks)
    assert len(net.final_report["checks"]) == len(checks)


def test_a_config_object_and_bad_jitter(tmp_path):
    config = load_config(QUICKSTART)
    with VirtualNetwork(config, bring_up=False) as net:
        assert not any(v.at_target for v in net.views().values())
    from mlink_sim.config import ConfigError

    with pytest.raises(ConfigError, match="jitter"):
        load_config(_config(tmp_path, 'latency = "10us"\njitter = "20us"'))
