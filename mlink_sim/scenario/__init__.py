"""The scenario engine: a config's timeline on explicit time (:class:`Timeline`), its checks judged from what the
master sees (:mod:`.checks`, :mod:`.faultchecks`), the checks its drive settings cannot meet found before a run
(:mod:`.expectations`), a failed check's cause in the user's terms (:mod:`.explain`), and a station's values as its
config makes them (:mod:`.values`).

Sans-I/O: no clock, no socket, no task. Its driver — sleeping to each step's time, performing the actions through
the network's operations, reading the views — is :mod:`mlink_sim.aio.control.timeline`; tests drive it on explicit
times.
"""

from .checks import DRIVE_CHECKS, CheckResult, StationViews, judge
from .timeline import Request, Timeline
from .values import SpeedScale, drive_settings, restart_profile, speed_scale, speed_scales, station_values

__all__ = ["CheckResult", "DRIVE_CHECKS", "Request", "SpeedScale", "StationViews", "Timeline", "drive_settings", "judge",
           "restart_profile", "speed_scale", "speed_scales", "station_values"]
