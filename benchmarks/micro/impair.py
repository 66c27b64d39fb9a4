"""What the impairment layer costs per datagram (docs/faults.md, "Cost"; its target: an idle layer at most
1 µs per datagram), and the realised loss rate over real UDP on the wall clock.

Cases (each timed in batches of ``--batch`` datagrams, ``--batches`` times; per-datagram figures are a batch's
time divided by its size, the median and p99 over the batches):

* ``raw``            the master's socket as it is with no impairment in place: ``sock.sendto`` on loopback UDP.
                     The layer is not in this path at all (``Master.impair_with`` wraps the socket only while a
                     fault is in place), so an idle layer costs exactly nothing here.
* ``wrapped-other``  the same sends through an ``ImpairedSocket`` while another station is impaired (this one
                     is not): the cost of the layer for a station it leaves alone, the most a datagram pays when
                     it is not impaired itself.
* ``fabric-check``   the virtual fabric's test ``impair is not None and impair.active`` alone (no socket).
* ``other-station``  ``layer.process`` for a station that has no fault while another station has one (no socket).
* ``active``         ``layer.process`` with loss 5 %, delay 200 µs ± 50 µs, duplicate 1 %, corrupt 1 % (no
                     socket), for scale.

Then the lateness of a 300 µs delay on the wall clock beyond those 300 µs (2,000 datagrams over loopback UDP,
send to read), and ``--loss-check N``: N datagrams (default 10,000) from one loopback UDP socket to another through an
``ImpairedSocket`` with loss 5 % on the wall clock, counted at the receiver: the realised loss rate must be within
±10 % (relative) of 5 %.

``--up``: the same through a whole ``mlink-sim up`` on the real clock: one SI-T3 at 1 ms, the commands to it lost
at 5 % for 10 s (10,000 commands). The card's own count of reception failures (SI-T3 Table 22), divided by the
commands sent meanwhile, must be within ±10 % of 5 %; so must the layer's drops. The last line is JSON.

Run from the repository's root on a quiet machine: ``python -m benchmarks.micro.impair``.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import socket
import statistics
import sys
import time
from collections.abc import Callable
from typing import Any
from pathlib import Path

from mlink_sim.aio.transport.impaired import ImpairedSocket
from mlink_sim.impair import Direction, Impairment, ImpairmentLayer

__all__ = ["TARGET_NS", "bench", "delay_check", "loss_check", "main", "up_check"]

DATAGRAM = bytes([0x4D, 2, 1, 0x21]) + bytes(42) + b"\x00\x00"  # a 32-byte MECHATROLINK-II command's size
TARGET_NS = 1_000


def _pair() -> tuple[socket.socket, socket.socket]:
    a, b = (socket.socket(socket.AF_INET, socket.SOCK_DGRAM) for _ in range(2))
    for s in (a, b):
        s.bind(("127.0.0.1", 0))
        s.setblocking(False)
        s.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 22)
    return a, b


def _drain(sock: socket.socket) -> int:
    n = 0
    while True:
        try:
            sock.recv(4096)
            n += 1
        except BlockingIOError:
            return n


def timed(fn: Callable[[int], None], batch: int, batches: int, after: Callable[[], object] = lambda: None) -> list[float]:
    """Per-datagram ns of *fn(batch)*, one figure per batch."""
    out = []
    fn(batch)  # warm-up
    after()
    for _ in range(batches):
        t0 = time.perf_counter_ns()
        fn(batch)
        out.append((time.perf_counter_ns() - t0) / batch)
        after()
    return out


def summary(samples: list[float]) -> dict[str, float]:
    s = sorted(samples)
    return {"median_ns": round(statistics.median(s), 1), "p99_ns": round(s[min(len(s) - 1, int(0.99 * len(s)))], 1)}


async def bench(batch: int, batches: int) -> dict[str, dict[str, float]]:
    loop = asyncio.get_running_loop()
    a, b = _pair()
    dest = b.getsockname()
    layer = ImpairmentLayer(seed=1)
    layer.impair(Impairment(loss=0.05), 0x22, 0)  # another station: 21H's datagrams pass the layer untouched
    wrapped = ImpairedSocket(a, layer, loop, on_ready=lambda: None, on_error=lambda exc: None, on_idle=lambda: None)
    results: dict[str, dict[str, float]] = {}

    def raw(n: int) -> None:
        send = a.sendto
        for _ in range(n):
            send(DATAGRAM, dest)

    def through(n: int) -> None:
        send = wrapped.sendto
        for _ in range(n):
            send(DATAGRAM, dest)

    # raw and wrapped-idle interleaved, so that both see the same machine
    raw_s, wrapped_s = [], []
    for _ in range(batches):
        raw_s += timed(raw, batch, 1, lambda: _drain(b))
        wrapped_s += timed(through, batch, 1, lambda: _drain(b))
    results["raw"] = summary(raw_s)
    results["wrapped-other"] = summary(wrapped_s)
    results["wrapped-other-overhead"] = {"median_ns": round(statistics.median(wrapped_s) - statistics.median(raw_s),
                                                            1)}

    holder = type("Fabric", (), {"impair": ImpairmentLayer(seed=1)})()  # idle: no fault anywhere

    def check(n: int) -> None:
        for _ in range(n):
            impair = holder.impair
            if impair is not None and impair.active:
                raise AssertionError

    results["fabric-check"] = summary(timed(check, batch, batches))

    other = ImpairmentLayer(seed=1)
    other.impair(Impairment(loss=0.05), 0x22, 0)

    def process_other(n: int) -> None:
        process = other.process
        for k in range(n):
            process(DATAGRAM, Direction.TO_STATION, 0x21, k)

    results["other-station"] = summary(timed(process_other, batch, batches))

    active = ImpairmentLayer(seed=1)
    active.impair(Impairment(loss=0.05, delay=200_000, jitter=50_000, duplicate=0.01, corrupt=0.01), 0x21, 0)

    def process_active(n: int) -> None:
        process = active.process
        for k in range(n):
            process(DATAGRAM, Direction.TO_STATION, 0x21, k * 1_000_000)

    results["active"] = summary(timed(process_active, batch, batches))
    wrapped.close()
    b.close()
    return results


async def loss_check(n: int, rate: float) -> dict[str, float]:
    """*n* datagrams at *rate* loss over loopback UDP on the wall clock, paced at 10 µs; counted at the receiver."""
    loop = asyncio.get_running_loop()
    a, b = _pair()
    layer = ImpairmentLayer(seed=int(time.time()))  # any seed: the rate must hold whatever it is
    layer.impair(Impairment(loss=rate), None, time.monotonic_ns())
    wrapped = ImpairedSocket(a, layer, loop, on_ready=lambda: None, on_error=lambda exc: None, on_idle=lambda: None)
    received = 0
    for k in range(n):
        data = bytes([0x4D, 2, 1, 0x21]) + k.to_bytes(4, "little") + bytes(40)
        wrapped.sendto(data, b.getsockname())
        if k % 64 == 63:
            received += _drain(b)
            await asyncio.sleep(0)
    await asyncio.sleep(0.05)
    received += _drain(b)
    wrapped.close()
    b.close()
    realised = 1 - received / n
    return {"datagrams": n, "requested": rate, "realised": round(realised, 5), "seed": layer.seed,
            "relative_error": round(abs(realised - rate) / rate, 4),
            "ok": abs(realised - rate) <= 0.1 * rate, "injected_drops": layer.injected()[0x21]["drops"]}


UP_CONFIG = """
[network]
name = "loss-check"
transmission_cycle = "1ms"

[[station]]
address = 0x21
card = "si-t3"

[[timeline]]
at = "0s"
station = 0x21
do = "impair"
direction = "to-station"
loss = 0.05
for = "10s"
"""


def up_check(seed: int) -> dict[str, Any]:
    """``mlink-sim up`` with 5 % loss to the station for 10 s; the card's reception failures against the drops."""
    import subprocess
    import tempfile

    with tempfile.TemporaryDirectory() as tmp:
        cfg, report = Path(tmp) / "loss.toml", Path(tmp) / "report.json"
        cfg.write_text(UP_CONFIG)
        r = subprocess.run([sys.executable, "-m", "mlink_sim", "up", str(cfg), "--no-status", "--duration", "10.2s",
                            "--seed", str(seed), "--report", str(report)], capture_output=True, text=True)
        st = json.loads(report.read_text())["station"]["0x21"]
    sent, drops, failures = st["sent"], st["injected"]["drops"], st["reception_failures"]
    return {"exit": r.returncode, "sent": sent, "drops": drops, "reception_failures": failures,
            "drop_rate": round(drops / sent, 5), "observed_rate": round(failures / sent, 5),
            "ok": abs(drops / sent - 0.05) <= 0.005 and abs(failures / sent - 0.05) <= 0.005}


async def delay_check(n: int, delay_ns: int) -> dict[str, float]:
    """How late a delayed datagram arrives beyond its delay on the wall clock (the timerfd queue), *n* datagrams
    1 ms apart, each timed from its send to its reading at the other socket."""
    loop = asyncio.get_running_loop()
    a, b = _pair()
    layer = ImpairmentLayer(seed=1)
    layer.impair(Impairment(delay=delay_ns), None, time.monotonic_ns())
    wrapped = ImpairedSocket(a, layer, loop, on_ready=lambda: None, on_error=lambda exc: None, on_idle=lambda: None)
    sent: dict[int, int] = {}
    extra: list[int] = []

    def on_readable() -> None:
        now = time.monotonic_ns()
        while True:
            try:
                data = b.recv(4096)
            except BlockingIOError:
                return
            k = int.from_bytes(data[4:8], "little")
            extra.append(now - sent[k] - delay_ns)

    loop.add_reader(b.fileno(), on_readable)
    for k in range(n):
        sent[k] = time.monotonic_ns()
        wrapped.sendto(bytes([0x4D, 2, 1, 0x21]) + k.to_bytes(4, "little") + bytes(40), b.getsockname())
        await asyncio.sleep(0.001)
    await asyncio.sleep(0.05)
    loop.remove_reader(b.fileno())
    wrapped.close()
    b.close()
    return {"delay_ns": delay_ns, "received": len(extra), **{k.replace("_ns", "_late_ns"): v
                                                           for k, v in summary([float(x) for x in extra]).items()}}


def main() -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.micro.impair", description=__doc__.splitlines()[0])
    parser.add_argument("--batch", type=int, default=1000)
    parser.add_argument("--batches", type=int, default=200)
    parser.add_argument("--loss-check", type=int, default=10_000, metavar="N")
    parser.add_argument("--up", action="store_true", help="also the loss check through a whole 'mlink-sim up'")
    args = parser.parse_args()
    results = asyncio.run(bench(args.batch, args.batches))
    for name, fig in results.items():
        print(f"{name:22} " + "  ".join(f"{k} {v:8.1f}" for k, v in fig.items()))
    check = asyncio.run(loss_check(args.loss_check, 0.05))
    print(f"loss 5 % over {check['datagrams']} datagrams on the wall clock (seed {check['seed']}): realised "
          f"{check['realised'] * 100:.2f} %, {check['relative_error'] * 100:.1f} % off "
          f"({'ok' if check['ok'] else 'FAIL'}: ±10 % relative)")
    late = asyncio.run(delay_check(2000, 300_000))
    print(f"delay 300us on the wall clock: arrives {late['median_late_ns'] / 1e3:.1f} us late (median), "
          f"{late['p99_late_ns'] / 1e3:.1f} us (p99), over {late['received']} datagrams")
    up = None
    if args.up:
        up = up_check(int(time.time()) % 1000)
        print(f"up, 5 % loss to 21H for 10 s: {up['sent']} commands, {up['drops']} dropped "
              f"({up['drop_rate'] * 100:.2f} %), the card counted {up['reception_failures']} reception failures "
              f"({up['observed_rate'] * 100:.2f} %) ({'ok' if up['ok'] else 'FAIL'}: ±10 % relative)")
    # idle (no fault anywhere): the real-time master's socket is not wrapped (0 ns by construction: ``raw`` is its
    # path); the virtual fabric pays its one test
    idle = results["fabric-check"]["median_ns"]
    ok = idle <= TARGET_NS and check["ok"] and (up is None or bool(up["ok"]))
    print(json.dumps({"results": results, "loss_check": check, "delay_check": late, "up_check": up, "target_idle_ns": TARGET_NS,
                      "ok": ok}))
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
