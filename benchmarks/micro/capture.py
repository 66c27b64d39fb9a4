"""What ``--capture`` costs per datagram (its target: at most 2 µs of CPU per datagram on the quickstart).

Everything is CPU time (user + system), never wall time. The **headline** is the sum of two parts, each measured
apart where its noise is small, quoted as the median [p10, p90] over ``--repeat`` repeats:

* **(a) the tap**, what the event loop pays per datagram: the master's own I/O calls bare and tapped on
  loopback, in alternating blocks of at most 1 000 datagrams (process CPU time): a ``BurstSocket`` (the
  uncaptured run's socket) against a ``TappedBurstSocket`` (``mlink_sim.aio.transport.tapped``), or, where the kernel
  lacks the batched calls, a plain socket against a :class:`TappedSocket`. Every kind of call the quickstart makes (``sendto`` of one
  command, ``sendmmsg`` of k, a read of k answers) is measured and weighted by how often its capture holds it
  (:func:`io_calls`);
* **(b) the writer**, what turning the queue into the file costs per datagram (thread CPU time,
  ``CaptureStats.writer_cpu_s``), **in situ**: the writer thread's own CPU in the real-clock quickstart runs below
  (median over the runs). Also shown (and used for the headline with ``--no-real``): a **replay** of the
  datagrams and notes of a quickstart capture through a :class:`CaptureWriter`, in the 250-ms batches its thread
  takes, with the sources of answers shared as the batched tap shares them (fresh tuples without the batched
  calls, as ``recvfrom`` makes them). The replay reads lower than the in-situ figure (docs/performance.md,
  "Capture", has the two and what was ruled out).

**Cross-checks**, in the same run: ``mlink-sim up quickstart`` with and without ``--capture``, the two runs of a
pair back to back (their order alternates), on the real clock (``--duration D``) and on the virtual clock (the whole
timeline: both runs do the same work, and the capture is written in place, without a thread). What is counted:
the CPU time of the process that runs the master and the capture (``getrusage(RUSAGE_SELF)`` at exit: the event
loop and the writer), capture on minus capture off, divided by the datagrams the capture holds. Both runs import
the capture libraries first, so that one-off cost (reported apart) is not spread over the datagrams. On the real
clock this figure is dominated by the spinning master's noise (docs/timing.md): it is shown, not judged. On the
virtual clock it is the whole cost (no tap: the fabric records directly), and it is judged too, from the run alone:
each run's report gives the CPU from the session's start to its report (``meta.wall.cpu_s``), without the start-up
and imports that make most of the process's CPU and most of its noise.

Run it from the repository's root on a quiet machine, and keep it short (about 1.5 minutes with the defaults)::

    python -m benchmarks.micro.capture [--repeat 7] [--n 20000] [--pairs 3]
        [--virtual-pairs 7] [--duration 4] [--no-real] [--no-virtual] [--json]

Exit status 0 when the headline (a) + (b) is at most the target, and so is the virtual-clock figure when it ran;
1 when either is over it; 3 ("void", rerun) when the headline is met but the machine's speed changed during the
virtual-clock pairs (the capture-off runs, the same deterministic work each time, differ by more than
:data:`DRIFT`), so their figure cannot be judged.
"""

from __future__ import annotations

import argparse
import json
import re
import resource
import shutil
import socket
import statistics
import subprocess
import sys
import tempfile
import time
from collections import Counter, deque
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from mlink_sim.aio.transport import mmsg
from mlink_sim.aio.transport.tapped import TappedBurstSocket
from mlink_sim.capture import CaptureWriter, TappedSocket, read_capture

__all__ = ["DRIFT", "TARGET_US", "hot_path", "main", "measure", "verdict", "writer_cost"]

TARGET_US = 2.0
#: the capture-off virtual runs do the same work: when the slowest took more than this times the CPU of the fastest,
#: the machine's speed changed during the pairs (a busy host), and their on − off differences say nothing
DRIFT = 1.25
FLUSH_NS = 250_000_000  # the writer thread's wake-up period (CaptureWriter.flush_s)
RESPONSE = 0x02  # envelope byte 2, kind: 01H command, 02H response (docs/wire-format.md §1)

#: run mlink-sim with the capture libraries imported first, and write the process's own CPU time at exit to the
#: file its first argument names (``python -c _WRAP CPU_FILE up …``)
_WRAP = """
import atexit, resource, sys
import mlink_sim.capture, mlink_sim.capture.writer, mlink_sim.capture.tap
_CPU_FILE = sys.argv.pop(1)
def _cpu():
    ru = resource.getrusage(resource.RUSAGE_SELF)
    with open(_CPU_FILE, "w") as f:
        f.write(repr(ru.ru_utime + ru.ru_stime))
atexit.register(_cpu)
from mlink_sim.cli import main
sys.argv[0] = "mlink-sim"
main()
"""

#: one datagram or note of a capture, as the writer gets it: (ts_ns, datagram or note text, src, dst)
Item = tuple[int, Any, Any, Any]


def spread(values: Sequence[float]) -> dict[str, float]:
    """Median and 10th/90th percentiles (linear interpolation between the repeats)."""
    xs = sorted(values)
    if len(xs) == 1:
        return {"median": xs[0], "p10": xs[0], "p90": xs[0], "n": 1}
    q = statistics.quantiles(xs, n=10, method="inclusive")
    return {"median": statistics.median(xs), "p10": q[0], "p90": q[-1], "n": len(xs)}


def fmt(s: dict[str, float], unit: str = "us") -> str:
    return f"{s['median']:.2f} {unit} [p10 {s['p10']:.2f}, p90 {s['p90']:.2f}; {s['n']} runs]"


# ---------------------------------------------------------------------------------------------------- (a) the tap
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


def io_calls(items: Sequence[Item]) -> Counter[tuple[str, int]]:
    """The master's I/O calls that moved the datagrams of *items*: ``("send", k)`` for a call that sent *k*
    commands (``sendto`` for one, one ``sendmmsg`` for more), ``("recv", k)`` for a read that returned *k*
    answers. The datagrams of one call share its time stamp (the tap stamps a call once); consecutive datagrams of
    the same direction and master socket with the same time (µs, the file's resolution) are taken as one call."""
    calls: Counter[tuple[str, int]] = Counter()
    key, k = None, 0
    for ts, data, src, dst in items:
        if src is None:
            continue
        answer = len(data) > 2 and data[2] == RESPONSE
        now = (ts // 1000, answer, dst if answer else src)
        if now == key:
            k += 1
            continue
        if key is not None:
            calls[("recv" if key[1] else "send", k)] += 1
        key, k = now, 1
    if key is not None:
        calls[("recv" if key[1] else "send", k)] += 1
    return calls


def _drain_plain(sock: socket.socket) -> None:
    try:
        while True:
            sock.recv(4096)
    except BlockingIOError:
        return


def hot_path(calls: Counter[tuple[str, int]], n: int, repeat: int) -> dict[str, Any]:
    """µs of CPU per I/O call of the master, bare and tapped, for every kind of call in *calls*, and what the tap
    adds per datagram with the calls weighted as *calls* counts them (the records go to a deque, as in a run;
    turning them into the file is the writer's part (b)).

    What is measured is what the master runs: with ``sendmmsg``/``recvmmsg`` supported, a :class:`~mlink_sim.aio.transport.mmsg.BurstSocket` (the uncaptured run) against a
    :class:`~mlink_sim.capture.tap.TappedBurstSocket` (``sendto`` for one command, ``send_burst`` for more,
    ``recv_burst(k)`` for the answers); without, a plain socket against a :class:`TappedSocket` (``sendto`` and
    ``recv`` per datagram). Bare and tapped alternate in blocks of at most 1 000 datagrams."""
    batched = mmsg.supported()
    payload = b"\x4d" * 46
    a, b = _pair()
    a.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 22)  # a block of answers waits whole: none dropped
    a.setblocking(False)
    b.setblocking(False)
    station, master = b.getsockname(), a.getsockname()
    queue: deque[Any] = deque()
    sockets = {"bare": mmsg.BurstSocket(a) if batched else a,
               "tapped": TappedBurstSocket(a, queue.append) if batched else TappedSocket(a, queue.append)}

    def sender(s: Any, k: int, per: int) -> Callable[[], object]:
        if k == 1 or not batched:
            send, count = s.sendto, per * k
            return lambda: [send(payload, station) for _ in range(count)]
        burst, items = s.send_burst, [(payload, station)] * k
        return lambda: [burst(items) for _ in range(per)]

    def reader(s: Any, k: int, per: int) -> Callable[[], object]:
        if not batched:
            recv, count = s.recv, per * k
            return lambda: [recv(4096) for _ in range(count)]
        burst = s.recv_burst
        return lambda: [burst(k) for _ in range(per)]

    out: dict[str, Any] = {"batched": batched, "calls": {f"{kind} {k}": c for (kind, k), c in sorted(calls.items())}}
    total = sum(k * c for (_, k), c in calls.items())
    per_repeat = [0.0] * repeat
    for (kind, k), count in sorted(calls.items()):
        per = max(1, 1000 // k)  # calls per block: at most 1 000 datagrams wait in a receive buffer
        blocks = max(1, n // (per * k))
        cpu: dict[str, list[float]] = {"bare": [], "tapped": []}
        for r in range(repeat):
            spent = dict.fromkeys(cpu, 0.0)
            for _ in range(blocks):
                for name, s in sockets.items():
                    if kind == "send":
                        spent[name] += _cpu(sender(s, k, per))
                        _drain_plain(b)
                    else:
                        for _ in range(per * k):
                            b.sendto(payload, master)
                        spent[name] += _cpu(reader(s, k, per))
                        if name == "tapped" and len(queue) != per * k:  # every read found its k answers
                            sys.exit(f"capture: {len(queue)} answers read of {per * k} sent (dropped?)")
                queue.clear()
            for name in cpu:
                cpu[name].append(spent[name] / (blocks * per) * 1e6)
            per_repeat[r] += count * (cpu["tapped"][-1] - cpu["bare"][-1]) / total
        added = [t - p for t, p in zip(cpu["tapped"], cpu["bare"], strict=True)]
        out[f"{kind} {k}"] = {"bare": spread(cpu["bare"]), "tapped": spread(cpu["tapped"]), "added": spread(added),
                              "added_per_datagram": spread([x / k for x in added])}
    a.close()
    b.close()
    out["per_datagram"] = spread(per_repeat)
    return out


# ---------------------------------------------------------------------------------------------------- (b) the writer
def traffic_of(path: Path) -> list[Item]:
    """The datagrams and notes of a capture, in order, as the hot path queued them: ``(ts_ns, datagram, src,
    dst)`` and, after a datagram, its comments as notes ``(ts_ns, text, None, None)``. The master's own addresses
    are shared objects (the tap's ``local``, the master's endpoint table), and so is the source of an answer read
    with ``recvmmsg`` (the tap keeps one tuple per source); without the batched calls it is a fresh tuple and string
    (``recvfrom`` makes new ones for every datagram)."""
    shared: dict[Any, Any] = {}
    fresh = not mmsg.supported()
    items: list[Item] = []
    for d in read_capture(path).datagrams:
        if fresh and len(d.data) > 2 and d.data[2] == RESPONSE:
            src, dst = (d.src[0].encode().decode(), d.src[1]), shared.setdefault(d.dst, d.dst)
        else:
            src, dst = shared.setdefault(d.src, d.src), shared.setdefault(d.dst, d.dst)
        items.append((d.ts_ns, d.data, src, dst))
        items.extend((d.ts_ns, c, None, None) for c in d.comments)
    return items


def synthetic_traffic(n: int) -> list[Item]:
    """Quickstart-like traffic when no capture is at hand (``--no-real --no-virtual``): three stations on a 2-ms
    cycle, 46- and 78-byte datagrams."""
    master = ("127.0.0.1", 40000)
    slaves = [("127.0.0.1", 47001 + i) for i in range(3)]
    sizes = (46, 46, 78)
    items: list[Item] = []
    for i in range(n):
        k = i // 2 % 3
        data = bytes([0x4D, 0x02, RESPONSE if i % 2 else 0x01]) + bytes(sizes[k] - 3)
        src, dst = ((slaves[k][0].encode().decode(), slaves[k][1]), master) if i % 2 else (master, slaves[k])
        items.append((i * 2_000_000 // 6, data, src, dst))
    return items


def directions(items: Sequence[Item]) -> tuple[int, int]:
    """(commands the master sent, answers it received) in *items*."""
    answers = sum(1 for _, data, src, _ in items if src is not None and len(data) > 2 and data[2] == RESPONSE)
    return sum(1 for it in items if it[2] is not None) - answers, answers


def writer_cost(items: Sequence[Item], repeat: int) -> dict[str, float]:
    """µs of the writer's CPU per datagram for *items*, queued in the batches of :data:`FLUSH_NS` its thread takes."""
    batches: list[list[Item]] = []
    start = None
    for item in items:
        if start is None or item[0] - start >= FLUSH_NS:
            batches.append([])
            start = item[0]
        batches[-1].append(item)
    results = []
    for _ in range(repeat):
        with tempfile.TemporaryDirectory() as tmp:
            w = CaptureWriter(Path(tmp) / "b.pcapng", epoch_offset_ns=0).start(background=False)
            for batch in batches:
                for ts, data, src, dst in batch:
                    if src is None:
                        w.note(ts, data)
                    else:
                        w.record(ts, data, src, dst)
                w.flush()  # what the thread does when it wakes; times itself (thread CPU) into writer_cpu_s
            stats = w.close()
            results.append(stats.writer_cpu_s / stats.datagrams * 1e6)
    return spread(results)


# ---------------------------------------------------------------------------------------------------- cross-checks
def _children_cpu() -> float:
    ru = resource.getrusage(resource.RUSAGE_CHILDREN)
    return ru.ru_utime + ru.ru_stime


def _up(args: list[str], capture: bool, keep: Path | None) -> tuple[float, int, float, float | None]:
    """One ``mlink-sim up`` run: (CPU of the master's process, datagrams, writer µs/dg, CPU of the virtual run
    alone or None); its capture is copied to *keep* when given. The virtual run's own CPU is its report's
    ``meta.wall.cpu_s`` (from the session's start to its report: no start-up, no imports)."""
    virtual = "virtual" in args
    with tempfile.TemporaryDirectory() as tmp:
        cpu_file, report = Path(tmp) / "cpu", Path(tmp) / "report.json"
        cmd = [sys.executable, "-c", _WRAP, str(cpu_file), "up", "quickstart", "--no-status", *args]
        if capture:
            cmd += ["--capture", str(Path(tmp) / "q.pcapng")]
        if virtual:
            cmd += ["--report", str(report)]
        proc = subprocess.run(cmd, capture_output=True, text=True, check=False)
        if not cpu_file.exists() or (virtual and not report.exists()):
            sys.exit(f"capture: {' '.join(cmd[4:])} failed (exit {proc.returncode}): {proc.stderr[-2000:]}")
        own = float(cpu_file.read_text())
        run = float(json.loads(report.read_text())["meta"]["wall"]["cpu_s"]) if virtual else None
        if capture and keep is not None:
            shutil.copy(Path(tmp) / "q.pcapng", keep)
    m = re.search(r"capture \S+: (\d+) datagrams", proc.stderr)
    w = re.search(r"writer ([\d.]+) us CPU per datagram", proc.stderr)
    if capture and m is None:
        sys.exit(f"capture: no capture summary from {' '.join(cmd[4:])}: {proc.stderr[-2000:]}")
    return own, int(m.group(1)) if m else 0, float(w.group(1)) if w else float("nan"), run


def quickstart(args: list[str], pairs: int, keep: Path) -> dict[str, Any]:
    """Pairs of runs, capture off and on back to back (alternating which goes first), after one warm-up run; the
    first capture to *keep*. On the virtual clock also the run's own CPU, on − off (``run_*``): what is judged,
    and the drift of the capture-off runs' (the same deterministic work each time)."""
    off_cpu, on_cpu, added, datagrams, writer, run_off, run_added = [], [], [], [], [], [], []
    _up(args, True, None)  # a warm-up run, not counted: the first run of a process reads its files from disk
    for i in range(pairs):
        runs = {}
        for capture in ((False, True) if i % 2 == 0 else (True, False)):
            runs[capture] = _up(args, capture, keep if i == 0 else None)
        (own0, _, _, run0), (own1, n, wr, run1) = runs[False], runs[True]
        off_cpu.append(own0)
        on_cpu.append(own1)
        datagrams.append(n)
        writer.append(wr)
        added.append((own1 - own0) / n * 1e6)
        if run0 is not None and run1 is not None:
            run_off.append(run0)
            run_added.append((run1 - run0) / n * 1e6)
    result: dict[str, Any] = {"cpu_s_off": spread(off_cpu), "cpu_s_on": spread(on_cpu), "datagrams": spread(datagrams),
              "added_us_per_datagram": spread(added), "writer_us_per_datagram": spread(writer)}
    if run_off:
        result.update({"run_cpu_s_off": spread(run_off), "run_added_us_per_datagram": spread(run_added),
                       "drift": max(run_off) / min(run_off)})
    return result


def import_cost(repeat: int) -> dict[str, float]:
    """CPU seconds a process spends importing the capture libraries (dpkt, python-pcapng): once per run."""
    def cpu(code: str) -> float:
        c0 = _children_cpu()
        subprocess.run([sys.executable, "-c", code], check=True)
        return _children_cpu() - c0

    base = "import mlink_sim.aio.run.network, mlink_sim.cli"
    return spread([cpu(base + ", mlink_sim.capture") - cpu(base) for _ in range(max(3, repeat))])


# ---------------------------------------------------------------------------------------------------- main
def measure(args: argparse.Namespace) -> dict[str, Any]:
    result: dict[str, Any] = {"target_us": TARGET_US, "date_utc": time.strftime("%Y-%m-%d %H:%M", time.gmtime())}
    with tempfile.TemporaryDirectory() as tmp:
        source = "synthetic"
        real_cap, virtual_cap = Path(tmp) / "real.pcapng", Path(tmp) / "virtual.pcapng"
        if not args.no_real:
            result["quickstart_real"] = quickstart(["--duration", f"{args.duration}s"], args.pairs, real_cap)
        if not args.no_virtual:
            result["quickstart_virtual"] = quickstart(["--clock", "virtual"], args.virtual_pairs, virtual_cap)
        if real_cap.exists():
            items, source = traffic_of(real_cap), "real-clock quickstart capture"
        elif virtual_cap.exists():
            items, source = traffic_of(virtual_cap), "virtual-clock quickstart capture"
        else:
            items = synthetic_traffic(args.n)
    sent, received = directions(items)
    hot = hot_path(io_calls(items), args.n, args.repeat)
    write = writer_cost(items, args.repeat)
    tap = hot["per_datagram"]["median"]
    result.update({
        "traffic": {"source": source, "datagrams": sent + received, "sent": sent, "received": received,
                    "notes": sum(1 for it in items if it[2] is None)},
        "tap_us": hot, "tap_us_per_datagram": tap, "writer_us_per_datagram": write,
        "import_cpu_s": import_cost(args.repeat)})
    # (b) in situ when the real-clock runs were made (the writer thread's own CPU on the quickstart's traffic, as
    # it runs beside the master); else the replay of the traffic through a writer
    if "quickstart_real" in result:
        result["writer_headline"] = ("in situ", result["quickstart_real"]["writer_us_per_datagram"]["median"])
    else:
        result["writer_headline"] = ("replay", write["median"])
    result["headline_us"] = tap + result["writer_headline"][1]
    result["verdict"] = verdict(result["headline_us"], result.get("quickstart_virtual"))
    result["met"] = result["verdict"] == "met"
    return result


def verdict(headline_us: float, virtual: dict[str, Any] | None) -> str:
    """"met", "not met" or "void": the headline against the target, and the virtual clock's run-alone figure when
    it ran, unless its capture-off runs drifted more than :data:`DRIFT` (then "void" where the headline is met)."""
    if headline_us > TARGET_US:
        return "not met"
    if virtual is None:
        return "met"
    if virtual["drift"] > DRIFT:  # the same deterministic timeline took more CPU in one run than in another
        return "void"
    return "met" if virtual["run_added_us_per_datagram"]["median"] <= TARGET_US else "not met"


def report(r: dict[str, Any], duration: float) -> None:
    hot, t = r["tap_us"], r["traffic"]
    print(f"({r['date_utc']} UTC) traffic: {t['source']}, {t['datagrams']} datagrams ({t['sent']} sent, "
          f"{t['received']} received), {t['notes']} notes")
    print(f"(a) the master's I/O calls, {'batched (sendmmsg/recvmmsg)' if hot['batched'] else 'per datagram'}, "
          f"µs per call; calls in the traffic: {hot['calls']}")
    for call in hot["calls"]:
        c = hot[call]
        print(f"    {call}: {fmt(c['bare'])} bare, {fmt(c['tapped'])} tapped: added {fmt(c['added'])}")
    print(f"(a) tap per datagram (calls weighted as in the traffic): {fmt(hot['per_datagram'])}")
    print(f"(b) writer per datagram, replay of the traffic: {fmt(r['writer_us_per_datagram'])}")
    if "quickstart_real" in r:
        print(f"(b) writer per datagram, in situ (the writer thread of the real-clock runs): "
              f"{fmt(r['quickstart_real']['writer_us_per_datagram'])}")
    print(f"headline (a) + (b, {r['writer_headline'][0]}): {r['headline_us']:.2f} us per datagram "
          f"(target <= {TARGET_US} us)")
    print(f"one-off import of the capture libraries: {fmt(r['import_cpu_s'], 's')}")
    for key, what in (("quickstart_real", f"cross-check, real clock, {duration:g} s (noise of a spinning master)"),
                      ("quickstart_virtual", "virtual clock, whole timeline")):
        if key in r:
            q = r[key]
            print(f"{what}: master process CPU {fmt(q['cpu_s_off'], 's')} off, {fmt(q['cpu_s_on'], 's')} on, "
                  f"{q['datagrams']['median']:.0f} datagrams")
            print(f"  added per datagram: {fmt(q['added_us_per_datagram'])}; the writer alone "
                  f"{fmt(q['writer_us_per_datagram'])}")
            if "run_added_us_per_datagram" in q:
                print(f"  the virtual run alone (its report's meta.wall.cpu_s, no start-up): CPU "
                      f"{fmt(q['run_cpu_s_off'], 's')} off; added per datagram "
                      f"{fmt(q['run_added_us_per_datagram'])} (judged)")
    if "quickstart_virtual" in r and r["quickstart_virtual"]["drift"] > DRIFT:
        print(f"the machine's speed changed during the run: the capture-off virtual runs, the same work each time, "
              f"took up to {r['quickstart_virtual']['drift']:.2f}x the CPU of the fastest (more than {DRIFT}x): "
              f"the virtual-clock figure is not judged")
    print(f"verdict: {r['verdict'].replace('not met', 'NOT met')}")


def main() -> int:
    ap = argparse.ArgumentParser(prog="python -m benchmarks.micro.capture", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--n", type=int, default=20_000, help="datagrams per tap measurement")
    ap.add_argument("--repeat", type=int, default=7, help="repeats of (a) and (b)")
    ap.add_argument("--pairs", type=int, default=3, help="quickstart pairs (capture off/on) per clock")
    ap.add_argument("--virtual-pairs", type=int, default=7,
                    help="virtual-clock quickstart pairs (each run about 1 s; its CPU is noisier than its length)")
    ap.add_argument("--duration", type=float, default=4.0, help="real-clock quickstart run length after bring-up, s")
    ap.add_argument("--no-real", action="store_true", help="skip the real-clock quickstart pairs")
    ap.add_argument("--no-virtual", action="store_true", help="skip the virtual-clock quickstart pairs")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    result = measure(args)
    if args.json:
        print(json.dumps(result, indent=2))
    else:
        report(result, args.duration)
    return {"met": 0, "not met": 1}.get(result["verdict"], 3)


if __name__ == "__main__":
    sys.exit(main())
