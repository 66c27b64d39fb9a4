"""Keep the garbage collector's full collections off the cycle.

A full (generation 2) collection walks every object alive. In a master or slave process after start-up, that
is tens of thousands of objects (pydantic models, construct layouts, the drive tables), and one pass took
28–56 ms (measured with ``gc.callbacks`` in ``mlink-sim up configs/quickstart.toml``). At a 2 ms cycle that is
15–25 cycles without a command, so every slave reported a communication alarm and tripped bUS. Freezing the
start-up heap (:func:`gc.freeze`) moves those objects out of the collector's reach, and later collections only
scan what the run itself allocates.

Touches: the garbage collector of this process.
"""

from __future__ import annotations

import gc

__all__ = ["settle_heap"]


def settle_heap(*, collect: bool = True) -> None:
    """Collect once, then freeze everything alive: call after start-up, before the cycle starts. *collect* False
    freezes without the collection (the virtual clock: the collection alone costs 0.10–0.16 s, a quarter of the
    quickstart's budget; what start-up left as garbage then stays)."""
    if collect:
        gc.collect()
    gc.freeze()
