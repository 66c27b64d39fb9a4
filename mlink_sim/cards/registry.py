"""The card registry: a card's profile -> its station class, in the style of python-can's ``BACKENDS`` (the
profiles name the class as ``"module:Class"``, :mod:`mlink_sim.profiles`; the module is imported when a station of
that card is first created)."""

from __future__ import annotations

import importlib

from ..profiles import CardProfile, lookup
from .base import Station
from .settings import CardSettings

__all__ = ["create_card", "station_class"]

_CLASSES: dict[str, type[Station]] = {}  # profile key -> its station class, once imported


def station_class(card: str | CardProfile) -> type[Station]:
    """The station class of *card* (any spelling, or its profile): ``SiT3`` for ``"si-t3"``. Unknown card:
    :class:`ValueError` listing the cards; a profile whose class cannot be imported, or is no station:
    :class:`ValueError` naming it."""
    profile = card if isinstance(card, CardProfile) else lookup(card)
    cls = _CLASSES.get(profile.key)
    if cls is None:
        module, _, name = profile.station.partition(":")
        try:
            found = getattr(importlib.import_module(module), name)
        except (ImportError, AttributeError) as exc:
            raise ValueError(f"card {profile.key!r}: its station class {profile.station!r} cannot be "
                             f"imported ({exc})") from None
        if not (isinstance(found, type) and issubclass(found, Station)):
            raise ValueError(f"card {profile.key!r}: {profile.station!r} is not a Station class")
        cls = _CLASSES[profile.key] = found
    return cls


def create_card(name: str, *, settings: CardSettings, now: int, eeprom: bytes | None = None) -> Station:
    """Power up the card *name* (any spelling of a registered card, :func:`mlink_sim.profiles.lookup`) at *now*
    (monotonic ns) with *settings* and the EEPROM image saved by a previous run (``Station.take_eeprom()``), if any.
    Unknown *name*: :class:`ValueError` listing the cards. An unusable EEPROM image is ignored (logged, and shown
    as ``snapshot().eeprom_error``)."""
    profile = lookup(name)
    return station_class(profile)(profile, settings=settings, now=now, eeprom=eeprom)
