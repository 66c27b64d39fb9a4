#!/usr/bin/env python3
"""What ``--capture`` costs per datagram (the target of issue 20: at most 2 µs of CPU per datagram on the quickstart).

Everything is CPU time (user + system), never wall time. Three measurements, each repeated ``--repeat`` times and
quoted as median [p10, p90] over the repeats:

* **micro, hot path**: ``sendto``/``recv`` through a :class:`TappedSocket` against the bare socket on loopback, in
  alternating blocks of 1 000 (the difference is what the event loop pays per datagram);
* **micro, writer**: the writer thread's work per datagram (:meth:`CaptureWriter._drain`: queue → IP/UDP header →
  dpkt's pcapng blocks → file), on quickstart traffic (three flows, 46- and 78-byte datagrams) in batches of 750,
  what 250 ms of the quickstart queues;
* **quickstart**: ``mlink-sim up quickstart`` with and without ``--capture``, the two runs of a pair back to back
  (their order alternates), on the real clock (``--duration D``) and on the virtual clock (the whole timeline,
  deterministic: both runs do the same work). What is counted: the CPU time of the process that runs the master
  and the capture (``getrusage(RUSAGE_SELF)`` at exit: the event loop *and* the writer thread), capture on minus
  capture off, divided by the datagrams the capture holds. Both runs import the capture libraries first (dpkt,
  python-pcapng), so that one-off cost (reported apart, once per process) is not spread over the datagrams. The
  slave workers of the real-clock run are other processes: their CPU (which capture does not touch) is left out
  of the figure and shown beside it ("tree").

Run it on a quiet machine and keep it short (``flock -x /tmp/mlink-cpu.lock``; about 2 minutes with the defaults)::

    python scripts/bench_capture.py [--repeat 5] [--n 30000] [--duration 5] [--no-real] [--no-virtual] [--json]

Exit status 0 when the median over the real-clock quickstart pairs (the virtual clock's with ``--no-real``, the
micro total with both off) is at most the target.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import resource
import socket
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Sequence
from pathlib import Path

from mlink_sim.capture import CaptureWriter

ROOT = Path(__file__).resolve().parents[1]
TARGET_US = 2.0
BATCH = 750  # datagrams the quickstart queues in 250 ms (3 stations, 2 ms cycle, command + answer)

#: run mlink-sim with the capture libraries imported first, and write the process's own CPU time at exit
_WRAP = """
import atexit, os, resource, sys
import mlink_sim.capture, mlink_sim.capture.writer, mlink_sim.capture.tap
def _cpu():
    ru = resource.getrusage(resource.RUSAGE_SELF)
    with open(os.environ["MLINK_BENCH_CPU"], "w") as f:
        f.write(repr(ru.ru_utime + ru.ru_stime))
atexit.register(_cpu)
from mlink_sim.cli import main
sys.argv[0] = "mlink-sim"
main()
"""


def spread(values: Sequence[float]) -> dict[str, float]:
    """Median and 10th/90th percentiles (linear interpolation between the repeats)."""
    xs = sorted(values)
    if len(xs) == 1:
        return {"median": xs[0], "p10": xs[0], "p90": xs[0], "n": 1}
    q = statistics.quantiles(xs, n=10, method="inclusive")
    return {"median": statistics.median(xs), "p10": q[0], "p90": q[-1], "n": len(xs)}


def fmt(s: dict[str, float], unit: str = "us") -> str:
    return f"{s['median']:.2f} {unit} [p10 {s['p10']:.2f}, p90 {s['p90']:.2f}; {s['n']} runs]"


# ---------------------------------------------------------------------------------------------------- micro
def _pair() -> tuple[socket.socket, socket.socket]:
    a = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    b = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    a.bind(("127.0.0.1", 0))
    b.bind(("127.0.0.1", 0))
    b.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 22)
    return a, b


def _cpu(fn: Callable[[], object]) -> float:
    t = time.process_time()
    fn()
    return time.process_time() - t


def hot_path(n: int, repeat: int) -> dict[str, dict[str, float]]:
    """µs of CPU per sendto and per recv, bare and tapped (the records go to the writer's deque, as in a run)."""
    payload = b"\x4d" * 46
    a, b = _pair()
    dst = b.getsockname()
    writer = CaptureWriter(os.devnull)
    ta, tb = writer.wrap(a), writer.wrap(b)
    out: dict[str, list[float]] = {"send": [], "send_tapped": [], "recv": [], "recv_tapped": []}
    block = 1000  # what the receive buffer holds easily
    for _ in range(repeat):
        cpu = dict.fromkeys(out, 0.0)
        for _ in range(max(1, n // block)):
            for name, s, r in (("", a, b), ("_tapped", ta, tb)):
                send, recv = s.sendto, r.recv
                cpu["send" + name] += _cpu(lambda: [send(payload, dst) for _ in range(block)])  # noqa: B023
                cpu["recv" + name] += _cpu(lambda: [recv(4096) for _ in range(block)])  # noqa: B023
            writer._queue.clear()  # the records themselves are not the point here
        for k, v in cpu.items():
            out[k].append(v / (max(1, n // block) * block) * 1e6)
    a.close()
    b.close()
    result = {k: spread(v) for k, v in out.items()}
    result["send_added"] = spread([t - p for t, p in zip(out["send_tapped"], out["send"], strict=True)])
    result["recv_added"] = spread([t - p for t, p in zip(out["recv_tapped"], out["recv"], strict=True)])
    return result


def writer_cost(n: int, repeat: int) -> dict[str, float]:
    """µs of CPU per datagram for the writer thread's work, quickstart traffic in batches of :data:`BATCH`."""
    master = ("127.0.0.1", 40000)
    flows = [(master, ("127.0.0.1", 47001 + i)) for i in range(3)]
    sizes = (46, 46, 78)
    datagrams = [bytes([0x4D, i % 256]) * (sizes[i % 3] // 2) for i in range(BATCH)]
    results = []
    for _ in range(repeat):
        with tempfile.TemporaryDirectory() as tmp:
            w = CaptureWriter(Path(tmp) / "b.pcapng", flush_s=3600)
            w.start()  # its thread sleeps for an hour: the drains below run in this thread, timed on its clock
            cpu = 0.0
            for start in range(0, n, BATCH):
                for i in range(BATCH):
                    slave = flows[i % 3][1]
                    if i % 2:
                        w.record((start + i) * 1_000, datagrams[i], slave, master)
                    else:
                        w.record((start + i) * 1_000, datagrams[i], master, slave)
                t = time.thread_time()
                w._drain()
                cpu += time.thread_time() - t
            t = time.thread_time()
            stats = w.close()
            cpu += time.thread_time() - t
            assert stats.datagrams == (n + BATCH - 1) // BATCH * BATCH, stats
            results.append(cpu / stats.datagrams * 1e6)
    return spread(results)


# ---------------------------------------------------------------------------------------------------- quickstart
def _children_cpu() -> float:
    ru = resource.getrusage(resource.RUSAGE_CHILDREN)
    return ru.ru_utime + ru.ru_stime


def _up(args: list[str], capture: Path | None) -> tuple[float, float, int, float]:
    """One ``mlink-sim up`` run: (CPU of the master's process, CPU of the whole tree, datagrams, writer µs/dg)."""
    with tempfile.TemporaryDirectory() as tmp:
        cpu_file = Path(tmp) / "cpu"
        cmd = [sys.executable, "-c", _WRAP, "up", "quickstart", "--no-status", *args]
        if capture is not None:
            cmd += ["--capture", str(Path(tmp) / capture)]
        c0 = _children_cpu()
        proc = subprocess.run(cmd, capture_output=True, text=True, check=False,
                              env={**os.environ, "MLINK_BENCH_CPU": str(cpu_file)})
        tree = _children_cpu() - c0
        if not cpu_file.exists():
            sys.exit(f"bench_capture: {' '.join(cmd[3:])} failed (exit {proc.returncode}): {proc.stderr[-2000:]}")
        own = float(cpu_file.read_text())
    m = re.search(r"capture \S+: (\d+) datagrams", proc.stderr)
    w = re.search(r"writer ([\d.]+) us CPU per datagram", proc.stderr)
    if capture is not None and m is None:
        sys.exit(f"bench_capture: no capture summary from {' '.join(cmd[3:])}: {proc.stderr[-2000:]}")
    return own, tree, int(m.group(1)) if m else 0, float(w.group(1)) if w else float("nan")


def quickstart(args: list[str], repeat: int) -> dict[str, object]:
    """Pairs of runs, capture off and on back to back (alternating which goes first)."""
    off_cpu, on_cpu, added, added_tree, datagrams, writer = [], [], [], [], [], []
    for i in range(repeat):
        runs = {}
        for capture in ((None, Path("q.pcapng")) if i % 2 == 0 else (Path("q.pcapng"), None)):
            runs[capture is not None] = _up(args, capture)
        (own0, tree0, _, _), (own1, tree1, n, wr) = runs[False], runs[True]
        off_cpu.append(own0)
        on_cpu.append(own1)
        datagrams.append(n)
        writer.append(wr)
        added.append((own1 - own0) / n * 1e6)
        added_tree.append((tree1 - tree0) / n * 1e6)  # the tree's CPU holds the master's process too
    return {"cpu_s_off": spread(off_cpu), "cpu_s_on": spread(on_cpu), "datagrams": spread(datagrams),
            "added_us_per_datagram": spread(added), "added_us_per_datagram_tree": spread(added_tree),
            "writer_thread_us_per_datagram": spread(writer)}


def import_cost(repeat: int) -> dict[str, float]:
    """CPU seconds a process spends importing the capture libraries (dpkt, python-pcapng): once per run."""
    def cpu(code: str) -> float:
        c0 = _children_cpu()
        subprocess.run([sys.executable, "-c", code], check=True)
        return _children_cpu() - c0

    base = "import mlink_sim.aio.network, mlink_sim.cli"
    return spread([cpu(base + ", mlink_sim.capture") - cpu(base) for _ in range(max(3, repeat))])


# ---------------------------------------------------------------------------------------------------- main
def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--n", type=int, default=30_000, help="datagrams per micro measurement")
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--duration", type=float, default=5.0, help="real-clock quickstart run length after bring-up, s")
    ap.add_argument("--no-real", action="store_true", help="skip the real-clock quickstart pairs")
    ap.add_argument("--no-virtual", action="store_true", help="skip the virtual-clock quickstart pairs")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    hot = hot_path(args.n, args.repeat)
    write = writer_cost(args.n, args.repeat)
    # each datagram is recorded once: on send (the master's commands) or on receive (the slaves' answers)
    micro = (hot["send_added"]["median"] + hot["recv_added"]["median"]) / 2 + write["median"]
    result: dict[str, object] = {"target_us": TARGET_US, "hot_path_us": hot, "writer_us_per_datagram": write,
                                 "micro_us_per_datagram": micro, "import_cpu_s": import_cost(args.repeat)}
    verdict = micro
    if not args.no_virtual:
        q = result["quickstart_virtual"] = quickstart(["--clock", "virtual"], args.repeat)
        verdict = q["added_us_per_datagram"]["median"]  # type: ignore[index]
    if not args.no_real:
        q = result["quickstart_real"] = quickstart(["--duration", f"{args.duration}s"], args.repeat)
        verdict = q["added_us_per_datagram"]["median"]  # type: ignore[index]
    result["verdict_us"] = verdict
    if args.json:
        print(json.dumps(result, indent=2))
    else:
        print(f"hot path, sendto: {fmt(hot['send'])} bare, {fmt(hot['send_tapped'])} tapped, "
              f"added {fmt(hot['send_added'])}")
        print(f"hot path, recv:   {fmt(hot['recv'])} bare, {fmt(hot['recv_tapped'])} tapped, "
              f"added {fmt(hot['recv_added'])}")
        print(f"writer thread: {fmt(write)} per datagram")
        print(f"micro total (mean of send and recv added, + writer): {micro:.2f} us per datagram")
        print(f"one-off import of the capture libraries: {fmt(result['import_cpu_s'], 's')}")  # type: ignore[arg-type]
        for key, what in (("quickstart_virtual", "quickstart, virtual clock"),
                          ("quickstart_real", f"quickstart, real clock, {args.duration:g} s")):
            if key in result:
                q = result[key]  # type: ignore[assignment]
                print(f"{what}: master process CPU {fmt(q['cpu_s_off'], 's')} off, {fmt(q['cpu_s_on'], 's')} on, "
                      f"{q['datagrams']['median']:.0f} datagrams")
                print(f"  added per datagram: {fmt(q['added_us_per_datagram'])} (the process tree: "
                      f"{fmt(q['added_us_per_datagram_tree'])}); the writer thread alone "
                      f"{fmt(q['writer_thread_us_per_datagram'])}")
        print(f"verdict: {verdict:.2f} us per datagram (target <= {TARGET_US} us): "
              f"{'met' if verdict <= TARGET_US else 'NOT met'}")
    return 0 if verdict <= TARGET_US else 1


if __name__ == "__main__":
    sys.exit(main())
