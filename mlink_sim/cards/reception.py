"""Reception-failure monitor: missed commands from gaps in the cycle numbers and from silence.

What is counted: the "Communications failure" of SI-T3 Table 24 (SI-T/V7 Table 9, "Transmission LSI detected a
data reception failure") and its "Transmission cycle fault" (:class:`FailureKind`); the watchdog timer error of
the same tables is :mod:`mlink_sim.cards.watchdog`'s. In phases 2 and 3 the first reception failure is warning 96,
a second consecutive one alarm E6, and phase 1 never notifies: SI-T3 Table 22 / SI-T/V7 Table 7, as data in
:data:`mlink_sim.cards.alarms.ML2_RECEPTION_FAILURES` (the codes are SI-T3 Table 23 / SI-T/V7 Table 8). SI-ET3
"COMM_ALM": warnings 1/2/3, alarms 8/9/A (:func:`mlink_sim.cards.alarms.ml3_failure_code`). This module only
counts.

A failure is one communication cycle (transmission cycle × COM_TIM, SI-ET3 CONNECT) without a valid command
for this station. Two detectors feed the same count, so nothing is counted twice:

* **gap** – the envelope cycle number of a command advances by more than one communication cycle, by at most as
  many transmission cycles as the time since the last valid command allows (elapsed // transmission cycle, plus
  the one communication cycle of the command itself);
* **silence** – no valid command for longer than one communication cycle plus a tolerance (default
  ``max(cycle, 2 ms)``, ``CardOptions.silence_tolerance_ns``), then one more failure per further
  cycle. Failures found by silence (or by a bad FCS) are subtracted from the next gap.

A valid command ends a run of consecutive failures.

A cycle number the elapsed time does not allow (further ahead than the bound, or behind: a u32 that wrapped or a
master that renumbered) is a **discontinuity**: one reception failure, not the jump (the tables above count
commands that were due and not received; a number no cycle of the master's clock can have reached counts none of
them), and the monitor resynchronises on it. So no count grows faster than commands arrive and cycles pass,
whatever the numbers a peer sends.
"""

from __future__ import annotations

import enum
from typing import Final

__all__ = ["FailureKind", "ReceptionMonitor", "DEFAULT_MIN_TOLERANCE_NS"]

DEFAULT_MIN_TOLERANCE_NS: Final = 2_000_000
_HALF: Final = 1 << 31
_MASK: Final = 0xFFFF_FFFF


class FailureKind(enum.Enum):
    """What was missed (SI-ET3 COMM_ALM distinguishes them; MECHATROLINK-II reports 96/E6 for all)."""

    FCS = "fcs"  #: a datagram for this station with a bad FCS (COMM_ALM 1/8)
    GAP = "gap"  #: command data not received (COMM_ALM 2/9)
    SILENCE = "silence"  #: nothing received at all: in phase 3 the synchronous frame is missing (COMM_ALM 3/A)
    CYCLE = "cycle"  #: transmission cycle fault – header cycle differs from CONNECT's (E6 / COMM_ALM B)


class ReceptionMonitor:
    """Counts missed communication cycles while active (phases 2 and 3)."""

    __slots__ = ("active", "comm_cycle_ns", "cycles_per_comm", "tcycle_ns", "tolerance_ns", "last_cycle", "last_rx",
                 "accounted", "consecutive", "_deadline")

    def __init__(self) -> None:
        self.active = False
        self.comm_cycle_ns = 2_000_000
        self.cycles_per_comm = 1
        self.tcycle_ns = 2_000_000  #: the transmission cycle: the time one step of the cycle number takes
        self.tolerance_ns = DEFAULT_MIN_TOLERANCE_NS
        self.last_cycle = 0
        self.last_rx = 0
        self.accounted = 0  #: failures already counted since the last valid command
        self.consecutive = 0  #: failures since the last valid command
        self._deadline = 0

    def start(self, cycle: int, now: int, comm_cycle_ns: int, cycles_per_comm: int,
              tolerance_ns: int | None) -> None:
        """Begin monitoring after CONNECT (the CONNECT command is the first valid command)."""
        self.active = True
        self.comm_cycle_ns = max(1, comm_cycle_ns)
        self.cycles_per_comm = max(1, cycles_per_comm)
        self.tcycle_ns = max(1, self.comm_cycle_ns // self.cycles_per_comm)
        self.tolerance_ns = (max(self.comm_cycle_ns, DEFAULT_MIN_TOLERANCE_NS)
                             if tolerance_ns is None else max(0, tolerance_ns))
        self._good(cycle, now)

    def stop(self) -> None:
        self.active = False
        self.accounted = self.consecutive = 0

    def _good(self, cycle: int, now: int) -> None:
        self.last_cycle = cycle
        self.last_rx = now
        self.accounted = 0
        self.consecutive = 0
        self._deadline = now + self.comm_cycle_ns + self.tolerance_ns

    def on_command(self, cycle: int, now: int) -> tuple[int, int, int, bool] | None:
        """A valid command with envelope *cycle* at *now*: ``(new failures, consecutive failures before them,
        communication cycles elapsed, discontinuity)``, or None for a duplicate (the same cycle number again).
        The run of consecutive failures ends with this command.

        The gap counted is bounded by the time since the last valid command: at most ``(now - last_rx) //
        tcycle_ns + cycles_per_comm`` transmission cycles (the command's own communication cycle included). A
        jump beyond that bound, or backwards, is a discontinuity: one failure (the module docstring)."""
        delta = (cycle - self.last_cycle) & _MASK
        if delta == 0:
            return None
        before = self.consecutive
        step = self.cycles_per_comm
        # one communication cycle on is always allowed: the steady state costs no division
        if delta > step and (delta >= _HALF or delta > (now - self.last_rx) // self.tcycle_ns + step):
            self._good(cycle, now)
            return 1, before, 1, True
        elapsed = max(1, (delta + step // 2) // step)
        missed = max(0, elapsed - 1 - self.accounted)
        self._good(cycle, now)
        return missed, before, elapsed, False

    def on_lost(self) -> int:
        """One failure found elsewhere (a bad FCS), not to be counted again by the next gap; returns the
        consecutive count before it."""
        before = self.consecutive
        self.accounted += 1
        self.consecutive += 1
        self._deadline += self.comm_cycle_ns  # that cycle is accounted for: silence starts counting after it
        return before

    def poll(self, now: int) -> tuple[int, int]:
        """Silence at *now*: ``(communication cycles newly found missing, consecutive count before them)``."""
        if not self.active or now < self._deadline:
            return 0, self.consecutive
        n = (now - self._deadline) // self.comm_cycle_ns + 1
        before = self.consecutive
        self._deadline += n * self.comm_cycle_ns
        self.accounted += n
        self.consecutive += n
        return n, before

    def deadline(self) -> int | None:
        """When :meth:`poll` can next find a failure (None while inactive)."""
        return self._deadline if self.active else None
