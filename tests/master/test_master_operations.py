"""The requests the core builds by what they do (``core.prm_rd``, ``prm_wr``, ``config``, ``id_rd``, ``alm_rd``,
``alm_clr``, ``disconnect_all``; mlink_sim/master/operations.py), on explicit time: the body of the station's
generation, the padding, the name resolved to its register, the result the answer gives, the deadline from *now*.
The I/O layer only awaits these requests (mlink_sim/aio/master/runner.py)."""

from __future__ import annotations

import pytest
from master_fakes import MS

from mlink_sim.master import (
    ParamRequestError,
    ParamValue,
    RequestTimeout,
    StationPlan,
    StationState,
)
from mlink_sim.master.machine import CONNECTED, MAY_HOLD_CONNECTION
from mlink_sim.wire import Link, ml2, ml3

S = StationState
ML2 = pytest.param(Link.ML2, ml2, "si-t3", id="ML-II")
ML3 = pytest.param(Link.ML3, ml3, "si-et3", id="ML-III")


def up(net_of, link, card, *more, **options):
    net = net_of(link, MS, StationPlan(0x21, link, card=card), *more, **options)
    net.run_until(net.core.all_at_target, limit=20)
    return net


def finish(net, req, limit=200):
    net.run_until(lambda: req.done, limit=limit)
    assert req.done
    return req


@pytest.mark.parametrize(("link", "mod", "card"), [ML2, ML3])
def test_si_t3_table_8_prm_rd_by_name_is_built_and_read_by_the_core(net_of, link, mod, card):
    net = up(net_of, link, card)
    req = net.core.prm_rd(0x21, "C1-01", now=7 * MS)
    assert req.body == mod.PrmRd(0x0200, 2)  # C1-01 is MEMOBUS register 0200H (SI-T3 Table 4)
    assert (req.command, req.sub) == ("PRM_RD", False)
    assert req.deadline_ns == 7 * MS + net.core.plan.request_timeout_ns  # the timeout runs from *now*
    finish(net, req)
    assert isinstance(req.result, ParamValue)
    assert (float(req.result), req.result.unit, req.result.raw, req.result.register) == (10.0, "s", 100, 0x0200)


@pytest.mark.parametrize(("link", "mod", "card"), [ML2, ML3])
def test_a_register_by_number_gives_the_word_or_the_bytes(net_of, link, mod, card):
    net = up(net_of, link, card)
    assert finish(net, net.core.prm_rd(0x21, 0x0200)).result == 100
    word = finish(net, net.core.prm_rd(0x21, 0x0180)).result  # b1-01
    four = finish(net, net.core.prm_rd(0x21, 0x0180, size=4))  # b1-01, b1-02
    assert four.body == mod.PrmRd(0x0180, 4)
    assert type(four.result) is bytes and len(four.result) == 4 and four.result[:2] == word.to_bytes(2, "little")


@pytest.mark.parametrize(("link", "mod", "card"), [ML2, ML3])
def test_si_t3_table_9_prm_wr_data_is_padded_to_the_8_byte_field(net_of, link, mod, card):
    net = up(net_of, link, card)
    w = net.core.prm_wr(0x21, "C1-01", 5.0, now=3 * MS, timeout_ns=40 * MS)
    assert w.body == mod.PrmWr(0x0200, 2, b"\x32\x00" + bytes(6))  # 50 counts of 0.1 s, then zeros
    assert w.deadline_ns == 43 * MS
    assert finish(net, w).error is None
    assert float(finish(net, net.core.prm_rd(0x21, "C1-01")).result) == 5.0
    raw = net.core.prm_wr(0x21, 0x0200, -1)  # a raw int, two's complement in SIZE bytes
    assert raw.body.data == b"\xff\xff" + bytes(6)


def test_a_bad_name_or_value_is_refused_before_anything_is_queued(net_of):
    net = up(net_of, Link.ML2, "si-t3")
    core = net.core
    with pytest.raises(ParamRequestError, match="unknown parameter 'Z9-99'"):
        core.prm_rd(0x21, "Z9-99")
    with pytest.raises(ParamRequestError, match="out of range"):
        core.prm_wr(0x21, "C1-01", 7000.0)
    with pytest.raises(ParamRequestError, match="SIZE 3"):
        core.prm_rd(0x21, 0x0200, size=3)
    read = finish(net, core.prm_rd(0x21, "C1-01"))  # nothing queued ahead of it, nothing written
    assert (float(read.result), read.attempts) == (10.0, 1)


@pytest.mark.parametrize(("link", "mod", "card", "code", "want"), [
    pytest.param(Link.ML2, ml2, "si-t3", 0x00, b"CIMR", id="SI-T3 Table 10"),
    pytest.param(Link.ML3, ml3, "si-et3", 0x10, b"\x20\x00", id="SI-ET3 Table 14"),
])
def test_id_rd_gives_the_bytes_asked_for(net_of, link, mod, card, code, want):
    net = up(net_of, link, card)
    req = net.core.id_rd(0x21, code, 0, len(want))
    assert req.body == mod.IdRd(code, 0, len(want))
    assert finish(net, req).result == want


@pytest.mark.parametrize(("link", "mod", "card"), [ML2, ML3])
def test_config_alm_rd_and_alm_clr_bodies(net_of, link, mod, card):
    net = up(net_of, link, card)
    core = net.core
    config, alm_rd, alm_clr = core.config(0x21, 1), core.alm_rd(0x21, 0), core.alm_clr(0x21)
    assert (config.body, alm_rd.body, alm_clr.body) == (mod.Config(1), mod.AlmRd(0, 0), mod.AlmClr(0))
    for req in (config, alm_rd, alm_clr):
        assert finish(net, req).error is None
    assert alm_rd.result.alm_rd_mod == 0  # ALM_RD's result is the response body


def test_a_request_times_out_on_the_deadline_its_now_gave(net_of):
    net = up(net_of, Link.ML2, "si-t3")
    start = net.cycle * MS
    req = net.core.prm_rd(0x21, "C1-01", now=start, timeout_ns=5 * MS)
    net.cut.add(0x21)  # unplugged: nothing answers
    net.run(8)
    assert isinstance(req.error, RequestTimeout)


def test_disconnect_all_releases_the_stations_that_may_hold_a_connection(net_of):
    net = up(net_of, Link.ML2, "si-t3", StationPlan(0x22, Link.ML2, card="si-t3"))
    core = net.core
    net.cut.add(0x22)
    net.run_until(lambda: core.state(0x22) is S.OFFLINE, limit=100)
    reqs = core.disconnect_all(now=net.cycle * MS)
    assert [r.station for r in reqs] == [0x21]  # the offline one holds nothing
    for req in reqs:
        finish(net, req)
    assert core.state(0x21) is S.PHASE1 and all(r.error is None for r in reqs)


def test_connected_is_phase_2_or_3_and_a_connect_sent_may_hold_one():
    assert set(CONNECTED) == {s for s in S if s.phase >= 2}  # SI-ET3 Table 4 CON "Connection established"
    assert set(MAY_HOLD_CONNECTION) == set(CONNECTED) | {S.CONNECTING}
