"""Slave stations: the SI-T3 (MECHATROLINK-II), SI-ET3 (MECHATROLINK-III) and SI-T/V7 (MECHATROLINK-I/II) option
cards as sans-I/O state machines (docs/cards.md); which cards there are, and what each is, is their profiles'
table (:mod:`mlink_sim.profiles`).

>>> from mlink_sim.cards import CardSettings, create_card
>>> station = create_card("si-t3", settings=CardSettings(), now=0)
>>> station.address, station.data_size, station.phase
(33, 32, 1)
"""

from .base import DriveSnapshot, Station, StationCounters, StationSnapshot
from .eeprom import EepromError, EepromImage
from .registry import create_card, station_class
from .settings import CardOptions, CardSettings, settings_for

__all__ = [
    "CardOptions",
    "CardSettings",
    "DriveSnapshot",
    "EepromError",
    "EepromImage",
    "Station",
    "StationCounters",
    "StationSnapshot",
    "create_card",
    "settings_for",
    "station_class",
]
