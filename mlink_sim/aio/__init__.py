"""asyncio/uvloop side of mlink-sim: moves bytes, keeps time (the wall clock's, or a virtual one).

Sub-packages by role, each importing only those below it (the ``aio-layers`` contract in pyproject.toml):

* :mod:`.run` (the network run: ``up``, ``master``, the session, the timeline, the embedded virtual network) and
  :mod:`.tools` (the probe and the impairing proxy), independent of each other;
* :mod:`.virtual`: the virtual clock and the in-memory network;
* :mod:`.slave` (the slave server) and :mod:`.master` (the master runner), independent of each other;
* :mod:`.transport`: the sockets and the batched system calls;
* :mod:`.timing`: the cycle timer, timerfd, real-time scheduling, the arrival poll.

The package itself exports the cycle timer and, on first use, :class:`~mlink_sim.aio.run.embed.VirtualNetwork`.
"""

from typing import Any

from .timing.ticker import STRATEGIES, CycleTimer, available_strategies

__all__ = ["CycleTimer", "available_strategies", "STRATEGIES", "VirtualNetwork"]


def __getattr__(name: str) -> Any:
    if name == "VirtualNetwork":  # imported on demand: it brings the config models and the card cores
        from .run.embed import VirtualNetwork

        return VirtualNetwork
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
