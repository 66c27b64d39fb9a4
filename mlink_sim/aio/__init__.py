"""asyncio/uvloop side of mlink-sim: moves bytes, keeps time (the wall clock's, or a virtual one)."""

from typing import Any

from .timing.ticker import STRATEGIES, CycleTimer, available_strategies

__all__ = ["CycleTimer", "available_strategies", "STRATEGIES", "VirtualNetwork"]


def __getattr__(name: str) -> Any:
    if name == "VirtualNetwork":  # imported on demand: it brings the config models and the card cores
        from .run.embed import VirtualNetwork

        return VirtualNetwork
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
