"""Capacity sweep: stations × transmission cycle × generation, each against the floor measured in the same run.

For every cell the sweep brings a network up exactly as ``mlink-sim up --workers W`` does (slave worker
processes, the master in this process; W defaults to one per CPU but one, so the master keeps a CPU for
itself) and measures it for ``--duration`` after bring-up. In the same run it measures **the floor** twice
(:mod:`benchmarks.floor`), in turns with the network: a cell longer than 10 s is measured in turns of at most
10 s (network, plain floor, batched floor, network …; :func:`benchmarks.figures.turns`), each side's turns added
up, so that the simulator and its floors see the same phases of the host. The floor is one process serving all N
stations as a packed worker does (one socket shared by the N stations where the network packs its stations into
fewer workers: ``Cell.layout`` "shared"; a socket per station otherwise), driven by a client that sends the same
bursts on the same ``CycleTimer`` as the master and reads as the master reads, but with no protocol work on either
side; once with the per-datagram system calls (**plain**), once with ``sendmmsg``/``recvmmsg`` (**batched**,
``mlink_sim.aio.transport.mmsg``).

Figures per cell, the network's and the floors' by one definition (:mod:`benchmarks.figures`): missed (the
exchanges due but not answered within a cycle, over the exchanges due), RTT p50/p99 (every answer read, late ones
included), cycle-start lateness p99, CPU % of the master and the workers, **CPU per exchange** (master + workers
CPU time over the answers read, from the kernel's accounting), wake-ups per cycle (voluntary context switches),
and the same figures of both floors. The simulator uses the system calls the kernel supports (the batched ones
where ``sendmmsg``/``recvmmsg`` exist, the cell's ``io``); the ratios (CPU per exchange, RTT p99) are taken
against the floor that uses the same calls.

``--arrival-poll`` sets the workers' arrival poll (``[network] arrival_poll``: ``auto``, the default of
``mlink-sim up``, ``off`` or a lead; ``mlink_sim.aio.timing.arrival``); the JSON's ``host.arrival_poll`` records it.

Run from the repository's root:

    python -m benchmarks.bench                         # the full sweep (~25 min), table + bench.json + bench.png
    python -m benchmarks.bench --stations 30 --cycles 1ms --links ML2 --duration 60s   # one cell, one minute
    python -m benchmarks.bench --quick                 # a few cells, 2 s each (smoke test)
    python -m benchmarks.bench --targets               # the capacity targets, ~15 min (--duration 10s: ~5 min)
    python -m benchmarks.bench --render bench.json --markdown   # an earlier run's table, as in docs/performance.md
    python -m benchmarks.bench --targets --pm-qos      # the same with idle CPUs polling, floor and simulator alike
    python -m benchmarks.bench --targets --no-realtime # every process with ordinary scheduling (an ordinary user)
    python -m benchmarks.bench --stations 8 --cycles 250us --links ML3 --arrival-poll off   # without the workers' poll

``--targets`` runs the cells of the capacity targets (:mod:`benchmarks.targets`: 62 ML-III and 30 ML-II stations
at 1 ms for 60 s, 8 ML-III stations at 250 µs for 30 s, and ML-III at 1 ms with 15, 30 and 45 stations, 30 s
each, for the knee) and prints met / not met for each bound, with the floor's figure beside it and, where a bound
is not met, what bounds it (from the same run). ``--duration`` shortens every cell for a quick run. Exit status 0
either way: a benchmark reports, it does not gate.

The whole sweep runs as ``mlink-sim up`` runs by default where it may (its ``--realtime``: root or
``CAP_SYS_NICE``): the master and the floors' clients at SCHED_FIFO 40 on the highest CPU, the workers and the
floors' servers at SCHED_FIFO 30 on the others, memory locked, a CPU wake-up latency of 0 µs
(``mlink_sim.aio.timing.realtime``), floors and simulator alike. Where any of that is refused (an unprivileged user), the
run withdraws what it got and every process runs with ordinary scheduling, as that user's ``mlink-sim up`` does; it
says so on stderr. ``--realtime`` insists (refused, the run does not start: exit 2); ``--no-realtime`` asks for
nothing. The JSON's ``host.realtime`` says what was granted (null: ordinary scheduling).

``--pm-qos`` holds the kernel's request for a CPU wake-up latency of 0 µs (``/dev/cpu_dma_latency``, as
``mlink-sim up --realtime`` does: ``mlink_sim.aio.timing.realtime.hold_wakeup_latency``) for the whole run, so the floors
and the simulator run on CPUs that poll instead of halting when idle (the real-time default holds it already: with
``--no-realtime`` it is that request alone); refused (not root), the run does not start (exit 2). The JSON's
``host.pm_qos`` says which way a run was made.

Cells the manuals rule out are listed as such and not run: MECHATROLINK-II below 0.5 ms (17-byte) or beyond
30 stations (SI-T3 Table 29). Loops are bounded by --duration; all traffic stays on loopback. Ctrl-C or SIGTERM
ends the run: the network or floor being measured is stopped, the benchmark says so and exits 130 or 143 without
writing; killed outright, its workers and the floor's server end with it (``PR_SET_PDEATHSIG``).
"""

from __future__ import annotations

import argparse
import asyncio
import dataclasses
import json
import os
import platform
import signal
import sys
import tempfile
import time
from collections import Counter
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, TypeVar

from mlink_sim.aio.timing import realtime
from mlink_sim.aio.transport import mmsg
from mlink_sim.aio.run.session import NetworkSession
from mlink_sim.aio.control.endpoint import query_control
from mlink_sim.aio.transport.udp import new_event_loop
from mlink_sim.cli.logs import configure_logging
from mlink_sim.config import format_ns, load_config, parse_duration_ns
from mlink_sim.config.units import parse_arrival_poll

from benchmarks import targets
from benchmarks.common import write_atomically
from benchmarks.figures import During, Window, add_window, turns
from benchmarks.floor import floor_from, floor_window, host_ticks, proc_cpu_s, proc_wakeups, self_wakeups, ticks_between
from benchmarks.tables import chart, markdown, table

T = TypeVar("T")

__all__ = ["CYCLES", "Cell", "Interrupted", "LINKS", "STATIONS", "applicable", "load_cells", "main", "measure_network",
           "measuring", "render", "run_cell", "watching_rtt", "write_config"]

STATIONS = (1, 8, 9, 15, 30, 62)  # the sweep, with 8 for the target of 8 stations at 250 µs
CYCLES = ("250us", "500us", "1ms", "2ms")
LINKS = ("ML2", "ML3")


@dataclass
class Cell:
    link: str
    stations: int
    cycle_ns: int
    workers: int
    duration_s: float = 0.0     #: measuring time of the network and of each floor
    io: str = "batched"         #: the simulator's system calls: batched (sendmmsg/recvmmsg, where the kernel has
    #: them) or plain; the floor with the same calls is the cell's reference (:attr:`ref`)
    layout: str = "station"     #: shared: each worker's stations share one port (packed workers); station: a port each
    status: str = "ok"          #: ok / n/a (reason) / failed (reason)
    frame_size: int = 0
    missed_rate: float = 0.0        #: exchanges due but not answered within a cycle / exchanges due (benchmarks.figures)
    missed: int = 0                 #: cycles the clock skipped
    cycles: int = 0                 #: cycles due (started + skipped)
    due: int = 0                    #: exchanges due: sent + what the skipped cycles would have sent
    on_time: int = 0                #: answers read within a cycle of their cycle's start
    rtt_p50_ns: int = 0
    rtt_p99_ns: int = 0
    lateness_p99_ns: int = 0
    missing: int = 0
    late: int = 0
    cpu_master: float = 0.0
    cpu_slaves: float = 0.0
    sent: int = 0                   #: commands sent in the measuring window
    exchanges: int = 0              #: answers read (late ones included): a command the worker superseded is none
    cpu_per_exchange_us: float = 0.0  #: (master + workers CPU time) / exchanges
    spin_pct: float = 0.0           #: the master clock's spin before each deadline, % of the wall time
    cpu_per_exchange_nospin_us: float = 0.0  #: the same without the spin (the work an exchange itself costs)
    wakeups_master: float = 0.0     #: voluntary context switches per cycle
    wakeups_slaves: float = 0.0
    ahead_pct: float = 0.0          #: answers the workers made ahead from the cards' predictions, % of exchanges
    mispredicted: int = 0           #: of those, answers the card then contradicted (a bug: a note says so)
    steal_pct: float = 0.0          #: the hypervisor's steal over the window, % of all CPUs' time (figures.steal_share)
    turns: int = 1                  #: the windows it was measured in, in turn with its floors (figures.turns)
    missed_by_turn: list[int] = field(default_factory=list)  #: exchanges not on time in each turn, in order
    #: the host stalls in each turn: [cycles the master clock's delayed, its longest in ns, the workers' stalls
    #: (their 1 ms tick 3 ms or more late), their longest in ns, how many answers those can have made late]
    #: (``_turn_stalls``; docs/report.md, host)
    stalls_by_turn: list[list[int]] = field(default_factory=list)
    floor: dict[str, Any] | None = None          #: benchmarks.floor.Floor, plain system calls
    floor_batched: dict[str, Any] | None = None  #: benchmarks.floor.Floor, sendmmsg/recvmmsg
    notes: list[str] = field(default_factory=list)

    @property
    def ref(self) -> dict[str, Any] | None:
        """The floor with the simulator's own system calls (the other one where only it was measured)."""
        same, other = (self.floor_batched, self.floor) if self.io == "batched" else (self.floor, self.floor_batched)
        return same or other

    def ratio(self, key: str, ours: float) -> float | None:
        """*ours* ÷ the reference floor's *key* (None without a floor)."""
        ref = self.ref
        return round(ours / ref[key], 2) if ref and ref.get(key) else None


def applicable(link: str, stations: int, cycle_ns: int) -> str | None:
    """Why a cell is outside what the manuals allow (None: run it)."""
    if link == "ML2" and stations > 30:
        return "n/a: MECHATROLINK-II has at most 30 stations (SI-T3 Table 29)"
    if link == "ML2" and cycle_ns < 500_000:
        return "n/a: MECHATROLINK-II's shortest cycle is 0.5 ms (17-byte, SI-T3 CONNECT)"
    return None


def write_config(path: Path, link: str, stations: int, cycle_ns: int, arrival_poll: str = "auto") -> int:
    """A network of *stations* SI-T3 (ML-II, 17-byte) or SI-ET3 (ML-III, 32-byte) cards, its workers' arrival poll
    as *arrival_poll* says; returns the frame size."""
    card, size, first = ("si-t3", 17, 0x21) if link == "ML2" else ("si-et3", 32, 0x03)
    lines = ["[network]", f'name = "bench-{link}-{stations}"', f'link = "{link}"',
             f'transmission_cycle = "{cycle_ns}ns"', f'arrival_poll = "{arrival_poll}"', ""]
    for i in range(stations):
        lines += ["[[station]]", f"address = 0x{first + i:02X}", f'card = "{card}"', f'link = "{link}"',
                  f"frame_size = {size}", 'params = { "b1-01" = 3, "b1-02" = 3 }', ""]
    path.write_text("\n".join(lines))
    return size


# ----------------------------------------------------------------------------------------------- the network
async def measure_network(config_path: Path, workers: int, duration_s: float, cell: Cell,
                          rt: bool = False, during: During | None = None) -> Window:
    """One window of the network of *config_path*, measured for *duration_s* after bring-up, with
    ``--realtime``'s requests if *rt*; what it saw go wrong goes to *cell.notes*. *during(pids, duration_s)*, if
    given, is awaited instead of the window's sleep (it must last *duration_s*): the master's process id first,
    then the workers' (:mod:`benchmarks.lab.recovery` stops them)."""
    session = None
    try:
        config = load_config(config_path)
        session = await NetworkSession.open(config, config_path, workers=workers, restart_slaves=False, realtime=rt)
        refused = sorted(f"{who}: {what}" for who, what in session.realtime_granted.items() if "refused" in what)
        if refused:
            cell.notes.append("realtime refused: " + "; ".join(refused))
        not_up = await session.bring_up(timeout=20.0)
        if not_up:
            cell.notes.append(f"{len(not_up)} station(s) not up{_states(session)}")
        # No control query inside the window: a query's reply takes the worker's loop, and even a cpu query can make
        # answers late at 250 µs (benchmarks.lab.control measures it). The workers are asked before it (their counters) and
        # after it (their counters and own stalls, one stats query, since the window's start); their CPU is read
        # from the kernel's accounting, as the floor's server's is.
        before = await _ask_workers(session, "cpu")
        session.reset_metrics()
        pids = [w.pid for w in session.worker_list if w.alive and w.pid]
        timers = list({id(m.timer): m.timer for m in session.masters.values() if m.timer is not None}.values())
        spun0 = sum(t.spun_ns for t in timers)
        cpu0, wall0 = time.process_time(), time.monotonic()
        slaves0 = [proc_cpu_s(p) for p in pids]
        wake0, swake0, host0 = self_wakeups(), sum(proc_wakeups(p) for p in pids), host_ticks()
        await (during([os.getpid(), *pids], duration_s) if during is not None else asyncio.sleep(duration_s))
        host1 = host_ticks()
        wall = time.monotonic() - wall0
        cpu_master_s = time.process_time() - cpu0
        cpu_slaves_s = sum(max(0.0, proc_cpu_s(p) - c) for p, c in zip(pids, slaves0, strict=True))  # gone: 0
        spun_s = (sum(t.spun_ns for t in timers) - spun0) / 1e9
        wake, swake = self_wakeups() - wake0, sum(proc_wakeups(p) for p in pids) - swake0
        metrics, meta = await session.snapshot(slave_stats=False)
        after = await _ask_workers(session, "stats", since=session.metrics.stalls.origin_ns)
        behind = _states(session)
        if behind:
            cell.notes.append(f"at the end not at their phase{behind}")
    finally:
        if session is not None:
            await session.close()
    report = metrics.report(meta=meta)
    ahead = _ahead(before, after, wall, metrics.rtt.count)
    return Window(cell.cycle_ns, wall_s=wall, started=report["cycles"] - report["missed"], skipped=report["missed"],
                  sent=report["sent"], missing=report["missing"], late=report["late"], cpu_a_s=cpu_master_s,
                  cpu_b_s=cpu_slaves_s, spin_s=spun_s, wake_a=wake,
                  wake_b=swake, ticks=ticks_between(host0, host1), rtt=metrics.rtt, lateness=metrics.lateness,
                  ahead=ahead["ahead"], mispredicted=ahead["mispredicted"],
                  stalls_by_turn=[_turn_stalls(report, after, cell.stations, cell.cycle_ns)])


@contextmanager
def watching_rtt(session: NetworkSession, on_rtt: Callable[[int], None]) -> Iterator[None]:
    """Each answer's round trip (ns) goes to *on_rtt* too, after the master's own record, while the block runs."""
    hooked = [(master, master.core.on_rtt) for master in session.masters.values()]
    for master, record in hooked:

        def chained(station: int, ns: int, record: Any = record) -> None:
            record(station, ns)
            on_rtt(ns)

        master.core.on_rtt = chained
    try:
        yield
    finally:
        for master, record in hooked:
            master.core.on_rtt = record


def fill(cell: Cell, w: Window) -> None:
    """*cell*'s figures from the simulator's window *w* (one turn, or the sum of its turns)."""
    for name, value in w.summary().items():
        setattr(cell, name, value)
    cell.late = w.late
    cell.stalls_by_turn = [list(t) for t in w.stalls_by_turn]
    cell.cpu_master, cell.cpu_slaves = w.pct(w.cpu_a_s), w.pct(w.cpu_b_s)
    cell.wakeups_master, cell.wakeups_slaves = w.per_cycle(w.wake_a), w.per_cycle(w.wake_b)
    cell.ahead_pct = round(100.0 * w.ahead / cell.exchanges, 2) if cell.exchanges else 0.0
    cell.mispredicted = w.mispredicted
    if w.mispredicted:
        cell.notes.append(f"{w.mispredicted} answer(s) made ahead that the card contradicted (a bug; the workers' "
                          "logs say answer_mispredicted)")


def _states(session: NetworkSession) -> str:
    """The master's states of the stations not at their target phase, ``" (alarm 12, syncing 5)"``; '' for none:
    whether they never came up or came up and fell back (a communication alarm, OFFLINE) tells what bounds a
    saturated cell."""
    if session.net is None:
        return ""
    counts = Counter(v.state.value for v in session.net.views().values() if not v.at_target)
    return f" ({', '.join(f'{k} {n}' for k, n in counts.most_common())})" if counts else ""


async def _ask_workers(session: NetworkSession, op: str, **fields: Any) -> list[dict[str, Any]]:
    """Every live worker's reply to ``{"op": op, **fields}`` (``mlink_sim.aio.slave.server``); a worker that does not answer
    within 1 s is left out."""
    replies = []
    for w in session.worker_list:
        if w.alive and w.control_port:
            reply = await query_control("127.0.0.1", w.control_port, op, timeout=1.0, **fields)
            if reply:
                replies.append(reply)
    return replies


def _turn_stalls(report: dict[str, Any], replies: list[dict[str, Any]], stations: int,
                 cycle_ns: int) -> tuple[int, int, int, int, int]:
    """A window's host stalls (``Cell.stalls_by_turn``), from the master's report (``host.by_process.master``) and
    the workers' ``stats`` *replies* (``stall_totals`` since the window's start; docs/report.md, host): the cycles
    the master's clock delayed and its longest stall (ns), the workers' stalls and their longest (ns), and how many
    answers those can have made late. That last is each stall of the master's clock the answers of the cycle then
    on its way (*stations*), and each worker's stalled time that many cycles, rounded up, of its own stations'
    answers. An upper bound, roughly: where the master and a worker stalled together (the whole VM paused) the
    commands waited too and fewer answers came late (in one such run 558 counted, 62 late), and a worker's 1 ms tick
    dates a stall to within a millisecond."""
    master = report.get("host", {}).get("by_process", {}).get("master", {})
    workers = [(r.get("stall_totals") or {}, len(r.get("stations") or {})) for r in replies]
    held = int(master.get("count", 0)) * stations + sum(
        hosted * -(-int(totals.get("total", 0)) // cycle_ns) for totals, hosted in workers)
    return (int(master.get("cycles", 0)), int(master.get("max", 0)), sum(int(t.get("count", 0)) for t, _ in workers),
            max((int(t.get("max", 0)) for t, _ in workers), default=0), held)


def _ahead(before: list[dict[str, Any]], after: list[dict[str, Any]], wall_s: float,
           answered: int) -> dict[str, int]:
    """The answers the workers made ahead in a window of *wall_s* (``"ahead"``) and the ones of those their cards
    contradicted (``"mispredicted"``), from their replies just *before* and just *after* it (``SlaveServer.cpu``:
    ``Bus.ahead``, ``Bus.mispredicted``; matched by ``pid``). Each worker's count spans its two readings (its own
    ``wall_s`` apart, a little longer than the window) and is scaled to the window at its steady rate; a
    contradicted one counts whenever it came. At most the *answered* of the window: the readings lie a query's
    travel off the window's ends, up to a cycle's answers."""
    first = {r.get("pid"): r for r in before}
    ahead, mispredicted = 0.0, 0
    for r in after:
        r0 = first.get(r.get("pid"))
        if r0 is None:
            continue
        span = float(r.get("wall_s", 0.0)) - float(r0.get("wall_s", 0.0))
        made = int(r.get("answered_ahead", 0)) - int(r0.get("answered_ahead", 0))
        ahead += made * min(1.0, wall_s / span) if span > 0 else made
        mispredicted += int(r.get("mispredicted", 0)) - int(r0.get("mispredicted", 0))
    return {"ahead": min(round(ahead), answered), "mispredicted": mispredicted}


# ----------------------------------------------------------------------------------------------- output
def load_cells(paths: list[Path]) -> tuple[list[Cell], dict[str, Any]]:
    """The cells of earlier runs' ``--json`` files (in order), and the last document. Fields a :class:`Cell` does
    not have (a file written by another version) are left out. Raises ValueError when a file is not such a run."""
    names = {f.name for f in dataclasses.fields(Cell)}
    cells: list[Cell] = []
    doc: dict[str, Any] = {}
    for path in paths:
        try:
            doc = json.loads(path.read_text())
            cells += [Cell(**{k: v for k, v in c.items() if k in names}) for c in doc["cells"]]
        except (OSError, ValueError, KeyError, TypeError, AttributeError) as exc:
            raise ValueError(f"{path}: not a benchmarks.bench --json file ({type(exc).__name__}: {exc})") from None
    return cells, doc


# ----------------------------------------------------------------------------------------------- main
def run_cell(loop: asyncio.AbstractEventLoop, tmp: Path, link: str, n: int, cycle: int, workers: int,
             duration_s: float, arrival_poll: str = "auto", cpus: tuple[set[int], set[int]] | None = None) -> Cell:
    """One cell: the network and both floors, each for *duration_s* in turns of at most
    :data:`benchmarks.figures.TURN_S` taken one after the other (network, floor, batched floor, network …), so that
    each sees the same phases of the host; never raises."""
    cell = Cell(link, n, cycle, min(workers, n), duration_s, "batched" if mmsg.supported() else "plain",
                layout="shared" if workers < n else "station")
    reason = applicable(link, n, cycle)
    if reason:
        cell.status = reason
        return cell
    path = tmp / f"{link}-{n}-{cycle}.toml"
    cell.frame_size = size = write_config(path, link, n, cycle, arrival_poll)
    absorb_ns = load_config(path).network.absorb_ns
    shared = cell.layout == "shared"
    ours: dict[int, Window] = {}
    floors: dict[bool, Window] = {}
    failed: set[bool] = set()
    sides = [False, True] if mmsg.supported() else [False]
    for turn in turns(duration_s):
        if cell.status == "ok":
            try:
                if cpus is not None:  # the floor's client took the master's CPU: the network turn starts from every
                    # CPU, as mlink-sim up does (its plan, realtime.allowed_cpus, and its workers, started unplaced,
                    # would not need it)
                    os.sched_setaffinity(0, cpus[0] | cpus[1])
                add_window(ours, 0, loop.run_until_complete(measure_network(path, cell.workers, turn, cell,
                                                                      rt=cpus is not None)))
            except Exception as exc:  # noqa: BLE001 - one failed cell must not end the sweep
                cell.status = f"failed: {type(exc).__name__}: {exc}"
        for batched in sides:
            if batched in failed:
                continue
            try:
                add_window(floors, batched, loop.run_until_complete(
                    floor_window(n, size, cycle, turn, batched, absorb_ns, shared=shared, cpus=cpus)))
            except Exception as exc:  # noqa: BLE001 - the cell keeps its own figures
                failed.add(batched)
                cell.notes.append(f"floor {'floor_batched' if batched else 'floor'} failed: "
                                  f"{type(exc).__name__}: {exc}")
    if cell.status == "ok" and 0 in ours:
        fill(cell, ours[0])
    print(f"{link} {n:>2} stations {format_ns(cycle):>6} {cell.io:<7} " + (
          cell.status if cell.status != "ok" else f"missed {cell.missed_rate * 100:.2f}% rtt p99 "
          f"{format_ns(cell.rtt_p99_ns)} {cell.cpu_per_exchange_us:.1f} µs/exchange, {cell.ahead_pct:.1f}% answered "
          f"ahead ({cell.turns} turns)"),
          file=sys.stderr, flush=True)
    result: dict[bool, dict[str, Any]] = {}
    for batched, w in floors.items():
        if batched in failed:
            continue
        f = floor_from(w, batched, n, shared)
        result[batched] = asdict(f)
        print(f"{'':>22}floor {'batched' if batched else 'plain':<7} missed {f.missed_rate * 100:.2f}% "
              f"rtt p99 {format_ns(f.rtt_p99_ns)} {f.cpu_per_exchange_us:.1f} µs/exchange", file=sys.stderr,
              flush=True)
    cell.floor, cell.floor_batched = result.get(False), result.get(True)
    return cell


def render(paths: list[Path], as_markdown: bool, png: Path | None) -> int:
    """``--render JSON …``: the table (and with ``--png`` the chart) of earlier runs, nothing run."""
    try:
        cells, doc = load_cells(paths)
    except ValueError as exc:
        print(f"bench: {exc}", file=sys.stderr)
        return 2
    print(markdown(cells) if as_markdown else table(cells))
    if doc.get("targets"):
        print()
        print(targets.verdicts(cells)[0])
    if png is not None:
        draw(cells, png)
    return 0


def draw(cells: list[Cell], png: Path) -> None:
    """The chart at *png* ('' or '.': none); without matplotlib a hint, not an error."""
    if str(png) in ("", "."):
        return
    try:
        chart(cells, png)
        print(f"wrote {png}", file=sys.stderr)
    except ImportError:
        print("matplotlib missing: pip install -e '.[bench]' for the chart", file=sys.stderr)


def _parse(args: argparse.Namespace) -> list[tuple[str, int, int, float]]:
    """The cells to run, ``(link, stations, cycle_ns, duration_s)``; ValueError for a bad option."""
    if args.quick:
        args.stations, args.cycles, args.duration = "1,9", "1ms,2ms", "2s"
    duration = None if args.duration is None else parse_duration_ns(args.duration, default_unit="s") / 1e9
    if args.workers < 1 or (duration is not None and duration <= 0):
        raise ValueError("--workers ≥ 1, --duration > 0")
    if args.targets:
        return [(link, n, parse_duration_ns(cycle), duration or parse_duration_ns(d) / 1e9)
                for link, n, cycle, d in targets.CELLS]
    stations = [int(s) for s in args.stations.split(",")]
    cycles = [parse_duration_ns(c, default_unit="us") for c in args.cycles.split(",")]
    links = [link.strip().upper() for link in args.links.split(",")]
    if any(link not in LINKS for link in links):
        raise ValueError("links are ML2/ML3")
    return [(link, n, cycle, duration or 5.0) for link in links for n in stations for cycle in cycles]


_SIGTERM_SEEN: list[int] = []  #: set by the SIGTERM handler: the interrupt it raised was a termination


def _terminated(signum: int, frame: Any) -> None:
    """SIGTERM while measuring: raised where the run is as KeyboardInterrupt (the one exception the event loop
    lets through from a signal handler instead of logging it), remembered as a termination (exit 143)."""
    _SIGTERM_SEEN.append(signum)
    raise KeyboardInterrupt


def _stop_what_runs(loop: asyncio.AbstractEventLoop) -> None:
    """After an interrupt: cancel the measurement the loop was running and let it end (the network session closes,
    the floor's server is terminated: their ``finally``), as ``asyncio.run`` does on its way out."""
    tasks = asyncio.all_tasks(loop)
    for task in tasks:
        task.cancel()
    if tasks:
        loop.run_until_complete(asyncio.gather(*tasks, return_exceptions=True))


class Interrupted(Exception):
    """Ctrl-C or SIGTERM ended a :func:`measuring` run; *code* is the exit status (130 / 143)."""

    def __init__(self, code: int) -> None:
        super().__init__(code)
        self.code = code


def measuring(prog: str, work: Callable[[asyncio.AbstractEventLoop, Path], T]) -> T:
    """``work(loop, tmp)`` on a fresh event loop with a temporary directory, logging errors only, SIGTERM raised as
    an interrupt meanwhile. Ctrl-C or SIGTERM: what the loop ran is stopped (before the directory goes), *prog*
    says "interrupted" or "terminated, nothing written", and :class:`Interrupted` carries 130 or 143 out."""
    configure_logging(level="error")
    loop = new_event_loop()
    previous = signal.signal(signal.SIGTERM, _terminated)
    try:
        with tempfile.TemporaryDirectory(prefix="mlink-bench-") as tmp:
            try:
                return work(loop, Path(tmp))
            except KeyboardInterrupt:
                _stop_what_runs(loop)
                print(f"{prog}: {'terminated' if _SIGTERM_SEEN else 'interrupted'}, nothing written", file=sys.stderr)
                raise Interrupted(143 if _SIGTERM_SEEN else 130) from None
    finally:
        signal.signal(signal.SIGTERM, previous)
        loop.close()


def main() -> int:
    ap = argparse.ArgumentParser(prog="python -m benchmarks.bench", description=__doc__.split("\n\n")[0])
    ap.add_argument("--stations", default=",".join(map(str, STATIONS)), help="comma-separated station counts")
    ap.add_argument("--cycles", default=",".join(CYCLES), help="comma-separated transmission cycles")
    ap.add_argument("--links", default=",".join(LINKS), help="ML2, ML3 or both")
    ap.add_argument("--duration", default=None,
                    help="measuring time per cell, of the network and of each floor (default 5s; with --targets "
                         "each target's own, 60s/30s/10s, and a value given here shortens them all)")
    ap.add_argument("--workers", type=int, default=max(1, (os.cpu_count() or 1) - 1),
                    help="slave worker processes; default: one per CPU but one, which is left to the master's clock")
    ap.add_argument("--json", type=Path, default=Path("bench.json"), help="write the cells here")
    ap.add_argument("--png", type=Path, default=None,
                    help="draw the chart here (default bench.png; '' = none; with --render only when given)")
    ap.add_argument("--quick", action="store_true", help="1 and 9 stations at 1 ms and 2 ms, 2 s each")
    ap.add_argument("--targets", action="store_true",
                    help="only the capacity targets' cells, met / not met per bound beside the floor (~15 min)")
    ap.add_argument("--markdown", action="store_true", help="print the table as Markdown (docs/performance.md)")
    ap.add_argument("--render", type=Path, nargs="+", metavar="JSON",
                    help="run nothing: print the table (and draw --png) from earlier runs' --json files")
    ap.add_argument("--pm-qos", action="store_true",
                    help="hold a CPU wake-up latency of 0 µs (/dev/cpu_dma_latency) for the whole run, floors and "
                         "simulator alike, as mlink-sim up --realtime does (root only)")
    ap.add_argument("--realtime", dest="realtime", action="store_const", const="on", default="auto",
                    help="as mlink-sim up runs by default where permitted (root or CAP_SYS_NICE), and the default "
                         "here too: SCHED_FIFO, locked memory, a wake-up latency of 0 µs and the master's CPU apart, "
                         "floors and simulator alike; given, a refusal ends the run (exit 2), else it runs on with "
                         "ordinary scheduling and says so")
    ap.add_argument("--no-realtime", dest="realtime", action="store_const", const="off",
                    help="ordinary scheduling for every process, floors and simulator alike, as an unprivileged "
                         "user's mlink-sim up runs")
    ap.add_argument("--arrival-poll", default="auto",
                    help="the workers' arrival poll ([network] arrival_poll): auto (the default, as mlink-sim up), "
                         "off, or a lead such as 80us (docs/performance.md)")
    args = ap.parse_args()
    if args.render is not None:
        return render(args.render, args.markdown, args.png)
    try:
        plan = _parse(args)
        parse_arrival_poll(args.arrival_poll)
    except ValueError as exc:
        print(f"bench: {exc}", file=sys.stderr)
        return 2
    pm_qos = None
    if args.pm_qos:
        pm_qos = realtime.hold_wakeup_latency()
        if not realtime.wakeup_latency_held():
            print(f"bench: --pm-qos: {pm_qos}", file=sys.stderr)
            return 2
    cpus, rt_granted = None, None
    if args.realtime != "off":  # asked once here, as mlink-sim up asks: all of it, or ordinary scheduling throughout
        plan_cpus = realtime.cpu_plan()
        granted = realtime.apply(realtime.MASTER_PRIORITY, plan_cpus[0])
        if "refused" not in granted:
            cpus, rt_granted = plan_cpus, granted
        elif args.realtime == "on":
            print(f"bench: --realtime: {granted}", file=sys.stderr)
            return 2
        else:
            realtime.withdraw()
            print(f"bench: real-time requests refused ({granted}): every process runs with ordinary scheduling, "
                  "as an unprivileged user's mlink-sim up does", file=sys.stderr)
    try:
        cells = measuring("bench", lambda loop, tmp: [
            run_cell(loop, tmp, link, n, cycle, args.workers, seconds, args.arrival_poll, cpus)
            for link, n, cycle, seconds in plan])
    except Interrupted as exc:
        return exc.code
    if pm_qos is not None:
        print(f"--pm-qos: {pm_qos}, held for the floors and the simulator alike")
    if rt_granted is not None:
        print(f"real time: {rt_granted} (the master and the floors' clients; the workers and the floors' servers "
              "alike on the other CPUs; --no-realtime: ordinary scheduling)")
    else:
        print("ordinary scheduling for every process (--no-realtime, or the real-time requests refused)")
    print(markdown(cells) if args.markdown else table(cells))
    doc: dict[str, Any] = {
        "host": {"node": platform.node(), "cpus": os.cpu_count(), "python": platform.python_version(),
                 "kernel": platform.release(), "load_avg": os.getloadavg(), "pm_qos": pm_qos, "realtime": rt_granted,
                 "arrival_poll": args.arrival_poll},
        "cells": [asdict(c) for c in cells]}
    if args.targets:
        text, rows = targets.verdicts(cells)
        print()
        print(text)
        doc["targets"] = rows
    write_atomically(args.json, json.dumps(doc, indent=1))
    print(f"wrote {args.json}", file=sys.stderr)
    if not args.targets:
        draw(cells, Path("bench.png") if args.png is None else args.png)
    return 0


if __name__ == "__main__":
    sys.exit(main())
