"""benchmarks.figures and benchmarks.floor: one definition of missed, RTT and CPU per exchange for the simulator and
its floor (so that a floor that loses most of its answers cannot count 0 % missed and divide its CPU by the few it
keeps), and the floor itself."""

from __future__ import annotations

import pytest

from mlink_sim.metrics import LatencyHistogram

from benchmarks import bench, figures, floor, targets
from benchmarks.common import ROOT, child_env, module_command

MS = 1_000_000




def _rtt(*values: int) -> LatencyHistogram:
    h = LatencyHistogram()
    for v in values:
        h.record(v)
    return h


def test_answers_later_than_a_cycle_are_missed_but_stay_in_the_rtt_tail() -> None:
    # 2 cycles × 2 stations; one answer 3 ms late, one never back
    f = figures.exchange_figures(cycle_ns=MS, started=2, skipped=0, sent=4, rtt=_rtt(400_000, 500_000, 3 * MS),
                                 cpu_s=0.0003)
    assert (f.due, f.answered, f.on_time) == (4, 3, 2)
    assert f.missed_rate == 0.5
    assert f.rtt_p99_ns >= 3 * MS  # the late answer is in the tail, not dropped
    assert f.cpu_per_exchange_us == 100.0  # 300 µs over the 3 answers read


def test_skipped_cycles_count_their_exchanges_as_missed() -> None:
    f = figures.exchange_figures(cycle_ns=MS, started=8, skipped=2, sent=16, rtt=_rtt(*[300_000] * 16),
                                 cpu_s=0.0016, spin_s=0.0008)
    assert (f.due, f.on_time, f.missed_rate) == (20, 16, 0.2)
    assert (f.cpu_per_exchange_us, f.cpu_per_exchange_nospin_us) == (100.0, 50.0)


def test_nothing_measured_is_no_division_by_zero() -> None:
    f = figures.exchange_figures(cycle_ns=MS, started=0, skipped=0, sent=0, rtt=LatencyHistogram(), cpu_s=0.1)
    assert (f.due, f.missed_rate, f.cpu_per_exchange_us, f.rtt_p99_ns) == (0, 0.0, 0.0, 0)


def test_targets_say_when_the_floor_itself_is_saturated() -> None:
    cell = bench.Cell("ML3", 62, MS, 1, duration_s=60.0, missed_rate=0.7, rtt_p99_ns=5 * MS,
                      floor_batched={"batched": True, "missed_rate": 0.688, "due": 3_720_000, "on_time": 1_160_308,
                                     "rtt_p99_ns": 2 * MS, "lateness_p99_ns": 200_000, "cpu_per_exchange_us": 30.0,
                                     "cpu_per_exchange_nospin_us": 28.0, "cpu_client_pct": 87.0,
                                     "cpu_server_pct": 98.0, "wakeups_client": 7.0, "wakeups_server": 0.1})
    text, rows = targets.verdicts([cell])
    assert "floor saturated at 62 ML3 @ 1ms, 60s: the floor itself misses 68.80 % (2,559,692 of 3,720,000" in text
    assert text.splitlines()[-1].endswith("bounds met")
    judged = [r for r in rows if r["target"].startswith("62 ML3 @ 1ms")]
    assert len(judged) == 3 and all(r["floor_saturated"] for r in judged)  # missed, RTT, CPU per exchange
    cell.floor_batched["missed_rate"] = 0.0004  # within the margin: carries the load
    text, rows = targets.verdicts([cell])
    assert "saturated" not in text and not any(r.get("floor_saturated") for r in rows)


def test_the_floor_counts_by_the_shared_definition() -> None:
    """A short real floor (2 stations, 5 ms cycle, loopback): its counts obey the shared definition's
    invariants whatever the machine's load (no timing is asserted)."""
    from mlink_sim.aio.transport.udp import new_event_loop

    loop = new_event_loop()
    try:
        f = loop.run_until_complete(floor.measure_floor(2, 32, 5 * MS, 0.3, batched=False))
    finally:
        loop.close()
    assert f.sent > 0 and f.due >= f.sent
    assert f.on_time <= f.exchanges <= f.sent + 2  # + the answers in flight when the window opened
    assert f.missed_rate == (f.due - f.on_time) / f.due
    assert f.exchanges + f.missing <= f.sent + 2 and f.cpu_per_exchange_us > 0


def test_a_cell_notes_the_states_of_the_stations_not_at_their_phase() -> None:
    from types import SimpleNamespace as NS

    from mlink_sim.master import StationState

    views = {a: NS(state=s, at_target=s is StationState.PHASE3) for a, s in enumerate(
        [StationState.ALARM] * 3 + [StationState.SYNCING, StationState.PHASE3, StationState.PHASE3])}
    session = NS(net=NS(views=lambda: views))
    assert bench._states(session) == " (alarm 3, syncing 1)"
    assert bench._states(NS(net=NS(views=dict))) == "" and bench._states(NS(net=None)) == ""


def test_turns_are_at_most_ten_seconds_all_alike() -> None:
    assert figures.turns(60.0) == [10.0] * 6 and figures.turns(5.0) == [5.0] and figures.turns(10.0) == [10.0]
    assert figures.turns(25.0) == pytest.approx([25 / 3] * 3)


def test_windows_of_one_side_add_up() -> None:
    a = figures.Window(MS, wall_s=10.0, started=10, skipped=1, sent=20, cpu_a_s=0.5, spin_s=0.1, wake_a=30,
                       ticks=(1, 0, 1, 8, 0, 0, 0, 0), rtt=_rtt(*[200_000] * 20))
    b = figures.Window(MS, wall_s=10.0, started=10, sent=20, cpu_b_s=0.5, wake_a=10, ticks=(1, 0, 1, 6, 0, 0, 0, 2),
                       rtt=_rtt(*[200_000] * 19, 3 * MS))
    a.add(b)
    assert (a.turns, a.started, a.skipped, a.sent, a.wake_a) == (2, 20, 1, 40, 40)
    assert (a.pct(a.cpu_a_s), a.per_cycle(a.wake_a), a.steal_pct()) == (2.5, 2.0, 10.0)  # 2 of 20 ticks
    f = a.figures()
    assert (f.due, f.answered, f.on_time) == (42, 40, 39) and f.cpu_per_exchange_us == 25_000.0  # 1 s / 40


def test_work_takes_three_or_four_durations_per_datagram() -> None:
    assert floor.Work.parse("0.9us, 0.2us, 800") == floor.Work(900, 200, 800)
    assert floor.Work.parse("0.9us,0.2us,800,1.7us") == floor.Work(900, 200, 800, 1_700)
    assert floor.Work.parse("0,0,0") == floor.Work()
    with pytest.raises(ValueError, match=r"SERVE,ENCODE,DECODE\[,SETTLE\]"):
        floor.Work.parse("1us,2us")
    with pytest.raises(ValueError, match="SERVE,ENCODE,DECODE"):
        floor.Work.parse("1us,2us,3us,4us,5us")
    with pytest.raises(ValueError, match="--work: expected a duration"):
        floor.Work.parse("1us,-2us,0")


@pytest.mark.parametrize("batched, shared", [(True, True), (False, False)])
def test_the_floor_with_the_cores_time_keeps_each_side_busy_in_the_chain(batched, shared) -> None:
    """``--work``: the server is busy *serve* per datagram before it echoes, the client *encode* per command
    after the cycle's start, so no answer comes back sooner than 2 × encode + serve after its cycle began (a
    lower bound on the monotonic clock, whatever the machine's load)."""
    from mlink_sim.aio.transport.udp import new_event_loop

    loop = new_event_loop()
    try:
        f = loop.run_until_complete(floor.measure_floor(2, 32, 5 * MS, 0.3, batched=batched, shared=shared,
                                                        work=floor.Work(300_000, 100_000, 50_000)))
    finally:
        loop.close()
    assert f.exchanges > 0 and f.rtt_p50_ns >= 2 * 100_000 + 300_000


def test_the_floor_settles_after_the_echoes_went_not_before() -> None:
    """``--work``'s SETTLE keeps the server busy after a read's echoes went back (a worker's ``Bus.settle``): with
    4 ms of it per read, the answers still come back long before those 4 ms are over (before them, every answer
    would be at least 4 ms late)."""
    from mlink_sim.aio.transport.udp import new_event_loop

    loop = new_event_loop()
    try:
        f = loop.run_until_complete(floor.measure_floor(2, 32, 10 * MS, 0.3, batched=True, shared=True,
                                                        work=floor.Work(settle_ns=2 * MS)))
    finally:
        loop.close()
    assert f.exchanges > 0 and f.rtt_p50_ns < 4 * MS


def test_the_floor_refuses_a_malformed_work_with_exit_2() -> None:
    import subprocess

    r = subprocess.run(module_command("benchmarks.floor", "--work", "1us,2us"), capture_output=True, text=True,
                       timeout=60, cwd=ROOT, env=child_env())
    assert r.returncode == 2 and "floor: --work takes SERVE,ENCODE,DECODE" in r.stderr
    assert "Traceback" not in r.stderr


def test_a_missed_bound_names_the_chain_beside_the_floors() -> None:
    """Where the missed bound fails, the verdict gives the RTT p50 of the simulator and of its floor: the chain
    between a command and its answer that a host stall can fall in (docs/performance.md)."""
    floor_batched = {"batched": True, "missed_rate": 0.0006, "due": 3_720_000, "on_time": 3_717_768,
                     "rtt_p50_ns": 98_751, "rtt_p99_ns": 315_391, "lateness_p99_ns": 50_000,
                     "cpu_per_exchange_us": 4.2, "cpu_per_exchange_nospin_us": 2.5, "wakeups_client": 1.5,
                     "wakeups_server": 1.0}
    cell = bench.Cell("ML3", 62, MS, 1, duration_s=60.0, missed_rate=0.0016, rtt_p50_ns=175_999,
                      rtt_p99_ns=419_839, cpu_per_exchange_us=6.2, floor_batched=floor_batched)
    _, rows = targets.verdicts([cell])
    missed = next(r for r in rows if r["target"].startswith("62 ML3") and r["bound"].startswith("missed"))
    assert not missed["met"]
    assert "RTT p50 176us against the floor's 98.75us (the chain a host stall can fall in" in missed["verdict"]


def test_the_shared_floor_echoes_a_backlog_newest_cycle_first() -> None:
    """As a packed worker answers a backlog (docs/cards.md, "A backlog's answers"): a read holding several cycles'
    datagrams (the client's: cycle number, then station index) is echoed newest cycle first, each cycle's in
    arrival order; a read cut in the middle of a burst too."""
    def dg(cycle: int, station: int) -> tuple[bytes, str]:
        return cycle.to_bytes(4, "little") + station.to_bytes(2, "little") + bytes(30), f"s{station}"

    read = [dg(7, 2), dg(8, 0), dg(8, 1), dg(8, 2), dg(9, 0), dg(9, 1), dg(9, 2), dg(256, 0)]
    assert floor.newest_cycle_first(read) == [dg(256, 0), dg(9, 0), dg(9, 1), dg(9, 2), dg(8, 0), dg(8, 1), dg(8, 2),
                                              dg(7, 2)]
