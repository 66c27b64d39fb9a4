"""The floor of a capacity cell: the simulator's I/O with no protocol work in it.

**Server** (a subprocess): ONE process serving N station sockets, as a packed slave worker does: the same
``BatchEndpoint`` per station (``mlink_sim.aio.transport.udp``, watched with ``loop.add_reader``, every waiting datagram read
in one wake-up), each datagram sent straight back to its source from the station's own socket. No card, no
decode, no 1 ms tick. Sharing one socket (``--shared``), a read holding several cycles' commands is echoed newest
cycle first, as the worker answers a backlog.

**Client** (in the calling process): the master's I/O with no core. One UDP socket, the same ``CycleTimer``
(timerfd + adaptive spin, the spin reading one answer at a time), and at each cycle: read the answers waiting,
count the ones given up (older than the answer window), send the burst of N datagrams of the stations' frame
size. RTT is measured as the master measures it: from the cycle's start (the time the core stamps its commands
with) to the time the answer is read, one stamp per read as the master's ``read_responses`` stamps it; an answer
is awaited as long as the master awaits one (its answer window, the network's ``stall_bound``), so a late answer
is in the RTT tail, not dropped from it.

Two variants, both measured by the caller in the same run: **plain** (``recvfrom``/``recv`` until the socket is
empty, one ``sendto`` per datagram) and **batched** (``mlink_sim.aio.transport.mmsg``: the client's burst in one
``sendmmsg``, its answers and each station socket's commands in one ``recvmmsg``; the echo's answers stay one
``sendto`` each, because each goes out from its own station's socket).

**With the cores' time** (``--work SERVE,ENCODE,DECODE[,SETTLE]``, off by default): the server keeps its CPU busy
*SERVE* per datagram before each echo and *SETTLE* per datagram after the read's echoes went back (a worker's cards
taking the commands they answered ahead: ``Bus.settle``; on a shared socket after one ``sched_yield``, as the
worker does), the client *ENCODE* per command after the cycle's start and before the burst, and *DECODE* per
answer after its stamp: a floor that takes as long as the simulator's cores and does none of their work, to tell
what the chain's length costs from what the simulator's I/O costs (docs/performance.md, "What bounds each figure"). ``--variant shared-batched`` measures only the floor a packed worker's network is judged against.

Missed, RTT and CPU per exchange are :func:`benchmarks.figures.exchange_figures`, the simulator's own definition:
missed = exchanges due but not answered within a cycle, over the exchanges due; CPU per exchange = (client CPU +
server CPU) / answers read, both from the kernel's accounting (``getrusage``, ``/proc/PID/stat``) over the
measuring window; wake-ups = voluntary context switches (``/proc/PID/status``) per cycle.

Run from the repository's root:

    python -m benchmarks.floor --stations 62 --cycle 1ms --duration 10s          # the four variants, one table
    python -m benchmarks.floor --variant shared-batched --work 0.92us,0.25us,1.1us   # with the cores' time
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import resource
import signal
import subprocess
import sys
import time
from collections import deque
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from mlink_sim.aio.timing import realtime
from mlink_sim.aio.transport import mmsg
from mlink_sim.aio.timing.ticker import CycleTimer
from mlink_sim.aio.transport.udp import bound_socket, close_watched, new_event_loop, open_batch_endpoint
from mlink_sim.config import format_ns, parse_duration_ns
from mlink_sim.metrics import LatencyHistogram

from benchmarks.common import child_env, module_command
from mlink_sim.aio.run.supervisor import die_with_parent
from benchmarks.figures import During, Window

__all__ = ["Floor", "Work", "floor_from", "floor_window", "host_ticks", "measure_floor", "proc_cpu_s", "proc_wakeups",
           "self_wakeups", "ticks_between"]


@dataclass(frozen=True)
class Work:
    """``--work``: the CPU time the cores take per datagram, spent busy with none of their work: *serve_ns* by the
    server before each echo (a card's ``receive``), *encode_ns* by the client per command before the burst goes
    out (the master's encode), *decode_ns* per answer after it is read and stamped (the master's decode),
    *settle_ns* by the server per datagram after the read's echoes went back (the cards' work after the send of
    answers made ahead, ``Bus.settle``). A floor with the cores' time and none of their work: what the cores' CPU
    alone costs on the machine it runs on, in the chain and after it."""

    serve_ns: int = 0
    encode_ns: int = 0
    decode_ns: int = 0
    settle_ns: int = 0

    @classmethod
    def parse(cls, text: str) -> Work:
        """``"SERVE,ENCODE,DECODE[,SETTLE]"``, each a duration (``0.9us``, ``900ns``; a bare number is in ns)."""
        parts = [p.strip() for p in text.split(",")]
        if len(parts) not in (3, 4):
            raise ValueError(f"--work takes SERVE,ENCODE,DECODE[,SETTLE] (durations per datagram), not {text!r}")
        try:
            return cls(*(parse_duration_ns(p, default_unit="ns") for p in parts))
        except ValueError as exc:
            raise ValueError(f"--work: {exc}") from None


def busy(ns: int) -> None:
    """Keep this CPU busy for *ns* (``--work``: the time the cores would take, with none of their work)."""
    end = time.monotonic_ns() + ns
    while time.monotonic_ns() < end:
        pass


def _raise(exc: OSError) -> None:
    """A socket error while the floor reads: the measurement is void, say so (mmsg.drain would count it a datagram)."""
    raise exc

HEADER = 12 + 2  # envelope + FCS (docs/wire-format.md): a datagram is HEADER + the frame size
WARM_UP_S = 0.5
_TICK = os.sysconf("SC_CLK_TCK")


@dataclass
class Floor:
    """One floor measurement (one variant of one cell)."""

    batched: bool
    stations: int
    cycle_ns: int
    duration_s: float
    cycles: int = 0
    missed: int = 0            #: cycles the clock skipped (as the master's ``missed``, same host-stall policy)
    missed_rate: float = 0.0   #: exchanges due but not answered within a cycle / exchanges due (benchmarks.figures)
    missing: int = 0           #: answers given up (not back within the answer window)
    sent: int = 0              #: datagrams sent
    due: int = 0               #: exchanges due: sent + what the skipped cycles would have sent
    on_time: int = 0           #: answers read within a cycle of their cycle's start
    exchanges: int = 0         #: answers read (within the answer window, late ones included)
    rtt_p50_ns: int = 0
    rtt_p99_ns: int = 0
    lateness_p99_ns: int = 0
    cpu_client_pct: float = 0.0
    cpu_server_pct: float = 0.0
    cpu_per_exchange_us: float = 0.0  #: (client + server CPU) / exchanges (answers read)
    spin_pct: float = 0.0             #: the client clock's spin before each deadline, % of the wall time
    cpu_per_exchange_nospin_us: float = 0.0  #: the same without the spin
    wakeups_client: float = 0.0       #: voluntary context switches per cycle
    wakeups_server: float = 0.0
    shared: bool = False              #: the server's stations share one socket (a packed worker's layout)
    steal_pct: float = 0.0            #: the hypervisor's steal over the window, % of all CPUs' time (figures.steal_share)
    turns: int = 1                    #: the windows it was measured in (figures.turns)
    missed_by_turn: list[int] = field(default_factory=list)  #: exchanges not on time in each turn, in order


def proc_cpu_s(pid: int) -> float:
    """User + system CPU seconds of process *pid* (``/proc/PID/stat``, clock ticks); 0.0 when it is gone."""
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except OSError:
        return 0.0
    return (int(fields[11]) + int(fields[12])) / _TICK  # utime, stime: fields 14 and 15 of proc(5)


def proc_wakeups(pid: int | str) -> int:
    """Voluntary context switches of *pid*'s main thread so far (a sleep on the socket or the clock)."""
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("voluntary_ctxt_switches:"):
                return int(line.split()[1])
    except OSError:
        pass
    return 0


def self_wakeups() -> int:
    return proc_wakeups("self")


def host_ticks(stat: str | None = None) -> tuple[int, ...]:
    """The machine's CPU time so far, in clock ticks, as the first line of ``/proc/stat`` gives it (user, nice,
    system, idle, iowait, irq, softirq, steal, …; *stat*: that file's text, for tests); () where it is missing."""
    try:
        text = Path("/proc/stat").read_text() if stat is None else stat
        fields = text.split("\n", 1)[0].split()
        return tuple(int(x) for x in fields[1:9]) if fields and fields[0] == "cpu" and len(fields) >= 9 else ()
    except (OSError, ValueError):
        return ()


def ticks_between(before: tuple[int, ...], after: tuple[int, ...]) -> tuple[int, ...]:
    """The ticks that passed in each field between two :func:`host_ticks`; () without both."""
    return tuple(b - a for a, b in zip(before, after)) if before and after else ()


def _self_cpu_s() -> float:
    ru = resource.getrusage(resource.RUSAGE_SELF)
    return ru.ru_utime + ru.ru_stime


# ----------------------------------------------------------------------------------------------- the server
def newest_cycle_first(batch: list[tuple[bytes, Any]]) -> list[tuple[bytes, Any]]:
    """A read holding several cycles' commands, echoed newest cycle first (bytes 0-3: the client's cycle number), each
    cycle's in arrival order: what a packed worker does with a backlog answered ahead (docs/cards.md, "A backlog's
    answers")."""
    return sorted(batch, key=lambda item: -int.from_bytes(item[0][:4], "little"))


def serve(count: int, batched: bool, shared: bool = False, work_ns: int = 0, cpus: set[int] | None = None,
          settle_ns: int = 0) -> None:
    """``--serve N``: N station sockets in this one process, each echoing; prints ``{"ports": […]}``, runs until
    SIGTERM. *shared*: one socket for the N stations, as a packed worker's (``SlaveServer(shared=True)``): each
    read's datagrams echoed in one burst (``BatchEndpoint.send_burst``), offloaded bursts read as one buffer.
    *work_ns*: the CPU is kept busy that long per datagram before the echo goes back, *settle_ns* per datagram
    after the read's echoes went (``--work``; shared, after one ``sched_yield``, as the worker's). *cpus*
    (``--realtime-cpus``): the real-time requests of a slave worker, on those CPUs (the capacity sweep's real time)."""
    loop = new_event_loop()
    if cpus:
        realtime.apply(realtime.WORKER_PRIORITY, cpus)  # granted: the sweep asked for its own real time first

    async def main() -> None:
        endpoints: list[Any] = []

        def echo_to(index: int) -> Any:
            def on_batch(batch: list[tuple[bytes, Any]]) -> None:
                if work_ns:
                    busy(work_ns * len(batch))
                sendto = endpoints[index].sendto
                for data, addr in batch:
                    sendto(data, addr)
                if settle_ns:
                    busy(settle_ns * len(batch))
            return on_batch

        if shared:
            # as the worker, before its settle: lets the reader of the answers run at once (docs/performance.md)
            pause = getattr(os, "sched_yield", None) if settle_ns else None

            def on_bus(batch: list[tuple[bytes, Any]]) -> None:
                if work_ns:
                    busy(work_ns * len(batch))
                if batch[0][0][:4] != batch[-1][0][:4]:  # more than one cycle's: newest first, as the worker's Bus
                    batch = newest_cycle_first(batch)
                endpoints[0].send_burst(batch)
                if settle_ns:
                    if pause is not None:
                        pause()
                    busy(settle_ns * len(batch))

            endpoints.append(await open_batch_endpoint(on_bus, batched=batched, burst=64 * count))
            endpoints[0].enable_gro()
            ports = [endpoints[0].local_address[1]] * count
        else:
            for i in range(count):
                endpoints.append(await open_batch_endpoint(echo_to(i), batched=batched))
            ports = [ep.local_address[1] for ep in endpoints]
        print(json.dumps({"ports": ports}), flush=True)
        stop = asyncio.Event()
        loop.add_signal_handler(signal.SIGTERM, stop.set)
        await stop.wait()
        for ep in endpoints:
            ep.close()

    loop.run_until_complete(main())


# ----------------------------------------------------------------------------------------------- the client
async def measure_floor(stations: int, size: int, cycle_ns: int, duration_s: float, batched: bool,
                        catch_up_ns: int = 100_000_000, shared: bool = False, work: Work | None = None) -> Floor:
    """The floor of one window (:func:`floor_window`), its figures read (:func:`floor_from`)."""
    window = await floor_window(stations, size, cycle_ns, duration_s, batched, catch_up_ns, shared, work)
    return floor_from(window, batched, stations, shared)


def floor_from(window: Window, batched: bool, stations: int, shared: bool) -> Floor:
    """The figures of a floor's *window* (one turn, or the sum of several: :meth:`benchmarks.figures.Window.add`)."""
    return Floor(batched, stations, window.cycle_ns, round(window.wall_s, 1), shared=shared, **window.summary(),
                 cpu_client_pct=window.pct(window.cpu_a_s), cpu_server_pct=window.pct(window.cpu_b_s),
                 wakeups_client=window.per_cycle(window.wake_a), wakeups_server=window.per_cycle(window.wake_b))


def _server_setup() -> None:  # in the server between fork and exec
    die_with_parent()  # a killed client leaves no server
    realtime.unplace_child()  # it starts as a worker does: off the client's CPU and priority (--realtime-cpus)


async def floor_window(stations: int, size: int, cycle_ns: int, duration_s: float, batched: bool,
                       catch_up_ns: int = 100_000_000, shared: bool = False, work: Work | None = None,
                       cpus: tuple[set[int], set[int]] | None = None, during: During | None = None) -> Window:
    """The floor of *stations* stations of frame size *size* at *cycle_ns*, measured for *duration_s* after a
    0.5 s warm-up; the server runs in a subprocess (``python -m benchmarks.floor --serve``). *catch_up_ns*: the clock's host-stall policy,
    as the network's (default: "absorb" up to 100 ms, the default of ``[network] stall_bound``); an answer is
    awaited as long (at least one cycle), as the master's answer window (``NetworkPlan.answer_window_ns``).
    *shared*: the stations share one socket of the server, as a packed worker's do (``mlink-sim up``); the
    batched client then reads offloaded bursts as one buffer, as the master does. *work*: each side keeps its CPU
    busy as long as the cores would take (:class:`Work`), with none of their work. *cpus*: ``(client CPUs, server
    CPUs)``: both sides ask for what ``mlink-sim up --realtime`` asks for its master and its workers (SCHED_FIFO
    at their priorities, locked memory, a wake-up latency of 0 µs, those CPUs; :mod:`benchmarks.bench`).
    *during(pids, duration_s)*, if given, is awaited instead of the window's sleep (it must last *duration_s*):
    the client's process id, then the server's (:mod:`benchmarks.lab.recovery` stops them)."""
    work = work or Work()
    args = ["--serve", str(stations), *([] if batched else ["--plain"]), *(["--shared"] if shared else []),
            f"--work-ns={work.serve_ns}", f"--settle-ns={work.settle_ns}",
            *([f"--realtime-cpus={realtime.format_cpus(cpus[1])}"] if cpus else [])]
    proc = subprocess.Popen(module_command("benchmarks.floor", *args), stdout=subprocess.PIPE, env=child_env(),
                            preexec_fn=_server_setup)
    if cpus:
        realtime.apply(realtime.MASTER_PRIORITY, cpus[0])
    loop = asyncio.get_running_loop()
    sock: Any = None
    timer: CycleTimer | None = None
    try:
        ports = json.loads(proc.stdout.readline())["ports"]  # type: ignore[union-attr]
        raw = bound_socket("127.0.0.1", 0)
        sock = mmsg.BurstSocket(raw) if batched else raw
        if shared and batched:  # as the master: its answers come as one burst
            sock.enable_gro()
        targets = [("127.0.0.1", p) for p in ports]
        pad = bytes(max(0, HEADER + size - 6))
        suffixes = [i.to_bytes(2, "little") + pad for i in range(stations)]
        rtt, lateness = LatencyHistogram(), LatencyHistogram()
        pending: dict[bytes, int] = {}
        by_cycle: deque[tuple[int, list[bytes]]] = deque()  # (cycle start, its keys), oldest first: aging
        window = max(catch_up_ns, cycle_ns)
        counts = {"missed": 0, "missing": 0, "sent": 0, "cycles": 0}
        mono = time.monotonic_ns

        decode_ns = work.decode_ns

        if batched:
            recv_burst = sock.recv_burst

            def read(limit: int = 512) -> None:  # as the master reads: one stamp per recvmmsg
                for batch in mmsg.drain(recv_burst, limit, _raise):
                    now = mono()
                    for data in batch:
                        t = pending.pop(data[:6], None)
                        if t is not None:
                            rtt.record(now - t)
                    if decode_ns:
                        busy(decode_ns * len(batch))
        else:
            recv = sock.recv

            def read(limit: int = 512) -> None:
                for _ in range(limit):
                    try:
                        data = recv(4096)
                    except BlockingIOError:
                        return
                    t = pending.pop(data[:6], None)
                    if t is not None:
                        rtt.record(mono() - t)
                    if decode_ns:
                        busy(decode_ns)

        def read_one() -> None:
            read(1)

        def on_cycle(k: int, deadline: int, now: int, skipped: int) -> None:
            counts["missed"] += skipped
            counts["cycles"] += 1
            lateness.record(now - deadline)
            read()
            horizon = now - window
            while by_cycle and by_cycle[0][0] < horizon:  # given up: older than the answer window
                for key in by_cycle.popleft()[1]:
                    if pending.pop(key, None) is not None:
                        counts["missing"] += 1
            if work.encode_ns:
                busy(work.encode_ns * stations)
            head = k.to_bytes(4, "little")
            burst = [head + s for s in suffixes]
            keys = [d[:6] for d in burst]
            for key in keys:
                pending[key] = now
            by_cycle.append((now, keys))
            if batched:
                sock.send_burst(list(zip(burst, targets)))
            else:
                sendto = sock.sendto
                for d, a in zip(burst, targets):
                    try:
                        sendto(d, a)
                    except OSError:
                        pass
            counts["sent"] += stations

        timer = CycleTimer(cycle_ns, on_cycle, loop=loop, idle=read_one, catch_up_ns=catch_up_ns)
        loop.add_reader(raw.fileno(), read)
        timer.start()
        await asyncio.sleep(WARM_UP_S)
        rtt.reset()
        lateness.reset()
        counts.update(missed=0, missing=0, sent=len(pending), cycles=0)  # in flight: as the master's reset_metrics
        wall0, cpu0, scpu0, spun0 = time.monotonic(), _self_cpu_s(), proc_cpu_s(proc.pid), timer.spun_ns
        wake0, swake0, host0 = self_wakeups(), proc_wakeups(proc.pid), host_ticks()
        await (during([os.getpid(), proc.pid], duration_s) if during is not None else asyncio.sleep(duration_s))
        host1 = host_ticks()
        wall = time.monotonic() - wall0
        cpu, scpu = _self_cpu_s() - cpu0, proc_cpu_s(proc.pid) - scpu0
        wake, swake = self_wakeups() - wake0, proc_wakeups(proc.pid) - swake0
        spun = (timer.spun_ns - spun0) / 1e9
        timer.stop()
    finally:
        if timer is not None:
            timer.stop()
        if sock is not None:
            close_watched(loop, sock)
        proc.terminate()
        proc.wait(5)
    return Window(cycle_ns, wall_s=wall, started=counts["cycles"], skipped=counts["missed"], sent=counts["sent"],
                  missing=counts["missing"], cpu_a_s=cpu, cpu_b_s=scpu, spin_s=spun, wake_a=wake, wake_b=swake,
                  ticks=ticks_between(host0, host1), rtt=rtt, lateness=lateness)


def describe(f: Floor) -> str:
    return (f"floor {'batched' if f.batched else 'plain':<7} {'shared' if f.shared else 'station':<7} "
            f"{f.stations:>3} × {format_ns(f.cycle_ns):>6}: "
            f"missed {f.missed_rate * 100:.2f}% ({f.due - f.on_time} of {f.due} exchanges; {f.missed} cycles "
            f"skipped, {f.missing} answers given up), "
            f"RTT p50 {format_ns(f.rtt_p50_ns)} p99 {format_ns(f.rtt_p99_ns)}, "
            f"lateness p99 {format_ns(f.lateness_p99_ns)}, CPU client/server {f.cpu_client_pct:.0f}/"
            f"{f.cpu_server_pct:.0f} %, {f.cpu_per_exchange_us:.1f} µs/exchange "
            f"({f.cpu_per_exchange_nospin_us:.1f} without the spin, {f.spin_pct:.0f} %), wake-ups/cycle "
            f"{f.wakeups_client:.2f}/{f.wakeups_server:.2f}, host steal {f.steal_pct:.1f} %")


def main() -> int:
    if len(sys.argv) >= 3 and sys.argv[1] == "--serve":
        work_ns = next((int(a.split("=", 1)[1]) for a in sys.argv[3:] if a.startswith("--work-ns=")), 0)
        settle_ns = next((int(a.split("=", 1)[1]) for a in sys.argv[3:] if a.startswith("--settle-ns=")), 0)
        cpus = next((realtime.parse_cpus(a.split("=", 1)[1]) for a in sys.argv[3:]
                     if a.startswith("--realtime-cpus=")), None)
        serve(int(sys.argv[2]), batched="--plain" not in sys.argv[3:], shared="--shared" in sys.argv[3:],
              work_ns=work_ns, cpus=cpus, settle_ns=settle_ns)
        return 0
    ap = argparse.ArgumentParser(prog="python -m benchmarks.floor", description=__doc__.split("\n\n")[0])
    ap.add_argument("--stations", type=int, default=62)
    ap.add_argument("--cycle", default="1ms")
    ap.add_argument("--size", type=int, default=32, help="frame size (ML-III 32/48/64, ML-II 17/32)")
    ap.add_argument("--duration", default="10s")
    ap.add_argument("--json", action="store_true", help="print the results as JSON")
    ap.add_argument("--work", default="0,0,0", metavar="SERVE,ENCODE,DECODE[,SETTLE]",
                    help="keep each side's CPU busy as long as the cores take, per datagram: the server before each "
                         "echo, the client per command before the burst and per answer after its stamp, the "
                         "server after the read's echoes went (e.g. 0.35us,0.3us,0.6us,1.7us; default none)")
    ap.add_argument("--variant", choices=("all", "shared-batched"), default="all",
                    help="all four variants (default), or only the one a packed worker's network is judged "
                         "against")
    args = ap.parse_args()
    try:
        cycle = parse_duration_ns(args.cycle, default_unit="us")
        duration = parse_duration_ns(args.duration, default_unit="s") / 1e9
        if args.stations < 1 or duration <= 0:
            raise ValueError("--stations ≥ 1, --duration > 0")
        work = Work.parse(args.work)
    except ValueError as exc:
        print(f"floor: {exc}", file=sys.stderr)
        return 2
    variants = [(True, True)] if args.variant == "shared-batched" else [(s, b) for s in (False, True)
                                                                          for b in (False, True)]
    loop = new_event_loop()
    results = [loop.run_until_complete(measure_floor(args.stations, args.size, cycle, duration, batched,
                                                     shared=shared, work=work))
               for shared, batched in variants]
    loop.close()
    if args.json:
        print(json.dumps([asdict(r) for r in results], indent=1))
    else:
        for r in results:
            print(describe(r))
    return 0


if __name__ == "__main__":
    sys.exit(main())
