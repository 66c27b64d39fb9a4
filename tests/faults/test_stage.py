"""The master-side fault stage against the real card cores: each fault provokes the reaction its manual tables give,
and the recovery after its end is measured (docs/faults.md)."""

from __future__ import annotations

import pytest

from mlink_sim.faults import BadCommand, FreezeWdt, Silence, SkipCycles
from mlink_sim.master import AlarmRaised, StationState
from mlink_sim.wire import CommAlm, M2Alarm

from .helpers import MS, Bench

CARDS = ["si-t3", "si-et3", "si-t-v7"]


def raised(bench: Bench) -> list[str]:
    return [e.name for e in bench.events if isinstance(e, AlarmRaised)]


@pytest.mark.parametrize("card", CARDS)
def test_skip_one_cycle_is_a_warning_only_si_t3_table_22(card):
    """SI-T3 Table 22 / V7 Table 7: the first reception failure is 96 (a warning; SI-ET3 COMM_ALM 2/3); the station
    stays in phase 3 and the episode counts as recovered at once."""
    b = Bench(card).up()
    b.stage.inject(0x21, SkipCycles(count=1), b.now)
    b.run(10)
    assert b.card.counters.reception_failures == 1
    assert b.card.phase == 3 and b.core.state(0x21) is StationState.PHASE3
    ep = b.stage.latest(0x21)
    assert ep.recovery_ns is not None and ep.recovery_ns <= 2 * MS
    assert not b.stage.active and not b.stage.watching


@pytest.mark.parametrize("card", CARDS)
def test_skip_two_cycles_is_e6_and_the_master_recovers(card):
    """A second consecutive failure is E6 (SI-T3 Tables 22/23; ET3 COMM_ALM 9/A): phase 3 -> 2; one communications
    alarm is below F6-26 = 2, so the master's ALM_CLR + SYNC_SET bring it back (SI-T3 Table 28 "E5"/"E6")."""
    b = Bench(card).up()
    b.stage.inject(0x21, SkipCycles(count=2), b.now)
    b.run(30)
    names = raised(b)
    assert "COMM_ERROR" in names or "NOT_RECEIVED" in names or "SYNC_NOT_RECEIVED" in names
    assert b.card.phase == 3
    ep = b.stage.latest(0x21)
    assert ep.recovery_ns is not None and 0 < ep.recovery_ns < 20 * MS
    assert len(b.sent) == b.core.view(0x21).sent - 2  # two commands never left the master


def test_skipping_past_f6_26_trips_bus_and_the_master_reconnects():
    """F6-26 (default 2) communications alarms in a row = bUS (SI-T3 Table 28), a drive fault per F6-01 (Table 26 22H),
    "only detected when the run command or frequency reference is assigned to the option" (b1-01/b1-02 = 3), and the
    card releases the connection. The master's reconnection (DISCONNECT + CONNECT, docs/master.md) resets the fault:
    DISCONNECT "clears the control command and carries out a fault reset" (SI-T3 "DISCONNECT")."""
    b = Bench("si-t3", params=("b1-01=3", "b1-02=3")).up()
    b.stage.inject(0x21, SkipCycles(count=5), b.now)
    ep = b.stage.latest(0x21)
    b.run_until(lambda: ep.recovered_ns is not None, 100)
    snap = b.card.snapshot()
    assert snap.drive.fault_history[:1] == ("bUS",) and snap.drive.fault is None
    assert snap.counters["bus_alarms"] >= 2 and b.core.view(0x21).recoveries == 1
    assert ep.recovery_ns > 0


@pytest.mark.parametrize(("card", "name"), [("si-t3", "WDT_ERROR"), ("si-t-v7", "WDT_ERROR"), ("si-et3", "WDT_ERROR")])
def test_frozen_wdt_is_a_wdt_error_si_t3_table_23_et3_comm_alm_c(card, name):
    """SI-T3 Tables 23/24 (V7 Table 8) E5 "WDT Error", SI-ET3 COMM_ALM CH: the card drops to phase 2 on a count
    that does not advance; once the count advances again (from where it stopped) the master's ALM_CLR + SYNC_SET
    recover the station and no further WDT error follows."""
    b = Bench(card).up()
    b.stage.inject(0x21, FreezeWdt(for_ns=20 * MS), b.now)
    b.run(5)
    assert b.card.counters.wdt_errors >= 1
    assert name in raised(b)
    if card != "si-et3":
        assert b.card.snapshot().alarm_code in (M2Alarm.WDT_ERROR, 0x39, 0x31) or b.card.phase == 2
    else:
        assert b.core.view(0x21).comm_alm in (CommAlm.WDT_ERROR, 0) or b.card.phase == 2
    b.run(40)
    ep = b.stage.latest(0x21)
    b.run_until(lambda: ep.recovered_ns is not None, 200)
    errors = b.card.counters.wdt_errors
    b.run(100)
    assert b.card.counters.wdt_errors == errors and b.card.phase == 3


CASES = [  # card, frame size, subcmd, kind, (code, name, where) of the answer, manual
    ("si-t3", 32, False, "data-size", (0x94, "DATA_SETTING_WARNING", "main")),  # SI-T3 PRM_RD "SIZE is odd"
    ("si-t3", 17, False, "data-size", (0x94, "DATA_SETTING_WARNING", "main")),
    ("si-t3", 32, True, "data-size", (0x94, "DATA_SETTING_WARNING", "sub")),
    ("si-t-v7", 32, True, "data-size", (0x94, "DATA_SETTING_WARNING", "sub")),  # V7 PRM_RD: main refused in 32-byte
    ("si-et3", 64, False, "data-size", (0x9, "INVALID_DATA", "main")),  # SI-ET3 PRM_RD "SIZE data is invalid"
    ("si-et3", 64, True, "data-size", (0x9, "INVALID_DATA", "sub")),
    ("si-t3", 32, True, "combination", (0x95, "COMMAND_WARNING", "sub")),  # SI-T3 Table 7 ALM_RD x PRM_RD "NG"
    ("si-t-v7", 32, True, "combination", (0x95, "COMMAND_WARNING", "sub")),
    ("si-et3", 64, True, "combination", (0xB, "SUBCMD_COMBINATION", "main")),  # SI-ET3 Table 13 note: CMD_ALM BH
    ("si-t3", 32, False, "phase", (0x95, "COMMAND_WARNING", "main")),  # INV_CTL "If not in phase 2 or 3"
    ("si-t-v7", 32, True, "phase", (0x95, "COMMAND_WARNING", "main")),
    ("si-et3", 64, False, "phase", (0xC, "PHASE_ERROR", "main")),  # SI-ET3 Table 9 INV_CTL "–" in phase 1
]


@pytest.mark.parametrize(("card", "size", "subcmd", "kind", "answer"), CASES,
                         ids=[f"{c[0]}-{c[1]}-{'sub' if c[2] else 'main'}-{c[3]}" for c in CASES])
def test_bad_command_is_answered_with_the_manuals_refusal(card, size, subcmd, kind, answer):
    b = Bench(card, frame_size=size, subcmd=subcmd).up()
    b.stage.inject(0x21, BadCommand(kind=kind), b.now)
    b.run(3)
    got = b.stage.last_answer(0x21)
    assert got is not None, "no answer recorded"
    assert (got[1].code, got[1].name, got[1].where) == answer
    assert b.card.counters.commands_refused >= 1
    ep = b.stage.latest(0x21)
    b.run_until(lambda: ep.recovered_ns is not None, 60)
    assert b.card.phase == 3 and b.core.state(0x21) is StationState.PHASE3
    if kind == "phase":
        assert b.core.view(0x21).recoveries == 1  # A.95 / CMD_ALM CH -> PHASE1 -> CONNECT (docs/master.md)


@pytest.mark.parametrize("card", CARDS)
def test_silence_keeps_the_card_running_and_the_master_reconnects(card):
    """Answers dropped on their way to the master: the card keeps receiving (no reception failure, its phase stays
    3), the master counts them missing, goes OFFLINE after offline_after and recovers once the station answers."""
    b = Bench(card).up()
    b.stage.inject(0x21, Silence(for_ns=30 * MS), b.now)
    b.run(25)
    assert b.core.state(0x21) is StationState.OFFLINE
    assert b.card.counters.reception_failures == 0 and b.card.phase == 3
    ep = b.stage.latest(0x21)
    b.run_until(lambda: ep.recovered_ns is not None, 100)
    assert 0 < ep.recovery_ns < 50 * MS
    assert b.core.view(0x21).missing >= 8


def test_an_idle_stage_lets_everything_through_unchanged():
    b = Bench("si-t3").up()
    assert not b.stage.active and not b.stage.watching
    for station, datagram in b.core.on_cycle(b.cycle + 1, b.now + MS):
        assert b.stage.to_station(station, datagram, b.now + MS) is datagram


def test_injected_counts_per_station():
    b = Bench("si-t3").up()
    b.stage.inject(0x21, SkipCycles(count=3), b.now)
    b.run(5)
    b.stage.inject(0x21, Silence(for_ns=4 * MS), b.now)
    b.run(8)
    assert b.stage.injected() == {0x21: {"skips": 3, "silences": 3}}  # answers within [t, t + 4 ms)


def test_from_station_reads_the_station_from_the_envelope():
    """What the master runner hands the stage (``FaultStage.from_station``): a silenced station's answer is dropped
    as ``to_master`` of its envelope's station drops it; another's, and a datagram shorter than an envelope, pass."""
    b = Bench("si-t3").up()
    b.cycle += 1  # the next cycle's command, answered by the card outside the bench's step
    answer = b.card.receive(b.core.on_cycle(b.cycle, b.now)[0][1], "master", b.now)
    assert answer is not None and answer[3] == 0x21
    b.stage.inject(0x21, Silence(for_ns=100 * MS), b.now)
    assert b.stage.from_station(answer, b.now) is None
    assert b.stage.from_station(answer[:4], b.now) == answer[:4]
    other = answer[:3] + bytes([0x22]) + answer[4:]
    assert b.stage.from_station(other, b.now) == other
