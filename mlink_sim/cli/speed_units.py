"""INV_CTL's speed reference and output frequency in Hz: the station's units (A1000 o1-03, VS-606V7 n035) as a
capture tells them.

A capture's card note (``station 21H: card SI-T3 (MECHATROLINK-II, 32-byte), speed in 0.01 Hz counts``, written
by ``up``, ``master`` and ``slave`` from the drive's parameters at start) gives the Hz of one count. Without that
part, the card's defaults give it (o1-03 = 0 on the A1000, n035 = 0 on the VS-606V7: 0.01 Hz; SI-T3 Table 4,
SI-ET3 Table 7 and the drives' parameter tables, :mod:`mlink_sim.params`), and so does the link's card (SI-ET3 on
MECHATROLINK-III, SI-T/V7 on MECHATROLINK-I) or, for a MECHATROLINK-II station of unknown card, the default both
of its cards share; :meth:`SpeedUnits.of` says which.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache

from ..capture.text import card_of_note, speed_of_note
from ..drive import DriveSettings, Family
from ..drive.monitors import ref_to_hz
from ..params import ParamError, for_card
from ..profiles import default_for, lookup
from ..wire import Link

__all__ = ["Scale", "SpeedUnits", "default_hz_per_count"]



@dataclass(frozen=True)
class Scale:
    """Hz of one count of a station's speed reference and output frequency, and where that comes from."""

    hz_per_count: float
    source: str  #: ``the capture's note``, or ``default of SI-T3 (o1-03 = 0)`` …

    @property
    def assumed(self) -> bool:
        """The capture does not say: a default."""
        return self.source.startswith("default")

    def hz(self, raw: int) -> float:
        """*raw* counts in Hz (the magnitude: the direction is the run bits)."""
        return abs(raw) * self.hz_per_count


@cache
def default_hz_per_count(card: str) -> tuple[float, str]:
    """Hz of one count at the card's default parameters, and the setting behind it (``o1-03 = 0``); ParamError
    for a card it does not know."""
    profile = lookup(card)
    table = for_card(profile)
    values = table.defaults()
    settings = DriveSettings.from_params(Family(profile.family), values)
    param = profile.frequency_units
    return ref_to_hz(settings, 1), f"{param} = {values[param]}"


class SpeedUnits:
    """The :class:`Scale` of each station of a capture, from its notes (:meth:`learn` each one) or the defaults."""

    def __init__(self) -> None:
        self._noted: dict[int, float] = {}
        self._cards: dict[int, str] = {}

    def learn(self, comment: str) -> None:
        found = card_of_note(comment)
        if found is None:
            return
        station, card = found
        self._cards[station] = card
        hz = speed_of_note(comment)
        if hz is not None:
            self._noted[station] = hz

    def of(self, link: Link | str, station: int) -> Scale:
        if station in self._noted:
            return Scale(self._noted[station], "the capture's note")
        link = Link[link] if isinstance(link, str) else Link(link)
        assumed = default_for(link)
        card = self._cards.get(station) or (assumed.key if assumed is not None else None)
        if card is not None:
            try:
                hz, setting = default_hz_per_count(card)
                return Scale(hz, f"default of {lookup(card).label} ({setting})")
            except (ParamError, ValueError):
                pass  # a card this version does not know: as an unknown one
        hz_t3, set_t3 = default_hz_per_count("si-t3")
        hz_v7, set_v7 = default_hz_per_count("si-t-v7")
        if hz_t3 == hz_v7:  # the card is not known, but both cards of MECHATROLINK-II read the same
            return Scale(hz_t3, f"default ({set_t3} / {set_v7})")
        return Scale(hz_t3, f"default of SI-T3 ({set_t3}; the card is not known)")
