"""The card registry: card name -> station class (in the style of python-can's ``BACKENDS``)."""

from __future__ import annotations

from collections.abc import Mapping
from types import MappingProxyType

from .base import Station
from .settings import CardSettings
from .si_et3 import SiEt3
from .si_t3 import SiT3
from .si_t_v7 import SiTV7

__all__ = ["CARDS", "create_card"]

#: Registry keys as the command line and the network TOML spell them.
CARDS: Mapping[str, type[Station]] = MappingProxyType({"si-t3": SiT3, "si-et3": SiEt3, "si-t-v7": SiTV7})


def create_card(name: str, *, settings: CardSettings, now: int, eeprom: bytes | None = None) -> Station:
    """Power up the card *name* at *now* (monotonic ns) with *settings* and the EEPROM image saved by a
    previous run (``Station.take_eeprom()``), if any. Unknown *name*: :class:`ValueError` listing the cards.
    An unusable EEPROM image is ignored (logged, and shown as ``snapshot().eeprom_error``)."""
    cls = CARDS.get(name)
    if cls is None:
        known = ", ".join(CARDS)
        raise ValueError(f"unknown option card {name!r} (known cards: {known})")
    return cls(settings=settings, now=now, eeprom=eeprom)
