"""Who may change a station (docs/cards.md, "Who may change a station"): no source other than the connected master
ever changes a parameter, the EEPROM, the run state or the phase. A station released by a connection loss (bUS after
F6-26 consecutive communications alarms, SI-T3 Table 28; the first one on the SI-T/V7, §8.1) is admitted as from
phase 1 – only CONNECT binds it – and a NOP stays a read-only status query from anyone."""

from __future__ import annotations

from typing import Any

import pytest

from mlink_sim.cards import Station
from mlink_sim.wire import CmdAlm, M2Alarm, M2Status, ml2, ml3

from .helpers import INTRUDER, MASTER, MS, Master, alarm, cmd_alm, station

CARDS = ["si-t3", "si-t-v7", "si-et3"]
RUN = {"si-t3": ("b1-01=3", "b1-02=3"), "si-et3": ("b1-01=3", "b1-02=3"), "si-t-v7": ("n003=3", "n004=9")}
#: the acceleration time: C1-01 (A1000 MEMOBUS 0200H, SI-T3 Table 8) / n019 (VS-606V7 0113H)
ACCEL = {"si-t3": ("C1-01", 0x0200), "si-et3": ("C1-01", 0x0200), "si-t-v7": ("n019", 0x0113)}


def _word(v: int) -> bytes:
    return v.to_bytes(2, "little").ljust(8, b"\0")


def _state(st: Station) -> tuple[Any, ...]:
    """Everything a foreign command must not change."""
    status = st.drive.status
    return (dict(st.store.active), dict(st.store.pending), st.phase, st.snapshot().connected_source,
            st.eeprom.generation, st.eeprom_pending, st._cmd_key, status.running, status.fault, st.tcycle_ns)


def _running_then_lost(card: str) -> Master:
    """A master brings the station up and runs the drive; then its commands stop arriving (a flood makes the kernel
    drop them) until the station declares bUS and releases the connection."""
    m = Master(station(card, params=RUN[card]))
    m.bring_up()
    run = ml3.InvCtl(1, 0, 3000) if m.ml3 else ml2.InvCtl(signals=1, speed_ref=3000)
    for _ in range(5):
        assert m.send(run) is not None
    m.now += 10 * MS
    m.st.poll(m.now)
    assert m.st.snapshot().connected_source is None, "the connection should be lost"
    return m


def _intruder(m: Master) -> Master:
    other = Master(m.st, source=INTRUDER, now=m.now)
    other.cycle, other.count = m.cycle + 50, m.count + 50
    return other


def _writes(m: Master, card: str) -> list[tuple[Any, Any]]:
    """PRM_WR of the acceleration time (77.7 s) as a main and as a sub-command, CONFIG to EEPROM, ALM_CLR,
    SYNC_SET, a RUN command, DISCONNECT."""
    _, reg = ACCEL[card]
    if m.ml3:
        wr = ml3.PrmWr(reg, 2, _word(777))
        return [(wr, None), (ml3.Nop(), wr), (ml3.Config(1), None), (ml3.AlmClr(0), None), (ml3.SyncSet(), None),
                (ml3.InvCtl(2, 0, 6000), None), (ml3.Disconnect(), None)]
    wr = ml2.PrmWr(reg, 2, _word(777))
    return [(wr, None), (ml2.Nop(), wr), (ml2.Config(1), None), (ml2.Nop(), ml2.Config(1)), (ml2.AlmClr(0), None),
            (ml2.SyncSet(), None), (ml2.InvCtl(signals=2, speed_ref=6000), None), (ml2.Disconnect(), None)]


@pytest.mark.parametrize("card", CARDS)
def test_after_a_connection_loss_no_foreign_command_writes(card: str) -> None:
    """After a connection loss, the flooder's PRM_WR and CONFIG to EEPROM (and every other writing command) on a released
    station change nothing: answered as from phase 1 (A.95 / CMD_ALM CH, SI-T3 "If not in phase 2 or 3", SI-ET3
    Table 9), or ignored (DISCONNECT without a connection)."""
    m = _running_then_lost(card)
    m.st.eeprom.take()
    before = _state(m.st)
    flooder = _intruder(m)
    for body, sub in _writes(flooder, card):
        r = flooder.send(body, sub)
        assert r is not None
        if type(body).__name__ in ("PrmWr", "Config", "AlmClr", "SyncSet", "InvCtl"):
            if m.ml3:
                assert cmd_alm(r) == CmdAlm.PHASE_ERROR
            else:  # the latched E6 (most recent alarm, Table 21) hides the A.95 warning: WARNG tells
                assert r.message.status & M2Status.WARNG
        assert _state(m.st) == before, f"{type(body).__name__}/{type(sub).__name__} changed the station"
    assert m.st.take_eeprom() is None


@pytest.mark.parametrize("card", CARDS)
def test_released_station_takes_a_master_only_through_connect(card: str) -> None:
    """On a released station NOPs from anyone (a probe, the old master) are status queries and bind nothing; the
    master's INV_CTL is answered as from phase 1, so it CONNECTs again and owns the station; the bUS count starts
    from zero with the new connection."""
    m = _running_then_lost(card)
    probe = _intruder(m)
    for _ in range(3):
        assert probe.nop() is not None
    assert m.st.snapshot().connected_source is None and m.st.counters.status_queries == 3
    assert m.nop() is not None and m.st.snapshot().connected_source is None
    m.tick(50)
    r = m.send(ml3.InvCtl(1, 0, 3000) if m.ml3 else ml2.InvCtl(signals=1, speed_ref=3000))
    if m.ml3:
        assert cmd_alm(r) == CmdAlm.PHASE_ERROR  # the master's codec reads this as "back in phase 1"
    else:
        assert r.message.status & M2Status.WARNG
    assert m.connect(sync=True) is not None
    assert m.st.snapshot().connected_source == MASTER and m.st.phase == 3
    assert m.st._bus_count == 0
    # the prober stays silent; the master is served and a foreign command is ignored again
    assert m.send(ml3.AlmClr(0) if m.ml3 else ml2.AlmClr(0)) is not None
    for _ in range(3):
        assert m.nop() is not None
    assert probe.send(ml3.Disconnect() if m.ml3 else ml2.Disconnect()) is None
    assert m.st.phase == 3 and m.st.snapshot().connected_source == MASTER


def test_si_et3_table_4_con_unlit_after_a_connection_loss() -> None:
    """Table 4 CON "Unlit: Connection with master device is not established" – also while released after bUS."""
    m = _running_then_lost("si-et3")
    assert m.st.snapshot().leds["CON"] == "off" and m.st.phase == 2
    assert m.connect() is not None and m.st.snapshot().leds["CON"] == "on"


def test_connect_on_a_released_station_binds_the_new_master() -> None:
    """The rule's other side: CONNECT is how a released station takes a new master (as from phase 1)."""
    m = _running_then_lost("si-t3")
    other = _intruder(m)
    assert other.connect(sync=False) is not None
    assert m.st.snapshot().connected_source == INTRUDER and m.st.phase == 2
    assert m.nop() is not None and m.st.counters.status_queries == 1  # the old master is now the foreign source


@pytest.mark.parametrize("card", CARDS)
def test_phase_1_never_written_by_anyone(card: str) -> None:
    """Before any CONNECT nobody owns the station: every writing command gets A.95 / CMD_ALM CH (SI-T3 "If not in
    phase 2 or 3", SI-ET3 Table 9) and DISCONNECT has no connection to release."""
    st = station(card, params=RUN[card])
    m = Master(st, source=INTRUDER)
    before = _state(st)
    for body, sub in _writes(m, card):
        assert m.send(body, sub) is not None
        assert _state(st) == before
    if not m.ml3:
        assert alarm(m.send(ml2.Config(1))) == M2Alarm.COMMAND_WARNING
