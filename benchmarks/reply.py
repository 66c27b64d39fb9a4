"""When a standalone slave answers each command: every command of the manuals' tables in a NOP stream, at the card's
shortest transmission cycle, beside a plain echo measured the same way in the same run (docs/timing.md, "When each
command is answered").

For each case (a card and a frame size at that card's shortest transmission cycle: :data:`CASES`) and each arm (real
time on, off), one run measures:

* **echo**: the floor's echo server (``python -m benchmarks.floor --serve 1 --plain``: one socket, each datagram sent
  straight back) under the same client: what the machine gives a process that does nothing;
* **slave**: ``mlink-sim slave --card … --station … --frame-size …`` (``--realtime`` in the real-time arm,
  ``--state-dir`` so that CONFIG_MOD 1 writes its EEPROM image), as a user starts one for a master of their own.

The client is a raw master in this process on the simulator's cycle timer (timerfd and adaptive spin, as
``benchmarks.floor``'s): one command per transmission cycle, a NOP in every cycle but every ``--every``-th, which
carries the next command of the card's round (:func:`round_of`: CONNECT, SYNC_SET, PRM_RD, PRM_WR, CONFIG, ALM_RD,
ALM_CLR, ID_RD, INV_CTL, INV_CTL with each sub-command the frame carries, CONFIG_MOD 1, DISCONNECT; the manuals'
Tables: SI-ET3 11/12, SI-T3 5/6, SI-T/V7 1/2 and §7.2). The WDT byte follows the watchdog convention
(docs/cards.md: the master's count advances one per cycle, the slave's count echoed); a CONFIG answered with CMDRDY
= 0 is repeated in the next cycle until CMDRDY = 1, as a master must (SI-T3 / SI-ET3 "STATUS", "CMD_STAT").

For each kind of command: how many were sent, the share **late** (answered more than one transmission cycle after
the cycle's start, when the command was sent, or not at all), RTT p50 and p99 (from the cycle's start to the read).
The target (docs/timing.md, "When each command is answered"): each command's late share within 2 points of
NOP's, and its p99 within 1.2 × NOP's.

    python -m benchmarks.reply                                   # every case, real time on and off (~8 min)
    python -m benchmarks.reply --cases si-et3:64 --duration 10s   # one case
    python -m benchmarks.reply --realtime off --json reply.json

Real time needs root (SCHED_FIFO, as ``mlink-sim up --realtime``); refused, that arm is left out and the run says so.
Ctrl-C or SIGTERM stops it (exit 130 / 143, nothing written).
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from mlink_sim.aio.run.supervisor import die_with_parent
from mlink_sim.aio.timing import realtime
from mlink_sim.aio.timing.ticker import CycleTimer
from mlink_sim.aio.transport.udp import bound_socket, close_watched
from mlink_sim.config import format_ns, parse_duration_ns
from mlink_sim.metrics import LatencyHistogram
from mlink_sim.wire import Frame, Kind, Link, M2Status, decode, encode, ml2, ml3
from mlink_sim.wire.frame import CYCLE_AT, FCS_SIZE, cycle_of, datagram_offset, patch_seal

from benchmarks.bench import Interrupted, measuring
from benchmarks.common import child_env, module_command, write_atomically

__all__ = ["CASES", "Case", "Command", "main", "round_of", "verdicts"]

_US = 1_000


@dataclass(frozen=True)
class Case:
    """A card, its frame size and the shortest transmission cycle it takes with it."""

    card: str
    size: int
    cycle_ns: int
    source: str  #: the table the cycle is from

    @property
    def name(self) -> str:
        return f"{self.card}:{self.size}"


#: The cases: each card at its shortest transmission cycle (SI-ET3 Table 28 "Minimum transmission cycle 250 μs";
#: SI-T3 and SI-T/V7 CONNECT "0.5 [ms] ≤ transmission cycle" in 17-byte mode, "1 [ms] ≤ transmission cycle" in
#: 32-byte mode, the one that carries sub-commands).
CASES: dict[str, Case] = {c.name: c for c in (
    Case("si-et3", 64, 250 * _US, "SI-ET3 Table 28"),
    Case("si-t3", 17, 500 * _US, "SI-T3 CONNECT, 17-byte"),
    Case("si-t3", 32, 1000 * _US, "SI-T3 CONNECT, 32-byte"),
    Case("si-t-v7", 17, 500 * _US, "SI-T/V7 CONNECT, 17-byte"),
    Case("si-t-v7", 32, 1000 * _US, "SI-T/V7 CONNECT, 32-byte"),
)}
_ADDRESS = {"si-et3": 0x23, "si-t3": 0x21, "si-t-v7": 0x21}
_RESULT_LATE_POINTS, _RESULT_P99 = 2.0, 1.2  #: the target: late share within 2 points of NOP's, p99 within 1.2×


@dataclass(frozen=True)
class Command:
    """One kind of command of a round: its name, its main command and sub-command bodies."""

    name: str
    body: Any
    sub: Any = None
    until_ready: bool = False  #: repeated in the next cycle while its answer says CMDRDY = 0 (CONFIG)


def _word(v: int) -> bytes:
    return v.to_bytes(2, "little").ljust(8, b"\0")


def round_of(case: Case) -> list[Command]:
    """The commands of one round, in order: CONNECT first, DISCONNECT last (the card back in phase 1), every main
    command of the card's table between them and, where the frame has a sub-command area, INV_CTL with each
    sub-command. PRM_WR writes C1-01 (n019 on the SI-T/V7) 5.0 s, so that each CONFIG has a value to apply."""
    v7 = case.card == "si-t-v7"
    reg = 0x0113 if v7 else 0x0200  # n019 / C1-01 (SI-T/V7 §7.1, SI-T3 Table 8: register 0200H)
    connect: Any
    id_rd: Any
    if case.card == "si-et3":
        ml: Any = ml3
        subs = case.size == 64
        connect, id_rd = ml3.Connect(0x30, 0x80 if subs else 0, 1, 0x20), ml3.IdRd(0x01, 0, 4)
    else:
        ml = ml2
        subs = case.size == 32
        connect, id_rd = ml2.Connect(0x21, 0x80 if subs else 0, 1), ml2.IdRd(0x00, 0, 8)
    out = [Command("CONNECT", connect), Command("SYNC_SET", ml.SyncSet()), Command("PRM_RD", ml.PrmRd(reg, 2)),
           Command("PRM_WR", ml.PrmWr(reg, 2, _word(50))), Command("CONFIG", ml.Config(0)),
           Command("ALM_RD", ml.AlmRd(0, 0)), Command("ALM_CLR", ml.AlmClr(0)), Command("ID_RD", id_rd),
           Command("INV_CTL", ml.InvCtl())]
    if subs:
        out += [Command(f"INV_CTL+{name}", ml.InvCtl(), sub) for name, sub in (
            ("NOP", ml.Nop()), ("PRM_RD", ml.PrmRd(reg, 2)), ("PRM_WR", ml.PrmWr(reg, 2, _word(60))),
            ("ALM_RD", ml.AlmRd(0, 0)), ("INV_IO", ml.InvIo(0, 0, 0x41, 0x41)))]
        if v7:  # the CONFIG sub-command (SI-T/V7 §7.2)
            out.append(Command("INV_CTL+CONFIG", ml2.InvCtl(), ml2.Config(0)))
    out += [Command("CONFIG(EEPROM)", ml.Config(1), until_ready=True), Command("DISCONNECT", ml.Disconnect())]
    return out


class _Templates:
    """Each kind's command datagram for *case* without its FCS, cycle and WDT patched in per cycle (``patch_seal``)."""

    def __init__(self, case: Case, kinds: list[Command]) -> None:
        ml = ml3 if case.card == "si-et3" else ml2
        self.link = Link.ML3 if case.card == "si-et3" else Link.ML2
        self.ml3 = self.link is Link.ML3
        frames = (ml3.COMMAND_FRAME_32, ml3.COMMAND_FRAME_64) if self.ml3 else (ml2.COMMAND_FRAME_17,
                                                                               ml2.COMMAND_FRAME_32)
        self.wdt_at = datagram_offset("wdt", *frames)
        rsp = (ml3.RESPONSE_FRAME_32, ml3.RESPONSE_FRAME_64) if self.ml3 else (ml2.RESPONSE_FRAME_17,
                                                                               ml2.RESPONSE_FRAME_32)
        self.rwdt_at = datagram_offset("rwdt", *rsp)
        address, size = _ADDRESS[case.card], case.size

        def message(body: Any, sub: Any) -> Any:
            if self.ml3:
                return ml3.M3Command(body, 0, 0, sub if sub is not None or size == 32 else ml3.Nop())
            return ml2.M2Command(body, 0, sub if sub is not None or size == 17 else ml2.Nop())

        def template(body: Any, sub: Any) -> bytes:
            dg = encode(Frame(self.link, Kind.COMMAND, address, 0, case.cycle_ns, message(body, sub)))
            return dg[:-FCS_SIZE]

        self.nop = template(ml.Nop(), None)
        self.kinds = [template(k.body, k.sub) for k in kinds]


@dataclass
class Figures:
    """One kind's figures in one measurement."""

    sent: int = 0
    late: int = 0  #: answered more than a transmission cycle after the cycle's start, or not at all
    rtt: LatencyHistogram = field(default_factory=LatencyHistogram)

    def as_dict(self) -> dict[str, Any]:
        n = self.rtt.count
        return {"sent": self.sent, "late": self.late, "late_pct": round(100 * self.late / self.sent, 2) if self.sent
                else None, "rtt_p50_ns": self.rtt.percentile(50.0) if n else None,
                "rtt_p99_ns": self.rtt.percentile(99.0) if n else None}


def _ready(answer: bytes) -> bool:
    """CMDRDY of a slave's answer (SI-ET3 CMD_STAT, SI-T3 STATUS bit 2); True where it cannot be read."""
    try:
        msg = decode(answer, kind=Kind.RESPONSE).message
    except Exception:  # noqa: BLE001 - an answer the client cannot read is judged by its time only
        return True
    if isinstance(msg, ml3.M3Response):
        return bool(msg.stat.cmdrdy)
    if isinstance(msg, ml2.M2Response):
        return bool(msg.status & M2Status.CMDRDY)
    return True


async def measure(case: Case, port: int, duration_s: float, every: int, *, slave: bool) -> dict[str, Figures]:
    """One measurement against the process listening on *port*: *duration_s* after a warm-up of a second, one command
    per transmission cycle; the figures of each kind (``"NOP"`` and the round's). *slave*: the answers are a card's
    (their RWDT echoed, a CONFIG's CMDRDY read), else an echo's."""
    loop = asyncio.get_running_loop()
    kinds = round_of(case)
    tpl = _Templates(case, kinds)
    period = case.cycle_ns
    sock = bound_socket("127.0.0.1", 0)
    target = ("127.0.0.1", port)
    figures: dict[str, Figures] = {"NOP": Figures(), **{k.name: Figures() for k in kinds}}
    pending: dict[int, tuple[str, int, bool]] = {}  # cycle -> (kind, cycle start, its CONFIG waits for CMDRDY)
    state = {"echo": 0, "next": 0, "since": 0, "repeat": -1, "counting": False}
    mono = time.monotonic_ns
    recv = sock.recv

    def read(limit: int = 64) -> None:
        for _ in range(limit):
            try:
                data = recv(4096)
            except BlockingIOError:
                return
            now = mono()
            if len(data) < 8:
                continue
            sent = pending.pop(cycle_of(data), None)
            if sent is None:
                continue
            name, t0, waits = sent
            if slave and len(data) > tpl.rwdt_at:
                state["echo"] = data[tpl.rwdt_at] & 0xF
            if waits and slave and not _ready(data):
                state["repeat"] = next(i for i, k in enumerate(kinds) if k.name == name)
            if state["counting"]:
                f = figures[name]
                f.rtt.record(now - t0)
                if now - t0 > period:
                    f.late += 1

    def on_cycle(k: int, deadline: int, now: int, skipped: int) -> None:
        read()
        horizon = now - 100_000_000  # given up: not answered in 100 ms
        for cycle in [c for c, (_, t0, _) in pending.items() if t0 < horizon]:
            name = pending.pop(cycle)[0]
            if state["counting"]:
                figures[name].late += 1
        state["since"] += 1
        index = -1
        if state["repeat"] >= 0:
            index, state["repeat"] = state["repeat"], -1
        elif state["since"] >= every:
            state["since"] = 0
            index = state["next"]
            state["next"] = (index + 1) % len(kinds)
        body = tpl.nop if index < 0 else tpl.kinds[index]
        name = "NOP" if index < 0 else kinds[index].name
        cycle = k & 0xFFFFFFFF
        dg = patch_seal(body, CYCLE_AT, cycle, tpl.wdt_at, (k & 0xF) << 4 | state["echo"])
        pending[cycle] = (name, now, index >= 0 and kinds[index].until_ready)
        if state["counting"]:
            figures[name].sent += 1
        try:
            sock.sendto(dg, target)
        except OSError:
            pass

    timer = CycleTimer(period, on_cycle, loop=loop, idle=lambda: read(1), catch_up_ns=0)
    loop.add_reader(sock.fileno(), read)
    try:
        timer.start()
        await asyncio.sleep(1.0)
        state["counting"] = True
        await asyncio.sleep(duration_s)
        state["counting"] = False
        await asyncio.sleep(0.2)  # the last answers
        for name, _, _ in pending.values():
            figures[name].late += 1
    finally:
        timer.stop()
        close_watched(loop, sock)
    return figures


def _child_setup() -> None:  # between fork and exec
    die_with_parent()
    realtime.unplace_child()  # it asks for its own real time (off this client's CPU)


def _start(cmd: list[str], stderr: Any) -> tuple[subprocess.Popen[bytes], dict[str, Any]]:
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=stderr, env=child_env(), preexec_fn=_child_setup)
    assert proc.stdout is not None
    line = proc.stdout.readline()
    try:
        return proc, json.loads(line)
    except ValueError:
        proc.terminate()
        proc.wait(5)
        raise RuntimeError(f"{' '.join(cmd[:4])} … did not start: {line!r}") from None


def _stop(proc: subprocess.Popen[bytes]) -> None:
    proc.terminate()
    try:
        proc.wait(5)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait(5)


async def measure_case(case: Case, duration_s: float, every: int, cpus: tuple[set[int], set[int]] | None,
                       tmp: Path) -> dict[str, Any]:
    """The echo, then the slave, for *case* in one arm (*cpus*: real time, the client on the first set)."""
    rt = cpus is not None
    echo_cmd = module_command("benchmarks.floor", "--serve", "1", "--plain",
                              *([f"--realtime-cpus={realtime.format_cpus(cpus[1])}"] if cpus else []))
    proc, ready = _start(echo_cmd, subprocess.DEVNULL)
    try:
        echo = await measure(case, ready["ports"][0], duration_s, every, slave=False)
    finally:
        _stop(proc)
    state = Path(tempfile.mkdtemp(prefix="eeprom-", dir=tmp))
    log = (tmp / f"slave-{case.card}-{case.size}-{'rt' if rt else 'off'}.log").open("wb")
    slave_cmd = [sys.executable, "-m", "mlink_sim", "slave", "--card", case.card, "--station",
                 f"{_ADDRESS[case.card]:02X}H", "--frame-size", str(case.size), "--listen", "127.0.0.1:0",
                 "--control", "off", "--ready-json", "--state-dir", str(state),
                 "--realtime" if rt else "--no-realtime"]
    with log:
        proc, ready = _start(slave_cmd, log)
        try:
            slave = await measure(case, ready["stations"][0]["port"], duration_s, every, slave=True)
        finally:
            _stop(proc)
    return {"case": case.name, "card": case.card, "frame_size": case.size, "cycle_ns": case.cycle_ns,
            "cycle_from": case.source, "realtime": rt,
            "echo": {k: f.as_dict() for k, f in echo.items() if f.sent},
            "slave": {k: f.as_dict() for k, f in slave.items()}}


def verdicts(result: dict[str, Any]) -> list[tuple[str, bool, str]]:
    """Each command kind of a case's slave against its NOP: ``(kind, met, why)`` by the target (module docstring)."""
    slave = result["slave"]
    nop = slave["NOP"]
    out = []
    for name, f in slave.items():
        if name == "NOP" or not f["sent"]:
            continue
        late_ok = f["late_pct"] is not None and f["late_pct"] <= (nop["late_pct"] or 0.0) + _RESULT_LATE_POINTS
        p99_ok = (f["rtt_p99_ns"] is not None and nop["rtt_p99_ns"] is not None
                  and f["rtt_p99_ns"] <= _RESULT_P99 * nop["rtt_p99_ns"])
        why = [] if late_ok else [f"late {f['late_pct']} % against NOP's {nop['late_pct']} % + 2"]
        if not p99_ok:
            why.append(f"p99 {_us(f['rtt_p99_ns'])} against 1.2 × NOP's {_us(nop['rtt_p99_ns'])}")
        out.append((name, late_ok and p99_ok, "; ".join(why)))
    return out


def _us(ns: int | None) -> str:
    return "–" if ns is None else format_ns(ns)


def table(results: list[dict[str, Any]]) -> str:
    lines = []
    for r in results:
        lines.append(f"{r['case']} at {format_ns(r['cycle_ns'])} ({r['cycle_from']}), real time "
                     f"{'on' if r['realtime'] else 'off'}")
        e = r["echo"]["NOP"]
        lines.append(f"  {'echo (NOP)':<18} {e['sent']:>7} sent  late {e['late_pct']:>6} %  p50 {_us(e['rtt_p50_ns']):>9}"
                     f"  p99 {_us(e['rtt_p99_ns']):>9}")
        verdict = {name: (ok, why) for name, ok, why in verdicts(r)}
        for name, f in r["slave"].items():
            ok, why = verdict.get(name, (True, ""))
            mark = "" if name == "NOP" else ("  met" if ok else f"  NOT MET: {why}")
            lines.append(f"  {name:<18} {f['sent']:>7} sent  late {f['late_pct']!s:>6} %  p50 "
                         f"{_us(f['rtt_p50_ns']):>9}  p99 {_us(f['rtt_p99_ns']):>9}{mark}")
    return "\n".join(lines)


def main() -> int:
    ap = argparse.ArgumentParser(prog="python -m benchmarks.reply", description=__doc__.split("\n\n")[0])
    ap.add_argument("--cases", default=",".join(CASES), help=f"comma-separated CARD:SIZE of {', '.join(CASES)}")
    ap.add_argument("--duration", default="20s", help="each measurement's time (echo and slave, each arm)")
    ap.add_argument("--every", type=int, default=20, help="a command of the round every N cycles, NOPs between")
    ap.add_argument("--realtime", choices=("both", "on", "off"), default="both",
                    help="the arms: real time on (root), off, or both (default)")
    ap.add_argument("--json", type=Path, default=None, help="write the figures here")
    args = ap.parse_args()
    try:
        cases = [CASES[name] for name in args.cases.split(",")]
        duration_s = parse_duration_ns(args.duration, default_unit="s") / 1e9
        if duration_s <= 0 or args.every < 2:
            raise ValueError("--duration above 0, --every at least 2")
    except KeyError as exc:
        print(f"reply: unknown case {exc} (known: {', '.join(CASES)})", file=sys.stderr)
        return 2
    except ValueError as exc:
        print(f"reply: {exc}", file=sys.stderr)
        return 2
    arms = {"both": (True, False), "on": (True,), "off": (False,)}[args.realtime]
    notes: list[str] = []

    def work(loop: asyncio.AbstractEventLoop, tmp: Path) -> list[dict[str, Any]]:
        out = []
        for rt in arms:
            cpus = None
            if rt:
                plan = realtime.cpu_plan()
                granted = realtime.apply(realtime.MASTER_PRIORITY, plan[0])
                if "refused" in granted:
                    realtime.withdraw()
                    notes.append(f"real time refused ({granted}): that arm is left out")
                    continue
                cpus = plan
            else:
                realtime.withdraw()
            for case in cases:
                out.append(loop.run_until_complete(measure_case(case, duration_s, args.every, cpus, tmp)))
        realtime.withdraw()
        return out

    try:
        results = measuring("reply", work)
    except Interrupted as exc:
        return exc.code
    except (RuntimeError, OSError) as exc:
        print(f"reply: {exc}", file=sys.stderr)
        return 1
    for note in notes:
        print(f"reply: {note}", file=sys.stderr)
    print(table(results))
    if args.json is not None:
        write_atomically(args.json, json.dumps({"duration_s": duration_s, "every": args.every, "cpus": os.cpu_count(),
                                                "results": results}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
