"""Load and validate a network TOML file; every problem becomes one :class:`ConfigError` naming file and field."""

from __future__ import annotations

import tomllib
from pathlib import Path
from typing import Any

from pydantic import BaseModel, ValidationError

from ..examples import example_names, example_path
from ..params import FAMILIES, ParamError
from ..operations import OpError, check_speed
from .model import Config, StationConfig

__all__ = ["ConfigError", "load_config", "parse_config", "resolve_config_path", "station_param_assignments"]


class ConfigError(ValueError):
    """A configuration problem; ``str()`` is one or more ``FILE: field: what was expected`` lines."""


def _loc(loc: tuple[Any, ...]) -> str:
    out = ""
    for part in loc:
        if isinstance(part, int):
            out += f"[{part}]"
        elif part in ("function-after", "function-before") or str(part).startswith(("literal[", "function-")):
            continue
        else:
            out += ("." if out else "") + str(part)
    return out


def _near(loc: tuple[Any, ...]) -> str:
    """``; did you mean 'hz'?`` for an unknown field close to one its table has (``speed_hz``, ``hz``), else ''."""
    import difflib

    from .model import NetworkConfig, StationConfig, TimelineStep

    models: dict[str, type[BaseModel]] = {"network": NetworkConfig, "station": StationConfig,
                                          "timeline": TimelineStep}
    model = models.get(str(loc[0])) if loc else None
    if model is None or not isinstance(loc[-1], str):
        return ""
    names = [f.alias or n for n, f in model.model_fields.items()]
    key = loc[-1]
    within = sorted((n for n in names if key.endswith("_" + n) or key.startswith(n + "_")), key=len)  # speed_hz: hz
    near = within[-1:] or difflib.get_close_matches(key, names, n=1, cutoff=0.6)
    return f"; did you mean {near[0]!r}?" if near else ""


def _format_validation(source: str, err: ValidationError) -> str:
    lines = []
    for e in err.errors(include_url=False):
        where = _loc(tuple(e["loc"]))
        msg = e["msg"]
        if msg.startswith("Value error, "):
            msg = msg[len("Value error, ") :]
        if e["type"] == "extra_forbidden":
            msg = "unknown field" + _near(tuple(e["loc"])) + " (see docs/configuration.md for the fields)"
        elif e["type"] == "missing":
            msg = "required field is missing"
        elif e["type"] == "literal_error":
            msg = f"{msg}, got {e.get('input')!r}"
        # model-level validators report their own "field: message" text
        lines.append(f"{source}: {where + ': ' if where else ''}{msg}")
    return "\n".join(lines)


def station_param_assignments(config: Config) -> dict[int, list[str]]:
    """``{address: ["C1-01=5.0", …]}`` – the station parameters as command-line assignments."""
    return {st.address: [f"{k}={v}" for k, v in st.params.items()] for st in config.station}


def _check_params(source: str, config: Config) -> None:
    problems = []
    for i, st in enumerate(config.station):
        table = FAMILIES[st.profile.family]
        for text in station_param_assignments(config)[st.address]:
            try:
                table.parse_assignment(text)
            except ParamError as exc:
                problems.append(f"{source}: station[{i}].params: {exc}")
    # set-param steps: the name and range of the parameter table of every station the step is for
    # (docs/parameters.md), so that a typo fails here rather than as a refused PRM_WR in the middle of a run
    for i, step in enumerate(config.timeline):
        if step.do != "set-param":
            continue
        targets = config.station if step.station == "all" else [config.station_by_address(step.station)]
        for st in targets:
            try:
                FAMILIES[st.profile.family].parse_assignment(f"{step.param}={step.value}")
            except ParamError as exc:
                problems.append(f"{source}: timeline[{i}].param: {exc} (station {st.address:02X}H, {st.card})")
                break
    if problems:
        raise ConfigError("\n".join(problems))
    _check_speeds(source, config)


def _check_speeds(source: str, config: Config) -> None:
    """Every ``run`` / ``speed`` step's ``hz`` against the maximum output frequency of each station it is for, as that
    frequency is at the step (the config's E1-04 / n011, then each earlier ``set-param`` of it): the rule, and the
    message, of every other surface (:func:`~mlink_sim.operations.check_speed`)."""
    tops = {st.address: max_frequency(st) for st in config.station}
    for i, step in sorted(enumerate(config.timeline), key=lambda item: item[1].at):
        targets = config.station if step.station == "all" else [config.station_by_address(step.station)]
        for st in targets:
            top, name = tops[st.address]
            if step.do == "set-param" and step.param is not None and step.value is not None:
                table = FAMILIES[st.profile.family]
                param, raw = table.parse_assignment(f"{step.param}={step.value}")
                if param.name == name:
                    tops[st.address] = (param.to_eng(raw), name)
            elif step.do in ("run", "speed") and step.hz is not None:
                try:
                    check_speed(step.hz, st.address, top, name)
                except OpError as exc:
                    raise ConfigError(f"{source}: timeline[{i}].{exc}") from None


def max_frequency(st: StationConfig) -> tuple[float, str]:
    """The station's maximum output frequency in Hz as its parameters set it (A1000 E1-04, VS-606V7 n011) and that
    parameter: the bound of every frequency reference it is given."""
    table = FAMILIES[st.profile.family]
    values = table.defaults()
    for name, value in st.params.items():
        param, raw = table.parse_assignment(f"{name}={value}")
        values[param.name] = raw
    name = st.profile.max_frequency
    return table.by_name(name).to_eng(values[name]), name


def parse_config(text: str, source: str = "<config>") -> Config:
    """Parse TOML *text*; raises :class:`ConfigError` with every problem found."""
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{source}: not valid TOML: {exc}") from None
    try:
        config = Config.model_validate(data)
    except ValidationError as exc:
        raise ConfigError(_format_validation(source, exc)) from None
    if "name" not in data.get("network", {}):
        config.network.name = Path(source).stem if source != "<config>" else "network"
    _check_params(source, config)
    return config


def resolve_config_path(path: str | Path) -> Path:
    """*path* itself when it exists, else the shipped example of that name (``quickstart`` → the package's
    ``examples/quickstart.toml``, also ``configs/quickstart.toml`` run outside the source tree), else *path*."""
    p = Path(path)
    if p.exists():
        return p
    return example_path(p.name if str(p.parent) == "configs" else str(path)) or p


def load_config(path: str | Path) -> Config:
    """Read and validate the TOML file at *path* (or the shipped example so named, :func:`resolve_config_path`)."""
    p = resolve_config_path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ConfigError(f"{p}: no such file (shipped examples, usable by name: {', '.join(example_names())})"
                          ) from None
    except UnicodeDecodeError as exc:
        raise ConfigError(f"{p}: not a UTF-8 text file (byte {exc.object[exc.start]:#04x} at offset {exc.start}); "
                          "save it as UTF-8") from None
    except IsADirectoryError:
        raise ConfigError(f"{p}: is a directory, expected a TOML file") from None
    except OSError as exc:
        raise ConfigError(f"{p}: cannot read: {exc.strerror}") from None
    return parse_config(text, str(p))
