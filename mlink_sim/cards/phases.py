"""Communication phases and command admission, as data.

**Phase transitions** – :data:`PHASE_TRANSITIONS`, (phase, :class:`PhaseEvent`) -> next phase, the same on all three
cards (SI-T3 Figure 8, SI-ET3 Figure 19, SI-T/V7 §5.3 "Communications Phases"); :func:`next_phase` rejects any other
pair with :class:`PhaseError`, in this one place.

**Admission** – three tables per generation, each cited from its manual:

* **phase × main command** – what a command gets in phase 1, 2 and 3:
  :data:`ML3_MAIN_PHASES` is SI-ET3 Table 9 verbatim (○ = ALLOWED, △ = IGNORED, – = PHASE_ERROR,
  reported as CMD_ALM CH); :data:`ML2_MAIN_PHASES` collects the per-command rules of SI-T3 §8 and
  SI-T/V7 §7.1 ("This command can be used in all phases", "If not in phase 2 or 3: Command warning
  (A.95)", CONNECT "Commands are also ignored in phase 2 (with no alarm)").
* **phase × sub-command** – SI-ET3 Table 10 (:data:`ML3_SUB_PHASES`); SI-T3 §8 "Sub-commands" and
  SI-T/V7 §7.2 (:data:`ML2_SUB_PHASES`).
* **main × sub-command combinations** – SI-ET3 Table 13 (:data:`ML3_COMBINATIONS`, "-" = CMD_ALM BH),
  SI-T3 Table 7 (:data:`ML2_COMBINATIONS`, "NG" = A.95), SI-T/V7 (:data:`V7_COMBINATIONS`): the wire's
  tables, :mod:`mlink_sim.wire.combinations` (the master reads the same), re-exported here.

A command code absent from a table is unsupported (A.95 / CMD_ALM 8H).
"""

from __future__ import annotations

import enum
from collections.abc import Mapping
from types import MappingProxyType

from mlink_sim.wire import M2Cmd, M3Cmd
from mlink_sim.wire.combinations import ML2_COMBINATIONS, ML3_COMBINATIONS, V7_COMBINATIONS, combination_ok

__all__ = [
    "PhaseEvent",
    "PhaseError",
    "PHASE_TRANSITIONS",
    "next_phase",
    "Admit",
    "ML2_MAIN_PHASES",
    "ML2_SUB_PHASES",
    "V7_SUB_PHASES",
    "ML3_MAIN_PHASES",
    "ML3_SUB_PHASES",
    "ML2_COMBINATIONS",
    "V7_COMBINATIONS",
    "ML3_COMBINATIONS",
    "admit",
    "combination_ok",
]


class PhaseEvent(enum.Enum):
    """What moves a station between phases (the arrows of SI-T3 Figure 8 / SI-ET3 Figure 19)."""

    CONNECT_ASYNC = "CONNECT (asynchronous)"  #: an accepted CONNECT with SYNCMOD(E) = asynchronous
    CONNECT_SYNC = "CONNECT (synchronous)"  #: an accepted CONNECT with SYNCMOD(E) = synchronous
    SYNC_SET = "SYNC_SET"
    DISCONNECT = "DISCONNECT"  #: a DISCONNECT that releases a connection
    COMM_ALARM = "communications fault"  #: a reception-failure alarm (E6 / COMM_ALM 8H–BH)
    WDT_ERROR = "watchdog timer fault"  #: E5 / COMM_ALM CH


class PhaseError(RuntimeError):
    """A phase transition the manuals do not have: a bug in the card (counted as ``internal_errors``)."""


_E = PhaseEvent

#: (phase, event) -> next phase. "phase" is the phase the station acts in: 1 for a station released by a connection
#: loss, which is admitted "as from phase 1" and keeps showing phase 2 (docs/cards.md, "Who may change a station").
#: SI-T3 Figure 8, SI-ET3 Figure 19, SI-T/V7 §5.3:
#: phase 1 "the phase moves to phase 2 or phase 3 after a response to the CONNECT command is returned";
#: phase 2 "moves to phase 3 when a SYNC_SET command is received, and it moves to phase 1 when a DISCONNECT
#: command is received"; phase 3 "If the DISCONNECT command is received, the phase moves to phase 1. If a reception
#: fault or a watchdog timer fault is detected, the phase moves to phase 2".
PHASE_TRANSITIONS: Mapping[tuple[int, PhaseEvent], int] = MappingProxyType({
    (1, _E.CONNECT_ASYNC): 2,
    (1, _E.CONNECT_SYNC): 3,
    (2, _E.SYNC_SET): 3,
    (2, _E.DISCONNECT): 1,
    (2, _E.COMM_ALARM): 2,  # reported in phase 2 (SI-T3 Table 22 / SI-T/V7 Table 7: 96, E6), no phase change
    (3, _E.SYNC_SET): 3,  # MECHATROLINK-I/II admit SYNC_SET in phase 3 (it re-arms the watchdog); SI-ET3 Table 9: △
    (3, _E.DISCONNECT): 1,
    (3, _E.COMM_ALARM): 2,
    (3, _E.WDT_ERROR): 2,  # the watchdog is checked in phase 3 only ("Watchdog timer faults ... are detected")
})


def next_phase(phase: int, event: PhaseEvent) -> int:
    """The phase after *event* in *phase*; :class:`PhaseError` for a pair :data:`PHASE_TRANSITIONS` does not have."""
    try:
        return PHASE_TRANSITIONS[phase, event]
    except KeyError:
        raise PhaseError(f"{event.value} in phase {phase}: no such transition (SI-T3 Figure 8, SI-ET3 Figure 19)") \
            from None


class Admit(enum.Enum):
    """What a command gets in a phase."""

    ALLOWED = "allowed"  #: executed (○)
    IGNORED = "ignored"  #: answered, not executed, no alarm (△)
    PHASE_ERROR = "phase error"  #: not executed; A.95 (MECHATROLINK-I/II) or CMD_ALM/SUBCMD_ALM CH (MECHATROLINK-III)


A, I, E = Admit.ALLOWED, Admit.IGNORED, Admit.PHASE_ERROR  # noqa: E741 - the tables' marks ○ △ – as letters


def _freeze(table: dict[int, tuple[Admit, Admit, Admit]]) -> Mapping[int, tuple[Admit, Admit, Admit]]:
    return MappingProxyType({int(k): v for k, v in table.items()})


#: SI-ET3 Table 9 "Main Command Communication Phases" – (phase 1, phase 2, phase 3).
#: NOP reads "–" in phase 1 although its section says "can be used in all communication phases": the card
#: follows the text by default, ``CardOptions.et3_nop_in_phase1 = False`` this table (docs/cards.md).
ML3_MAIN_PHASES = _freeze({
    M3Cmd.NOP: (E, A, A),
    M3Cmd.PRM_RD: (E, A, A),
    M3Cmd.PRM_WR: (E, A, A),
    M3Cmd.ID_RD: (E, A, A),
    M3Cmd.CONFIG: (E, A, A),
    M3Cmd.ALM_RD: (E, A, A),
    M3Cmd.ALM_CLR: (E, A, A),
    M3Cmd.SYNC_SET: (E, A, I),
    M3Cmd.CONNECT: (A, I, I),
    M3Cmd.DISCONNECT: (A, A, A),
    M3Cmd.INV_CTL: (E, A, A),
})

#: SI-ET3 Table 10 "Sub-Command Communication Phases".
ML3_SUB_PHASES = _freeze({
    M3Cmd.NOP: (E, A, A),
    M3Cmd.PRM_RD: (E, A, A),
    M3Cmd.PRM_WR: (E, A, A),
    M3Cmd.ALM_RD: (E, A, A),
    M3Cmd.INV_IO: (E, A, A),
})

#: SI-T3 §8 / SI-T/V7 §7.1 per-command phase rules (A.95 = PHASE_ERROR):
#: NOP, PRM_RD, ID_RD "can be used in all phases"; ALM_RD names no phase condition; PRM_WR, CONFIG,
#: ALM_CLR, SYNC_SET, INV_CTL "If not in phase 2 or 3: Command warning (A.95)"; CONNECT is executed in
#: phase 1 and "ignored in phase 2 (with no alarm)" (phase 3 likewise); DISCONNECT "can be used in
#: phases 2 and 3" and names no warning, so in phase 1 it is answered and ignored.
#: SI-T/V7 PRM_WR reads "If not in phase 2" – taken as the "2 or 3" of its sub-command (docs/cards.md).
ML2_MAIN_PHASES = _freeze({
    M2Cmd.NOP: (A, A, A),
    M2Cmd.PRM_RD: (A, A, A),
    M2Cmd.PRM_WR: (E, A, A),
    M2Cmd.ID_RD: (A, A, A),
    M2Cmd.CONFIG: (E, A, A),
    M2Cmd.ALM_RD: (A, A, A),
    M2Cmd.ALM_CLR: (E, A, A),
    M2Cmd.SYNC_SET: (E, A, A),
    M2Cmd.CONNECT: (A, I, I),
    M2Cmd.DISCONNECT: (I, A, A),
    M2Cmd.INV_CTL: (E, A, A),
})

#: SI-T3 §8 "Sub-commands" / SI-T/V7 §7.2: PRM_WR, CONFIG (SI-T/V7 only) and INV_I/O "If not in phase 2
#: or 3: A.95"; NOP, PRM_RD and ALM_RD name no phase condition.
ML2_SUB_PHASES = _freeze({
    M2Cmd.NOP: (A, A, A),
    M2Cmd.PRM_RD: (A, A, A),
    M2Cmd.PRM_WR: (E, A, A),
    M2Cmd.ALM_RD: (A, A, A),
    M2Cmd.INV_IO: (E, A, A),
})

#: SI-T/V7 §7.2 adds CONFIG as a sub-command ("If not in phase 2 or 3: Command fault (A.95)").
V7_SUB_PHASES = _freeze({**ML2_SUB_PHASES, M2Cmd.CONFIG: (E, A, A)})


def admit(table: Mapping[int, tuple[Admit, Admit, Admit]], code: int, phase: int) -> Admit | None:
    """The admission of *code* in *phase* (1–3), or None when the table does not know the code."""
    row = table.get(code)
    return None if row is None else row[phase - 1]
