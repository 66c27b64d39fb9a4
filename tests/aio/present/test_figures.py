"""Station figures (mlink_sim.aio.present.figures): one flat, JSON-safe dict per station from the master's view, its
monitors (SI-T3 Table 18, SI-ET3 Table 22, SI-T/V7 Table 5), the slave's snapshot and the cards' LED tables
(SI-T3 Table 3, SI-ET3 Table 4, SI-T/V7 §3.3), on a network of the virtual clock."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import pytest

from mlink_sim.aio.run.embed import VirtualNetwork
from mlink_sim.aio.present.figures import FIGURE_FIELDS, NetworkFigures, run_direction
from mlink_sim.config import load_config
from mlink_sim.jsonable import to_jsonable
from mlink_sim.master.types import StationState
from mlink_sim.wire import InvCmdStat, Link, M2Status

ROOT = Path(__file__).resolve().parents[3]
QUICKSTART = ROOT / "configs" / "quickstart.toml"
ML3_62 = ROOT / "mlink_sim" / "examples" / "ml3-62-max.toml"


@pytest.fixture(scope="module")
def running():
    """The quickstart with 21H forward at 30 Hz and 23H reverse at 20 Hz, 4 s after the run commands."""
    with VirtualNetwork(QUICKSTART, seed=1) as net:
        net.run(0x21, hz=30)
        net.run(0x22, hz=25)
        net.run(0x23, hz=20, direction="reverse")
        net.advance(4.0)
        figures = NetworkFigures(load_config(QUICKSTART))
        for _ in range(3):  # every station's RTT figures refreshed once at least
            plain = figures.stations(net.session.net, net.session.metrics)
        snapshots = {a: to_jsonable(s) for a, s in net.snapshots().items()}
        with_slaves = figures.stations(net.session.net, net.session.metrics, snapshots)
        views = net.views()
        yield {"plain": {r["address"]: r for r in plain}, "slaves": {r["address"]: r for r in with_slaves},
               "figures": figures, "net": net, "views": views, "snapshots": snapshots}


def test_every_station_has_every_figure_in_order_and_json_safe(running):
    for row in running["plain"].values():
        assert tuple(row) == FIGURE_FIELDS
        assert json.loads(json.dumps(row)) == row


def test_the_master_view_gives_phase_run_state_and_output(running):
    a, v7, et3 = running["plain"]["0x21"], running["plain"]["0x22"], running["plain"]["0x23"]
    assert (a["name"], a["card"], a["link"]) == ("21H", "si-t3", "ML2")
    assert (et3["link"], et3["card"]) == ("ML3", "si-et3")
    for row in (a, v7, et3):
        assert row["phase"] == 3 and row["connected"] and row["running"] and row["alarm"] is None
        assert row["rtt_p50_us"] is not None and 0 < row["rtt_p50_us"] <= row["rtt_p99_us"]
        assert row["missed"] == 0
    assert a["direction"] == "forward" and a["output_hz"] == pytest.approx(30, abs=0.1)
    assert v7["output_hz"] == pytest.approx(25, abs=0.1)
    assert et3["direction"] == "reverse" and et3["output_hz"] == pytest.approx(-20, abs=0.1)  # reverse: below 0
    assert a["output_current_a"] > 0


def test_the_default_monitors_give_reference_and_motor_speed_on_the_a1000_cards(running):
    """SEL_MON 41H: MON1 motor speed U1-05, MON2 frequency reference U1-01 (SI-T3 Table 18, SI-ET3 Table 22);
    rpm = Hz x 60 / pole pairs (4 poles: 30 Hz less slip, under 900 r/min)."""
    a, et3 = running["plain"]["0x21"], running["plain"]["0x23"]
    assert a["reference_hz"] == pytest.approx(30, abs=0.01)
    assert 800 < a["motor_speed_rpm"] <= 900
    assert et3["reference_hz"] == pytest.approx(-20, abs=0.01)  # U1-01, signed by the reverse run command
    assert -600 <= et3["motor_speed_rpm"] < -500  # U1-05 is signed
    assert a["dc_bus_v"] is None and et3["dc_bus_v"] is None  # not selected, and no snapshot


def test_the_latest_round_trip_and_the_regulation_from_the_slaves_snapshot(running):
    """``rtt_us``: the master's latest round trip; ``regulation``: the names of the snapshot's code
    (drive.activity.REGULATION), null without a snapshot."""
    a = running["plain"]["0x21"]
    assert a["rtt_us"] is not None and 0 < a["rtt_us"] < 10_000 and a["regulation"] is None
    view = running["views"][0x21]
    figures = running["figures"].by_address[0x21]
    assert figures.of(view, snapshot={"regulation": 0})["regulation"] == ()
    assert figures.of(view, snapshot={"regulation": 2})["regulation"] == ("stall-decel",)
    assert figures.of(view, snapshot={"regulation": 5})["regulation"] == ("stall-accel", "torque-limit")


def test_a_reverse_run_reads_below_0_hz_and_the_reference_keeps_its_sign_once_stopped():
    """The output by the response's run direction (SI-T3 STATUS REV), the reference by the master's run command:
    a reverse run plots below the axis; stopped, the reference keeps the last run command's sign."""
    with VirtualNetwork(QUICKSTART, seed=1) as net:
        figures = NetworkFigures(load_config(QUICKSTART))
        net.run(0x21, hz=20, direction="reverse")
        net.advance(3.0)
        row = figures.station(0x21, net.session.net)
        assert row["direction"] == "reverse" and row["output_hz"] == pytest.approx(-20, abs=0.1)
        assert row["reference_hz"] == pytest.approx(-20, abs=0.01) and row["motor_speed_rpm"] < 0
        net.stop(0x21)
        net.advance(3.0)
        row = figures.station(0x21, net.session.net)
        assert row["direction"] is None and row["output_hz"] == 0 and row["reference_hz"] == pytest.approx(-20)


def test_the_si_t_v7_has_no_motor_speed_monitor_the_slave_snapshot_fills_it_in(running):
    """SI-T/V7 Table 5: SEL_MON 1 is the output frequency U-02, so the motor speed comes from the slave."""
    plain, slaves = running["plain"]["0x22"], running["slaves"]["0x22"]
    assert plain["motor_speed_rpm"] is None and plain["reference_hz"] == pytest.approx(25, abs=0.01)
    drive = running["snapshots"][0x22]["drive"]
    assert slaves["motor_speed_rpm"] == pytest.approx(drive["motor_rpm"], abs=0.01)
    assert slaves["dc_bus_v"] == pytest.approx(drive["dc_bus_v"], abs=0.01) and slaves["dc_bus_v"] > 200


def test_the_leds_follow_the_cards_tables(running):
    """SI-T3 Table 3 / SI-T/V7 §3.3: RUN on, ERR off, TX/RX lit while data flows; SI-ET3 Table 4: R/E green, CON
    lit with a connection, LK1 lit while frames arrive, LK2 unlit (one port). The cards' own LEDs agree."""
    plain = running["plain"]
    for key in ("0x21", "0x22"):
        assert plain[key]["leds"] == {"RUN": "on", "ERR": "off", "TX": "on", "RX": "on"}
    assert plain["0x23"]["leds"] == {"R/E": "on", "CON": "on", "LK1": "on", "LK2": "off"}
    assert plain["0x23"]["led_colors"]["R/E"] == "green"
    for address, snap in running["snapshots"].items():
        key = f"0x{address:02x}"
        assert snap["leds"] == plain[key]["leds"] and snap["led_colors"] == plain[key]["led_colors"]


def _figures_of(running, address, **changes):
    view = dataclasses.replace(running["views"][address], **changes)
    return running["figures"].by_address[address].of(view)


def test_an_ml2_communication_alarm_is_the_alarm_and_lights_err(running):
    """SI-T3 Table 23: E6H COMM_ERROR is an alarm; Table 3: ERR on for a communication error."""
    row = _figures_of(running, 0x21, alarm=0xE6, alarm_name="COMM_ERROR", fault=True, state=StationState.ALARM)
    assert row["alarm"] == {"code": "E6H", "name": "COMM_ERROR"} and row["leds"]["ERR"] == "on"


def test_an_ml2_warning_code_is_a_warning_not_an_alarm(running):
    """SI-T3 Table 25: A.94 (94H) with STATUS.WARNG is a warning; ERR stays off."""
    row = _figures_of(running, 0x21, alarm=0x94, alarm_name="DATA_SETTING_WARNING", warning=True)
    assert row["alarm"] is None and row["warnings"] == ["DATA_SETTING_WARNING"] and row["leds"]["ERR"] == "off"


def test_ml3_comm_alarms_and_warnings_and_the_red_r_e_led(running):
    """SI-ET3 "COMM_ALM": 8H–CH alarms, 1H–3H warnings; Table 4: R/E lit in red for an error/alarm."""
    row = _figures_of(running, 0x23, comm_alm=0x9)
    assert row["alarm"] == {"code": "COMM_ALM 9H", "name": "NOT_RECEIVED"} and row["led_colors"]["R/E"] == "red"
    row = _figures_of(running, 0x23, comm_alm=0x2)
    assert row["alarm"] is None and row["warnings"] == ["NOT_RECEIVED_WARNING"]
    assert row["led_colors"]["R/E"] == "green"


def test_an_offline_station_has_its_leds_out_and_no_output(running):
    row = _figures_of(running, 0x23, state=StationState.OFFLINE, phase=0)
    assert row["leds"] == {"R/E": "off", "CON": "off", "LK1": "off", "LK2": "off"}
    assert not row["connected"] and row["output_hz"] is None and row["reference_hz"] is None


def test_a_station_the_master_does_not_reach_shows_the_cards_own_leds(running):
    """SI-T/V7 §3.3: a station address setting error blinks ERR; the master never hears from such a station, its
    slave's snapshot says what the card shows."""
    view = dataclasses.replace(running["views"][0x22], state=StationState.OFFLINE, phase=0)
    snapshot = {**running["snapshots"][0x22], "leds": {"RUN": "off", "ERR": "blink", "TX": "off", "RX": "on"}}
    row = running["figures"].by_address[0x22].of(view, snapshot=snapshot)
    assert row["leds"] == {"RUN": "off", "ERR": "blink", "TX": "off", "RX": "on"}


def test_the_direction_of_a_status_word():
    assert run_direction(Link.ML2, int(M2Status.RUNX)) == "forward"
    assert run_direction(Link.ML2, int(M2Status.RUNX | M2Status.REV)) == "reverse"
    assert run_direction(Link.ML2, int(M2Status.REV)) is None  # REV without RUNX: stopped
    assert run_direction(Link.ML3, int(InvCmdStat.REVERSE)) == "reverse"
    assert run_direction(Link.ML3, 0) is None


def test_62_stations_of_figures_fit_one_status_datagram():
    """The status reply stays one datagram (60,000 bytes) at 62 ML-III stations."""
    with VirtualNetwork(ML3_62, seed=1) as net:
        net.advance(0.2)
        rows = NetworkFigures(load_config(ML3_62)).stations(net.session.net, net.session.metrics)
    assert len(rows) == 62
    assert len(json.dumps(rows, separators=(",", ":"))) < 30_000
