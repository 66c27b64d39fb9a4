"""A fifth card for the tests, made the way docs/architecture.md ("Card profiles") says a card is added: its module
(this one) and one profile record, registered; no other module is touched.

The card is an SI-T3 under a key and label of its own that speaks MECHATROLINK-II only and takes the addresses
21H–2FH: what the config, ``--card``, ``--link`` and the master take from the record shows in every check. Its
station class is the SI-T3's own: on a compiled build the package's cards are mypyc classes, which a class defined
outside the build cannot derive from (a card of the package is compiled with the rest: its record in
``profiles.BUILTIN`` puts its module in ``_accel.COMPILED_MODULES``).
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager

from mlink_sim import profiles
from mlink_sim.cards.si_t3 import SiT3

__all__ = ["PROFILE", "SiT3Lab", "register", "registered"]

#: The station class the profile names (``tests.cards.fifth_card:SiT3Lab``).
SiT3Lab = SiT3

PROFILE = profiles.CardProfile(
    key="si-t3-lab", label="SI-T3/LAB", manual="SI-T3 MECHATROLINK-II technical manual",
    station=f"{__name__}:SiT3Lab", family="a1000", params="A1000_SI_T3",
    frames={"ML2": (32, 17)}, addresses=(0x21, 0x2F), selections="SI-T3",
    max_frequency="E1-04", frequency_units="o1-03", motor_speed="U1-05",
    sources={
        "frames": "SI-T3 Table 4 F6-21 (0 = 32-byte), MECHATROLINK-II only (the test card's choice)",
        "addresses": "SI-T3 Table 4 F6-20, 21H–2FH (the test card's choice)",
        "motor_speed": "SI-T3 Table 18: SEL_MON 1 is U1-05 motor speed",
    },
)


def register() -> profiles.CardProfile:
    """Register the card in this process (what a program that brings its own card does at start)."""
    return profiles.register(PROFILE)


@contextmanager
def registered() -> Iterator[profiles.CardProfile]:
    """The card registered for the time of a test; the registry as it was afterwards."""
    saved = [dict(getattr(profiles, name)) for name in ("_PROFILES", "_SPELLINGS", "_ASSUMED")]
    try:
        yield register()
    finally:
        for name, content in zip(("_PROFILES", "_SPELLINGS", "_ASSUMED"), saved, strict=True):
            table = getattr(profiles, name)
            table.clear()
            table.update(content)
