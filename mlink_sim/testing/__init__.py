"""Testing support: a network running beside a test, live figures, and the pytest plugin (``mlink_network``).

The plugin is registered through the ``pytest11`` entry point when mlink-sim is installed; see docs/ci.md.
"""

from .harness import NetworkNotUp, RunningNetwork
from .metrics import Latency, MetricsView, StationMetricsView
from .stalls import beyond_the_bound, run_beyond_the_bound
from .virtual import VirtualRunningNetwork

__all__ = ["RunningNetwork", "VirtualRunningNetwork", "NetworkNotUp", "MetricsView", "Latency",
           "StationMetricsView", "beyond_the_bound", "run_beyond_the_bound"]
