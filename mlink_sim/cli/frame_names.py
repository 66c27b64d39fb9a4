"""Names and units in decoded frames (``mlink-sim decode``): the parameter a PRM_RD / PRM_WR addresses, with its
value in engineering units, and the names of the status bits, where the station's card is known.

The card of a station comes from, in this order: ``--card ADDR=CARD``, ``--card CARD`` (every station), the
capture's note ``station 21H: card SI-T3`` (the master writes one per station when it starts recording), and
the link (:func:`mlink_sim.profiles.default_for`: MECHATROLINK-III is taken for the SI-ET3, MECHATROLINK-I for the
SI-T/V7). A MECHATROLINK-II station of unknown card (SI-T3 or SI-T/V7) keeps its raw NO and data. The card picks
the parameter table (:func:`mlink_sim.params.for_card`: the A1000 rows for SI-T3 / SI-ET3, the VS-606V7 n-numbers
for SI-T/V7).
"""

from __future__ import annotations

import copy
from typing import Any

from ..capture.text import card_of_note
from ..master import status_bits
from ..params import Param, ParamError, ParamTable, for_card
from ..profiles import default_for, lookup
from ..wire import Frame, Link, M2Alarm, describe

__all__ = ["FrameNames", "parse_card"]

#: A.94 / A.95: the answer's data is not the register's (SI-T3 Table 25)
_REFUSALS_ML2 = (int(M2Alarm.DATA_SETTING_WARNING), int(M2Alarm.COMMAND_WARNING))


def parse_card(text: str) -> tuple[int | None, str]:
    """``--card``: ``"si-t3"`` (every station) or ``"0x22=si-t-v7"`` / ``"22H=SI-T/V7"`` (any spelling of a card);
    the card as its key; ValueError with the reason."""
    from ..units import parse_address

    station: int | None = None
    card = text
    if "=" in text:
        left, card = (part.strip() for part in text.split("=", 1))
        station = parse_address(left)
    return station, lookup(card).key


class FrameNames:
    """Adds names to :func:`~mlink_sim.wire.describe`'s dict of a frame: ``param`` in each PRM_RD / PRM_WR body
    (name, register, value, unit, text) and ``invcmd_stat_bits`` in an INV_CTL response on MECHATROLINK-III
    (SI-ET3 "INVCMD_STAT"; MECHATROLINK-II STATUS bits are named by ``describe`` itself)."""

    def __init__(self, cards: dict[int, str] | None = None, card: str | None = None) -> None:
        self.cards = dict(cards or {})  #: given on the command line, by station
        self.card = card  #: given on the command line for every station
        self.noted: dict[int, str] = {}  #: from the capture's notes

    def learn(self, comment: str) -> None:
        """Take the card of a station from a capture note (``station 21H: card SI-T3 …``)."""
        found = card_of_note(comment)
        if found is not None:
            self.noted[found[0]] = found[1]

    def card_of(self, link: Link, station: int) -> str | None:
        assumed = default_for(link)
        return (self.cards.get(station) or self.card or self.noted.get(station)
                or (assumed.key if assumed is not None else None))

    def table(self, link: Link, station: int) -> ParamTable | None:
        card = self.card_of(link, station)
        if card is None:
            return None
        try:
            return for_card(card)
        except ParamError:  # a note of a card this process does not know
            return None

    def describe(self, frame: Frame) -> dict[str, Any]:
        """``describe(frame)`` with the names added (a copy: ``describe``'s own dict is what replay compares)."""
        d = copy.deepcopy(describe(frame))
        link = Link(frame.link)
        table = self.table(link, frame.station)
        refused = bool(d.get("alarm") in _REFUSALS_ML2 or d.get("cmd_stat", {}).get("cmd_alm"))
        sub_refused = bool(d.get("substatus_bits") and {"SUBALM", "SUBWARNG"} & set(d["substatus_bits"])
                           or d.get("sub_stat", {}).get("subcmd_alm"))
        for key, no_value in (("main", refused), ("sub", sub_refused)):
            body = d.get(key)
            if body is not None and table is not None and body["command"] in ("PRM_RD", "PRM_WR"):
                param = table.by_register(body.get("no", -1))
                if param is not None:
                    body["param"] = _param(param, body, no_value)
        if link is Link.ML3 and "invcmd_stat" in d["main"]:
            d["main"]["invcmd_stat_bits"] = list(status_bits(link, d["main"]["invcmd_stat"]))
        return d


def _param(param: Param, body: dict[str, Any], no_value: bool) -> dict[str, Any]:
    """The ``param`` entry of a PRM_RD / PRM_WR body: the value when the body carries one (a PRM_RD answer, a
    PRM_WR) of a 2-byte register."""
    out: dict[str, Any] = {"name": param.name, "register": param.register, "title": param.title}
    head = f"{param.name} ({param.register:04X}H)"
    data = body.get("parameter", body.get("data"))
    if data is None or no_value or body.get("size") != 2:
        extra = "" if body.get("size") == 2 else f" size={body.get('size')}"
        out["text"] = head + extra + (f" data={data}" if data is not None and body.get("size") != 2 else "")
        return out
    raw = param.decode(int.from_bytes(bytes.fromhex(data)[:2], "little"))
    out.update(value=param.to_eng(raw), unit=param.eng_unit, raw=raw, text=f"{head} = {param.format(raw)}")
    return out
