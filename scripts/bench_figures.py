"""One definition of "missed", RTT and CPU per exchange, for the simulator (``scripts/bench.py``) and its floor
(``scripts/bench_floor.py``) alike (docs/performance.md, "How a cell is measured").

Both sides count the same things in the measuring window: the cycles their ``CycleTimer`` started and the ones it
skipped, the commands sent, and every answer read within the answer window (the network's ``stall_bound``, as
the master's ``NetworkPlan.answer_window_ns``), each answer's round trip in a ``LatencyHistogram`` (from the
cycle's start, the time the commands are stamped with, to the time the answer was read). From those counts
:func:`exchange_figures` gives, for both:

* **exchanges due**: the commands sent plus those the skipped cycles would have sent (the sent per started cycle,
  times the skipped cycles);
* **on time**: answers read at most one transmission cycle after their cycle's start (a MECHATROLINK master needs
  the answer before its next cycle);
* **missed** (the rate judged): ``(due − on time) / due``: the exchanges of skipped cycles, the answers that came
  back later than a cycle and the ones that never came back, all counted alike;
* **RTT p50 / p99**: over every answer read, late ones included (an answer later than a cycle is not dropped from
  the tail);
* **CPU per exchange**: the CPU time of both sides (kernel's accounting, all costs in) over the answers read.

A floor whose own missed rate is above the targets' margin cannot carry the load itself: ``--targets`` says so
(``bench_targets.floor_saturation``), so that a bound "≤ floor + x" is read as relative to such a floor.
"""

from __future__ import annotations

from dataclasses import dataclass

from mlink_sim.metrics import LatencyHistogram

__all__ = ["ExchangeFigures", "exchange_figures"]


@dataclass(frozen=True)
class ExchangeFigures:
    """The figures of one measuring window (see the module's docstring)."""

    due: int                  #: exchanges due: sent + what the skipped cycles would have sent
    answered: int             #: answers read within the answer window
    on_time: int              #: of those, read at most one cycle after their cycle's start
    missed_rate: float        #: (due − on_time) / due
    rtt_p50_ns: int
    rtt_p99_ns: int
    cpu_per_exchange_us: float         #: CPU of both sides / answered
    cpu_per_exchange_nospin_us: float  #: the same without the clock's spin before each deadline


def exchange_figures(*, cycle_ns: int, started: int, skipped: int, sent: int, rtt: LatencyHistogram,
                     cpu_s: float, spin_s: float = 0.0) -> ExchangeFigures:
    """The figures of a window in which the clock started *started* cycles and skipped *skipped*, *sent* commands
    went out, *rtt* holds the round trip of every answer read and both sides used *cpu_s* of CPU (*spin_s* of it
    in the clock's spin)."""
    answered = rtt.count
    on_time = min(rtt.count_at_most(cycle_ns), sent)
    due = sent + (round(skipped * sent / started) if started else 0)
    summary = rtt.summary()
    per = 1e6 / answered if answered else 0.0
    return ExchangeFigures(
        due=due, answered=answered, on_time=on_time,
        missed_rate=(due - on_time) / due if due else 0.0,
        rtt_p50_ns=summary["p50"], rtt_p99_ns=summary["p99"],
        cpu_per_exchange_us=round(cpu_s * per, 2), cpu_per_exchange_nospin_us=round((cpu_s - spin_s) * per, 2))
