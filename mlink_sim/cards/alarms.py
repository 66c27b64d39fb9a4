"""Alarm and warning reporting.

MECHATROLINK-I/II (SI-T3 Table 19 "Fault Type", SI-T3 Table 20 "Fault Type and SI-T3 Processing", SI-T3 Table 21
"Response Data for Consecutive Alarms and/or Warnings"; SI-T/V7 §8.1 and SI-T/V7 Table 6) – :class:`Ml2Alarms`:

* four kinds: drive alarm (fault, SI-T3 Table 26 / V7 Table 10 code), communications alarm (E5, E6),
  drive warning (minor fault, Table 27 / V7 Table 11 code), communications warning (94, 95, 96);
* the ALARM byte carries the **most recent alarm**; with no alarm, the **warning with the lowest code**;
  alarms win over warnings (Table 21); STATUS ALM = an alarm is present, WARNG = a warning is present;
* communications warnings need no reset (Table 20 "Reset: Not required"): each is reported in the response
  that follows its detection and then drops; communications alarms stay until ALM_CLR or DISCONNECT;
* "Errors are not reported while the fault reset signal is ON" (SI-T3 Table 16 note <2>): drive faults are
  hidden from ALARM/ALM while the fault-reset input is on.

MECHATROLINK-III (SI-ET3 §8 "Command Status") – :class:`Ml3Alarms`: D_ALM / D_WAR from the drive;
CMD_ALM per command (cleared by the next normal command, so it is simply the verdict on the command being
answered); COMM_ALM latched until the ALM_CLR command or the rising edge of CMD_CTRL.ALM_CLR, which is
answered with ALM_CLR_CMP while the bit stays set; an alarm code replaces a warning, a newer alarm an older.

The failure → code mapping: SI-T3 Table 22 / SI-T/V7 Table 7 as data (:data:`ML2_RECEPTION_FAILURES`, read by
:func:`ml2_failure_code`); the SI-ET3 "COMM_ALM" codes in :func:`ml3_failure_code` (docs/cards.md for the FCS /
gap / silence distinction).
"""

from __future__ import annotations

from collections.abc import Mapping
from types import MappingProxyType

from mlink_sim.wire import CommAlm, M2Alarm

from .reception import FailureKind

__all__ = ["ML2_RECEPTION_FAILURES", "Ml2Alarms", "Ml3Alarms", "ml2_failure_code", "ml3_failure_code"]


#: SI-T3 Table 22 "Reception Failures in Each Phase" (SI-T/V7 Table 7): phase -> ALARM code of a first reception
#: failure, of a second (consecutive) one, and of a transmission cycle fault. Phase 1 is "−": "Even if a transfer
#: fault is detected in phase 1, no fault notification is provided" (the station does not monitor it, reception.py).
#: The codes are SI-T3 Table 23 (96 warning, E6 alarm); first / consecutive are counted by Station._failures.
ML2_RECEPTION_FAILURES: Mapping[int, tuple[int, int, int]] = MappingProxyType({
    2: (M2Alarm.COMM_WARNING, M2Alarm.COMM_ERROR, M2Alarm.COMM_ERROR),
    3: (M2Alarm.COMM_WARNING, M2Alarm.COMM_ERROR, M2Alarm.COMM_ERROR),
})


def ml2_failure_code(kind: FailureKind, first: bool, phase: int) -> int:
    """The ALARM code of a reception failure in *phase* (2 or 3), from :data:`ML2_RECEPTION_FAILURES` (SI-T3
    Table 22 / SI-T/V7 Table 7): first failure 96, consecutive E6; a transmission cycle fault E6."""
    first_code, consecutive, cycle_fault = ML2_RECEPTION_FAILURES[phase]
    if kind is FailureKind.CYCLE:
        return cycle_fault
    return first_code if first else consecutive


def ml3_failure_code(kind: FailureKind, first: bool, phase: int) -> int:
    """SI-ET3 COMM_ALM: FCS 1/8, command data not received 2/9, synchronous frame not received 3/A
    (silence in phase 3), synchronization interval error B (header transmission cycle changed)."""
    if kind is FailureKind.CYCLE:
        return CommAlm.SYNC_INTERVAL_ERROR
    if kind is FailureKind.FCS:
        return CommAlm.FCS_WARNING if first else CommAlm.FCS_ERROR
    if kind is FailureKind.SILENCE and phase == 3:
        return CommAlm.SYNC_NOT_RECEIVED_WARNING if first else CommAlm.SYNC_NOT_RECEIVED
    return CommAlm.NOT_RECEIVED_WARNING if first else CommAlm.NOT_RECEIVED


class Ml2Alarms:
    """ALARM byte and STATUS ALM/WARNG of MECHATROLINK-I/II responses (SI-T3 Table 19, SI-T3 Table 20, SI-T3 Table 21,
    SI-T/V7 Table 6)."""

    __slots__ = ("_fault_codes", "_minor_codes", "_seq", "_comm", "_warnings", "_fault", "_fault_seq",
                 "_cached")

    def __init__(self, fault_codes: Mapping[object, int], minor_codes: Mapping[object, int]) -> None:
        self._fault_codes = fault_codes
        self._minor_codes = minor_codes
        self._seq = 0
        self._comm: dict[int, int] = {}  # communications alarm code -> order of occurrence
        self._warnings: set[int] = set()  # communications warnings awaiting their one report
        self._fault: object | None = None  # drive fault last seen
        self._fault_seq = 0
        self._cached: tuple[object, object, tuple[int, bool, bool]] | None = None

    # -- events ------------------------------------------------------------------------------
    def alarm(self, code: int) -> None:
        """A communications alarm (E5, E6): the most recent alarm from now on."""
        self._seq += 1
        self._comm[code] = self._seq
        self._cached = None

    def warning(self, code: int) -> None:
        """A communications warning (94, 95, 96): reported in the next response."""
        self._warnings.add(code)
        self._cached = None

    def observe(self, fault: object | None) -> None:
        """The drive's current fault; a new one becomes the most recent alarm."""
        if fault is not self._fault:
            self._fault = fault
            if fault is not None:
                self._seq += 1
                self._fault_seq = self._seq
            self._cached = None

    def reported(self) -> None:
        """A response went out: the communications warnings it carried drop (no reset required)."""
        if self._warnings:
            self._warnings.clear()
            self._cached = None

    def clear(self) -> None:
        """ALM_CLR / DISCONNECT: communications alarms and warnings."""
        self._comm.clear()
        self._warnings.clear()
        self._cached = None

    # -- state ---------------------------------------------------------------------------------
    @property
    def comm_alarm(self) -> int | None:
        """The most recent communications alarm (E5/E6), or None."""
        if not self._comm:
            return None
        return max(self._comm.items(), key=lambda kv: kv[1])[0]

    @property
    def comm_warnings(self) -> frozenset[int]:
        return frozenset(self._warnings)

    def report(self, fault: object | None, minor: object | None, hide_fault: bool) -> tuple[int, bool, bool]:
        """``(ALARM byte, STATUS ALM, STATUS WARNG)`` for drive *fault*/*minor* (SI-T3 Table 21, SI-T/V7 Table 6)."""
        key = (fault if not hide_fault else None, minor)
        cached = self._cached
        if cached is not None and cached[0] is key[0] and cached[1] is key[1]:
            return cached[2]
        best_seq, best = -1, 0
        for code, seq in self._comm.items():
            if seq > best_seq:
                best_seq, best = seq, code
        has_fault = key[0] is not None
        if has_fault and self._fault_seq > best_seq:
            best_seq, best = self._fault_seq, self._fault_codes.get(key[0], 0)
        alarm = best_seq >= 0
        warnings = set(self._warnings)
        if minor is not None:
            warnings.add(self._minor_codes.get(minor, 0) or 0x100)
        warng = bool(warnings)
        if not alarm:
            best = min(warnings) if warnings else 0
            if best == 0x100:
                best = 0  # a drive minor fault without a table code: WARNG set, code unknown
        result = (best, alarm, warng)
        self._cached = (key[0], key[1], result)
        return result


class Ml3Alarms:
    """COMM_ALM latch and the CMD_CTRL.ALM_CLR handshake of MECHATROLINK-III (SI-ET3 §8)."""

    __slots__ = ("comm_alm", "_clr_bit", "alm_clr_cmp")

    def __init__(self) -> None:
        self.comm_alm = 0
        self._clr_bit = False
        self.alm_clr_cmp = False

    def comm(self, code: int) -> None:
        """Latch a COMM_ALM code: an alarm replaces a warning or an older alarm; a warning only a warning."""
        if code >= 0x8 or self.comm_alm < 0x8:
            self.comm_alm = code

    def clear(self) -> None:
        self.comm_alm = 0

    def alm_clr_edge(self, bit: bool) -> bool:
        """Track CMD_CTRL.ALM_CLR; True on its rising edge. ALM_CLR_CMP follows the bit once processed."""
        rising = bit and not self._clr_bit
        self._clr_bit = bit
        if not bit:
            self.alm_clr_cmp = False
        return rising

    @property
    def comm_alarm_active(self) -> bool:
        return self.comm_alm >= 0x8
