"""settle_heap (mlink_sim.aio.heap): the start-up heap is frozen, so later full collections skip it."""

from __future__ import annotations

import gc

from mlink_sim.aio.heap import settle_heap


def test_settle_heap_freezes_what_is_alive() -> None:
    try:
        settle_heap()
        frozen = gc.get_freeze_count()
        assert frozen > 1000  # the interpreter, pytest and mlink_sim's modules at least
    finally:
        gc.unfreeze()
