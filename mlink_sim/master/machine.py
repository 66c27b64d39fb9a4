"""The master's view of one station as a state machine, as data (docs/master.md, "State machine").

In the style of h11's ``_state.py``: :data:`TRANSITIONS` is the whole machine, one entry per (state, event);
:func:`next_state` is the only place a state changes, and it rejects a pair the table does not hold with
:class:`IllegalTransition`. The core (:mod:`mlink_sim.master.core`) decides *which* event an answer or a slot is
(reading the :class:`~mlink_sim.master.codec.Reply` verdicts), asks :func:`expects` whether the current state
takes it (a late or repeated answer may not), and fires it. :data:`SENDS` is the command each state sends.

Every edge of the diagram in docs/master.md is one entry here, and tests/master/test_master_machine.py checks
the two against each other.
"""

from __future__ import annotations

import enum
from collections.abc import Mapping
from types import MappingProxyType

from .commands import Send
from .types import StationState

__all__ = ["Ev", "TRANSITIONS", "SENDS", "CONNECTED", "MAY_HOLD_CONNECTION", "IllegalTransition", "next_state",
           "expects"]

S = StationState


class Ev(enum.Enum):
    """What happened to a station: an answer as the core reads it, a slot falling due, or silence."""

    ANSWERED = "any response"
    SILENT = "no answer for offline_after communication cycles"
    CONNECT_DUE = "slot: enabled and not backing off, so CONNECT"
    CONNECTED = "CONNECT ok"
    PLAN_REFUSED = "CONNECT refused: A.94 / CMD_ALM 1, 9 / SI-T3 CyC; back off"
    NOT_ACCEPTED = "CONNECT ignored or refused otherwise (A.95, echo differs): DISCONNECT first"
    SYNC_DUE = "slot with target phase 3: SYNC_SET"
    SYNCED = "SYNC_SET ok"
    SYNC_REFUSED = "SYNC_SET refused: clear, then try again"
    COMM_ALARM = "E5/E6 (ML-II ALARM) or COMM_ALM >= 8 (ML-III)"
    CLEAR_REFUSED = "ALM_CLR refused: another round"
    CLEARED = "ALM_CLR ok, target phase 2"
    CLEARED_TO_SYNC = "ALM_CLR ok, target phase 3"
    ESCALATED = "more than clear_attempts ALARM rounds: DISCONNECT first, then CONNECT"
    NOT_CONNECTED = "A.95 to INV_CTL/SYNC_SET/ALM_CLR (ML-II), CMD_ALM CH (ML-III)"
    DISCONNECTED = "DISCONNECT ok (disconnect() on request)"


#: States in which the master has seen the slave take its connection (phase 2 or 3): what "connected" means in
#: the station figures and what the SI-ET3's CON LED shows, "Connection established" (SI-ET3 Table 4). Tuples of
#: members, as :data:`MAY_HOLD_CONNECTION`: ``in`` compares them by identity (an enum's hash runs in Python).
CONNECTED = (S.PHASE2, S.SYNCING, S.PHASE3, S.ALARM)
#: States in which the slave may hold a connection the master made: :data:`CONNECTED`, and CONNECTING, whose
#: CONNECT the slave may have taken although its answer has not come. DISCONNECT releases it: a station
#: disconnected on request and every station of a closing master are sent DISCONNECT in these states.
MAY_HOLD_CONNECTION = (S.CONNECTING, *CONNECTED)
_ANSWERING = frozenset(S) - {S.OFFLINE}
_UP = (S.PHASE2, S.SYNCING, S.PHASE3)


def _table() -> Mapping[tuple[StationState, Ev], StationState]:
    t: dict[tuple[StationState, Ev], StationState] = {
        # bring-up
        (S.OFFLINE, Ev.ANSWERED): S.PHASE1,
        (S.PHASE1, Ev.CONNECT_DUE): S.CONNECTING,
        (S.CONNECTING, Ev.CONNECTED): S.PHASE2,
        (S.CONNECTING, Ev.PLAN_REFUSED): S.PHASE1,
        (S.CONNECTING, Ev.NOT_ACCEPTED): S.CONNECTING,
        (S.PHASE2, Ev.SYNC_DUE): S.SYNCING,
        (S.SYNCING, Ev.SYNCED): S.PHASE3,
        # communication alarms: ALM_CLR rounds
        (S.SYNCING, Ev.SYNC_REFUSED): S.ALARM,
        (S.ALARM, Ev.CLEAR_REFUSED): S.ALARM,
        (S.ALARM, Ev.CLEARED): S.PHASE2,
        (S.ALARM, Ev.CLEARED_TO_SYNC): S.SYNCING,
    }
    for s in _UP:
        t[s, Ev.COMM_ALARM] = S.ALARM
    for s in (*_UP, S.ALARM):
        t[s, Ev.ESCALATED] = S.CONNECTING
    # The slave is back in phase 1 (restart, released connection, disconnect() done). A late answer can report
    # it after the master has moved on from the state it was sent in, so it is taken in every answering state.
    for s in _ANSWERING:
        t[s, Ev.NOT_CONNECTED] = S.PHASE1
        t[s, Ev.DISCONNECTED] = S.PHASE1
        t[s, Ev.SILENT] = S.OFFLINE
    return MappingProxyType(t)


#: (state, event) -> next state: the whole machine (docs/master.md, "State machine").
TRANSITIONS = _table()

#: The main command a slot sends in each state (docs/master.md, the table under the diagram). The core refines
#: it: RESET for CONNECT when the slave must be reset first, REQUEST for CYCLIC when a request is queued, PROBE
#: while backing off after a refused CONNECT, DISCONNECT / PROBE for a station disconnected on request.
SENDS: Mapping[StationState, Send] = MappingProxyType({
    S.OFFLINE: Send.PROBE,
    S.PHASE1: Send.PROBE,
    S.CONNECTING: Send.CONNECT,
    S.PHASE2: Send.CYCLIC,
    S.SYNCING: Send.SYNC,
    S.PHASE3: Send.CYCLIC,
    S.ALARM: Send.CLEAR,
})


class IllegalTransition(RuntimeError):
    """An event the state machine has no transition for in the current state: a bug in the core, never the
    slave's doing (the core asks :func:`expects` before it fires an event an answer may bring late)."""

    def __init__(self, state: StationState, event: Ev) -> None:
        super().__init__(f"no transition from {state.name} on {event.name} ({event.value})")
        self.state = state
        self.event = event


def expects(state: StationState, event: Ev) -> bool:
    """Whether *state* takes *event* (see :data:`TRANSITIONS`)."""
    return (state, event) in TRANSITIONS


def next_state(state: StationState, event: Ev) -> StationState:
    """The state after *event* in *state*; :class:`IllegalTransition` if the table has no such transition."""
    try:
        return TRANSITIONS[state, event]
    except KeyError:
        raise IllegalTransition(state, event) from None
