"""The generations of a card's EEPROM content and the CONFIG that waits for one to be durable
(:class:`EepromWriteBack`); :mod:`mlink_sim.cards.eeprom` has the image itself.

**When a CONFIG to EEPROM is complete**: the manuals acknowledge a command through the
ready bit of its response – SI-T3 and SI-T/V7 "STATUS Field" bit 2 CMDRDY "Command ready: 0 Busy, 1 Ready" (SUBSTATUS
SUBCMDRDY "Sub-command can be received" for the SI-T/V7 CONFIG sub-command), SI-ET3 "Command Status (CMD_STAT)"
CMDRDY "1: Command reception enabled 0: Other". When an I/O layer persists the images (``enabled``), the CONFIG that
stores to EEPROM answers CMDRDY = 0 until the layer reports the image written, fsync'd and renamed
(:meth:`EepromWriteBack.durable`); the master repeats a busy command, and its repetition after that point is
answered CMDRDY = 1. Meanwhile every command of that slot is answered busy and not executed. A write that fails
completes the CONFIG with A.94 / CMD_ALM 9H, the code SI-ET3 gives a "Writing Error during Parameter Processing".

A module of its own so that it is compiled with the cards (``mlink_sim._accel.COMPILED_MODULES``): a card reads
:attr:`EepromWriteBack.wait` and :attr:`EepromWriteBack.dirty` with every command it takes, and a native class
answers that without a dictionary or descriptor lookup.
"""

from __future__ import annotations

from dataclasses import dataclass

from .results import Err

__all__ = ["BUSY", "EepromWriteBack"]

#: CONFIG is 04H on both generations (SI-T3 Table 5 / SI-T/V7 §7.1, SI-ET3 Table 11).
_CONFIG = 0x04
#: :meth:`EepromWriteBack.hold`: answer the command busy (CMDRDY / SUBCMDRDY = 0) and do not execute it.
BUSY = object()


@dataclass
class _Wait:
    sub: bool  #: the CONFIG came as a sub-command (SI-T/V7 §7.2)
    generation: int  #: the image that must be durable
    failed: bool = False  #: that image could not be written


class EepromWriteBack:
    """Generations of the EEPROM content and the CONFIG that waits for one to be durable (see the module text).

    ``changed()`` bumps the generation (``dirty`` until ``take()``); the I/O layer takes an image, records ``taken``
    and reports it with ``durable(generation, ok)``. ``hold(sub, code)`` tells a card how to treat a command."""

    def __init__(self) -> None:
        #: True when an I/O layer persists the images and calls :meth:`durable` (``mlink_sim.aio.slave.server``);
        #: False: nothing is persisted and a CONFIG to EEPROM completes at once.
        self.enabled = False
        self.dirty = False
        self.generation = 0  #: of the content, +1 per change
        self.taken = 0  #: of the image the last take() handed out
        self.saved = 0  #: highest generation reported durable
        self.wait: _Wait | None = None

    def changed(self, *, config_sub: bool | None = None) -> None:
        """The content changed; *config_sub* not None: by a CONFIG (a sub-command when True) that waits for it."""
        self.dirty = True
        self.generation += 1
        if config_sub is not None and self.enabled:
            self.wait = _Wait(config_sub, self.generation)

    def take(self) -> bool:
        """Hand the current content out (True) if it changed since the last time."""
        if not self.dirty:
            return False
        self.dirty = False
        self.taken = self.generation
        return True

    def durable(self, generation: int, ok: bool) -> bool:
        """The image of *generation* is written, fsync'd and renamed (*ok*) or failed; returns *ok*."""
        if ok:
            self.saved = max(self.saved, generation)
        elif self.wait is not None and self.wait.generation <= generation:
            self.wait.failed = True
        return ok

    def busy(self, sub: bool) -> bool:
        """A CONFIG (main, or sub-command when *sub*) waits for its image: CMDRDY / SUBCMDRDY = 0."""
        w = self.wait
        return w is not None and w.sub is sub and not w.failed and self.saved < w.generation

    def hold(self, sub: bool, code: int) -> object:
        """How to treat a main command (a sub-command when *sub*) with *code*: None = process it; :data:`BUSY` =
        "command reception disabled" while a CONFIG waits (answer busy, execute nothing); an :class:`Err` = the
        waited-for CONFIG is complete: answer its repetition with this verdict without executing it again. Once the
        image is durable (or failed) the wait ends with the next command of that slot."""
        w = self.wait
        if w is None or w.sub is not sub:
            return None
        if self.busy(sub):
            return BUSY
        self.wait = None
        if code != _CONFIG:
            return None  # the master moved on: processed normally
        return Err.DATA if w.failed else Err.OK
