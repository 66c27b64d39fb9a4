"""What the live page costs the network (docs/web.md, "What the page costs the network"): the same network with the
page closed and with it open, in turns, in one run.

For each network (the quickstart, and 62 ML-III stations at 1 ms) the run brings it up as ``mlink-sim up --web``
does: the slave workers (``--workers auto``), the master in this process with its control endpoint, and the web
server in a process of its own (``mlink-sim web``, as ``up --web`` starts it). Then it measures, in turns of at most
:data:`~benchmarks.figures.TURN_S` (closed, open, closed, open …, each arm ``--duration`` in all):

* **closed**: the web server runs, nobody looks (it asks the network nothing);
* **open**: a page is open, played by a client process that reads ``GET /api/events`` (the page's only traffic once
  loaded: the status ten times a second and the events; the page does not poll);
* **trace** (with ``--trace``): the page closed, the network's trace sampled as ``--trace FILE.csv`` samples it (every
  station every 10 ms, the slaves' snapshots every half second) into a file in the run's temporary directory.

The target (docs/web.md, "What the page costs the network"): in each arm no answer late or missed, and its RTT p99
within 1.1 × the closed arm's; the run prints a verdict line per arm.

Figures per arm: the answers read, the late answers (the master's count of answers that came after their answer
window), the missed exchanges (answers missing) and the RTT p99 of every answer read in the arm's turns; for the
open arm, the status messages a second the page received (ten is the server's rate).

Run from the repository's root, on a quiet machine:

    python -m benchmarks.web                                  # both networks, 30 s per arm (~3 min)
    python -m benchmarks.web --networks quickstart --duration 10s
    python -m benchmarks.web --json web.json                  # the figures as JSON too
    python -m benchmarks.web --networks ml3-62-1ms --trace    # a traced arm beside the page's two

Ctrl-C or SIGTERM ends the run (exit 130 / 143, nothing written); the web server and the page's client die with it.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import signal
import sys
import time
import urllib.request
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from mlink_sim.aio.control.endpoint import ControlServer
from mlink_sim.aio.control.events import RunLog
from mlink_sim.aio.control.network import NetworkOps
from mlink_sim.aio.present.trace import TraceSampler
from mlink_sim.aio.run.session import NetworkSession
from mlink_sim.aio.run.supervisor import die_with_parent, resolve_workers
from mlink_sim.aio.run.webproc import WebProcess
from mlink_sim.config import format_ns, load_config, parse_duration_ns
from mlink_sim.examples import example_path
from mlink_sim.metrics.histogram import LatencyHistogram
from mlink_sim.metrics.trace import TraceWriter

from benchmarks.bench import Interrupted, measuring, watching_rtt, write_config
from benchmarks.common import child_env, module_command, write_atomically
from benchmarks.figures import turns

__all__ = ["NETWORKS", "Arm", "main"]

NETWORKS = ("quickstart", "ml3-62-1ms")
SETTLE_S = 1.0  #: after bring-up, and after a page opens, before a turn counts
P99_FACTOR = 1.1  #: the target: an arm's RTT p99 within this factor of the closed arm's


@dataclass
class Arm:
    """One arm's figures, its turns added up."""

    name: str
    seconds: float = 0.0
    answers: int = 0
    late: int = 0
    missed: int = 0
    status_messages: int = 0
    page_seconds: float = 0.0  #: how long the page was open (from its first status to its close)
    rtt: LatencyHistogram = field(default_factory=LatencyHistogram)

    def figures(self) -> dict[str, Any]:
        return {"arm": self.name, "seconds": round(self.seconds, 1), "answers": self.answers, "late": self.late,
                "missed": self.missed, "rtt_p99_ns": self.rtt.percentile(99.0) if self.rtt.count else None,
                "status_per_s": round(self.status_messages / self.page_seconds, 1) if self.page_seconds else None}


def _config(tmp: Path, network: str) -> Path:
    if network == "quickstart":
        shipped = example_path("quickstart")
        assert shipped is not None
        return shipped
    path = tmp / "ml3-62-1ms.toml"
    write_config(path, "ML3", 62, 1_000_000)
    return path


def _counts(session: NetworkSession) -> tuple[int, int]:
    assert session.net is not None
    views = session.net.views().values()
    return sum(v.late for v in views), sum(v.missing for v in views)


class Page:
    """An open page: ``python -m benchmarks.web --page URL`` reading the event stream in a process of its own."""

    def __init__(self, url: str) -> None:
        self.url = url
        self.proc: asyncio.subprocess.Process | None = None

    async def open(self) -> None:
        self.proc = await asyncio.create_subprocess_exec(
            *module_command("benchmarks.web", "--page", self.url), stdout=asyncio.subprocess.PIPE,
            env=child_env(), preexec_fn=die_with_parent)
        assert self.proc.stdout is not None
        if not (await asyncio.wait_for(self.proc.stdout.readline(), 15.0)).startswith(b"open"):
            raise RuntimeError("the page's client got no status from the web server")

    async def close(self) -> tuple[int, float]:
        """Close the page; the status messages it received, and in how long."""
        assert self.proc is not None and self.proc.stdout is not None
        self.proc.send_signal(signal.SIGTERM)
        out = (await asyncio.wait_for(self.proc.stdout.read(), 10.0)).split()
        await self.proc.wait()
        return (int(out[-2]), float(out[-1])) if len(out) >= 2 else (0, 0.0)


async def _network(path: Path, duration_s: float, rt: bool, trace: Path | None = None
                   ) -> tuple[dict[str, Any], list[Arm]]:
    """The arms of one network; *trace*: where the trace arm writes its trace (None: no trace arm)."""
    config = load_config(path)
    n = len(config.station)
    session = await NetworkSession.open(config, path, workers=resolve_workers("auto", n), restart_slaves=False,
                                        realtime=rt)
    web = WebProcess(("127.0.0.1", 0))
    server: ControlServer | None = None
    arms = {"closed": Arm("closed"), "open": Arm("open"), **({"trace": Arm("trace")} if trace is not None else {})}
    try:
        masters = list(session.masters.values())  # the control endpoint and the web server as up --web opens them
        log = RunLog(masters[0].now_ns)
        for master in masters:
            log.watch(master)
        server = ControlServer(NetworkOps(session, log).handlers(), "network", token="bench")
        where = await server.start("127.0.0.1", 0)
        url = await web.start(where, "bench")
        not_up = await session.bring_up(timeout=30.0)
        if not_up:
            raise RuntimeError(f"{len(not_up)} station(s) not up")
        await asyncio.sleep(SETTLE_S)
        for turn in turns(duration_s):
            for arm in arms.values():
                page = Page(url) if arm.name == "open" else None
                if page is not None:
                    await page.open()
                    await asyncio.sleep(SETTLE_S)
                sampler = None
                if arm.name == "trace" and trace is not None:
                    sampler = TraceSampler(session, TraceWriter(trace))
                    sampler.start(asyncio.get_running_loop().time())
                    await asyncio.sleep(SETTLE_S)
                late0, missed0 = _counts(session)
                t0 = time.monotonic()

                def on_rtt(ns: int, arm: Arm = arm) -> None:
                    arm.answers += 1
                    arm.rtt.record(ns)

                with watching_rtt(session, on_rtt):
                    await asyncio.sleep(turn)
                late1, missed1 = _counts(session)
                arm.seconds += time.monotonic() - t0
                arm.late += late1 - late0
                arm.missed += missed1 - missed0
                if page is not None:
                    count, seconds = await page.close()
                    arm.status_messages += count
                    arm.page_seconds += seconds
                if sampler is not None:
                    await sampler.close()
    finally:
        await web.stop()
        if server is not None:
            server.close()
        await session.close()
    meta = {"network": config.network.name, "stations": n, "cycle_ns": config.network.transmission_cycle}
    return meta, list(arms.values())


def _page(url: str) -> int:
    """The page's client: read ``/api/events``, say ``open`` at the first status; at SIGTERM print the status
    messages after the first one and the seconds since it."""
    count, first = 0, 0.0

    def done(*_: Any) -> None:
        print(max(0, count - 1), round(time.monotonic() - first, 3) if first else 0.0, flush=True)
        sys.exit(0)

    signal.signal(signal.SIGTERM, done)
    with urllib.request.urlopen(url + "api/events", timeout=30) as stream:
        for line in stream:
            if line.startswith(b"event: status"):
                count += 1
                if count == 1:
                    first = time.monotonic()
                    print("open", flush=True)
    done()
    return 0


def _label(arm: str) -> str:
    return "traced" if arm == "trace" else f"page {arm}"


def verdicts(arms: list[Arm]) -> list[tuple[str, bool, str]]:
    """Each arm against the closed one: ``(arm, met, figures)`` by the target (module docstring)."""
    closed = next((a for a in arms if a.name == "closed"), None)
    base = closed.rtt.percentile(99.0) if closed is not None and closed.rtt.count else None
    out = []
    for arm in arms:
        p99 = arm.rtt.percentile(99.0) if arm.rtt.count else None
        clean = arm.late == 0 and arm.missed == 0
        ratio = p99 / base if p99 is not None and base else None
        ok = clean and ratio is not None and ratio <= P99_FACTOR
        why = (f"{arm.late} late, {arm.missed} missed, RTT p99 "
               + ("–" if ratio is None else f"{ratio:.2f} × the closed arm's"))
        out.append((arm.name, ok, why))
    return out


def main() -> int:
    ap = argparse.ArgumentParser(prog="python -m benchmarks.web", description=__doc__.split("\n\n")[0])
    ap.add_argument("--networks", default=",".join(NETWORKS), help=f"comma-separated: {', '.join(NETWORKS)}")
    ap.add_argument("--duration", default="30s", help="each arm's time on each network (in turns of at most 10 s)")
    ap.add_argument("--realtime", action="store_true", help="as mlink-sim up --realtime (root)")
    ap.add_argument("--trace", action="store_true", help="a third arm: the network traced as --trace samples it")
    ap.add_argument("--json", type=Path, default=None, help="write the figures here")
    ap.add_argument("--page", metavar="URL", help=argparse.SUPPRESS)  # the open page's client process
    args = ap.parse_args()
    if args.page:
        return _page(args.page)
    try:
        duration_s = parse_duration_ns(args.duration, default_unit="s") / 1e9
        networks = args.networks.split(",")
        if any(n not in NETWORKS for n in networks) or duration_s <= 0:
            raise ValueError(f"--networks: one or more of {', '.join(NETWORKS)}; --duration above 0")
    except ValueError as exc:
        print(f"web: {exc}", file=sys.stderr)
        return 2

    def work(loop: asyncio.AbstractEventLoop, tmp: Path) -> list[tuple[dict[str, Any], list[Arm]]]:
        return [loop.run_until_complete(_network(_config(tmp, n), duration_s, args.realtime,
                                                 tmp / f"{n}.trace.csv" if args.trace else None))
                for n in networks]

    try:
        results = measuring("web", work)
    except Interrupted as exc:
        return exc.code
    except (RuntimeError, OSError, TimeoutError) as exc:
        print(f"web: {exc}", file=sys.stderr)
        return 1
    print(f"the page closed and open, {args.duration} each, in turns" + (" (--realtime)" if args.realtime else ""))
    for meta, arms in results:
        print(f"{meta['network']}: {meta['stations']} stations, {format_ns(meta['cycle_ns'])} cycle")
        for arm in arms:
            f = arm.figures()
            p99 = "–" if f["rtt_p99_ns"] is None else format_ns(f["rtt_p99_ns"])
            page = f", the page got {f['status_per_s']} status/s" if arm.name == "open" else ""
            print(f"  {_label(arm.name):<11} {f['answers']:>8} answers, {f['late']:>5} late, {f['missed']:>5} "
                  f"missed, RTT p99 {p99}{page}")
        for name, ok, why in verdicts(arms):
            print(f"  {_label(name):<11} {'met' if ok else 'not met'}: {why} (target: none late or missed, p99 ≤ "
                  f"{P99_FACTOR} × the closed arm's)")
    if args.json is not None:
        write_atomically(args.json, json.dumps({"duration_s": duration_s, "realtime": args.realtime, "networks": [
            {**meta, "arms": [a.figures() for a in arms],
             "verdicts": [{"arm": n, "met": ok, "figures": why} for n, ok, why in verdicts(arms)]}
            for meta, arms in results]}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
