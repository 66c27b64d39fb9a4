"""Which sub-command may travel with which main command: the manuals' combination tables, as data.

The one source of these tables; the cards (:mod:`mlink_sim.cards.phases`, which answer a forbidden combination
with A.95 / CMD_ALM BH) and the master (:mod:`mlink_sim.master.codec`, which never sends one) both read them.

* :data:`ML2_COMBINATIONS` – SI-T3 Table 7 "Main Command and Sub-command" (OK / NG (A.95)).
* :data:`V7_COMBINATIONS` – the SI-T/V7 manual has no combination table; SI-T3 Table 7 plus a column for the
  SI-T/V7's own CONFIG sub-command (V7 §7.2), marked like PRM_WR (docs/cards.md).
* :data:`ML3_COMBINATIONS` – SI-ET3 Table 13 "Main Commands and Sub-Commands" (OK / - = CMD_ALM BH).

Each table maps a main-command code to the frozenset of sub-command codes it accepts. The rows below are the
manuals' rows, column for column (``O`` = OK, ``-`` = NG); tests/wire/test_tables.py reads them against the
manual text.
"""

from __future__ import annotations

from collections.abc import Mapping
from types import MappingProxyType
from typing import TypeVar

from .codes import M2Cmd, M3Cmd

__all__ = [
    "ML2_COLUMNS",
    "ML2_COMBINATIONS",
    "V7_COLUMNS",
    "V7_COMBINATIONS",
    "ML3_COLUMNS",
    "ML3_COMBINATIONS",
    "combination_ok",
    "forbids",
]

Combinations = Mapping[int, frozenset[int]]
_Code = TypeVar("_Code", bound=int)  # M2Cmd or M3Cmd


def _combos(rows: Mapping[_Code, str], columns: tuple[int, ...]) -> Combinations:
    """Rows of 'O'/'-' marks per sub-command column -> main code -> allowed sub-command codes."""
    out: dict[int, frozenset[int]] = {}
    for main, marks in rows.items():
        marks = marks.replace(" ", "")
        if len(marks) != len(columns):
            raise ValueError(f"combination row {main:#04x}: {len(marks)} marks for {len(columns)} columns")
        out[int(main)] = frozenset(int(c) for c, m in zip(columns, marks, strict=True) if m == "O")
    return MappingProxyType(out)


#: SI-T3 Table 7 columns: NOP (00H), PRM_RD (01H), PRM_WR (02H), ALM_RD (05H), INV_I/O (41H).
ML2_COLUMNS = (M2Cmd.NOP, M2Cmd.PRM_RD, M2Cmd.PRM_WR, M2Cmd.ALM_RD, M2Cmd.INV_IO)
_ML2_ROWS = {  # SI-T3 Table 7 "Main Command and Sub-command": O = OK, - = NG (A.95)
    M2Cmd.NOP: "O O O O O",
    M2Cmd.PRM_RD: "O - - O O",
    M2Cmd.PRM_WR: "O - - O O",
    M2Cmd.ID_RD: "O O O O O",
    M2Cmd.CONFIG: "O - - - -",
    M2Cmd.ALM_RD: "O - - - -",
    M2Cmd.ALM_CLR: "O - - - -",
    M2Cmd.SYNC_SET: "O O O O O",
    M2Cmd.CONNECT: "O - - - -",
    M2Cmd.DISCONNECT: "O - - - -",
    M2Cmd.INV_CTL: "O O O O O",
}
ML2_COMBINATIONS: Combinations = _combos(_ML2_ROWS, ML2_COLUMNS)

#: SI-T/V7: SI-T3 Table 7 plus a CONFIG sub-command column (V7 §7.2) marked like PRM_WR (docs/cards.md).
V7_COLUMNS = (*ML2_COLUMNS, M2Cmd.CONFIG)
V7_COMBINATIONS: Combinations = _combos(
    {main: marks + " " + marks.replace(" ", "")[2] for main, marks in _ML2_ROWS.items()}, V7_COLUMNS
)

#: SI-ET3 Table 13 columns: NOP (00H), PRM_RD (01H), PRM_WR (02H), ALM_RD (05H), INV_I/O (51H).
ML3_COLUMNS = (M3Cmd.NOP, M3Cmd.PRM_RD, M3Cmd.PRM_WR, M3Cmd.ALM_RD, M3Cmd.INV_IO)
_ML3_ROWS = {  # SI-ET3 Table 13 "Main Commands and Sub-Commands": O = OK, - = CMD_ALM BH
    M3Cmd.NOP: "O O O O O",
    M3Cmd.PRM_RD: "O - - O O",
    M3Cmd.PRM_WR: "O - - O O",
    M3Cmd.ID_RD: "O O O O O",
    M3Cmd.CONFIG: "O - - - -",
    M3Cmd.ALM_RD: "O - - - -",
    M3Cmd.ALM_CLR: "O - - - -",
    M3Cmd.SYNC_SET: "O O O O O",
    M3Cmd.CONNECT: "O - - - -",
    M3Cmd.DISCONNECT: "O - - - -",
    M3Cmd.INV_CTL: "O O O O O",
}
ML3_COMBINATIONS: Combinations = _combos(_ML3_ROWS, ML3_COLUMNS)


def combination_ok(table: Combinations, main: int, sub: int) -> bool:
    """The slave's reading: True if sub-command *sub* may accompany main command *main*; a main command the
    table does not list allows only NOP (its code is unsupported anyway: A.95 / CMD_ALM 8H)."""
    allowed = table.get(main)
    if allowed is None:
        return sub == 0
    return sub in allowed


def forbids(table: Combinations, main: int, sub: int) -> bool:
    """The master's reading: True only where the table marks the pair NG. A main command whose row is all OK, or
    one the table does not list, forbids nothing (an unknown code is the slave's to refuse)."""
    allowed = table.get(main)
    if allowed is None or len(allowed) == max(map(len, table.values())):
        return False
    return sub not in allowed
