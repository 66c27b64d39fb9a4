"""Parameters by name and the decoded station view through the virtual network (VirtualNetwork, the real master
and cards on simulated time): PRM_RD/PRM_WR by name on each card, one clear error before anything is sent, and no
stray "Task exception was never retrieved"."""

from __future__ import annotations

import gc
from pathlib import Path

import pytest

from mlink_sim.aio.run.embed import VirtualNetwork
from mlink_sim.master import ParamRequestError, ParamValue
from mlink_sim.wire import ml3

QUICKSTART = Path(__file__).resolve().parents[3] / "configs" / "quickstart.toml"


@pytest.fixture(scope="module")
def net():
    with VirtualNetwork(QUICKSTART, seed=1) as net:
        yield net


def test_prm_rd_by_name_on_each_card(net):
    c1 = net.prm_rd(0x21, "C1-01")  # SI-T3 Tables 8/9: C1-01 at 0200H; the config sets 2.0 s
    assert isinstance(c1, ParamValue) and c1 == 2.0 and c1.unit == "s" and c1.raw == 20 and str(c1) == "2.0 s"
    assert net.prm_rd(0x23, "C1-01") == 2.0  # SI-ET3 §9 PRM_RD example register 0200H
    n019 = net.prm_rd(0x22, "n019")  # SI-T/V7: the VS-606V7 constants
    assert (float(n019), n019.register) == (2.0, 0x0113)
    assert net.prm_rd(0x21, 0x0200) == 20  # a register number: the raw count


def test_prm_wr_by_name_converts_and_takes_effect(net):
    net.prm_wr(0x21, "C1-02", 3.5)
    net.send_config(0x21)
    assert net.prm_rd(0x21, "C1-02") == 3.5 and net.prm_rd(0x21, 0x0201) == 35
    net.prm_wr(0x22, "n020", 1.0)  # the V7's PRM_WR goes as the sub-command on 32-byte frames (V7 §7.1)
    assert net.prm_rd(0x22, "n020") == 1.0


def test_a_wrong_name_or_value_raises_before_anything_is_sent_without_a_stray_traceback(net):
    loop_errors: list[dict] = []
    net.loop.set_exception_handler(lambda loop, context: loop_errors.append(context))
    sent = net.view(0x23).sent
    with pytest.raises(ParamRequestError, match=r"station 23H \(SI-ET3\): unknown parameter 'C9-99'"):
        net.prm_rd(0x23, "C9-99")
    with pytest.raises(ParamRequestError, match=r"7000.0 s is out of range 0.0 … 6000.0 s") as err:
        net.prm_wr(0x23, "C1-01", 7000.0)
    assert (err.value.station, err.value.name, err.value.allowed) == (0x23, "C1-01", "0.0 … 6000.0 s")
    # a body the layout cannot carry (a name where the register number goes) is refused when it is made,
    # not in the cycle, where it stopped the clock's task
    with pytest.raises(ValueError, match="PrmRd cannot be sent"):
        net.call(net.net.master(0x23).request(0x23, ml3.PrmRd("C1-01", 2)))
    net.step(5)
    gc.collect()  # a task that died unretrieved would report itself now
    assert loop_errors == []
    assert net.view(0x23).sent > sent  # the cycle goes on
    assert net.prm_rd(0x23, "C1-01") == 2.0


def test_view_decodes_output_hz_and_status_bits(net):
    net.run(0x21, hz=30)
    net.advance(3.0)
    view = net.view(0x21)
    assert view.output_hz == round(view.output_freq * 0.01, 2) == net.output_hz(0x21)  # o1-03 = 0: 0.01 Hz
    assert view.output_hz == pytest.approx(30, abs=0.1)
    assert {"RUNX", "AGREE", "CMDRDY"} <= set(view.status_bits) and view.bit("AGREE")
    assert view.alarm_text is None
    assert "FORWARD" not in net.view(0x23).status_bits  # SI-ET3 INVCMD_STAT: not running
    net.stop(0x21)


def test_a_call_cut_short_by_the_loop_leaves_no_unretrieved_task():
    """Should the loop stop on an error of its own (here: a body put in the queue past the request's checks, which
    the cycle cannot encode), the call raises that error, and the request's own failure later (at close) is
    collected: no "Task exception was never retrieved"."""
    from mlink_sim.master.types import Request

    loop_errors: list[dict] = []
    with VirtualNetwork(QUICKSTART, seed=1) as net:
        net.loop.set_exception_handler(lambda loop, context: loop_errors.append(context))
        slave = net.net.master(0x23).core._station(0x23)
        bad = ml3.PrmRd("C1-01", 2)  # type: ignore[arg-type]
        slave.main_q.append(Request(0x23, bad, False, "PRM_RD", 1, net.now_ns + 10**9))
        with pytest.raises(ValueError, match="PrmRd"):
            net.prm_rd(0x23, "C1-02")
    gc.collect()
    assert [c for c in loop_errors if "never retrieved" in c.get("message", "")] == []
