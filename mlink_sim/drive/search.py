"""Speed search: the drive's settings for it, as data (the search itself runs in ``integrate.py``).

The option manuals only name the fault: SI-T3 Table 26 lists 3BH "SEr Too Many Speed Search Restarts"
(SI-T/V7 Table 11's 20H "SEr" is a *sequence input* fault, not this one).  The function and its
parameters come from the drives' own documentation:

* A1000 (A1000 Technical Manual SIEP C710616 27, b3 group): b3-01 search at every start, b3-24 method
  (0 Current Detection, 1 Speed Estimation), b3-02 the current below which the motor speed counts as
  found (% of drive rated current), b3-03 the search deceleration time, b3-05 the delay before the
  search, b3-17 / b3-18 the current and time after which a search is restarted, b3-19 the number of
  restarts before SEr, b3-25 the wait between restarts; multi-function inputs H1 = 61H / 62H External
  Search Command 1 / 2 (from the maximum output frequency / from the frequency reference).
* VS-606V7 (TOE-S606-12): n101 speed search deceleration time, n102 speed search operation level
  (% of inverter rated current); multi-function inputs n05x = 14 / 15 search command from the maximum
  / from the set frequency.  The V7 has no search-at-start constant, no restart and no SEr.

Registers, ranges and defaults are in :mod:`mlink_sim.params` (marked unverified where not confirmed);
equations and assumptions in docs/drive-model.md, section "Speed search".
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

__all__ = ["SpeedSearch", "a1000_search", "v7_search"]


@dataclass(frozen=True)
class SpeedSearch:
    """Speed search settings in SI units (the defaults are the A1000 factory settings, search off)."""

    at_start: bool = False  # b3-01 = 1: search at every start (V7: only by input 14/15)
    estimation: bool = False  # b3-24 = 1: Speed Estimation (bidirectional); 0: Current Detection
    current_pct: float = 100.0  # b3-02 / n102: found when the current falls below this, % of drive rated
    decel_s: float = 2.0  # b3-03 / n101: the sweep falls by E1-04 (n011) in this time
    delay_s: float = 0.2  # b3-05: output off before the search (V7: no such constant, 0)
    restart_pct: float = 150.0  # b3-17: current after the search that restarts it (V7: inf, never)
    restart_s: float = 0.1  # b3-18: ... when it lasts this long
    restarts: int = 3  # b3-19: restarts allowed; one more trips SEr
    wait_s: float = 0.5  # b3-25: output off between a restart and the next search


def a1000_search(g: Callable[[str], int]) -> SpeedSearch:
    """From raw A1000 values (``g(name)`` -> raw count): b3-01/02/03/05/17/18/19/24/25."""
    return SpeedSearch(
        at_start=g("b3-01") == 1, estimation=g("b3-24") == 1, current_pct=float(g("b3-02")),
        decel_s=max(g("b3-03"), 1) * 0.1, delay_s=g("b3-05") * 0.1, restart_pct=float(g("b3-17")),
        restart_s=g("b3-18") * 0.01, restarts=g("b3-19"), wait_s=g("b3-25") * 0.1)


def v7_search(g: Callable[[str], int]) -> SpeedSearch:
    """From raw VS-606V7 values: n101 (0.1 s), n102 (%); no restart, no delay, Current Detection only."""
    return SpeedSearch(current_pct=float(g("n102")), decel_s=max(g("n101"), 1) * 0.1, delay_s=0.0,
                       restart_pct=math.inf, restarts=0, wait_s=0.0)
