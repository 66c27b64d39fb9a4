"""asyncio/uvloop side of mlink-sim: moves bytes, keeps time."""

from .ticker import STRATEGIES, CycleTimer, available_strategies

__all__ = ["CycleTimer", "available_strategies", "STRATEGIES"]
