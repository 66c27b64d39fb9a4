"""Command kinds, the same on every generation, and what a slot sends.

The wire has one code enum per generation (:class:`~mlink_sim.wire.M2Cmd`: SI-T3 Tables 5/6, V7 Tables 1/2;
:class:`~mlink_sim.wire.M3Cmd`: SI-ET3 Tables 11/12), which differ only in INV_CTL (40H / 50H) and INV_I/O
(41H / 51H). The master reasons about *kinds* (:class:`Cmd`) and keeps the codes for the wire.
"""

from __future__ import annotations

import enum
from collections.abc import Mapping
from types import MappingProxyType

from ..wire import Link, M2Cmd, M3Cmd

__all__ = ["Cmd", "Send", "cmd_of", "code_of"]


class Cmd(enum.Enum):
    """A command kind (main or sub-command), by its name in the manuals."""

    NOP = "NOP"
    PRM_RD = "PRM_RD"
    PRM_WR = "PRM_WR"
    ID_RD = "ID_RD"
    CONFIG = "CONFIG"
    ALM_RD = "ALM_RD"
    ALM_CLR = "ALM_CLR"
    SYNC_SET = "SYNC_SET"
    CONNECT = "CONNECT"
    DISCONNECT = "DISCONNECT"
    INV_CTL = "INV_CTL"
    INV_IO = "INV_IO"


class Send(enum.Enum):
    """What one slot sends, and why (the command per state: :data:`mlink_sim.master.machine.SENDS`)."""

    PROBE = "NOP to an offline, disconnected or backing-off station"
    CONNECT = "CONNECT"
    RESET = "DISCONNECT before CONNECT (the slave must be reset first)"
    DISCONNECT = "DISCONNECT on request"
    SYNC = "SYNC_SET"
    CLEAR = "ALM_CLR of a communication alarm"
    CYCLIC = "the cyclic INV_CTL"
    REQUEST = "a queued request"


def _by_code(codes: type[enum.IntEnum]) -> Mapping[int, Cmd]:
    return MappingProxyType({int(c): Cmd[c.name] for c in codes})


_KINDS = {Link.ML1: _by_code(M2Cmd), Link.ML2: _by_code(M2Cmd), Link.ML3: _by_code(M3Cmd)}
_CODES = {link: MappingProxyType({k: c for c, k in kinds.items()}) for link, kinds in _KINDS.items()}


def cmd_of(link: Link, code: int) -> Cmd | None:
    """The kind of command *code* on *link*; None for a code the manuals do not define."""
    return _KINDS[link].get(code)


def code_of(link: Link, kind: Cmd) -> int:
    """The code of *kind* on *link*."""
    return _CODES[link][kind]
