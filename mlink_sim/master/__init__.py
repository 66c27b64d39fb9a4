"""MECHATROLINK master core, sans-I/O (docs/master.md).

>>> from mlink_sim.wire import Link
>>> from mlink_sim.master import MasterCore, NetworkPlan, StationPlan
>>> core = MasterCore(NetworkPlan(Link.ML2, 1_000_000, (StationPlan(0x21, Link.ML2),)))
>>> [(station, len(datagram)) for station, datagram in core.on_cycle(0, now=0)]
[(33, 46)]
"""

from .codec import compatible
from .commands import Cmd
from .core import MasterCore
from .machine import IllegalTransition
from .plan import TCYCLE_RANGE_NS, NetworkPlan, StationPlan
from .types import (
    AlarmCleared,
    AlarmRaised,
    Control,
    Dropped,
    Event,
    Late,
    MasterDrop,
    MasterError,
    Missing,
    Recovered,
    RunHeld,
    RunResumed,
    Request,
    RequestTimeout,
    Rtt,
    StateChanged,
    StationAlarmError,
    StationDisconnected,
    StationState,
    StationView,
    ParamRequestError,
    ParamValue,
    status_bits,
)

__all__ = [
    "MasterCore",
    "NetworkPlan",
    "StationPlan",
    "TCYCLE_RANGE_NS",
    "StationState",
    "StationView",
    "ParamRequestError",
    "ParamValue",
    "status_bits",
    "Control",
    "Request",
    "Event",
    "Rtt",
    "Missing",
    "Late",
    "Dropped",
    "StateChanged",
    "AlarmRaised",
    "AlarmCleared",
    "Recovered",
    "RunHeld",
    "RunResumed",
    "MasterDrop",
    "MasterError",
    "StationAlarmError",
    "RequestTimeout",
    "StationDisconnected",
    "compatible",
    "Cmd",
    "IllegalTransition",
]
