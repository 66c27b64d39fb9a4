"""Network configuration: the TOML model (pydantic), loading with clear errors, durations with units."""

from .load import ConfigError, load_config, parse_config, resolve_config_path, station_param_assignments
from .model import (
    Config,
    LoadConfig,
    NetworkConfig,
    StationConfig,
    TimelineStep,
    check_cycle,
    parse_endpoint,
)
from ..units import format_ns, parse_address, parse_duration_ns

__all__ = [
    "Config",
    "NetworkConfig",
    "StationConfig",
    "TimelineStep",
    "LoadConfig",
    "ConfigError",
    "load_config",
    "parse_config",
    "resolve_config_path",
    "station_param_assignments",
    "parse_address",
    "parse_endpoint",
    "parse_duration_ns",
    "format_ns",
    "check_cycle",
]
