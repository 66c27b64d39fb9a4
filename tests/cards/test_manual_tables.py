"""Two hops from the card module to any table of its manual: each card module's ``MANUAL_TABLES`` lists every table
of the manual (titles checked against ../shared/manuals), names where it is implemented, and that place cites the
table by its own number, so grepping "SI-T3 Table 22" finds it."""

from __future__ import annotations

import importlib
import re
from pathlib import Path
from typing import Any

import pytest

from .helpers import module_source

from mlink_sim.cards import si_et3, si_t3, si_t_v7

MANUALS = Path(__file__).resolve().parents[3] / "shared" / "manuals"
CARDS = {  # card module, manual file, how a citation names the manual outside the card module
    "si-t3": (si_t3, "SI-T3_MECHATROLINK-II_technical_manual.txt", ("SI-T3",)),
    "si-et3": (si_et3, "SI-ET3_MECHATROLINK-III_technical_manual.txt", ("SI-ET3",)),
    "si-t-v7": (si_t_v7, "SI-T-V7_MECHATROLINK-I-II_technical_manual.txt", ("SI-T/V7", "V7")),
}


def _manual_tables(name: str) -> dict[int, str]:
    path = MANUALS / name
    if not path.exists():
        pytest.skip(f"manual not available: {path}")
    tables: dict[int, str] = {}
    for line in path.read_text(encoding="utf-8").splitlines():
        m = re.match(r"\s*Table (\d+)\s+([A-Z].*\S)\s*$", line)
        if m and int(m.group(1)) not in tables:
            tables[int(m.group(1))] = re.sub(r"\s+", " ", m.group(2))
    return tables


def _resolve(target: str) -> tuple[Any, Any]:
    """``"cards.alarms.ML2_RECEPTION_FAILURES"`` -> (module, object)."""
    parts = target.split(".")
    for i in range(len(parts), 0, -1):
        try:
            module = importlib.import_module("mlink_sim." + ".".join(parts[:i]))
        except ModuleNotFoundError:
            continue
        obj: Any = module
        for attr in parts[i:]:
            obj = getattr(obj, attr)
        return module, obj
    raise AssertionError(f"{target}: no such module")


@pytest.mark.parametrize("card", sorted(CARDS))
def test_the_card_module_lists_every_table_of_its_manual(card: str) -> None:
    module, manual, _ = CARDS[card]
    assert {n: title for n, (title, _) in module.MANUAL_TABLES.items()} == _manual_tables(manual)


@pytest.mark.parametrize("card", sorted(CARDS))
def test_each_table_is_cited_by_its_own_number_where_it_is_implemented(card: str) -> None:
    """One hop from the index: the target's module says "<manual> Table n" (the card's own module: "Table n")."""
    module, _, prefixes = CARDS[card]
    missing = []
    for n, (_, target) in module.MANUAL_TABLES.items():
        if target is None:
            continue
        where, _obj = _resolve(target)
        text = module_source(where)
        cites = [rf"{re.escape(p)} Table {n}\b" for p in prefixes]
        if where is module:
            cites.append(rf"\bTable {n}\b")
        if not any(re.search(c, text) for c in cites):
            missing.append(f"Table {n} -> {target}")
    assert missing == []
