"""Card cores built from a network config: what a slave process (``mlink-sim slave --config``) and the virtual
clock's in-process network (:mod:`mlink_sim.aio.run.virtual_session`) both power up, with the same settings.

Touches: the state directory (reads an EEPROM image); builds card cores, starts nothing.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ...config import StationConfig
from ...wire import Link
from .state import eeprom_path, read_state

__all__ = ["StationSpec", "build_station", "spec_for"]


@dataclass
class StationSpec:
    """Everything needed to power up one station (what the drive's parameters and switches say)."""

    card: str
    address: int
    host: str
    port: int
    frame_size: int | None
    params: list[str]
    load: Any = None
    link: Link | None = None  #: None: the card's own (the A1000's F6-22, the V7 card's link switch, config/model.py)
    options: dict[str, Any] | None = None


def spec_for(st: StationConfig, host: str = "127.0.0.1", port: int = 0) -> StationSpec:
    """The :class:`StationSpec` of a config's station, listening on *host*:*port*."""
    from ...drive import LoadSpec

    return StationSpec(
        card=st.card,
        address=st.address,
        host=host,
        port=port,
        frame_size=st.frame_size,
        params=[f"{k}={v}" for k, v in st.params.items()],
        load=LoadSpec.from_config(st.load.model_dump(exclude_none=True)),
        link=st.link,
        options=st.options,
    )


def build_station(spec: StationSpec, state_dir: Path | None, now: int, *, eeprom: bytes | None = None,
                  absorb_ns: int = 0) -> Any:
    """Create the card core for *spec* at *now*, with *eeprom* or else the image in *state_dir* if there is one.
    ``ValueError`` (a one-sentence message) for settings the card refuses.

    *absorb_ns*: the host-stall policy "absorb" (docs/timing.md): the reception-failure timer waits that long
    beyond a communication cycle before it takes silence for lost commands (``silence_tolerance_ns``, unless the
    station's options set it); lost commands are still found at once from the cycle numbers (SI-T3 Table 22)."""
    from ...cards import create_card, settings_for
    from ...cards.settings import CardOptions

    known = {f.name for f in dataclasses.fields(CardOptions)}
    unknown = sorted(set(spec.options or {}) - known)
    if unknown:
        raise ValueError(f"unknown card option(s) {', '.join(unknown)} (known: {', '.join(sorted(known))})")
    link_speed = spec.link.speed_mbps if spec.link is not None else None
    settings = settings_for(
        spec.card,
        spec.address,
        spec.frame_size,
        spec.params,
        load=spec.load,
        link_speed_mbps=link_speed,
        options=CardOptions(**{**_absorbing(absorb_ns), **(spec.options or {})}),
    )
    if eeprom is None and state_dir:
        eeprom = read_state(eeprom_path(state_dir, spec.card, spec.address))
    return create_card(spec.card, settings=settings, now=now, eeprom=eeprom)


def _absorbing(absorb_ns: int) -> dict[str, Any]:
    """The card option of the host-stall policy "absorb": silence counts only after the bound."""
    return {"silence_tolerance_ns": absorb_ns} if absorb_ns else {}
