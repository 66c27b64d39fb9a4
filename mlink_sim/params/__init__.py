"""Parameter and monitor tables per drive family, as pure data.

* :data:`A1000` – the A1000/GA-class drive behind SI-T3 and SI-ET3 (``a1000.py``);
* :data:`VS606V7` – the VS-606V7 behind SI-T/V7 (``v7.py``);
* :data:`FAMILIES` – ``{"a1000": A1000, "v7": VS606V7}``;
* :func:`for_card` – the table as a card sees it, the one its profile names (``CardProfile.params``:
  ``A1000_SI_T3`` narrows F6-01 and F6-20 to SI-T3 Table 4; ``A1000_SI_ET3`` follows SI-ET3 Table 7).

Lookups: ``table.by_name("c1-01")``, ``table.by_register(0x0200)``; command line:
``table.parse_assignment("C1-01=5.0")`` -> ``(Param, 50)``.  See docs/parameters.md.
"""

from __future__ import annotations

from ..profiles import CardProfile, lookup
from .a1000 import A1000, A1000_SI_ET3, A1000_SI_T3
from .table import FAMILY_TABLES, Param, ParamError, ParamTable
from .v7 import VS606V7

__all__ = [
    "A1000",
    "A1000_SI_ET3",
    "A1000_SI_T3",
    "FAMILIES",
    "Param",
    "ParamError",
    "ParamTable",
    "VS606V7",
    "for_card",
]

FAMILIES: dict[str, ParamTable] = {"a1000": A1000, "v7": VS606V7}
FAMILY_TABLES.update(FAMILIES)


def for_card(card: str | CardProfile) -> ParamTable:
    """The table a card uses, the one its profile names: "SI-T3", "si-et3", "SI-T/V7" (any spelling,
    :func:`mlink_sim.profiles.lookup`) or the profile itself. An unknown card: :class:`ParamError` listing the
    cards."""
    try:
        profile = card if isinstance(card, CardProfile) else lookup(card)
    except ValueError as exc:
        raise ParamError(str(exc)) from None
    table = globals().get(profile.params)
    if not isinstance(table, ParamTable):
        raise ParamError(f"card {profile.key!r}: no parameter table {profile.params!r} in mlink_sim.params")
    return table
