"""Which command an answer is for, and how it counts (docs/master.md).

A response datagram names the command it answers by the envelope's cycle number. That command is the station's
outstanding one (the last slot's: on time), one still in flight within the answer window
(``NetworkPlan.answer_window_ns``: on time as well), or one already counted :class:`~.types.Missing` (a late
answer: counted once as :class:`~.types.Late`, and still processed, since the station executed the command).
Anything else is a duplicate or was never sent. :func:`answer_to` finds the command and :func:`take` counts the
answer; the core's general path and its steady-state path straight from the bytes (:mod:`.fastpath`) both call
them, so the two cannot count an answer differently. :func:`shows` decides whether an answer sets what the
station shows, which an older answer that arrives after a newer one must not.

The functions work on the core's per-station record (:class:`~.slave.Slave`) and report through ``emit``.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Final

from .slave import Sent, Slave
from .types import Event, Late, Rtt

__all__ = ["answer_to", "take", "shows"]

_U32: Final = 0xFFFFFFFF


def answer_to(st: Slave, cycle: int) -> Sent | None:
    """The command a response for *cycle* answers: the outstanding one, one in flight, or the one already counted
    missing (once: a late answer); None when it answers none of them (a duplicate or unexpected datagram)."""
    sent = st.outstanding
    if sent is not None and sent.cycle == cycle:
        return sent
    if st.inflight:
        sent = st.inflight.get(cycle)
        if sent is not None:
            return sent
    sent = st.expired
    if sent is not None and sent.cycle == cycle and not sent.late_seen:
        return sent
    return None


def take(st: Slave, sent: Sent, now: int, on_rtt: Callable[[int, int], None] | None,
         emit: Callable[[Event], None]) -> None:
    """Count the answer to *sent*, received at *now*: its round trip (to *on_rtt*, or an ``Rtt`` event when that
    is None) when *sent* is the outstanding command or one in flight, else a ``Late`` event. A late answer still
    tells the truth (the command was executed), so the caller processes it; its handlers check the current state,
    so nothing is done twice (what the station shows from it: :func:`shows`)."""
    if sent is st.outstanding or st.inflight.pop(sent.cycle, None) is sent:
        if sent is st.outstanding:
            st.outstanding = None
        st.rtt = rtt = now - sent.at
        if on_rtt is None:
            emit(Rtt(st.address, rtt))
        else:
            on_rtt(st.address, rtt)
    else:
        sent.late_seen = True
        st.late += 1
        emit(Late(st.address, sent.cycle, now - sent.at))
    st.answered = sent.cycle
    st.silent = 0
    st.responses += 1
    st.last_rx = now


def shows(st: Slave, cycle: int, rwdt: int) -> bool:
    """Whether the answer to the command of *cycle*, with *rwdt*, sets what *st* shows (RWDT, status, alarms): False
    only for an answer the slave made before the one shown, which came after it (a worker answers its backlog newest
    cycle first, ``mlink_sim.aio.slave.bus``). That answer is still counted and its command's outcome processed
    (:func:`take`, ``MasterCore._advance``); the answer shown already showed the slave after both commands.

    "Made before" needs both: a command *cycle* older than the one shown (the envelope's u32 cycle number,
    docs/wire-format.md) and a slave count (RWDT bits 0–3, one further with each answer: ``cards.watchdog``) behind
    the one shown, by 1–8. Commands the network reordered fail the second: the slave took the older command last,
    so its answer is the newer one, and it may carry the WDT fault the reordering caused (SI-T3 Table 24 and SI-T/V7
    Table 9 "WDT count fault in a synchronous frame"; SI-ET3 COMM_ALM CH "WDT error")."""
    shown = st.shown
    if shown >= 0 and (cycle - shown) & _U32 > 0x7FFFFFFF and (rwdt - st.rwdt) & 0xF > 7:
        return False
    st.shown = cycle
    return True
