"""A card's answer to the command it expects next, made before that command comes (docs/cards.md, "The answer
made ahead").

In the steady state a card's per-cycle INV_CTL answer is a fixed point: the master sends the same command again
with only its cycle number and WDT count advanced, and the card answers with the same fields, only the cycle and the
RWDT count advanced. Right after such an answer, a card (``Station.prediction``) can therefore say exactly which
command comes next and exactly what it will answer: a :class:`Prediction`. A slave worker checks each datagram of a
read against its station's prediction (:meth:`Prediction.answer_to`: one C call, no card code) and sends the
predicted answers at once; it hands the same datagrams to the card's ``receive`` right after the send, and counts any
answer that differs from the one sent (``mlink_sim.aio.slave.bus``). So the cards' work per cycle leaves the time
between a command and its answer, and what the card does with the command stays the same, with the same ``now``.

A prediction holds for a command that

* comes from the connected master (the same source);
* is the last command taken byte for byte but for its cycle, its WDT byte and its FCS, which is right
  (:func:`~mlink_sim.wire.frame.steady_delta`);
* carries the next cycle number (the last one plus the cycles of one communication cycle, so that the reception
  monitor counts no failure: :mod:`mlink_sim.cards.reception`) and the master's WDT count advanced by one (the
  watchdog's check holds: :mod:`mlink_sim.cards.watchdog`; the low nibble, the master's echo, is not read);
* arrives before :attr:`Prediction.until`: while the drive is steady nothing it shows changes
  (``Drive.quiet_until``). The card's silence deadline does not bound it: silence is counted only by the card's
  ``poll``, and whatever polls a card drops its prediction first (``Port.forget``); a command read after the
  deadline but before a poll is taken by the card as any other (a worker held up reads what queued before it polls:
  ``SlaveServer._on_tick``), and answered the same.

The card offers one only after an answer that repeated the one before in every field but the cycle and the RWDT,
with nothing pending that the next answer would show differently (each card's ``_fast_receive`` says what).

**A backlog.** When a worker fell behind (its CPU held by the host, or the master caught up on cycles a stall of
its own delayed), one read holds several commands for a station, each the one after the other. The fixed point
holds for each of them in turn, so a prediction that answered one can be moved on to the next
(:meth:`Prediction.advance`): the cycle after, the master's WDT count and the card's RWDT count each one further,
the same answer's fields. The worker answers the whole run ahead and the card then takes the commands in their
order; the card still checks every answer it would have given against the one sent.
"""

from __future__ import annotations

from typing import Any, Final

from mlink_sim.wire.frame import CYCLE_AT, Template, patch_seal, steady_delta

from .reception import ReceptionMonitor
from .watchdog import Watchdog

__all__ = ["Prediction", "offer"]

#: The bits of :func:`~mlink_sim.wire.frame.steady_delta`'s result a prediction fixes: the cycle (bits 0-31) and
#: the master's WDT count (bits 36-39); the WDT's low nibble (bits 32-35) is the master's echo of the RWDT.
_EXPECT_MASK: Final = 0xF0_FFFF_FFFF
_U32: Final = 0xFFFF_FFFF


class Prediction:
    """The answer a card will give to one command, known before it comes (see the module docstring)."""

    def __init__(self, source: Any, command: bytes, wdt_at: int, expect: int, answer: bytes, until: int,
                 body: bytes = b"", rwdt_at: int = 0, step: int = 0) -> None:
        self.source: Any = source      #: the connected master
        self.command: bytes = command  #: the command the next one repeats but for cycle, WDT and FCS
        self.wdt_at: int = wdt_at      #: the WDT byte's offset in the command datagram
        self.expect: int = expect      #: the next cycle | the master's next WDT count << 36
        self.answer: bytes = answer    #: the answer datagram, sealed
        self.until: int = until        #: the last ``now`` (ns) it holds for
        #: for :meth:`advance`: the answer without its FCS (cycle and RWDT zero; b"": it cannot advance), the RWDT
        #: byte's offset in it (the RWDT itself is read from :attr:`answer`), the cycles from one command to the next
        self.body: bytes = body
        self.rwdt_at: int = rwdt_at
        self.step: int = step
        #: the last datagram :meth:`answer_to` compared with :attr:`command` (the ``bytes`` a read gave: immutable),
        #: and what ``steady_delta`` gave: the card that then takes that very object does not compare it again
        #: (``Station._steady_delta``)
        self.checked: bytes = b""
        self.delta: int = -1

    def answer_to(self, datagram: bytes, source: Any, now: int) -> bytes | None:
        """:attr:`answer` when *datagram* from *source* at *now* is the command predicted, else None."""
        if now > self.until or (source is not self.source and source != self.source):
            return None
        d = self.delta = steady_delta(datagram, self.command, CYCLE_AT, self.wdt_at)
        self.checked = datagram
        if d < 0 or d & _EXPECT_MASK != self.expect:
            return None
        return self.answer

    def advance(self) -> bool:
        """Move on to the command after the one just answered, before the card took that one (a backlog: the
        module docstring): the next cycle, the master's WDT count and the card's RWDT count one further
        (:mod:`mlink_sim.cards.watchdog`), the answer sealed again. False where it cannot (no answer body): the
        card must take the commands answered so far first."""
        body = self.body
        if not body:
            return False
        expect = self.expect
        nxt = ((expect & _U32) + self.step) & _U32
        count = ((expect >> 36) + 1) & 0xF
        self.expect = nxt | count << 36
        rwdt_at = self.rwdt_at
        rwdt = (self.answer[rwdt_at] + 1) & 0xF | count << 4
        self.answer = patch_seal(body, CYCLE_AT, nxt, rwdt_at, rwdt)
        return True


def offer(pred: Prediction | None, source: Any, command: bytes, wdt_at: int, cycle: int, quiet_until: int,
          reception: ReceptionMonitor, watchdog: Watchdog, template: Template, now: int) -> Prediction | None:
    """The prediction after an answer to *cycle* from *template* that was a fixed point (``Station.prediction``
    decides that): the next command's cycle and WDT count, and the answer with the watchdog's next RWDT (its own
    count and the master's, each advanced by one). It holds until the drive's *quiet_until* (-1: no prediction),
    and None is returned when that is before *now* (the silence deadline: the module docstring). *pred*, the
    card's one object, is updated in place (None: a new one)."""
    if quiet_until < 0:
        return None
    until = quiet_until - 1  # the last instant that cannot differ
    if until < now:
        return None
    step = reception.cycles_per_comm
    nxt = (cycle + step) & _U32
    count = (watchdog.master + 1) & 0xF
    answer = template.seal(nxt, (watchdog.slave + 1) & 0xF | count << 4)
    if pred is None:
        return Prediction(source, command, wdt_at, nxt | count << 36, answer, until, template.body, template.wdt_at,
                          step)
    pred.source, pred.command, pred.wdt_at, pred.until = source, command, wdt_at, until
    pred.expect, pred.answer, pred.step = nxt | count << 36, answer, step
    pred.body, pred.rwdt_at = template.body, template.wdt_at
    return pred
