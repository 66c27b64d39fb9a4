"""The option card's non-volatile memory: saved parameters and the fault history.

SI-T3 / SI-ET3 CONFIG (Tables 12 / 15): CONFIG_MOD = 1 saves the setting values in EEPROM; SI-T3 ALM_RD:
"The fault history is saved in EEPROM and is kept even when the control power is interrupted" (also
SI-T/V7 ALM_RD). The image is serialised as JSON with a version field; the card hands the bytes to the
I/O layer (``Station.take_eeprom()``), which writes them atomically under ``--state-dir``, and gets them
back at power-up (``create_card(..., eeprom=...)``). Nothing here touches a file.

Format (version 1)::

    {"version": 1, "card": "si-t3", "params": {"C1-01": 50, ...}, "fault_history": ["bUS", "oC"]}

``params`` are raw counts by parameter name (only values that differ from the family default are kept);
``fault_history`` is most recent first, by operator display name (:class:`mlink_sim.drive.faults.Fault`
values), at most 10 entries.

**When a CONFIG to EEPROM is complete** (:class:`EepromWriteBack`): the manuals acknowledge a command through the
ready bit of its response – SI-T3 and SI-T/V7 "STATUS Field" bit 2 CMDRDY "Command ready: 0 Busy, 1 Ready" (SUBSTATUS
SUBCMDRDY "Sub-command can be received" for the SI-T/V7 CONFIG sub-command), SI-ET3 "Command Status (CMD_STAT)"
CMDRDY "1: Command reception enabled 0: Other". When an I/O layer persists the images (``enabled``), the CONFIG that
stores to EEPROM answers CMDRDY = 0 until the layer reports the image written, fsync'd and renamed
(:meth:`EepromWriteBack.durable`); the master repeats a busy command, and its repetition after that point is
answered CMDRDY = 1. Meanwhile every command of that slot is answered busy and not executed. A write that fails
completes the CONFIG with A.94 / CMD_ALM 9H, the code SI-ET3 gives a "Writing Error during Parameter Processing".
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType

from .results import Err

__all__ = ["EEPROM_VERSION", "EepromError", "EepromImage", "EepromWriteBack", "HISTORY_DEPTH", "BUSY"]

EEPROM_VERSION = 1
HISTORY_DEPTH = 10  #: U3-01 … U3-10 (SI-T3 Table 14)
_MAX_BYTES = 1 << 20


class EepromError(ValueError):
    """An EEPROM image that cannot be used (corrupt, another card, a newer version)."""


@dataclass(frozen=True)
class EepromImage:
    """One EEPROM image: the card it belongs to, saved parameter values and the fault history."""

    card: str
    params: Mapping[str, int] = field(default_factory=dict)
    fault_history: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        object.__setattr__(self, "params", MappingProxyType(dict(self.params)))
        object.__setattr__(self, "fault_history", tuple(self.fault_history)[:HISTORY_DEPTH])

    def to_bytes(self) -> bytes:
        doc = {
            "version": EEPROM_VERSION,
            "card": self.card,
            "params": dict(sorted(self.params.items())),
            "fault_history": list(self.fault_history),
        }
        return (json.dumps(doc, indent=1, ensure_ascii=False) + "\n").encode("utf-8")

    @classmethod
    def from_bytes(cls, data: bytes, *, card: str) -> EepromImage:
        """Parse and check an image for *card*; raises :class:`EepromError` with a one-line reason."""
        if len(data) > _MAX_BYTES:
            raise EepromError(f"EEPROM image of {len(data)} bytes is too large")
        try:
            doc = json.loads(data.decode("utf-8"))
        except (UnicodeDecodeError, json.JSONDecodeError) as exc:
            raise EepromError(f"EEPROM image is not valid JSON: {exc}") from None
        if not isinstance(doc, dict):
            raise EepromError("EEPROM image is not a JSON object")
        version = doc.get("version")
        if version != EEPROM_VERSION:
            raise EepromError(f"EEPROM image version {version!r} is not supported (expected {EEPROM_VERSION})")
        if doc.get("card") != card:
            raise EepromError(f"EEPROM image belongs to card {doc.get('card')!r}, not {card!r}")
        params = doc.get("params", {})
        history = doc.get("fault_history", [])
        if not isinstance(params, dict) or not all(
            isinstance(k, str) and isinstance(v, int) and not isinstance(v, bool) for k, v in params.items()
        ):
            raise EepromError("EEPROM image 'params' must map parameter names to integers")
        if not isinstance(history, list) or not all(isinstance(f, str) for f in history):
            raise EepromError("EEPROM image 'fault_history' must be a list of fault names")
        return cls(card, params, tuple(history))


#: CONFIG is 04H on both generations (SI-T3 Table 5 / SI-T/V7 §7.1, SI-ET3 Table 11).
_CONFIG = 0x04
#: :meth:`EepromWriteBack.hold`: answer the command busy (CMDRDY / SUBCMDRDY = 0) and do not execute it.
BUSY = object()


@dataclass(slots=True)
class _Wait:
    sub: bool  #: the CONFIG came as a sub-command (SI-T/V7 §7.2)
    generation: int  #: the image that must be durable
    failed: bool = False  #: that image could not be written


class EepromWriteBack:
    """Generations of the EEPROM content and the CONFIG that waits for one to be durable (see the module text).

    ``changed()`` bumps the generation (``dirty`` until ``take()``); the I/O layer takes an image, records ``taken``
    and reports it with ``durable(generation, ok)``. ``hold(sub, code)`` tells a card how to treat a command."""

    __slots__ = ("enabled", "dirty", "generation", "taken", "saved", "wait")

    def __init__(self) -> None:
        #: True when an I/O layer persists the images and calls :meth:`durable` (``mlink_sim.aio.slave``);
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
