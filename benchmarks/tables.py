"""The tables and the chart of the capacity sweep's cells (:mod:`benchmarks.bench`): a plain table for the
terminal, the Markdown table of docs/performance.md, and the three-panel chart (missed, RTT p99, CPU per exchange
against the number of stations, the simulator solid, its floors dashed and dotted). It only formats
``benchmarks.bench.Cell`` objects; ``python -m benchmarks.bench --render JSON`` shows an earlier run's."""

from __future__ import annotations

import os
import platform
from pathlib import Path
from typing import TYPE_CHECKING, Any

from mlink_sim.config import format_ns

if TYPE_CHECKING:
    from benchmarks.bench import Cell

__all__ = ["MD_HEAD", "chart", "markdown", "table"]


def _cpe(figures: Any) -> str:
    """CPU per exchange, all in and (in brackets) without the clock's spin: ``113.6 (40.2)``."""
    get = figures.get if isinstance(figures, dict) else lambda k, d=0.0: getattr(figures, k, d)
    return f"{get('cpu_per_exchange_us', 0.0):.1f} ({get('cpu_per_exchange_nospin_us', 0.0):.1f})"


def _ratios(c: Cell) -> str:
    """The simulator's CPU per exchange ÷ the reference floor's, all in and without the spin: ``1.34 (2.00)``."""
    a = c.ratio("cpu_per_exchange_us", c.cpu_per_exchange_us)
    b = c.ratio("cpu_per_exchange_nospin_us", c.cpu_per_exchange_nospin_us)
    return f"{a:.2f} ({b:.2f})" if a and b else (f"{a:.2f}" if a else "—")


def _floor_cols(f: dict[str, Any] | None) -> str:
    if not f:
        return f"{'—':>8} {'—':>9} {'—':>9} {'—':>13}"
    return (f"{f['missed_rate'] * 100:>7.2f}% {format_ns(f['rtt_p99_ns']):>9} {format_ns(f['lateness_p99_ns']):>9} "
            f"{_cpe(f):>13}")


def table(cells: list[Cell]) -> str:
    """The cells as a text table: the simulator, then its reference floor (same system calls), the ratios, and the
    other floor's CPU per exchange."""
    head = (f"{'gen':<4}{'st':>4}{'cycle':>8} {'io':<7} {'missed':>8} {'rtt p99':>9} {'late p99':>9} "
            f"{'cpu m/w %':>11} {'µs/exch':>13} {'wake m/w':>9} | {'floor':>8} {'rtt p99':>9} {'late p99':>9} "
            f"{'µs/exch':>13} | {'×cpu':>11} {'×rtt':>5} | {'other floor':>13}")
    rows = [head, "-" * len(head)]
    for c in cells:
        lead = f"{c.link:<4}{c.stations:>4}{format_ns(c.cycle_ns):>8} {c.io:<7}"
        if c.status != "ok":
            rows.append(f"{lead} {c.status}")
            continue
        other = c.floor if c.ref is c.floor_batched else c.floor_batched
        rtt_x = c.ratio("rtt_p99_ns", c.rtt_p99_ns)
        rows.append(
            f"{lead} {c.missed_rate * 100:>7.2f}% {format_ns(c.rtt_p99_ns):>9} {format_ns(c.lateness_p99_ns):>9} "
            f"{c.cpu_master:>5.0f}/{c.cpu_slaves:<5.0f} {_cpe(c):>13} "
            f"{c.wakeups_master:>4.1f}/{c.wakeups_slaves:<4.1f} | {_floor_cols(c.ref)} | "
            f"{_ratios(c):>11} {rtt_x or 0:>5.2f} | {_cpe(other) if other else '—':>13}"
            + (f"  ({'; '.join(notes)})" if (notes := [*c.notes, *_steal(c)]) else ""))
    return "\n".join(rows)


_STEAL_NOTED = 0.5  #: % of the machine's CPU time the hypervisor took, from which a row says so


def _steal(c: Cell) -> list[str]:
    """A note when the hypervisor took CPU time from the VM during the cell (the simulator's window or its
    floor's): a floor that misses cycles while the host steals points at the host (docs/performance.md, "Turns, steal and scheduling")."""
    ref = c.ref or {}
    ours, floor = c.steal_pct, float(ref.get("steal_pct", 0.0))
    if max(ours, floor) < _STEAL_NOTED:
        return []
    return [f"host steal {ours:.1f} % (floor {floor:.1f} %)"]


def _human(ns: int) -> str:
    """A time for the docs table: 139 ns, 27 µs, 1.86 ms (three significant figures at most)."""
    if ns < 1_000:
        return f"{ns} ns"
    if ns < 1_000_000:
        return f"{ns / 1e3:.3g} µs"
    return f"{ns / 1e6:.3g} ms"


MD_HEAD = ("| gen | stations | cycle | I/O | missed | RTT p50 | RTT p99 | lateness p99 | CPU master / workers % "
           "| CPU per exchange (without the spin) | floor missed | floor RTT p99 | floor lateness p99 "
           "| floor CPU per exchange, plain / batched | CPU ÷ floor | RTT p99 ÷ floor |")


def markdown(cells: list[Cell]) -> str:
    """The sweep as the Markdown table of docs/performance.md (cells the manuals rule out are left out). The floor
    columns are the reference floor's (the simulator's own system calls), except the CPU per exchange of both."""
    rows = [MD_HEAD, "|" + "---|" * MD_HEAD.count(" | ") + "---|"]
    width = MD_HEAD.count("|")
    for c in cells:
        if c.status.startswith("n/a"):
            continue
        head = f"| {c.link} | {c.stations} | {_human(c.cycle_ns)} | {c.io} |"
        if c.status != "ok":
            rows.append(f"{head} {c.status} |" + " |" * (width - head.count("|") - 1))
            continue
        notes = f" ({'; '.join(n.replace(' station(s)', '') for n in c.notes)})" if c.notes else ""
        f = c.ref
        floor = (f"{f['missed_rate'] * 100:.2f} % | {_human(f['rtt_p99_ns'])} | {_human(f['lateness_p99_ns'])}"
                 if f else "— | — | —")
        both = " / ".join(_cpe(x) if x else "—" for x in (c.floor, c.floor_batched))
        rtt_x = c.ratio("rtt_p99_ns", c.rtt_p99_ns)
        rows.append(
            f"{head} {c.missed_rate * 100:.2f} %{notes} | {_human(c.rtt_p50_ns)} | {_human(c.rtt_p99_ns)} | "
            f"{_human(c.lateness_p99_ns)} | {c.cpu_master:.0f} / {c.cpu_slaves:.0f} | {_cpe(c)} µs | "
            f"{floor} | {both} µs | {_ratios(c)} | {f'{rtt_x:.2f}' if rtt_x else '—'} |")
    return "\n".join(rows)


def chart(cells: list[Cell], path: Path) -> None:
    """Three panels against the number of stations: missed exchanges, RTT p99, and CPU per exchange of the simulator
    (solid) and of both floors (batched dashed, plain dotted)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(17, 4.8))
    for link, marker in (("ML2", "o"), ("ML3", "s")):
        for cycle in sorted({c.cycle_ns for c in cells}):
            for io in ("batched", "plain"):
                run = sorted((c for c in cells if c.link == link and c.cycle_ns == cycle and c.io == io
                              and c.status == "ok"), key=lambda c: c.stations)
                if not run:
                    continue
                xs = [c.stations for c in run]
                label = f"{link} {format_ns(cycle)}" + ("" if io == "batched" else " (plain I/O)")
                line = axes[0].plot(xs, [max(c.missed_rate * 100, 1e-3) for c in run], marker=marker, label=label)
                colour = line[0].get_color()
                axes[1].plot(xs, [c.rtt_p99_ns / 1e3 for c in run], marker=marker, color=colour, label=label)
                axes[2].plot(xs, [c.cpu_per_exchange_us for c in run], marker=marker, color=colour,
                             label=f"{label}: simulator")
                for key, style, name in (("floor_batched", "--", "floor, batched"), ("floor", ":", "floor, plain")):
                    pts = [(c.stations, getattr(c, key)["cpu_per_exchange_us"]) for c in run if getattr(c, key)]
                    if pts and io == "batched":
                        axes[2].plot(*zip(*pts), linestyle=style, marker=marker, color=colour, alpha=0.7,
                                     label=f"{link} {format_ns(cycle)}: {name}")
    axes[0].set(xscale="log", yscale="log", xlabel="stations", ylabel="missed exchanges % (0 drawn at 0.001)",
                title="missed: not answered within a cycle")
    axes[1].set(xscale="log", yscale="log", xlabel="stations", ylabel="RTT p99 (µs)", title="round trip p99")
    axes[2].set(xscale="log", yscale="log", xlabel="stations", ylabel="µs of CPU per exchange (both sides)",
                title="CPU per exchange: simulator vs floor")
    for ax in axes:
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=6)
    fig.suptitle(f"mlink-sim capacity on {platform.node() or 'this host'} ({os.cpu_count()} CPUs)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
