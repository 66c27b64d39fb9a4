#!/usr/bin/env python3
"""Capacity sweep: stations × transmission cycle × generation, each against a bare uvloop UDP echo baseline.

For every cell the sweep brings a network up exactly as ``mlink-sim up --workers W`` does (slave worker
processes, the master in this process; W defaults to one per CPU but one, so the master keeps a CPU for
itself), measures for ``--duration`` after bring-up, then runs the baseline in the same way: W echo processes
(bare uvloop ``DatagramProtocol`` that sends every datagram back) and, in this process, a client that sends the
same burst (one datagram of the same size per station) on the same cycle clock (``CycleTimer``) and times the
answers. Figures per cell: missed-cycle rate, RTT p50/p99, cycle-start lateness
p99, CPU % of master and slaves, the echo's RTT p50/p99 and the ratio RTT p99 / echo p99.

    scripts/bench.py                                   # the full sweep (~10 min), table + bench.json + bench.png
    scripts/bench.py --stations 30 --cycles 1ms --links ML2 --duration 60s     # one cell, one minute
    scripts/bench.py --quick                           # a few cells, 2 s each (smoke test)
    scripts/bench.py --targets                         # the three capacity targets of docs/performance.md, ~4 min
    scripts/bench.py --render docs/bench.json --markdown   # an earlier run's table, as in docs/performance.md

``--targets`` runs the cells of the capacity targets (30 ML-II stations at 1 ms for 60 s, 62 ML-III stations at
1 ms, 8 ML-III stations at 250 µs) and prints, for each bound, the figure measured and the same figure of the
bare echo in the same run: where the echo breaks the bound too, the bound is below what this machine gives any
process on its clock and loopback (the platform floor), not a limit of mlink-sim. Exit status 0 either way: a
benchmark reports, it does not gate.

Cells the manuals rule out are listed as such and not run: MECHATROLINK-II below 0.5 ms (17-byte) or beyond
30 stations (SI-T3 Table 29). Loops are bounded by --duration; all traffic stays on loopback.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import platform
import signal
import subprocess
import sys
import tempfile
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from collections.abc import Callable
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from mlink_sim.aio.session import NetworkSession  # noqa: E402
from mlink_sim.aio.ticker import CycleTimer  # noqa: E402
from mlink_sim.aio.udp import new_event_loop  # noqa: E402
from mlink_sim.cli.logs import configure_logging  # noqa: E402
from mlink_sim.config import format_ns, load_config, parse_duration_ns  # noqa: E402
from mlink_sim.metrics import LatencyHistogram  # noqa: E402

STATIONS = (1, 8, 9, 15, 30, 62)  # the sweep, plus 8 for the 250 µs × 8 stations target
CYCLES = ("250us", "500us", "1ms", "2ms")
LINKS = ("ML2", "ML3")
HEADER = 12 + 2  # envelope + FCS (docs/wire-format.md)


@dataclass
class Cell:
    link: str
    stations: int
    cycle_ns: int
    workers: int
    duration_s: float = 0.0     #: measuring time of the network and of the echo, each
    status: str = "ok"          #: ok / n/a (reason) / failed (reason)
    frame_size: int = 0
    missed_rate: float = 0.0
    missed: int = 0
    cycles: int = 0
    rtt_p50_ns: int = 0
    rtt_p99_ns: int = 0
    lateness_p99_ns: int = 0
    missing: int = 0
    late: int = 0
    cpu_master: float = 0.0
    cpu_slaves: float = 0.0
    echo_p50_ns: int = 0
    echo_p99_ns: int = 0
    echo_missed_rate: float = 0.0
    echo_missed: int = 0
    echo_lateness_p99_ns: int = 0
    ratio_p99: float = 0.0
    notes: list[str] = field(default_factory=list)


def applicable(link: str, stations: int, cycle_ns: int) -> str | None:
    """Why a cell is outside what the manuals allow (None: run it)."""
    if link == "ML2" and stations > 30:
        return "n/a: MECHATROLINK-II has at most 30 stations (SI-T3 Table 29)"
    if link == "ML2" and cycle_ns < 500_000:
        return "n/a: MECHATROLINK-II's shortest cycle is 0.5 ms (17-byte, SI-T3 CONNECT)"
    return None


def write_config(path: Path, link: str, stations: int, cycle_ns: int) -> int:
    """A network of *stations* SI-T3 (ML-II, 17-byte) or SI-ET3 (ML-III, 32-byte) cards; returns the frame size."""
    card, size, first = ("si-t3", 17, 0x21) if link == "ML2" else ("si-et3", 32, 0x03)
    lines = ["[network]", f'name = "bench-{link}-{stations}"', f'link = "{link}"',
             f'transmission_cycle = "{cycle_ns}ns"', ""]
    for i in range(stations):
        lines += ["[[station]]", f"address = 0x{first + i:02X}", f'card = "{card}"', f'link = "{link}"',
                  f"frame_size = {size}", 'params = { "b1-01" = 3, "b1-02" = 3 }', ""]
    path.write_text("\n".join(lines))
    return size


# ----------------------------------------------------------------------------------------------- the network
async def measure_network(config_path: Path, workers: int, duration_s: float, cell: Cell) -> None:
    config = load_config(config_path)
    session = await NetworkSession.open(config, config_path, workers=workers, restart_slaves=False)
    try:
        not_up = await session.bring_up(timeout=20.0)
        if not_up:
            cell.notes.append(f"{len(not_up)} station(s) not up")
        session.reset_metrics()
        await session.refresh_slave_stats()  # CPU baselines after bring-up
        cpu0 = time.process_time()
        wall0 = time.monotonic()
        slaves0 = await _slave_cpu(session)
        await asyncio.sleep(duration_s)
        wall = time.monotonic() - wall0
        cpu_master = (time.process_time() - cpu0) / wall * 100
        slaves1 = await _slave_cpu(session)
        metrics, meta = await session.snapshot(slave_stats=False)
    finally:
        await session.close()
    report = metrics.report(meta=meta)
    cell.cycles, cell.missed = report["cycles"], report["missed"]
    cell.missed_rate = report["missed_rate"]
    cell.rtt_p50_ns, cell.rtt_p99_ns = report["rtt"]["p50"], report["rtt"]["p99"]
    cell.lateness_p99_ns = report["lateness"]["p99"]
    cell.missing, cell.late = report["missing"], report["late"]
    cell.cpu_master = round(cpu_master, 1)
    cell.cpu_slaves = round(sum(slaves1.get(k, 0.0) - v for k, v in slaves0.items()) / wall * 100, 1)


async def _slave_cpu(session: NetworkSession) -> dict[str, float]:
    from mlink_sim.aio.slave import query_control

    out: dict[str, float] = {}
    for w in session.worker_list:
        if w.alive and w.control_port:
            reply = await query_control("127.0.0.1", w.control_port, "cpu", timeout=1.0)
            if reply:
                out[str(w.spec.index)] = float(reply.get("cpu_s", 0.0))
    return out


# ----------------------------------------------------------------------------------------------- the baseline
def echo_server(count: int) -> None:
    """``--echo-server N``: N bare uvloop UDP echo sockets on loopback; prints their ports, runs until SIGTERM."""
    loop = new_event_loop()

    class Echo(asyncio.DatagramProtocol):
        def connection_made(self, transport: Any) -> None:
            self.transport = transport

        def datagram_received(self, data: bytes, addr: Any) -> None:
            self.transport.sendto(data, addr)

    async def main() -> None:
        ports = []
        for _ in range(count):
            transport, _ = await loop.create_datagram_endpoint(Echo, local_addr=("127.0.0.1", 0))
            ports.append(transport.get_extra_info("sockname")[1])
        print(json.dumps(ports), flush=True)
        stop = asyncio.Event()
        loop.add_signal_handler(signal.SIGTERM, stop.set)
        await stop.wait()

    loop.run_until_complete(main())


async def measure_echo(stations: int, size: int, cycle_ns: int, workers: int, duration_s: float,
                       cell: Cell) -> None:
    groups = [stations // workers + (1 if i < stations % workers else 0) for i in range(workers)]
    procs = [subprocess.Popen([sys.executable, __file__, "--echo-server", str(n)], stdout=subprocess.PIPE)
             for n in groups if n]
    try:
        ports = [p for proc in procs for p in json.loads(proc.stdout.readline())]  # type: ignore[union-attr]
        loop = asyncio.get_running_loop()
        hist = LatencyHistogram()
        sent: dict[int, int] = {}
        payload = bytes(HEADER + size - 4)

        class Client(asyncio.DatagramProtocol):
            def datagram_received(self, data: bytes, addr: Any) -> None:
                now = time.monotonic_ns()
                seq = int.from_bytes(data[:4], "little")
                t = sent.pop(seq, None)
                if t is not None:
                    hist.record(now - t)

        transport, _ = await loop.create_datagram_endpoint(Client, local_addr=("127.0.0.1", 0))
        seq = 0
        lateness = LatencyHistogram()
        missed = 0

        def on_cycle(k: int, deadline: int, now: int, skipped: int) -> None:
            nonlocal seq, missed
            missed += skipped
            lateness.record(now - deadline)
            sent.clear()  # answers later than a cycle do not count, as for the master
            for port in ports:
                seq += 1
                sent[seq] = time.monotonic_ns()
                transport.sendto(seq.to_bytes(4, "little") + payload, ("127.0.0.1", port))

        timer = CycleTimer(cycle_ns, on_cycle, loop=loop)
        timer.start()
        await asyncio.sleep(duration_s)
        timer.stop()
        transport.close()
        s = hist.summary()
        cell.echo_p50_ns, cell.echo_p99_ns = s["p50"], s["p99"]
        total = lateness.count + missed
        cell.echo_missed = missed
        cell.echo_missed_rate = missed / total if total else 0.0
        cell.echo_lateness_p99_ns = lateness.summary()["p99"]
    finally:
        for proc in procs:
            proc.terminate()
        for proc in procs:
            proc.wait(5)


# ----------------------------------------------------------------------------------------------- output
def table(cells: list[Cell]) -> str:
    head = (f"{'gen':<4}{'st':>4}{'cycle':>8} {'missed':>8} {'rtt p50':>9} {'rtt p99':>9} {'late p99':>9} "
            f"{'cpu m/s %':>11} {'echo p99':>9} {'ratio':>6} {'echo missed':>12} {'echo late p99':>14}")
    rows = [head, "-" * len(head)]
    for c in cells:
        if c.status != "ok":
            rows.append(f"{c.link:<4}{c.stations:>4}{format_ns(c.cycle_ns):>8}  {c.status}")
            continue
        echo = c.echo_p99_ns != 0
        rows.append(
            f"{c.link:<4}{c.stations:>4}{format_ns(c.cycle_ns):>8} {c.missed_rate * 100:>7.2f}% "
            f"{format_ns(c.rtt_p50_ns):>9} {format_ns(c.rtt_p99_ns):>9} {format_ns(c.lateness_p99_ns):>9} "
            f"{c.cpu_master:>5.0f}/{c.cpu_slaves:<5.0f} {format_ns(c.echo_p99_ns) if echo else '—':>9} "
            f"{c.ratio_p99:>6.2f} {c.echo_missed_rate * 100:>11.2f}% "
            f"{format_ns(c.echo_lateness_p99_ns) if echo else '—':>14}"
            + (f"  ({'; '.join(c.notes)})" if c.notes else ""))
    return "\n".join(rows)


def _human(ns: int) -> str:
    """A time for the docs table: 139 ns, 27 µs, 1.86 ms (three significant figures at most)."""
    if ns < 1_000:
        return f"{ns} ns"
    if ns < 1_000_000:
        return f"{ns / 1e3:.3g} µs"
    return f"{ns / 1e6:.3g} ms"


def markdown(cells: list[Cell]) -> str:
    """The sweep as the Markdown table of docs/performance.md (cells the manuals rule out are left out)."""
    rows = ["| gen | stations | cycle | missed | RTT p50 | RTT p99 | lateness p99 | CPU master / slaves % | echo p99 "
            "| RTT p99 ÷ echo p99 | echo missed | echo lateness p99 |",
            "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for c in cells:
        if c.status.startswith("n/a"):
            continue
        head = f"| {c.link} | {c.stations} | {_human(c.cycle_ns)} |"
        if c.status != "ok":
            rows.append(f"{head} {c.status} |" + " |" * 8)
            continue
        notes = f" ({'; '.join(n.replace(' station(s)', '') for n in c.notes)})" if c.notes else ""
        echo = c.echo_p99_ns != 0
        rows.append(
            f"{head} {c.missed_rate * 100:.2f} %{notes} | {_human(c.rtt_p50_ns)} | {_human(c.rtt_p99_ns)} | "
            f"{_human(c.lateness_p99_ns)} | {c.cpu_master:.0f} / {c.cpu_slaves:.0f} | "
            f"{_human(c.echo_p99_ns) if echo else '—'} | {f'{c.ratio_p99:.2f}' if echo else '—'} | "
            f"{c.echo_missed_rate * 100:.2f} % | {_human(c.echo_lateness_p99_ns) if echo else '—'} |")
    return "\n".join(rows)


def load_cells(path: Path) -> tuple[list[Cell], dict[str, Any]]:
    """The cells of an earlier run's ``--json`` file, and the whole document. Raises ValueError when it is not one."""
    try:
        doc = json.loads(path.read_text())
        cells = [Cell(**c) for c in doc["cells"]]
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise ValueError(f"{path}: not a bench.py --json file ({type(exc).__name__}: {exc})") from None
    return cells, doc


# --------------------------------------------------------------------------------------- the capacity targets
@dataclass(frozen=True)
class Bound:
    """One bound of a target: the figure *network* reads off a cell and the same figure *echo* reads off the
    cell's bare echo (None: the bound is itself relative to the echo), both against *limit*."""

    text: str
    network: Callable[[Cell], float]
    echo: Callable[[Cell], float] | None
    limit: float
    unit: str  #: "%" (fractions shown in per cent, bound strict), "ns", "x" or "n" (a count)

    def holds(self, value: float) -> bool:
        return value < self.limit if self.unit == "%" else value <= self.limit


@dataclass(frozen=True)
class Target:
    link: str
    stations: int
    cycle: str
    duration: str
    bounds: tuple[Bound, ...]


#: The capacity targets (issue 6; docs/performance.md "Targets"). A bound holds when measured ≤ limit (< for %).
TARGETS = (
    Target("ML2", 30, "1ms", "60s", (
        Bound("missed cycles == 0 over 60 s", lambda c: c.missed, lambda c: c.echo_missed, 0, "n"),
        Bound("RTT p99 ≤ 1.5 × echo p99", lambda c: c.ratio_p99, None, 1.5, "x"),
    )),
    Target("ML3", 62, "1ms", "10s", (
        Bound("missed < 0.1 %", lambda c: c.missed_rate, lambda c: c.echo_missed_rate, 0.001, "%"),
    )),
    Target("ML3", 8, "250us", "10s", (
        Bound("lateness p99 ≤ 50 µs", lambda c: c.lateness_p99_ns, lambda c: c.echo_lateness_p99_ns, 50_000, "ns"),
    )),
)


def _fmt(value: float, unit: str) -> str:
    if unit == "%":
        return f"{value * 100:.2f} %"
    if unit == "ns":
        return format_ns(int(value))
    if unit == "x":
        return f"{value:.2f} ×"
    return f"{int(value)}"


def verdicts(cells: list[Cell]) -> tuple[str, list[dict[str, Any]]]:
    """The targets' table and its rows as data: each bound, measured, the echo's figure, met or not and why.
    *cells* are the cells of :data:`TARGETS`, in that order. Where the echo breaks a bound too, the bound is below
    the platform floor; where mlink-sim is also more than twice the echo's figure, it is well beyond that floor
    and its own CPU per exchange is named as well."""
    rows: list[dict[str, Any]] = []
    for target, cell in zip(TARGETS, cells):
        name = f"{target.stations} {target.link} @ {target.cycle}, {target.duration}"
        for b in target.bounds:
            if cell.status != "ok":
                rows.append({"target": name, "bound": b.text, "verdict": cell.status})
                continue
            measured = b.network(cell)
            echo = b.echo(cell) if b.echo is not None else None
            met = b.holds(measured)
            if met:
                verdict = "met"
            elif echo is not None and not b.holds(echo):
                verdict = "not met: platform floor (the bare echo breaks it too)"
                if measured > 2 * echo:
                    verdict += ", and CPU per exchange"
            elif echo is None:  # a bound relative to the echo
                verdict = "not met: CPU per exchange"
            else:
                verdict = "not met: CPU per exchange (the bare echo holds it)"
            rows.append({"target": name, "bound": b.text, "measured": _fmt(measured, b.unit),
                         "echo": "—" if echo is None else _fmt(echo, b.unit), "met": met, "verdict": verdict})
    w = max(len(r["target"]) for r in rows)
    wb = max(len(r["bound"]) for r in rows)
    lines = [f"{'target':<{w}}  {'bound':<{wb}}  {'measured':>10}  {'bare echo':>10}  verdict",
             "-" * (w + wb + 40)]
    for r in rows:
        lines.append(f"{r['target']:<{w}}  {r['bound']:<{wb}}  {r.get('measured', '—'):>10}  "
                     f"{r.get('echo', '—'):>10}  {r['verdict']}")
    return "\n".join(lines), rows


def chart(cells: list[Cell], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(12, 4.5))
    for link, marker in (("ML2", "o"), ("ML3", "s")):
        for cycle in sorted({c.cycle_ns for c in cells}):
            run = [c for c in cells if c.link == link and c.cycle_ns == cycle and c.status == "ok"]
            if not run:
                continue
            xs = [c.stations for c in run]
            label = f"{link} {format_ns(cycle)}"
            axes[0].plot(xs, [max(c.missed_rate * 100, 1e-3) for c in run], marker=marker, label=label)
            axes[1].plot(xs, [c.rtt_p99_ns / 1e3 for c in run], marker=marker, label=label)
    axes[0].set(xscale="log", yscale="log", xlabel="stations", ylabel="missed cycles % (0 drawn at 0.001)",
                title="missed-cycle rate")
    axes[1].set(xscale="log", yscale="log", xlabel="stations", ylabel="RTT p99 (µs)", title="round trip p99")
    for ax in axes:
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
    fig.suptitle(f"mlink-sim capacity on {platform.node() or 'this host'} ({os.cpu_count()} CPUs)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)


# ----------------------------------------------------------------------------------------------- main
def run_cell(loop: asyncio.AbstractEventLoop, tmp: Path, link: str, n: int, cycle: int, workers: int,
             duration_s: float) -> Cell:
    """One cell: the network, then the echo baseline, both for *duration_s*; never raises."""
    cell = Cell(link, n, cycle, min(workers, n), duration_s)
    reason = applicable(link, n, cycle)
    if reason:
        cell.status = reason
        return cell
    path = tmp / f"{link}-{n}-{cycle}.toml"
    cell.frame_size = write_config(path, link, n, cycle)
    print(f"{link} {n:>2} stations {format_ns(cycle):>6} …", end=" ", file=sys.stderr, flush=True)
    try:
        loop.run_until_complete(measure_network(path, cell.workers, duration_s, cell))
        loop.run_until_complete(measure_echo(n, cell.frame_size, cycle, cell.workers, duration_s, cell))
    except Exception as exc:  # noqa: BLE001 - one failed cell must not end the sweep
        cell.status = f"failed: {type(exc).__name__}: {exc}"
    if cell.echo_p99_ns:
        cell.ratio_p99 = round(cell.rtt_p99_ns / cell.echo_p99_ns, 2)
    print(cell.status if cell.status != "ok" else
          f"missed {cell.missed_rate * 100:.2f}% rtt p99 {format_ns(cell.rtt_p99_ns)} "
          f"(echo {format_ns(cell.echo_p99_ns)})", file=sys.stderr, flush=True)
    return cell


def render(path: Path, as_markdown: bool, png: Path | None) -> int:
    """``--render JSON``: the table (and with ``--png`` the chart) of an earlier run, nothing run."""
    try:
        cells, doc = load_cells(path)
    except ValueError as exc:
        print(f"bench.py: {exc}", file=sys.stderr)
        return 2
    print(markdown(cells) if as_markdown else table(cells))
    if doc.get("targets"):
        print()
        print(verdicts(cells)[0])
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


def main() -> int:
    if len(sys.argv) == 3 and sys.argv[1] == "--echo-server":
        echo_server(int(sys.argv[2]))
        return 0
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--stations", default=",".join(map(str, STATIONS)), help="comma-separated station counts")
    ap.add_argument("--cycles", default=",".join(CYCLES), help="comma-separated transmission cycles")
    ap.add_argument("--links", default=",".join(LINKS), help="ML2, ML3 or both")
    ap.add_argument("--duration", default="5s", help="measuring time per cell (and per baseline)")
    ap.add_argument("--workers", type=int, default=max(1, (os.cpu_count() or 1) - 1),
                    help="slave worker processes (and echo processes); default: one per CPU but one, which is left "
                         "to the master's clock")
    ap.add_argument("--json", type=Path, default=Path("bench.json"), help="write the cells here")
    ap.add_argument("--png", type=Path, default=None,
                    help="draw the chart here (default bench.png; '' = none; with --render only when given)")
    ap.add_argument("--quick", action="store_true", help="1 and 9 stations at 1 ms and 2 ms, 2 s each")
    ap.add_argument("--targets", action="store_true",
                    help="only the capacity targets' cells, each bound beside the bare echo's figure (~4 min)")
    ap.add_argument("--markdown", action="store_true", help="print the table as Markdown (docs/performance.md)")
    ap.add_argument("--render", type=Path, metavar="JSON",
                    help="run nothing: print the table (and draw --png) from an earlier run's --json file")
    args = ap.parse_args()
    if args.render is not None:
        return render(args.render, args.markdown, args.png)
    try:
        if args.quick:
            args.stations, args.cycles, args.duration = "1,9", "1ms,2ms", "2s"
        stations = [int(s) for s in args.stations.split(",")]
        cycles = [parse_duration_ns(c, default_unit="us") for c in args.cycles.split(",")]
        links = [link.strip().upper() for link in args.links.split(",")]
        duration_s = parse_duration_ns(args.duration, default_unit="s") / 1e9
        if any(link not in LINKS for link in links) or args.workers < 1 or duration_s <= 0:
            raise ValueError("links are ML2/ML3, --workers ≥ 1, --duration > 0")
    except ValueError as exc:
        print(f"bench.py: {exc}", file=sys.stderr)
        return 2
    if args.targets:
        plan = [(t.link, t.stations, parse_duration_ns(t.cycle), parse_duration_ns(t.duration) / 1e9)
                for t in TARGETS]
    else:
        plan = [(link, n, cycle, duration_s) for link in links for n in stations for cycle in cycles]
    configure_logging(level="error")
    loop = new_event_loop()
    with tempfile.TemporaryDirectory(prefix="mlink-bench-") as tmp:
        cells = [run_cell(loop, Path(tmp), link, n, cycle, args.workers, seconds)
                 for link, n, cycle, seconds in plan]
    loop.close()
    print(markdown(cells) if args.markdown else table(cells))
    doc: dict[str, Any] = {
        "host": {"node": platform.node(), "cpus": os.cpu_count(), "python": platform.python_version(),
                 "kernel": platform.release()},
        "duration_s": None if args.targets else duration_s,  # --targets: each cell has its own
        "cells": [asdict(c) for c in cells]}
    if args.targets:
        text, rows = verdicts(cells)
        print()
        print(text)
        doc["targets"] = rows
    args.json.write_text(json.dumps(doc, indent=1))
    print(f"wrote {args.json}", file=sys.stderr)
    if not args.targets:
        draw(cells, Path("bench.png") if args.png is None else args.png)
    return 0


if __name__ == "__main__":
    sys.exit(main())
