"""A station's values as its config makes them: its parameter set, its drive settings, its speed scale (Hz <->
the drive's own frequency units, o1-03 / n035) and the master's restart rule for it.

Deriving a station's drive settings takes about a millisecond: every run builds what it needs once, before its
clock starts (:func:`speed_scales`).
"""

from __future__ import annotations

from typing import Any

from ..config import Config, StationConfig
from ..drive import DriveSettings, Family
from ..drive.monitors import hz_to_ref, ref_to_hz
from ..params import FAMILIES

__all__ = ["SpeedScale", "station_values", "drive_settings", "speed_scale", "speed_scales", "restart_profile"]


class SpeedScale:
    """Hz <-> raw speed reference / output frequency of one station (its o1-03 / n035 units)."""

    def __init__(self, settings: Any) -> None:
        self._settings = settings

    @property
    def max_hz(self) -> float:
        """The drive's maximum output frequency (E1-04 / n011), Hz."""
        return float(self._settings.max_freq_hz)

    def to_raw(self, hz: float) -> int:
        return int(hz_to_ref(self._settings, hz))

    def to_hz(self, raw: int) -> float:
        return float(ref_to_hz(self._settings, raw))


def station_values(st: StationConfig) -> dict[str, int]:
    """The station's parameter set: family defaults with the config's assignments applied (raw values)."""
    table = FAMILIES[st.profile.family]
    values = table.defaults()
    for name, value in st.params.items():
        param, raw = table.parse_assignment(f"{name}={value}")
        values[param.name] = raw
    return values


def drive_settings(st: StationConfig) -> DriveSettings:
    """The station's drive settings as its parameters make them (about a millisecond: not in the cycle)."""
    return DriveSettings.from_params(Family(st.profile.family), station_values(st))


def speed_scale(st: StationConfig) -> SpeedScale:
    return SpeedScale(drive_settings(st))


def speed_scales(config: Config) -> dict[int, SpeedScale]:
    """Every station's :class:`SpeedScale`, built before the cycle starts."""
    return {st.address: speed_scale(st) for st in config.station}


def restart_profile(st: StationConfig) -> dict[str, Any]:
    """The ``StationPlan`` fields of the master's restart rule (docs/master.md): ``speed_search`` (the drive
    catches a turning motor: A1000 b3-01 = 1, or a speed-search input H1 = 61H/62H, VS-606V7 n05x = 14/15),
    ``search_input`` (the ``Control.multi_inputs`` bits of that input, switched on with the run command) and
    ``standstill`` (2 % of E1-04/n011 in the drive's own frequency units)."""
    settings = drive_settings(st)
    search_input = settings.inputs.search_ref or settings.inputs.search_max
    return {"speed_search": settings.search.at_start or bool(search_input),
            "search_input": 0 if settings.search.at_start else search_input,
            "standstill": max(1, abs(hz_to_ref(settings, 0.02 * settings.max_freq_hz)))}
