"""The WDT/RWDT watchdog bytes (SI-T3 §7 "Communications Phases", SI-ET3 §7, SI-T/V7 §5.3).

The manuals say only that phase 2 "starts to count the watchdog timer in the communications frame" and
that phase 3 detects "a WDT count fault in a synchronous frame" (SI-T3 Table 24). The byte layout is the
convention of the MECHATROLINK masters, which this simulator fixes as (docs/cards.md):

* command **WDT**: bits 4–7 are the master's count, incremented by one every communication cycle; bits
  0–3 echo the slave's count from its last response;
* response **RWDT**: bits 0–3 are the slave's own count, incremented each time it answers; bits 4–7
  echo the master's count of the command being answered.

In phase 3 a master count that does not advance by exactly the number of communication cycles since the
previous command (one, when nothing was lost; the cycle numbers of the envelope tell) is a WDT error:
MECHATROLINK-II ALARM E5, MECHATROLINK-III COMM_ALM CH. A command lost on the way is a reception failure
(SI-T3 Table 24 "Communications failure"), not a watchdog fault, hence the elapsed-cycles rule.
"""

from __future__ import annotations

__all__ = ["Watchdog"]


class Watchdog:
    """Slave side of the watchdog bytes: echoes, counts, and checks the master's count in phase 3."""

    __slots__ = ("master", "slave", "armed")

    def __init__(self) -> None:
        self.master = 0  #: last master count seen (WDT bits 4–7)
        self.slave = 0  #: own count, sent in RWDT bits 0–3
        self.armed = False  #: checking (phase 3); the next command sets the baseline when False

    def arm(self, wdt: int) -> None:
        """Start checking from the count in *wdt* (phase 3 entered with this command)."""
        self.master = (wdt >> 4) & 0xF
        self.armed = True

    def disarm(self) -> None:
        self.armed = False

    def check(self, wdt: int, cycles: int) -> bool:
        """Take the master count of *wdt*; True if it advanced by *cycles* (mod 16) or checking is off."""
        count = (wdt >> 4) & 0xF
        ok = not self.armed or count == (self.master + cycles) & 0xF
        self.master = count
        return ok

    def peek(self) -> int:
        """The RWDT byte as it stands, without advancing the slave's count (status replies to other sources)."""
        return self.slave | (self.master << 4)

    def rwdt(self) -> int:
        """The RWDT byte of the next response (advances the slave's count)."""
        self.slave = (self.slave + 1) & 0xF
        return self.slave | (self.master << 4)
