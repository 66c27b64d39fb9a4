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

**When a CONFIG to EEPROM is complete**: :mod:`mlink_sim.cards.writeback` (:class:`EepromWriteBack`, compiled with
the cards: a card reads its state with every command).
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any

from mlink_sim.params import ParamError, ParamTable

from .writeback import BUSY, EepromWriteBack

__all__ = ["EEPROM_VERSION", "EepromError", "EepromImage", "EepromWriteBack", "HISTORY_DEPTH", "BUSY", "PowerUp",
           "power_up"]

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


@dataclass(frozen=True)
class PowerUp:
    """What a station powers up with (:func:`power_up`)."""

    values: dict[str, int]  #: every parameter's raw value, by name
    saved: dict[str, int]  #: the values the EEPROM image holds (what CONFIG_MOD = 1 stored), by name
    history: tuple[str, ...]  #: the fault history the image holds, most recent first
    error: str | None  #: why the image was not used (None: it was, or there was none)


def power_up(card: str, table: ParamTable, eeprom: bytes | None, assignments: Mapping[str, int],
             log: Any) -> PowerUp:
    """The parameter values of a station at power-up: the table's defaults, then the values saved in the EEPROM
    image *eeprom* (as the card reads its EEPROM when the control power comes on), then the power-up settings'
    *assignments* (raw counts by name). An image that cannot be used is ignored whole and a saved value the table
    refuses (an unknown name, out of range) alone, each with a warning on *log*: the card powers up with its
    defaults rather than not at all. A bad assignment raises :class:`~mlink_sim.params.ParamError`."""
    values = table.defaults()
    image = None
    error = None
    if eeprom is not None:
        try:
            image = EepromImage.from_bytes(eeprom, card=card)
        except EepromError as exc:
            error = str(exc)
            log.warning("eeprom_ignored", reason=error)
    saved: dict[str, int] = {}
    if image is not None:
        for name, raw in image.params.items():
            p = table.get(name)
            try:
                if p is None:
                    raise ParamError(f"unknown parameter {name}")
                table.check(p, raw)
            except ParamError as exc:
                log.warning("eeprom_param_ignored", param=name, reason=str(exc))
                continue
            values[p.name] = saved[p.name] = raw
    for name, raw in assignments.items():
        p = table.by_name(name)
        table.check(p, raw)
        values[p.name] = raw
    return PowerUp(values, saved, image.fault_history if image is not None else (), error)
