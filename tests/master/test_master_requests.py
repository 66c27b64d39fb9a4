"""Requests (PRM_RD, PRM_WR, CONFIG, ID_RD, ALM_RD, ALM_CLR, DISCONNECT, sub-commands) and bad input."""

from __future__ import annotations

import pytest
from master_fakes import MS

from mlink_sim.master import (
    Dropped,
    MasterCore,
    MasterDrop,
    NetworkPlan,
    RequestTimeout,
    StationAlarmError,
    StationDisconnected,
    StationPlan,
    StationState,
)
from mlink_sim.wire import DropReason, Frame, Kind, Link, Unknown, encode, ml2, ml3

S = StationState
ML2 = pytest.param(Link.ML2, ml2, id="ML-II")
ML3 = pytest.param(Link.ML3, ml3, id="ML-III")


def up(net_of, link, **plan):
    net = net_of(link, MS, StationPlan(0x21, link, **plan))
    net.run_until(net.core.all_at_target, limit=20)
    return net


def finish(net, req, limit=200):
    net.run_until(lambda: req.done, limit=limit)
    return req


@pytest.mark.parametrize(("link", "mod"), [ML2, ML3])
def test_si_t3_table_8_prm_rd_c1_01(net_of, link, mod):
    net = up(net_of, link)
    req = finish(net, net.core.request(0x21, mod.PrmRd(0x0200, 2)))
    assert req.error is None
    assert isinstance(req.result, mod.PrmRdResponse)
    assert int.from_bytes(req.result.parameter[:2], "little") == 100
    assert req.attempts == 1


@pytest.mark.parametrize(("link", "mod"), [ML2, ML3])
def test_si_t3_table_9_prm_wr_then_read_back(net_of, link, mod):
    net = up(net_of, link)
    w = finish(net, net.core.request(0x21, mod.PrmWr(0x0200, 2, (250).to_bytes(2, "little").ljust(8, b"\0"))))
    assert w.error is None
    r = finish(net, net.core.request(0x21, mod.PrmRd(0x0200, 2)))
    assert int.from_bytes(r.result.parameter[:2], "little") == 250


def test_si_t3_table_25_bad_register_fails_with_a94(net_of):
    net = up(net_of, Link.ML2)
    req = finish(net, net.core.request(0x21, ml2.PrmRd(0x7777, 2)))
    assert isinstance(req.error, StationAlarmError)
    assert (req.error.station, req.error.code, req.error.name) == (0x21, 0x94, "DATA_SETTING_WARNING")
    assert "94H" in str(req.error)
    assert net.core.state(0x21) is S.PHASE3  # a refused command does not disturb the connection


def test_si_et3_prm_rd_bad_register_fails_with_cmd_alm_9(net_of):
    net = up(net_of, Link.ML3)
    req = finish(net, net.core.request(0x21, ml3.PrmRd(0x7777, 2)))
    assert isinstance(req.error, StationAlarmError)
    assert (req.error.code, req.error.name) == (9, "INVALID_DATA")
    assert net.core.state(0x21) is S.PHASE3


def test_si_et3_unsupported_command_fails_with_cmd_alm_8(net_of):
    net = up(net_of, Link.ML3)
    req = finish(net, net.core.request(0x21, Unknown(0x33, bytes(28))))
    assert isinstance(req.error, StationAlarmError) and req.error.code == 8


FAKE_ONLY = pytest.mark.parametrize("slave_factory", ["fake"], indirect=True)  # the cards are never busy


@FAKE_ONLY
@pytest.mark.parametrize(("link", "mod"), [ML2, ML3])
def test_config_is_repeated_while_cmdrdy_busy(net_of, link, mod):
    net = up(net_of, link)
    net.slaves[0x21].busy_config = 4
    req = finish(net, net.core.request(0x21, mod.Config(1)))
    assert req.error is None and isinstance(req.result, mod.Config)
    assert req.busy == 4 and req.attempts == 5
    assert [n for n, _ in net.slaves[0x21].log].count("Config") == 5


@FAKE_ONLY
def test_busy_forever_times_out(net_of):
    net = up(net_of, Link.ML2)
    net.slaves[0x21].busy_config = 10_000
    req = finish(net, net.core.request(0x21, ml2.Config(1), timeout_ns=20 * MS))
    assert isinstance(req.error, RequestTimeout)
    assert req.error.busy >= 15 and "CONFIG" in str(req.error)


def test_request_never_answered_fails_after_request_retries(net_of):
    """A command the slave never answers (others it does) fails after ``request_retries`` silent sends instead of
    making the station look offline."""
    net = up(net_of, Link.ML2)
    req = net.core.request(0x21, ml2.PrmRd(0x0200, 2))
    first = net.cycle
    net.fault = lambda d, st, dg, now: None if d == "rsp" and net.cycle >= first and not req.done else dg
    finish(net, req, limit=10)
    assert isinstance(req.error, RequestTimeout) and req.error.attempts == 3 and "not answered" in str(req.error)
    net.run(5)
    assert net.core.state(0x21) is S.PHASE3


def test_request_to_absent_station_times_out(net_of):
    net = net_of(Link.ML2, MS, StationPlan(0x21, Link.ML2))
    del net.slaves[0x21]
    req = finish(net, net.core.request(0x21, ml2.PrmRd(0x0200, 2), timeout_ns=10 * MS))
    assert isinstance(req.error, RequestTimeout) and req.attempts == 0


def test_request_waits_for_bring_up(net_of):
    net = net_of(Link.ML3, MS, StationPlan(0x21, Link.ML3))
    req = net.core.request(0x21, ml3.IdRd(0x02, 0, 4))
    finish(net, req)
    assert req.error is None and net.core.state(0x21) is S.PHASE3
    assert [n for n, _ in net.slaves[0x21].log][:4] == ["Nop", "Connect", "SyncSet", "IdRd"]


@pytest.mark.parametrize(("link", "mod", "code", "want"), [
    (Link.ML2, ml2, 0x00, b"CIMR"),  # SI-T3 Table 10 DEVICE_CODE 00H: drive model in ASCII
    (Link.ML3, ml3, 0x10, b"\x20\x00"),  # SI-ET3 Table 14 ID_CODE 10H: profile type 0020H
])
def test_id_rd_alm_rd_alm_clr(net_of, link, mod, code, want):
    net = up(net_of, link)
    idr = finish(net, net.core.request(0x21, mod.IdRd(code, 0, 4)))
    assert idr.error is None and idr.result.id[:len(want)] == want
    alm = finish(net, net.core.request(0x21, mod.AlmRd(0)))
    assert isinstance(alm.result, mod.AlmRdResponse)
    clr = finish(net, net.core.request(0x21, mod.AlmClr(0)))
    assert clr.error is None


@pytest.mark.parametrize(("link", "mod"), [ML2, ML3])
def test_sub_command_prm_rd_alongside_inv_ctl(net_of, link, mod):
    net = up(net_of, link, subcmd=True)
    net.core.set_control(0x21, forward=True, speed_ref=3000)
    req = finish(net, net.core.request(0x21, mod.PrmRd(0x0200, 2), sub=True))
    assert int.from_bytes(req.result.parameter[:2], "little") == 100
    assert net.slaves[0x21].log[-1][0] == "InvCtl"  # the main command kept INV_CTL going
    bad = finish(net, net.core.request(0x21, mod.PrmWr(0x7777, 2), sub=True))
    assert isinstance(bad.error, StationAlarmError)
    assert bad.error.code == (9 if link is Link.ML3 else 0x94)


def test_sub_and_main_requests_respect_si_t3_table_7(net_of):
    """PRM_RD main + PRM_RD sub is "NG (A.95)": the master never puts them in one frame."""
    net = up(net_of, Link.ML2, subcmd=True)
    frames = []
    net.fault = lambda d, st, dg, now: (frames.append(dg) if d == "cmd" else None) or dg
    main = net.core.request(0x21, ml2.PrmRd(0x0180, 2))
    sub = net.core.request(0x21, ml2.PrmRd(0x0181, 2), sub=True)
    net.run_until(lambda: main.done and sub.done, limit=20)
    assert main.error is None and sub.error is None
    from mlink_sim.wire import decode

    for dg in frames:
        m = decode(dg).message
        assert not (type(m.body) is ml2.PrmRd and type(m.sub) is ml2.PrmRd)


def test_sub_requires_subcmd_in_plan(net_of):
    net = up(net_of, Link.ML2)
    with pytest.raises(ValueError, match="sub-commands are not enabled"):
        net.core.request(0x21, ml2.PrmRd(0x0200, 2), sub=True)


def test_v7_32_byte_prm_rd_goes_to_the_sub_command_by_default():
    """SI-T/V7 §7.1: in 32-byte mode PRM_RD/PRM_WR can be used only as sub-commands."""
    core = MasterCore(NetworkPlan(Link.ML2, MS, (StationPlan(0x21, Link.ML2, subcmd=True, card="SI-T/V7"),)))
    assert core.request(0x21, ml2.PrmRd(0x0200, 2)).sub is True
    core3 = MasterCore(NetworkPlan(Link.ML2, MS, (StationPlan(0x21, Link.ML2, subcmd=True, card="si-t3"),)))
    assert core3.request(0x21, ml2.PrmRd(0x0200, 2)).sub is False


def test_wrong_generation_body_and_managed_commands_are_refused():
    core = MasterCore(NetworkPlan(Link.ML2, MS, (StationPlan(0x21, Link.ML2),)))
    with pytest.raises(TypeError, match="not a MECHATROLINK-II main command"):
        core.request(0x21, ml3.PrmRd(0x0200, 2))
    with pytest.raises(ValueError, match="CONNECT is sent by the master core"):
        core.request(0x21, ml2.Connect(0x21, 2, 1))
    with pytest.raises(KeyError):
        core.request(0x99, ml2.Nop())


@pytest.mark.parametrize(("link", "mod"), [ML2, ML3])
def test_disconnect_then_connect(net_of, link, mod):
    net = up(net_of, link)
    req = finish(net, net.core.disconnect(0x21))
    assert req.error is None
    net.run(5)
    assert net.core.state(0x21) is S.PHASE1 and net.slaves[0x21].phase == 1
    assert net.core.at_target(0x21)  # a disconnected station's target is phase 1
    refused = net.core.request(0x21, mod.PrmRd(0x0200, 2))
    assert isinstance(refused.error, StationDisconnected)
    net.core.connect(0x21)
    net.run_until(lambda: net.core.state(0x21) is S.PHASE3, limit=20)
    assert net.slaves[0x21].phase == 3


@pytest.mark.parametrize("mutate", [
    pytest.param(lambda dg: dg[:-1] + bytes([dg[-1] ^ 0xFF]), id="bad-FCS"),
    pytest.param(lambda dg: dg[:10], id="too-short"),
    pytest.param(lambda dg: b"X" + dg[1:], id="bad-magic"),
])
def test_corrupt_response_is_counted_not_raised(net_of, mutate):
    net = up(net_of, Link.ML2)
    net.events.clear()
    when = net.cycle + 1
    net.fault = lambda d, st, dg, now: mutate(dg) if d == "rsp" and net.cycle == when else dg
    net.run(3)
    assert sum(net.core.drops.values()) == 1
    assert [e for e in net.events if isinstance(e, Dropped)]
    assert net.core.state(0x21) is S.PHASE3


def test_foreign_and_stray_responses_are_dropped_by_reason(net_of):
    net = up(net_of, Link.ML2)
    core = net.core
    stray = encode(Frame(Link.ML2, Kind.RESPONSE, 0x55, 1, MS, ml2.M2Response(ml2.Nop())))
    core.on_response(stray, 0)
    wrong_link = encode(Frame(Link.ML3, Kind.RESPONSE, 0x21, 1, MS, ml3.M3Response(ml3.Nop())))
    core.on_response(wrong_link, 0)
    old = encode(Frame(Link.ML2, Kind.RESPONSE, 0x21, 3, MS, ml2.M2Response(ml2.Nop(), sub=ml2.Nop())))
    core.on_response(old, 0)
    command = encode(Frame(Link.ML2, Kind.COMMAND, 0x21, 1, MS, ml2.M2Command(ml2.Nop())))
    core.on_response(command, 0)
    core.on_response(b"", 0)
    assert core.drops[MasterDrop.UNKNOWN_STATION] == 1
    assert core.drops[MasterDrop.WRONG_LINK] == 1
    assert core.drops[MasterDrop.NOT_EXPECTED] == 1
    assert core.drops[DropReason.WRONG_KIND] == 1
    assert core.drops[DropReason.TOO_SHORT] == 1


def test_disconnect_of_a_station_never_connected_completes_at_once():
    core = MasterCore(NetworkPlan(Link.ML2, MS, (StationPlan(0x21, Link.ML2),)))
    req = core.disconnect(0x21)
    assert req.done and req.error is None
    assert core.at_target(0x21)


def test_abort_requests_fails_everything_queued():
    core = MasterCore(NetworkPlan(Link.ML3, MS, (StationPlan(0x21, Link.ML3, subcmd=True),)))
    reqs = [core.request(0x21, ml3.PrmRd(0x0200, 2)), core.request(0x21, ml3.PrmRd(0x0200, 2), sub=True)]
    seen = []
    reqs[0].add_done_callback(seen.append)
    assert core.abort_requests("stopping") == 2
    assert all(isinstance(r.error, StationDisconnected) for r in reqs) and seen == [reqs[0]]


def test_duplicate_response_is_dropped(net_of):
    net = up(net_of, Link.ML2)
    copies = []
    net.fault = lambda d, st, dg, now: (copies.append(dg) if d == "rsp" else None) or dg
    net.run(1)
    net.core.on_response(copies[-1], net.cycle * MS)
    assert net.core.drops[MasterDrop.DUPLICATE] == 1


@pytest.mark.parametrize("slave_factory", ["card"], indirect=True)
@pytest.mark.parametrize(("link", "mod"), [ML2, ML3])
def test_config_to_eeprom_completes_only_once_the_card_reports_the_image_durable(net_of, link, mod):
    """The master repeats a CONFIG the card answers CMDRDY = 0 (SI-T3 "STATUS Field" "0 Busy", SI-ET3 CMD_STAT) and
    completes it only after the I/O layer reported the EEPROM image durable (docs/cards.md, "EEPROM")."""
    net = up(net_of, link)
    card = net.slaves[0x21].station
    card.eeprom.enabled = True
    req = net.core.request(0x21, mod.Config(1))
    net.run(20)
    assert not req.done and req.busy >= 10
    assert card.take_eeprom() is not None
    net.run(5)
    assert not req.done  # taken by the writer, not yet on disk
    card.eeprom_durable(card.eeprom.taken)
    finish(net, req, limit=5)
    assert req.error is None and net.core.state(0x21) is S.PHASE3
