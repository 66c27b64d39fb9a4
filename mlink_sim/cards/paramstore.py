"""Parameters as PRM_RD / PRM_WR / CONFIG see them (SI-T3 Table 8, SI-T3 Table 9, SI-T3 Table 12; SI-ET3 PRM_RD,
PRM_WR, CONFIG Table 15; SI-T/V7 §7.1).

* Register numbers are MEMOBUS register numbers ("The register number (NO) is the same as the register
  number that is set and referenced in MEMOBUS/Modbus transfers"); SIZE is 2, 4, 6 or 8 bytes = 1–4
  consecutive registers, least significant byte first. Any other SIZE, an unknown register, a read-only
  target (monitors) or a value outside the parameter's range is refused (A.94 / CMD_ALM 9H) and, on a read,
  PARAMETER is zero ("0 is stored in PARAMETER when command error occurs", SI-ET3 PRM_RD).
* SI-T3 / SI-ET3: a written value is *pending* until CONFIG ("The CONFIG command is used to enable the data
  for which parameters have been written"); PRM_RD returns it already ("For offline parameters, it reads
  the most recently updated setting values", SI-T3 PRM_RD). SI-T/V7: it takes effect at once (CONFIG_MOD 0
  "Not required. The setting value is enabled after PRM_WR is executed").
* Monitors (read-only rows) are read through a callback (the drive link).
"""

from __future__ import annotations

import struct
from collections.abc import Callable, Mapping

from mlink_sim.params import ParamError, ParamTable

from .results import Err

__all__ = ["ParamStore", "SIZES"]

SIZES = frozenset((2, 4, 6, 8))
_ZERO8 = bytes(8)
_WORDS = {n: struct.Struct(f"<{n}H") for n in (1, 2, 3, 4)}


class ParamStore:
    """Active (in effect) and pending (written, not yet CONFIGed) parameter values of one card."""

    __slots__ = ("table", "active", "pending", "immediate", "version")

    def __init__(self, table: ParamTable, values: Mapping[str, int], *, immediate: bool) -> None:
        self.table = table
        self.active: dict[str, int] = dict(values)
        self.pending: dict[str, int] = {}
        self.immediate = immediate  #: SI-T/V7: PRM_WR takes effect without CONFIG
        self.version = 0  #: +1 at every change of the active or pending values (what settings built ahead were for)

    def value(self, name: str) -> int:
        """The most recently written value of a settable parameter."""
        v = self.pending.get(name)
        return self.active[name] if v is None else v

    def read_register(self, register: int, monitor: Callable[[str], int]) -> int | None:
        """One register as a 16-bit word, or None when no parameter or monitor lives there."""
        p = self.table.by_register(register)
        if p is None:
            return None
        raw = monitor(p.name) if p.read_only else self.value(p.name)
        return raw & 0xFFFF

    def read(self, no: int, size: int, monitor: Callable[[str], int]) -> tuple[bytes, Err]:
        """PRM_RD: ``(PARAMETER bytes (8, zero padded), verdict)`` (SI-T3 Table 8 reads C1-01 at register 200H)."""
        if size not in SIZES or no + size // 2 > 0x10000:
            return _ZERO8, Err.DATA
        words = []
        for reg in range(no, no + size // 2):
            w = self.read_register(reg, monitor)
            if w is None:
                return _ZERO8, Err.DATA
            words.append(w)
        return _WORDS[len(words)].pack(*words).ljust(8, b"\0"), Err.OK

    def write(self, no: int, size: int, data: bytes) -> tuple[Err, dict[str, int]]:
        """PRM_WR: check every register first, then store all or nothing. Returns the verdict and the values
        written (by name)."""
        if size not in SIZES or no + size // 2 > 0x10000 or len(data) < size:
            return Err.DATA, {}
        words = _WORDS[size // 2].unpack_from(data)
        changes: dict[str, int] = {}
        for reg, word in zip(range(no, no + size // 2), words, strict=True):
            p = self.table.by_register(reg)
            if p is None or p.read_only:
                return Err.DATA, {}
            raw = p.decode(word)
            try:
                self.table.check(p, raw)
            except ParamError:
                return Err.DATA, {}
            changes[p.name] = raw
        if self.immediate:
            self.active.update(changes)
        else:
            self.pending.update(changes)
        self.version += 1
        return Err.OK, changes

    def apply(self) -> bool:
        """CONFIG: pending values take effect; True if anything changed."""
        changed = any(self.active.get(k) != v for k, v in self.pending.items())
        self.active.update(self.pending)
        self.pending.clear()
        self.version += 1
        return changed

    def enter(self, name: str, raw: int) -> None:
        """*raw* in effect for *name* at once, a value written and not yet applied dropped (the drive's keypad)."""
        self.pending.pop(name, None)
        self.active[name] = raw
        self.version += 1

    def overrides(self) -> dict[str, int]:
        """Active values that differ from the table default (what CONFIG_MOD = 1 saves)."""
        out = {}
        for name, v in self.active.items():
            p = self.table.get(name)
            if p is not None and not p.read_only and v != p.default:
                out[name] = v
        return out
