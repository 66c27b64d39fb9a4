"""Keep the garbage collector's full collections off the cycle.

A full (generation 2) collection walks every object alive. In a master or slave process after start-up, that
is tens of thousands of objects (pydantic models, construct layouts, the drive tables), and one pass takes tens
of milliseconds (docs/performance.md, "Garbage collection"): at a 2 ms cycle, many cycles without a command, so
every slave would report a communication alarm and trip bUS. Freezing the
start-up heap (:func:`gc.freeze`) moves those objects out of the collector's reach, and later collections only
scan what the run itself allocates.

Touches: the garbage collector of this process.
"""

from __future__ import annotations

import gc

__all__ = ["settle_heap"]


def settle_heap(*, collect: bool = True) -> None:
    """Collect once, then freeze everything alive: call after start-up, before the cycle starts. *collect* False
    freezes without the collection (the virtual clock, whose quickstart runs in well under a second of wall time,
    which the collection would take a large part of: docs/performance.md, "Garbage collection"; what start-up
    left as garbage then stays)."""
    if collect:
        gc.collect()
    gc.freeze()
