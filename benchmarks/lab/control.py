"""What a control query costs the cycle: a network is brought up as :mod:`benchmarks.bench` brings up a cell, and
the master asks its worker ``{"op": OP}`` (``stats``, ``cpu``, ``ping``: ``mlink_sim.aio.slave.server``) every ``--every``
while every answer later than one transmission cycle is kept. A late answer read from a moment before a query was
sent to :data:`AFTER_NS` after its reply came counts as the query's (:func:`attribute`); the same number of equally
long windows half-way between the queries give the background the host makes anyway.

A worker builds its ``stats`` reply one station a millisecond, so that a query does not hold its loop for
longer than a cycle's work (docs/performance.md); this tool tells whether a
query still makes answers late, e.g. after a change to the replies or at a shorter cycle. ``mlink-sim up`` sends
one such query at the end of its run, inside its report; the capacity sweep asks its workers only before and
after each measuring window.

Run from the repository's root:

    python -m benchmarks.lab.control --stations 62 --cycles 1ms --op stats --queries 20
    python -m benchmarks.lab.control --stations 8 --cycles 250us --op stats,cpu,ping --realtime   # as root
"""

from __future__ import annotations

import argparse
import asyncio
import json
import sys
import time
from bisect import bisect_left, bisect_right
from dataclasses import asdict, dataclass
from pathlib import Path

from mlink_sim.aio.timing import realtime
from mlink_sim.aio.run.session import NetworkSession
from mlink_sim.aio.control.endpoint import query_control
from mlink_sim.config import load_config, parse_duration_ns

from benchmarks.bench import Interrupted, measuring, watching_rtt, write_config
from benchmarks.common import write_atomically

__all__ = ["AFTER_NS", "BEFORE_NS", "OPS", "Outcome", "attribute"]

OPS = ("stats", "cpu", "ping")
BEFORE_NS = 1_000_000  #: a late answer read this long before a query was sent may be the query's (its send path)
AFTER_NS = 3_000_000  #: … and this long after its reply came (the answers it held up, read after it)
SETTLE_S = 0.5  #: after bring-up, before the first query: the bring-up's own late answers are not counted


@dataclass
class Outcome:
    """One op's figures: its queries, how long each took (ns), the late answers in their windows and in as many
    windows of the same lengths between queries (the host's background)."""

    op: str
    queries: int
    reply_p50_us: float
    late_per_query: float
    background_per_window: float
    late_in_queries: int
    late_in_background: int
    answers: int


def attribute(late_reads: list[int], queries: list[tuple[int, int]], every_ns: int) -> tuple[int, int]:
    """``(late answers in the queries' windows, late answers in the background windows)``: *late_reads* are the
    read times of the late answers (sorted), *queries* each query's (sent, reply) times. A query's window is
    ``[sent − BEFORE_NS, reply + AFTER_NS]``; its background window is as long and lies half an *every_ns* later."""
    ours = background = 0
    for sent, reply in queries:
        lo, hi = sent - BEFORE_NS, reply + AFTER_NS
        ours += bisect_right(late_reads, hi) - bisect_left(late_reads, lo)
        shift = every_ns // 2
        background += bisect_right(late_reads, hi + shift) - bisect_left(late_reads, lo + shift)
    return ours, background


async def _measure(config_path: Path, op: str, queries: int, every_ns: int, rt: bool) -> Outcome:
    config = load_config(config_path)
    cycle = config.network.transmission_cycle
    session = await NetworkSession.open(config, config_path, workers=1, restart_slaves=False, realtime=rt)
    late: list[int] = []
    answers = [0]
    times: list[tuple[int, int]] = []
    try:
        not_up = await session.bring_up(timeout=20.0)
        if not_up:
            raise RuntimeError(f"{len(not_up)} station(s) not up")
        await asyncio.sleep(SETTLE_S)
        port = session.worker_list[0].control_port
        if not port:
            raise RuntimeError("the worker has no control endpoint")

        def on_rtt(ns: int) -> None:
            answers[0] += 1
            if ns > cycle:
                late.append(time.monotonic_ns())

        with watching_rtt(session, on_rtt):
            start = time.monotonic_ns()
            for k in range(queries):
                await asyncio.sleep(max(0.0, (start + (k + 1) * every_ns - time.monotonic_ns()) / 1e9))
                sent = time.monotonic_ns()
                reply = await query_control("127.0.0.1", port, op, timeout=1.0)
                if reply is None:
                    raise RuntimeError(f"the worker did not answer {op!r} within 1 s")
                times.append((sent, time.monotonic_ns()))
            await asyncio.sleep(every_ns / 1e9)  # the last query's background window
    finally:
        await session.close()
    ours, background = attribute(sorted(late), times, every_ns)
    took = sorted(r - s for s, r in times)
    return Outcome(op, len(times), round(took[len(took) // 2] / 1e3, 1), round(ours / len(times), 2),
                   round(background / len(times), 2), ours, background, answers[0])


def main() -> int:
    ap = argparse.ArgumentParser(prog="python -m benchmarks.lab.control", description=__doc__.split("\n\n")[0])
    ap.add_argument("--stations", type=int, default=62)
    ap.add_argument("--links", default="ML3", choices=("ML2", "ML3"))
    ap.add_argument("--cycles", default="1ms", help="the transmission cycle")
    ap.add_argument("--op", default="stats", help=f"comma-separated control ops: {', '.join(OPS)}")
    ap.add_argument("--queries", type=int, default=20, help="queries of each op (one network each op)")
    ap.add_argument("--every", default="500ms", help="time between two queries")
    ap.add_argument("--realtime", action="store_true", help="as mlink-sim up --realtime (root)")
    ap.add_argument("--json", type=Path, default=None, help="write the figures here")
    args = ap.parse_args()
    try:
        cycle = parse_duration_ns(args.cycles, default_unit="us")
        every = parse_duration_ns(args.every, default_unit="ms")
        ops = args.op.split(",")
        if any(op not in OPS for op in ops):
            raise ValueError(f"--op: one or more of {', '.join(OPS)}")
        if not 1 <= args.stations <= 62 or args.queries < 1 or every < 20 * cycle:
            raise ValueError("--stations 1–62, --queries ≥ 1, --every ≥ 20 cycles")
    except ValueError as exc:
        print(f"control: {exc}", file=sys.stderr)
        return 2
    if args.realtime:
        granted = realtime.apply(realtime.MASTER_PRIORITY, realtime.cpu_plan()[0])
        if "refused" in granted:
            print(f"control: --realtime: {granted}", file=sys.stderr)
            return 2

    def work(loop: asyncio.AbstractEventLoop, tmp: Path) -> list[Outcome]:
        path = tmp / "net.toml"
        write_config(path, args.links, args.stations, cycle)
        return [loop.run_until_complete(_measure(path, op, args.queries, every, args.realtime)) for op in ops]

    try:
        outcomes = measuring("control", work)
    except Interrupted as exc:
        return exc.code
    except (RuntimeError, OSError) as exc:
        print(f"control: {exc}", file=sys.stderr)
        return 1
    print(f"{args.stations} {args.links} stations at {args.cycles}, a query each {args.every}"
          + (" (--realtime)" if args.realtime else ""))
    for o in outcomes:
        print(f"  {o.op:<6} {o.queries:>3} queries, reply p50 {o.reply_p50_us:>7.1f} µs: {o.late_per_query:>7.2f} late "
              f"answers per query, {o.background_per_window:.2f} in as long a window between queries")
    if args.json is not None:
        write_atomically(args.json, json.dumps({"stations": args.stations, "link": args.links, "cycle_ns": cycle,
                                                "every_ns": every, "realtime": args.realtime,
                                                "outcomes": [asdict(o) for o in outcomes]}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
