"""Parameter and monitor tables per drive family, as pure data.

* :data:`A1000` – the A1000/GA-class drive behind SI-T3 and SI-ET3 (``a1000.py``);
* :data:`VS606V7` – the VS-606V7 behind SI-T/V7 (``v7.py``);
* :data:`FAMILIES` – ``{"a1000": A1000, "v7": VS606V7}``;
* :data:`CARDS` / :func:`for_card` – the table as a card sees it (``A1000_SI_T3`` narrows F6-01
  and F6-20 to SI-T3 Table 4; ``A1000_SI_ET3`` follows SI-ET3 Table 7); :func:`card_label` – a card as its manual
  names it.

Lookups: ``table.by_name("c1-01")``, ``table.by_register(0x0200)``; command line:
``table.parse_assignment("C1-01=5.0")`` -> ``(Param, 50)``.  See docs/parameters.md.
"""

from __future__ import annotations

from .a1000 import A1000, A1000_SI_ET3, A1000_SI_T3
from .table import FAMILY_TABLES, Param, ParamError, ParamTable
from .v7 import VS606V7

__all__ = [
    "A1000",
    "A1000_SI_ET3",
    "A1000_SI_T3",
    "CARDS",
    "FAMILIES",
    "Param",
    "ParamError",
    "ParamTable",
    "VS606V7",
    "card_label",
    "for_card",
]

FAMILIES: dict[str, ParamTable] = {"a1000": A1000, "v7": VS606V7}
FAMILY_TABLES.update(FAMILIES)

CARDS: dict[str, ParamTable] = {"si-t3": A1000_SI_T3, "si-et3": A1000_SI_ET3, "si-t/v7": VS606V7}



def _key(card: str) -> str:
    """A card's name without case and punctuation: "SI-T/V7", "si-t-v7" and "sitv7" are one card."""
    return "".join(ch for ch in card.lower() if ch.isalnum())


_CARD_KEYS = {_key(key): table for key, table in CARDS.items()}
_LABELS = {_key(label): label for label in ("SI-T3", "SI-ET3", "SI-T/V7")}


def card_label(card: str) -> str:
    """A card as its manual names it: "si-t-v7" -> "SI-T/V7"; a name it does not know as it is."""
    return _LABELS.get(_key(card), card)


def for_card(card: str) -> ParamTable:
    """The table a card uses: "SI-T3", "si-et3", "SI-T/V7" (punctuation and case ignored)."""
    try:
        return _CARD_KEYS[_key(card)]
    except KeyError:
        known = ", ".join(sorted(CARDS))
        raise ParamError(f"unknown option card '{card}' (known cards: {known})") from None
