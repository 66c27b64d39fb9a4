"""The master's answer window (``NetworkPlan.answer_window_ns``), the master side of the host-stall policy
"absorb" (docs/timing.md, "Host stalls"): a slave process that was held up answers late but completely, and no
command counts as missing; a real loss is still found, only later."""

from __future__ import annotations

from master_fakes import MS

from mlink_sim.master import Late, Missing, Rtt, StateChanged, StationPlan, StationState
from mlink_sim.wire import Link

S = StationState


def up(net_of, **options):
    net = net_of(Link.ML2, MS, StationPlan(0x21, Link.ML2), **options)
    net.run_until(net.core.all_at_target, limit=30)
    net.events.clear()
    return net


def hold_up_responses(net, cycles, until_ns):
    """The slave's answers of *cycles* cycles leave only at *until_ns* (a worker process stalled meanwhile)."""
    first = net.cycle
    net.fault = lambda d, st, dg, now: ((dg, until_ns - now) if d == "rsp" and first <= net.cycle < first + cycles
                                        else dg)


def of(net, kind):
    return [e for e in net.events if isinstance(e, kind)]


def test_a_held_up_slave_costs_no_command_within_the_window(net_of):
    net = up(net_of, answer_window_ns=50 * MS)
    hold_up_responses(net, 8, (net.cycle + 9) * MS)  # 8 answers, the oldest 9 ms late
    net.run(30)
    assert of(net, Missing) == []
    assert max(e.ns for e in of(net, Rtt)) >= 8 * MS  # the delay shows in the RTT
    view = net.core.view(0x21)
    assert view.missing == 0 and view.state is S.PHASE3 and not of(net, StateChanged)


def test_strict_counts_the_same_hold_up_as_missing(net_of):
    net = up(net_of)  # answer_window_ns = 0: as a MECHATROLINK master judges
    hold_up_responses(net, 8, (net.cycle + 9) * MS)
    net.run(30)
    assert len(of(net, Missing)) >= 7


def test_a_real_loss_is_still_missing_once_the_window_has_passed(net_of):
    net = up(net_of, answer_window_ns=10 * MS)
    first = net.cycle
    net.fault = lambda d, st, dg, now: None if d == "rsp" and first <= net.cycle < first + 3 else dg
    net.run(8)
    assert of(net, Missing) == []  # still within the window
    net.run(10)
    assert [e.cycle for e in of(net, Missing)] == [first, first + 1, first + 2]
    assert net.core.state(0x21) is S.PHASE3


def test_a_dead_station_goes_offline_after_the_window(net_of):
    net = up(net_of, answer_window_ns=10 * MS)
    net.cut.add(0x21)
    net.run(8)
    assert net.core.state(0x21) is S.PHASE3  # not yet judged
    net.run(30)
    assert net.core.state(0x21) is S.OFFLINE


def test_on_rtt_takes_the_round_trips_instead_of_rtt_events(net_of):
    """``MasterCore.on_rtt``: the same round trips, as calls, and no Rtt event; a late answer is still ``Late``."""
    plain, hooked = up(net_of, answer_window_ns=50 * MS), up(net_of, answer_window_ns=50 * MS)
    calls = []
    hooked.core.on_rtt = lambda station, ns: calls.append((station, ns))
    for net in (plain, hooked):
        hold_up_responses(net, 3, (net.cycle + 4) * MS)
        net.run(20)
    assert of(hooked, Rtt) == []
    assert calls == [(e.station, e.ns) for e in of(plain, Rtt)] and len(calls) >= 15
    assert of(hooked, Late) == of(plain, Late)
