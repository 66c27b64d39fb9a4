"""The capacity targets, each judged against the floor measured in the same run (``python -m benchmarks.bench
--targets``; the cells are ``benchmarks.bench.Cell``, the floor :mod:`benchmarks.floor`).

The targets (ratios in one run, on the machine the run names):

1. 62 ML-III stations @ 1 ms for 60 s: missed ≤ the floor's missed + 0.05 percentage points; RTT p99 ≤ 2 × the
   floor's p99;
2. 62 ML-III stations @ 500 µs for 30 s: the same bounds;
3. 30 ML-II stations @ 1 ms for 60 s: the same bounds;
4. 8 ML-III stations @ 250 µs for 30 s: cycle lateness p99 ≤ 50 µs; missed ≤ the floor's + 0.05 points;
5. CPU per exchange (master and workers, all costs in) ≤ 1.3 × the floor's at 62 ML-III @ 1 ms, ≤ 2 × in each of
   the other cells above (:data:`TARGETS`);
6. the 1 ms knee, the most ML-III stations at 1 ms with missed ≤ floor + 0.05 points (every smaller cell of the
   run holding too), reaches 62 (cells of 15, 30 and 45 stations, 30 s each, and the 62 of target 1).

The knee's cells last 30 s, in three turns like the 250 µs cell, because of the host's stalls. Under real-time
scheduling a host stall of 3–4 ms on the worker's CPU (a guest's non-preemptible kernel thread, the hypervisor)
costs a cell that many cycles of every station, and such stalls can come several times a minute; the margin of
0.05 points is 5 cycles in 10 s, so two such stalls in the simulator's one turn and none in its floor's would put
a 10 s cell over. In 30 s the margin is 15 cycles, and each side's stalls average over three turns.

"The floor" of a cell is the floor with the simulator's own system calls (``Cell.ref``). Both are read by
one definition of missed, RTT and CPU per exchange (:func:`benchmarks.figures.exchange_figures`). Where a bound is
not met the verdict says what bounds it, from the same run: the CPU of the master and the workers, CPU per
exchange against the floor's, wake-ups per cycle, stations that did not come up, or the floor itself breaking the
bound. A floor that itself misses more than the margin (answers not back within a cycle) is **saturated**: it
cannot carry the load on the machine the benchmark runs on either, and the table says so under its bounds
(:func:`floor_saturation`).
"""

from __future__ import annotations

from typing import Any

from mlink_sim.config import format_ns, parse_duration_ns

__all__ = ["CELLS", "TARGETS", "by_turn", "floor_saturation", "verdicts", "knee"]

#: (link, stations, cycle, duration, CPU factor): the targets' cells, each with its bound on CPU per exchange (× the
#: floor's); a 250 µs cell is judged by its clock's lateness, the others by their RTT p99
TARGETS = (("ML3", 62, "1ms", "60s", 1.3), ("ML3", 62, "500us", "30s", 2.0), ("ML2", 30, "1ms", "60s", 2.0),
           ("ML3", 8, "250us", "30s", 2.0))
#: (link, stations, cycle, duration): the targets' cells, then the knee's
CELLS = tuple(t[:4] for t in TARGETS) + (("ML3", 15, "1ms", "30s"), ("ML3", 30, "1ms", "30s"),
                                         ("ML3", 45, "1ms", "30s"))
MISSED_MARGIN = 0.0005  # 0.05 percentage points
RTT_FACTOR = 2.0
LATENESS_NS = 50_000
KNEE_GOAL = 62


def _cell(cells: list[Any], link: str, stations: int, cycle: str) -> Any:
    cycle_ns = parse_duration_ns(cycle)
    for c in cells:
        if (c.link, c.stations, c.cycle_ns) == (link, stations, cycle_ns):
            return c
    return None


def _name(c: Any) -> str:
    return f"{c.stations} {c.link} @ {format_ns(c.cycle_ns)}, {c.duration_s:g}s"


def _pct(rate: float) -> str:
    return f"{rate * 100:.2f} %"


def bounded_by(c: Any) -> str:
    """What holds the cell back, in figures of the same run."""
    ref = c.ref or {}
    fl = ref.get("cpu_per_exchange_us", 0.0)
    x = f" = {c.cpu_per_exchange_us / fl:.1f} × the floor's {fl:.1f}" if fl else ""
    busy = max(c.cpu_master, c.cpu_slaves) >= 90
    chain = (f"; RTT p50 {format_ns(c.rtt_p50_ns)} against the floor's {format_ns(ref['rtt_p50_ns'])} (the chain a "
             f"host stall can fall in; docs/performance.md, \"What bounds the missed answers\")"
             if ref.get("rtt_p50_ns") and c.rtt_p50_ns else "")
    text = (f"{'CPU: ' if busy else ''}master {c.cpu_master:.0f} %, workers {c.cpu_slaves:.0f} % of a CPU; "
            f"{c.cpu_per_exchange_us:.1f} µs per exchange{x}; wake-ups per cycle {c.wakeups_master:.1f} / "
            f"{c.wakeups_slaves:.1f} (floor {ref.get('wakeups_client', 0):.1f} / {ref.get('wakeups_server', 0):.1f})"
            f"{chain}")
    return text + (f"; {'; '.join(c.notes)}" if c.notes else "")


def by_turn(c: Any) -> str:
    """The answers not back within a cycle in each turn, the cell's and its floor's, the host stalls the master's
    clock and the workers logged in each of the cell's turns, and how many late answers those account for
    (:func:`_weighed`): an excess in one turn of six is a host event the floor's turns missed; one spread
    over all of them is the simulator's own."""
    ours, floor = list(getattr(c, "missed_by_turn", None) or []), list((c.ref or {}).get("missed_by_turn") or [])
    stalls = list(getattr(c, "stalls_by_turn", None) or [])
    if not ours:
        return ""
    text = (f"not back within a cycle per turn {', '.join(f'{n:,}' for n in ours)}"
            + (f" (floor {', '.join(f'{n:,}' for n in floor)})" if floor else ""))
    if len(stalls) == len(ours):
        text += ("; the master's clock per turn, cycles its host stalls delayed / the longest: "
                 + ", ".join(f"{s[0]:,} / {format_ns(s[1])}" for s in stalls))
        if all(len(s) >= 4 for s in stalls):
            text += ("; the workers' stalls of 3 ms or more per turn / the longest: "
                     + ", ".join(f"{s[2]:,} / {format_ns(s[3])}" for s in stalls))
        if all(len(s) >= 5 for s in stalls):
            text += "; " + _weighed(c, [s[4] for s in stalls])
    return text


def _weighed(c: Any, held: list[int]) -> str:
    """How many late answers the logged host stalls can account for (*held*, per turn: ``bench._turn_stalls``),
    against the answers by which the cell is over its limit: as many or more, and the host's stalls can explain
    it; fewer, and the rest is the simulator's own or a holdup neither process logged. *held* is an upper bound:
    where the master and the worker stalled together (the whole VM paused) fewer answers came late."""
    ref = c.ref or {}
    over = round((c.missed_rate - _missed_limit(ref)) * getattr(c, "due", 0))
    total = sum(held)
    text = (f"late answers those stalls can account for, per turn: {', '.join(f'{n:,}' for n in held)} "
            f"(up to {total:,} in all)")
    if over > 0:
        text += (f", {'at least' if total >= over else 'fewer than'} the {over:,} by which the cell is over its "
                 f"limit" + (": the host's stalls can explain it" if total >= over else
                             ": the rest is the simulator's own, or a holdup neither process logged"))
    return text


def floor_saturation(c: Any) -> str:
    """'' when the cell's floor carries its load (missed ≤ the margin), else a sentence saying it does not, with
    its figures."""
    ref = c.ref
    if ref is None or ref["missed_rate"] <= MISSED_MARGIN:
        return ""
    due, on_time = ref.get("due", 0), ref.get("on_time", 0)
    of = f" ({due - on_time:,} of {due:,} answers not back within a cycle)" if due else ""
    return (f"floor saturated at {_name(c)}: the floor itself misses {_pct(ref['missed_rate'])}{of}, client / "
            f"server CPU {ref.get('cpu_client_pct', 0):.0f} / {ref.get('cpu_server_pct', 0):.0f} %, its clock's "
            f"lateness p99 {format_ns(ref.get('lateness_p99_ns', 0))}: the bounds of this cell are relative to a "
            f"floor that cannot carry the load on this machine either")


def _missed_limit(ref: dict[str, Any]) -> float:
    """The most a cell may miss: its floor's missed plus the margin."""
    return float(ref.get("missed_rate", 0.0)) + MISSED_MARGIN


def _missed_why(c: Any) -> str:
    """Why a cell's missed bound was not met: its turns and their stalls (:func:`by_turn`), then its CPU
    (:func:`bounded_by`)."""
    return "; ".join(filter(None, (by_turn(c), bounded_by(c))))


def _missed_ok(c: Any) -> bool:
    ref = c.ref
    return ref is not None and c.missed_rate <= _missed_limit(ref)


def knee(cells: list[Any], goal: int = KNEE_GOAL) -> tuple[int, list[Any]]:
    """The most ML-III stations at 1 ms that hold (missed ≤ floor + 0.05 points) with every smaller measured cell
    holding as well (0: none), and the cells it was read from, by station count."""
    run = sorted((c for c in cells if c.link == "ML3" and c.cycle_ns == 1_000_000 and c.status == "ok"
                  and c.stations <= goal), key=lambda c: c.stations)
    best = 0
    for c in run:
        if not _missed_ok(c):
            break
        best = c.stations
    return best, run


def verdicts(cells: list[Any]) -> tuple[str, list[dict[str, Any]]]:
    """The targets' table and its rows as data: each bound, the figure measured, the floor's, the limit, met or
    not and, where not, what bounds it."""
    rows: list[dict[str, Any]] = []

    def row(c: Any, bound: str, measured: str, floor: str, limit: str, met: bool, why: str = "") -> None:
        rows.append({"target": _name(c), "bound": bound, "measured": measured, "floor": floor, "limit": limit,
                     "met": met, "verdict": "met" if met else f"not met: {why or bounded_by(c)}",
                     "floor_saturated": floor_saturation(c)})

    def failed(c: Any, target: str) -> bool:
        if c is not None and c.status == "ok" and c.ref is not None:
            return False
        status = "not run" if c is None else (c.status if c.status != "ok" else "no floor measured")
        rows.append({"target": target, "bound": "—", "met": False, "verdict": status})
        return True

    judged = []
    for link, n, cycle, dur, factor in TARGETS:
        c = _cell(cells, link, n, cycle)
        if failed(c, f"{n} {link} @ {cycle}, {dur}"):
            continue
        judged.append((c, factor))
        ref = c.ref
        if c.cycle_ns == 250_000:
            floor_late = ref["lateness_p99_ns"]
            row(c, "lateness p99 ≤ 50 µs", format_ns(c.lateness_p99_ns), format_ns(floor_late),
                format_ns(LATENESS_NS), c.lateness_p99_ns <= LATENESS_NS,
                "" if floor_late <= LATENESS_NS else f"the floor breaks it too; {bounded_by(c)}")
        row(c, "missed ≤ floor + 0.05 points", _pct(c.missed_rate), _pct(ref["missed_rate"]),
            _pct(_missed_limit(ref)), _missed_ok(c), _missed_why(c))
        if c.cycle_ns != 250_000:
            limit = RTT_FACTOR * ref["rtt_p99_ns"]
            row(c, "RTT p99 ≤ 2 × floor p99", format_ns(c.rtt_p99_ns), format_ns(ref["rtt_p99_ns"]),
                format_ns(int(limit)), c.rtt_p99_ns <= limit)
    for c, factor in judged:
        fl = c.ref["cpu_per_exchange_us"]
        row(c, f"CPU per exchange ≤ {factor:g} × floor", f"{c.cpu_per_exchange_us:.1f} µs", f"{fl:.1f} µs",
            f"{factor * fl:.1f} µs", 0 < c.cpu_per_exchange_us <= factor * fl)
    best, run = knee(cells)
    if run:
        steps = ", ".join(f"{c.stations}: {_pct(c.missed_rate)} vs {_pct(c.ref['missed_rate']) if c.ref else '—'}"
                          for c in run)
        beyond = next((c for c in run if c.stations > best), None)
        why = f"missed vs floor per cell {steps}"
        if beyond is not None:
            why += f"; at {beyond.stations}: {_missed_why(beyond)}"
        rows.append({"target": "1 ms knee (ML3)", "bound": f"reaches {KNEE_GOAL} stations", "measured": str(best),
                     "floor": "—", "limit": str(KNEE_GOAL), "met": best >= KNEE_GOAL,
                     "verdict": "met" if best >= KNEE_GOAL else f"not met: {why}",
                     "floor_saturated": "; ".join(filter(None, (floor_saturation(c) for c in run)))})
    else:
        rows.append({"target": "1 ms knee (ML3)", "bound": f"reaches {KNEE_GOAL} stations", "met": False,
                     "verdict": "not run"})
    return _text(rows), rows


def _text(rows: list[dict[str, Any]]) -> str:
    w = max(len(r["target"]) for r in rows)
    wb = max(len(r["bound"]) for r in rows)
    lines = [f"{'target':<{w}}  {'bound':<{wb}}  {'measured':>10}  {'floor':>10}  {'limit':>10}  verdict",
             "-" * (w + wb + 60)]
    for r in rows:
        lines.append(f"{r['target']:<{w}}  {r['bound']:<{wb}}  {r.get('measured', '—'):>10}  "
                     f"{r.get('floor', '—'):>10}  {r.get('limit', '—'):>10}  {r['verdict']}")
    saturated = list(dict.fromkeys(s for r in rows for s in r.get("floor_saturated", "").split("; ") if s))
    lines += [f"! {s}" for s in saturated]
    met = sum(1 for r in rows if r["met"])
    lines.append(f"{met} of {len(rows)} bounds met")
    return "\n".join(lines)
