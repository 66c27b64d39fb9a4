#!/usr/bin/env python3
"""What ``--capture`` costs per datagram (target: at most 2 µs of CPU per datagram on the quickstart).

Two measurements, both in CPU time (``time.process_time`` / ``getrusage``), best of ``--repeat``:

* **micro**: the hot path – ``sendto``/``recv`` through a :class:`TappedSocket` against the bare socket on loopback
  (the difference is what the event loop pays per datagram) – and the writer thread's work per datagram (IP/UDP
  header, pcapng block, file write) on quickstart-sized datagrams from six flows.
* **quickstart**: ``mlink-sim up configs/quickstart.toml --duration D`` with and without ``--capture``; the
  extra CPU of the whole process tree divided by the datagrams the capture holds, with and without the one-off
  import of dpkt and python-pcapng (~0.1 s per process). Noisier (the run's own CPU varies by a few percent);
  run it on a quiet machine (``flock -x /tmp/mlink-cpu.lock``).

    python scripts/bench_capture.py [--repeat 5] [--n 50000] [--duration 5] [--no-quickstart] [--json]
"""

from __future__ import annotations

import argparse
import json
import os
import re
import resource
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from mlink_sim.capture import CaptureWriter

ROOT = Path(__file__).resolve().parents[1]
TARGET_US = 2.0


def _pair() -> tuple[socket.socket, socket.socket]:
    a = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    b = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    a.bind(("127.0.0.1", 0))
    b.bind(("127.0.0.1", 0))
    b.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 22)
    return a, b


def _cpu_per_op(fn, n: int) -> float:  # noqa: ANN001
    t = time.process_time()
    fn(n)
    return (time.process_time() - t) / n * 1e6


def hot_path(n: int, repeat: int) -> dict[str, float]:
    """µs of CPU per sendto and per recv, bare and tapped (records go to a deque, as in a run)."""
    payload = b"\x4d" * 46
    a, b = _pair()
    dst = b.getsockname()
    writer = CaptureWriter(os.devnull)
    ta, tb = writer.wrap(a), writer.wrap(b)
    out: dict[str, list[float]] = {"send": [], "send_tapped": [], "recv": [], "recv_tapped": []}

    def sends(sock) -> None:  # noqa: ANN001
        def run(k: int) -> None:
            for _ in range(k):
                sock.sendto(payload, dst)
        return run

    def recvs(sock) -> None:  # noqa: ANN001
        def run(k: int) -> None:
            for _ in range(k):
                sock.recv(4096)
        return run

    chunk = min(n, 2000)  # what the receive buffer holds
    for _ in range(repeat):
        for name, send_sock, recv_sock in (("", a, b), ("_tapped", ta, tb)):
            s = r = 0.0
            for _ in range(n // chunk):
                s += _cpu_per_op(sends(send_sock), chunk) * chunk
                r += _cpu_per_op(recvs(recv_sock), chunk) * chunk
            out["send" + name].append(s / n)
            out["recv" + name].append(r / n)
        writer._queue.clear()  # noqa: SLF001 - the records of this round are not the point here
    a.close()
    b.close()
    best = {k: min(v) for k, v in out.items()}
    best["send_added"] = best["send_tapped"] - best["send"]
    best["recv_added"] = best["recv_tapped"] - best["recv"]
    return best


def writer_cost(n: int, repeat: int) -> float:
    """µs of CPU per datagram for the writer thread's work (header, block, write), quickstart-like traffic."""
    flows = [(("127.0.0.1", 40000), ("127.0.0.1", 47001 + i)) for i in range(3)]
    sizes = (46, 46, 78)
    results = []
    for _ in range(repeat):
        with tempfile.TemporaryDirectory() as tmp:
            w = CaptureWriter(Path(tmp) / "b.pcapng", flush_s=3600)
            w.start()
            for i in range(n):
                master, slave = flows[i % 3]
                data = bytes([0x4D]) * sizes[i % 3]
                if i % 2:
                    w.record(i * 1000, data, slave, master)
                else:
                    w.record(i * 1000, data, master, slave)
            t = time.process_time()
            w.close()  # the writer thread was idle: close() drains and writes everything in this thread
            results.append((time.process_time() - t) / n * 1e6)
    return min(results)


def _children_cpu() -> float:
    ru = resource.getrusage(resource.RUSAGE_CHILDREN)
    return ru.ru_utime + ru.ru_stime


def import_cost(repeat: int) -> float:
    """CPU seconds a process spends importing the capture libraries (dpkt, python-pcapng): paid once per run."""
    def cpu(code: str) -> float:
        c0 = _children_cpu()
        subprocess.run([sys.executable, "-c", code], check=True)
        return _children_cpu() - c0

    base = "import mlink_sim.aio.network, mlink_sim.cli"
    runs = [cpu(base + ", mlink_sim.capture") - cpu(base) for _ in range(max(3, repeat))]
    return sorted(runs)[len(runs) // 2]


def quickstart(duration: float, repeat: int) -> dict[str, float]:
    """CPU of ``mlink-sim up`` (whole process tree) with and without --capture; µs added per captured datagram."""
    cmd = [sys.executable, "-m", "mlink_sim", "up", str(ROOT / "configs" / "quickstart.toml"), "--duration",
           f"{duration}s", "--no-status"]
    plain, captured, datagrams, writer = [], [], [], []
    for _ in range(repeat):
        c0 = _children_cpu()
        subprocess.run(cmd, capture_output=True, text=True, check=False)
        plain.append(_children_cpu() - c0)
        with tempfile.TemporaryDirectory() as tmp:
            c0 = _children_cpu()
            proc = subprocess.run([*cmd, "--capture", str(Path(tmp) / "q.pcapng")], capture_output=True, text=True,
                                  check=False)
            captured.append(_children_cpu() - c0)
            m = re.search(r"capture \S+: (\d+) datagrams", proc.stderr)
            datagrams.append(int(m.group(1)) if m else 0)
            m = re.search(r"writer ([\d.]+) us CPU per datagram", proc.stderr)
            writer.append(float(m.group(1)) if m else float("nan"))
    n = sum(datagrams) / len(datagrams)
    extra = sorted(captured)[len(captured) // 2] - sorted(plain)[len(plain) // 2]
    once = import_cost(repeat)
    return {"cpu_s_plain_median": sorted(plain)[len(plain) // 2], "cpu_s_capture_median":
            sorted(captured)[len(captured) // 2], "datagrams": n, "import_cpu_s": once,
            "writer_thread_us_per_datagram_median": sorted(writer)[len(writer) // 2],
            "added_us_per_datagram": extra / n * 1e6 if n else float("nan"),
            "added_us_per_datagram_after_import": (extra - once) / n * 1e6 if n else float("nan")}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--n", type=int, default=50_000, help="datagrams per micro measurement")
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--duration", type=float, default=5.0, help="quickstart run length after bring-up, s")
    ap.add_argument("--no-quickstart", action="store_true", help="only the micro measurements")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    hot = hot_path(args.n, args.repeat)
    write = writer_cost(args.n, args.repeat)
    # each datagram is recorded once: on send (master's commands) or on receive (the slaves' answers)
    per_datagram = (hot["send_added"] + hot["recv_added"]) / 2 + write
    result = {"hot_path_us": hot, "writer_us_per_datagram": write, "micro_us_per_datagram": per_datagram,
              "target_us": TARGET_US}
    if not args.no_quickstart:
        result["quickstart"] = quickstart(args.duration, max(1, args.repeat // 2))
    if args.json:
        print(json.dumps(result, indent=2))
    else:
        print(f"hot path: sendto {hot['send']:.2f} -> {hot['send_tapped']:.2f} us (+{hot['send_added']:.2f}), "
              f"recv {hot['recv']:.2f} -> {hot['recv_tapped']:.2f} us (+{hot['recv_added']:.2f})")
        print(f"writer thread: {write:.2f} us per datagram")
        print(f"micro total: {per_datagram:.2f} us of CPU per datagram (target <= {TARGET_US} us)")
        if "quickstart" in result:
            q = result["quickstart"]
            print(f"quickstart: {q['cpu_s_plain_median']:.2f} s -> {q['cpu_s_capture_median']:.2f} s CPU for "
                  f"{q['datagrams']:.0f} datagrams: {q['added_us_per_datagram']:+.2f} us per datagram; without the "
                  f"one-off import of the capture libraries ({q['import_cpu_s'] * 1e3:.0f} ms): "
                  f"{q['added_us_per_datagram_after_import']:+.2f} us; the writer thread alone "
                  f"{q['writer_thread_us_per_datagram_median']:.2f} us per datagram")
    return 0 if per_datagram <= TARGET_US else 1


if __name__ == "__main__":
    sys.exit(main())
