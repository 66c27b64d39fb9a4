"""settle_heap (mlink_sim.aio.timing.heap): the start-up heap is frozen, so later full collections skip it."""

from __future__ import annotations

import gc
import weakref

from mlink_sim.aio.timing.heap import settle_heap


def test_settle_heap_freezes_what_is_alive() -> None:
    try:
        settle_heap()
        frozen = gc.get_freeze_count()
        assert frozen > 1000  # the interpreter, pytest and mlink_sim's modules at least
    finally:
        gc.unfreeze()


def test_settle_heap_without_collect_keeps_start_up_garbage_frozen() -> None:
    class Cycle:
        other: object

    a, b = Cycle(), Cycle()
    a.other, b.other = b, a  # a reference cycle: only a collection frees it
    gone = weakref.ref(a)
    del a, b
    try:
        settle_heap(collect=False)
        gc.collect()  # a later full collection does not reach the frozen heap
        assert gone() is not None and gc.get_freeze_count() > 1000
    finally:
        gc.unfreeze()
        gc.collect()
