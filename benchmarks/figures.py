"""One definition of "missed", RTT and CPU per exchange, for the simulator (:mod:`benchmarks.bench`) and its floor
(:mod:`benchmarks.floor`) alike (docs/performance.md, "The method").

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

**Turns.** A cell measured for longer than :data:`TURN_S` is measured in turns of at most that long: the
simulator, the floor, the batched floor, then the simulator again, and so on (:mod:`benchmarks.bench`). Each turn's
raw counts are a :class:`Window`; the turns of one side add up (:meth:`Window.add`) before the figures are read,
so the simulator and its floor see the same phases of the host. Measured one after the other, the floor at 8
ML-III stations × 250 µs missed 0.09 % in one run and 0.99 % in the next, on the same quiet machine: a bound of
"floor + 0.05 points" then judged the host's phase more than the simulator.

A floor whose own missed rate is above the targets' margin cannot carry the load itself: ``--targets`` says so
(:func:`benchmarks.targets.floor_saturation`), so that a bound "≤ floor + x" is read as relative to such a floor.
"""

from __future__ import annotations

from collections.abc import Awaitable, Callable
from dataclasses import dataclass, field
from typing import Any

from mlink_sim.metrics import LatencyHistogram

__all__ = ["During", "ExchangeFigures", "TURN_S", "Window", "add_window", "exchange_figures", "steal_share", "turns"]

TURN_S = 10.0  #: the longest turn of one side of a cell before the other sides take theirs

#: What a side's window awaits instead of its plain sleep: ``during(pids, duration_s)``, lasting *duration_s*, with
#: the process ids of the side (the master or the floor's client first); :mod:`benchmarks.lab.recovery` stops them.
During = Callable[[list[int], float], Awaitable[None]]


def turns(duration_s: float) -> list[float]:
    """*duration_s* cut into turns of at most :data:`TURN_S`, all alike: ``turns(60) == [10.0] * 6``,
    ``turns(5) == [5.0]``, ``turns(25) == [8.33…] * 3``."""
    n = max(1, -int(-duration_s // TURN_S))
    return [duration_s / n] * n


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


@dataclass
class Window:
    """The raw counts of one measuring window, of the simulator (``a``: the master, ``b``: the workers) or of a
    floor (``a``: its client, ``b``: its server). Windows of one side add up (:meth:`add`); the figures are read
    from the sum (:meth:`figures`)."""

    cycle_ns: int
    wall_s: float = 0.0
    started: int = 0           #: cycles the clock started
    skipped: int = 0           #: cycles it skipped
    sent: int = 0
    missing: int = 0           #: answers given up
    late: int = 0              #: answers later than the master's window (the simulator's count; 0 for a floor)
    cpu_a_s: float = 0.0
    cpu_b_s: float = 0.0
    spin_s: float = 0.0        #: of ``cpu_a_s``, the clock's spin before each deadline
    wake_a: int = 0            #: voluntary context switches
    wake_b: int = 0
    ahead: int = 0             #: answers made ahead from the cards' predictions (the simulator's; 0 for a floor)
    mispredicted: int = 0      #: of those, answers the card then contradicted
    ticks: tuple[int, ...] = ()  #: the host's CPU ticks over the window (``benchmarks.floor.host_ticks`` deltas)
    rtt: LatencyHistogram = field(default_factory=LatencyHistogram)
    lateness: LatencyHistogram = field(default_factory=LatencyHistogram)
    turns: int = 1
    #: the exchanges not on time (due − on time) in each turn, in order; empty: one turn, read from the counts
    by_turn: list[int] = field(default_factory=list)
    #: the simulator's host stalls in each turn: (cycles the master clock's delayed, its longest in ns, the workers'
    #: stalls, their longest in ns, about how many answers they made late), from the report's ``host.by_process``
    #: and the workers' ``stall_totals`` (docs/report.md); empty for a floor
    stalls_by_turn: list[tuple[int, ...]] = field(default_factory=list)

    def add(self, other: Window) -> None:
        """Add *other*'s counts (a later turn of the same side) to these."""
        self.by_turn = self.not_on_time_by_turn() + other.not_on_time_by_turn()
        self.stalls_by_turn = self.stalls_by_turn + other.stalls_by_turn
        for name in ("wall_s", "started", "skipped", "sent", "missing", "late", "cpu_a_s", "cpu_b_s", "spin_s",
                     "wake_a", "wake_b", "ahead", "mispredicted", "turns"):
            setattr(self, name, getattr(self, name) + getattr(other, name))
        if self.ticks and other.ticks:
            self.ticks = tuple(a + b for a, b in zip(self.ticks, other.ticks))
        else:
            self.ticks = self.ticks or other.ticks
        self.rtt.merge(other.rtt)
        self.lateness.merge(other.lateness)

    def not_on_time_by_turn(self) -> list[int]:
        """The exchanges due but not answered within a cycle, turn by turn: whether a side's excess came in one
        turn (a host event) or in all of them."""
        if self.by_turn:
            return list(self.by_turn)
        fig = self.figures()
        return [fig.due - fig.on_time]

    def figures(self) -> ExchangeFigures:
        return exchange_figures(cycle_ns=self.cycle_ns, started=self.started, skipped=self.skipped, sent=self.sent,
                                rtt=self.rtt, cpu_s=self.cpu_a_s + self.cpu_b_s, spin_s=self.spin_s)

    def summary(self) -> dict[str, Any]:
        """The figures a cell (``benchmarks.bench.Cell``) and a floor (``benchmarks.floor.Floor``) both report, by the field names
        they share; each adds its own names for the two sides' CPU and wake-ups."""
        fig = self.figures()
        return {"cycles": self.started + self.skipped, "missed": self.skipped, "missing": self.missing,
                "sent": self.sent, "due": fig.due, "on_time": fig.on_time, "exchanges": fig.answered,
                "missed_rate": fig.missed_rate, "rtt_p50_ns": fig.rtt_p50_ns, "rtt_p99_ns": fig.rtt_p99_ns,
                "lateness_p99_ns": self.lateness.summary()["p99"], "spin_pct": self.pct(self.spin_s),
                "cpu_per_exchange_us": fig.cpu_per_exchange_us,
                "cpu_per_exchange_nospin_us": fig.cpu_per_exchange_nospin_us, "steal_pct": self.steal_pct(),
                "turns": self.turns, "missed_by_turn": self.not_on_time_by_turn()}

    def pct(self, seconds: float) -> float:
        """*seconds* of CPU in % of the windows' wall time."""
        return round(seconds / self.wall_s * 100, 1) if self.wall_s > 0 else 0.0

    def per_cycle(self, count: int) -> float:
        return round(count / max(1, self.started), 2)

    def steal_pct(self) -> float:
        """The hypervisor's steal over the windows, % of all CPUs' time (:func:`steal_share`)."""
        return steal_share(self.ticks)


def add_window(windows: dict[Any, Window], key: Any, w: Window) -> None:
    """*w* added to the window of *key* in *windows* (a later turn of that side), or kept as its first."""
    if key in windows:
        windows[key].add(w)
    else:
        windows[key] = w


def steal_share(ticks: tuple[int, ...]) -> float:
    """The time the hypervisor ran something else while the guest's CPUs had work (``steal``, the 8th field of
    ``/proc/stat``'s first line), in % of all CPUs' time, from the ticks that passed in each of the first 8 fields
    (``benchmarks.floor.ticks_between``); 0.0 without them. A floor that misses cycles while this is high points at the
    host (a slowdown the host causes without stealing is not in it)."""
    total = sum(ticks[:8]) if len(ticks) >= 8 else 0
    return round(100 * ticks[7] / total, 1) if total > 0 else 0.0
