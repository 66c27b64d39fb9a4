"""Phase transitions as data: SI-T3 Figure 8, SI-ET3 Figure 19, SI-T/V7 §5.3 "Communications Phases"."""

from __future__ import annotations

import pytest

from mlink_sim.cards.phases import PHASE_TRANSITIONS, PhaseError, PhaseEvent, next_phase
from mlink_sim.wire import ml2, ml3

from .helpers import Master, station


def test_phase_transitions_si_t3_figure_8_si_et3_figure_19() -> None:
    """The arrows of the figures: CONNECT 1 -> 2/3, SYNC_SET 2 -> 3, DISCONNECT 2/3 -> 1, a reception or watchdog
    timer fault 3 -> 2; a reception fault in phase 2 is reported and changes nothing."""
    E = PhaseEvent
    assert dict(PHASE_TRANSITIONS) == {
        (1, E.CONNECT_ASYNC): 2, (1, E.CONNECT_SYNC): 3,
        (2, E.SYNC_SET): 3, (2, E.DISCONNECT): 1, (2, E.COMM_ALARM): 2,
        (3, E.SYNC_SET): 3, (3, E.DISCONNECT): 1, (3, E.COMM_ALARM): 2, (3, E.WDT_ERROR): 2,
    }


@pytest.mark.parametrize("phase", [1, 2, 3])
@pytest.mark.parametrize("event", list(PhaseEvent))
def test_illegal_phase_transitions_are_rejected_in_one_place(phase: int, event: PhaseEvent) -> None:
    if (phase, event) in PHASE_TRANSITIONS:
        assert next_phase(phase, event) == PHASE_TRANSITIONS[phase, event]
    else:
        with pytest.raises(PhaseError, match="no such transition"):
            next_phase(phase, event)


@pytest.mark.parametrize("card", ["si-t3", "si-et3", "si-t-v7"])
def test_every_phase_change_goes_through_the_table(card: str, monkeypatch: pytest.MonkeyPatch) -> None:
    """CONNECT, SYNC_SET, a watchdog timer fault, a reception fault and DISCONNECT all take their transition from
    phases.next_phase (the station's only way to change its phase)."""
    from mlink_sim.cards import connection

    taken: list[tuple[int, PhaseEvent]] = []
    real = connection.next_phase
    monkeypatch.setattr(connection, "next_phase", lambda phase, event: taken.append((phase, event)) or real(phase, event))
    m = Master(station(card))
    m.connect(sync=False)
    m.sync_set()
    m.nop(wdt=0x05)  # the master count did not advance by one: watchdog timer fault, 3 -> 2
    m.sync_set()
    m.tick(2)
    m.nop()  # two cycles missing: a warning, then a reception-failure alarm, 3 -> 2
    E = PhaseEvent
    assert taken == [(1, E.CONNECT_ASYNC), (2, E.SYNC_SET), (3, E.WDT_ERROR), (2, E.SYNC_SET), (3, E.COMM_ALARM)]
    assert m.st.phase == 2
    if card != "si-t-v7":  # the SI-T/V7 has lost the connection at its first communications alarm (bUS)
        m.send(ml3.Disconnect() if card == "si-et3" else ml2.Disconnect())
        assert taken[-1] == (2, E.DISCONNECT) and m.st.phase == 1
