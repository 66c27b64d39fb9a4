"""The command handlers both generations share, written against the station's public operations.

A card answers a command through a handler table keyed by command code (in the spirit of aioquic's frame-handler
table): :data:`mlink_sim.cards.ml2_card.MAIN_HANDLERS` / ``SUB_HANDLERS`` for MECHATROLINK-I/II,
:data:`mlink_sim.cards.si_et3.MAIN_HANDLERS` / ``SUB_HANDLERS`` for MECHATROLINK-III. Every entry has the
same shape:

* main command: ``handler(station, body, frame, source, now) -> (response body, Err)``;
* sub-command: ``handler(station, sub, now) -> (response body, Err)``.

The handlers below do the same on both generations and use only the :class:`~mlink_sim.cards.base.Station`
operations (``alarm_clear``, ``sync_set``, ``select_refs``, ``monitor``) and the parameter operations of
:mod:`mlink_sim.cards.parameters` (PRM_RD, PRM_WR, CONFIG). The response body is the request's counterpart in the
same wire module (:data:`RESPONSE_OF`, derived from the wire declarations). The generation's own handlers (CONNECT, DISCONNECT, ID_RD, ALM_RD,
INV_CTL) are methods of its station class, next to the state they touch.
"""

from __future__ import annotations

from collections.abc import Callable, Hashable, Mapping
from types import MappingProxyType
from typing import TYPE_CHECKING, Any

from mlink_sim.wire import Frame, ml2, ml3

from . import parameters
from .results import Err

if TYPE_CHECKING:
    from .base import Station

__all__ = [
    "Handler", "SubHandler", "RESPONSE_OF",
    "nop", "prm_rd", "prm_wr", "config", "alm_clr", "sync_set",
    "sub_nop", "sub_prm_rd", "sub_prm_wr", "sub_config", "sub_inv_io",
]

#: ``handler(station, body, frame, source, now) -> (response body, verdict)`` – a main command.
Handler = Callable[[Any, Any, Frame, Hashable, int], tuple[Any, Err]]
#: ``handler(station, sub, now) -> (response body, verdict)`` – a sub-command.
SubHandler = Callable[[Any, Any, int], tuple[Any, Err]]


def _responses() -> Mapping[type, type]:
    """Request body class -> response body class of the same code, from the wire modules' slots."""
    out: dict[type, type] = {}
    for wire in (ml2, ml3):
        for commands, responses in ((wire.COMMAND_MAIN, wire.RESPONSE_MAIN), (wire.COMMAND_SUB, wire.RESPONSE_SUB)):
            for code, layout in commands.by_code.items():
                response = responses.by_code.get(code)
                if response is not None:
                    out[layout.cls] = response.cls
    return MappingProxyType(out)


#: The response body class of each request body class (``ml2.PrmRd`` -> ``ml2.PrmRdResponse`` …).
RESPONSE_OF: Mapping[type, type] = _responses()


# -- main commands ------------------------------------------------------------------------------------------
def nop(station: Station, body: Any, frame: Frame, source: Hashable, now: int) -> tuple[Any, Err]:
    """NOP (SI-T3 / SI-T/V7 NOP, SI-ET3 NOP): "The current state is returned as a response"."""
    return body, Err.OK


def prm_rd(station: Station, body: Any, frame: Frame, source: Hashable, now: int) -> tuple[Any, Err]:
    """PRM_RD (SI-T3 Table 8, SI-ET3 PRM_RD, SI-T/V7 PRM_RD): PARAMETER is zero on an error."""
    data, err = parameters.read_params(station, body.no, body.size)
    return RESPONSE_OF[type(body)](body.no, body.size, data), err


def prm_wr(station: Station, body: Any, frame: Frame, source: Hashable, now: int) -> tuple[Any, Err]:
    """PRM_WR (SI-T3 Table 9, SI-ET3 PRM_WR, SI-T/V7 PRM_WR): the command is echoed."""
    return body, parameters.write_params(station, body.no, body.size, body.data, now)


def config(station: Station, body: Any, frame: Frame, source: Hashable, now: int) -> tuple[Any, Err]:
    """CONFIG (SI-T3 Table 12, SI-ET3 Table 15, SI-T/V7 CONFIG)."""
    return body, parameters.config(station, body.config_mod, now)


def alm_clr(station: Station, body: Any, frame: Frame, source: Hashable, now: int) -> tuple[Any, Err]:
    """ALM_CLR (SI-T3 Table 15, SI-ET3 ALM_CLR): ALM_CLR_MOD 0 only, otherwise A.94 / CMD_ALM 9H."""
    if body.alm_clr_mod != 0:
        return body, Err.DATA
    station.alarm_clear(now)
    return body, Err.OK


def sync_set(station: Station, body: Any, frame: Frame, source: Hashable, now: int) -> tuple[Any, Err]:
    """SYNC_SET: phase 2 -> 3 (SI-T3 Figure 8, SI-ET3 Figure 19); "Completing this command commences watchdog data
    error detection" (SI-ET3 SYNC_SET)."""
    station.sync_set(frame.message.wdt)
    return body, Err.OK


# -- sub-commands (SI-T3 §8 "Sub-commands", SI-T/V7 §7.2, SI-ET3 §10) --------------------------------------------
def sub_nop(station: Station, sub: Any, now: int) -> tuple[Any, Err]:
    return sub, Err.OK


def sub_prm_rd(station: Station, sub: Any, now: int) -> tuple[Any, Err]:
    data, err = parameters.read_params(station, sub.no, sub.size)
    return RESPONSE_OF[type(sub)](sub.no, sub.size, data), err


def sub_prm_wr(station: Station, sub: Any, now: int) -> tuple[Any, Err]:
    return sub, parameters.write_params(station, sub.no, sub.size, sub.data, now)


def sub_config(station: Station, sub: Any, now: int) -> tuple[Any, Err]:
    """The SI-T/V7 CONFIG sub-command (§7.2); the SI-T3 and the SI-ET3 have none."""
    return sub, parameters.config(station, sub.config_mod, now, sub=True)


def sub_inv_io(station: Station, sub: Any, now: int) -> tuple[Any, Err]:
    """INV_I/O: REF3–REF6 by SEL_REF3/4, 5/6 and MON3–MON6 by SEL_MON3/4, 5/6 (SI-T3 Tables 17/18, SI-ET3
    Tables 21/22, SI-T/V7 Tables 4/5)."""
    station.select_refs(sub.sel_ref34, sub.ref3, sub.ref4)
    station.select_refs(sub.sel_ref56, sub.ref5, sub.ref6)
    m34, m56 = sub.sel_mon34, sub.sel_mon56
    monitor = station.monitor
    return RESPONSE_OF[type(sub)](sub.sel_ref34, sub.sel_ref56, m34, m56, monitor(m34 & 0xF), monitor(m34 >> 4),
                                  monitor(m56 & 0xF), monitor(m56 >> 4)), Err.OK
