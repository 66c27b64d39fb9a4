"""``mlink-sim`` with the tests' fifth card registered in its process (tests/cards/fifth_card.py): the program a
user who brings a card of their own runs instead of ``mlink-sim``. ``python tests/cards/fifth_card_cli.py slave
--card si-t3-lab --station 22H``."""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # the repository: tests.cards.fifth_card

from tests.cards.fifth_card import register

register()

from mlink_sim.cli import main  # noqa: E402 - the card first: the commands read the registry when they are made

main()
