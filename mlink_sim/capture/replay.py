"""``mlink-sim replay``: send a capture's master frames to a live slave on their original timing and compare its
answers with the recorded ones (a regression test for cards and for a user's recorded traffic).

:func:`plan_replay` and :func:`compare` are pure (bytes in, differences out); :func:`run_replay` moves the
datagrams over one UDP socket, paced by the capture's own timestamps.

Answers are matched to commands by station and cycle number (a response echoes the cycle of the command it
answers, docs/wire-format.md §1). Fields that change by nature are left out of the comparison
(:data:`VOLATILE`, :data:`MONITORS`, docs/capture.md): the RWDT (it follows the slave's own counter);
the reception-timing warnings (ML-II A.96, ML-III COMM_ALM 1–3), which depend on when each datagram arrives and so
on the load of the machine that replays, and which of the ML-III reception alarms 9H/AH/BH is raised; the monitors – output frequency and current, MON1…MON6 – which sample
the drive model at the instant each command arrives (after a stop the motor still coasts: a speed monitor of -33
against -31); and while the drive moves (either answer shows output frequency, a run status or ZSP clear, or did
so less than :data:`SETTLE_NS` before) the drive-state bits that change when a ramp reaches a speed (ML-II
BB_OFF, RUNX, ZSP, REV, AGREE; ML-III forward/reverse in progress, BB released, ZSP, AGREE), which follow the
drive model's clock, not the commands.
"""

from __future__ import annotations

import dataclasses
import select
import socket
import time
from typing import Any

from ..wire import WireError, decode, describe
from ..wire.frame import HEADER
from .reader import Datagram

__all__ = ["ReplayPlan", "ReplayResult", "VOLATILE", "MONITORS", "SETTLE_NS",
           "plan_replay", "compare", "answer_moving", "run_replay", "scope"]

#: left out of every comparison
VOLATILE = ("rwdt",)
#: left out of every comparison too: the monitors of INV_CTL / INV_I/O answers
MONITORS = ("output_freq", "output_current", "mon1", "mon2", "mon3", "mon4", "mon5", "mon6")
#: the drive-state bits that change when a ramp reaches a speed – ML-II STATUS BB_OFF, RUNX, ZSP, REV, AGREE
#: (SI-T3 "STATUS Field"); ML-III INVCMD_STAT forward/reverse in progress, BB released, ZSP, AGREE (SI-ET3
#: "INVCMD_STAT")
_MOVING_BITS = {"status": (1 << 3) | (1 << 5) | (1 << 6) | (1 << 7) | (1 << 9),
                "invcmd_stat": (1 << 0) | (1 << 1) | (1 << 2) | (1 << 4) | (1 << 5)}
_RUN_BITS = {"status": 1 << 5,  # RUNX
             "invcmd_stat": (1 << 0) | (1 << 1)}  # FORWARD / REVERSE in progress
_COMM_WARNING, _WARNG = 0x96, 1 << 1  # ML-II ALARM A.96 (SI-T3 Table 23), STATUS WARNG
#: ML-III COMM_ALM command / sync frame not received, sync interval error (SI-ET3 "COMM_ALM")
_RECEPTION_ALARMS = (0x9, 0xA, 0xB)
#: after the drive was last seen turning, its monitors keep settling (current, torque) for this long
SETTLE_NS = 1_000_000_000


@dataclasses.dataclass
class ReplayPlan:
    commands: list[tuple[int, int, int, bytes]]  #: (offset ns from the first command, station, cycle, datagram)
    recorded: dict[tuple[int, int], bytes]  #: (station, cycle) -> the recorded answer
    stations: list[int]
    #: station -> offset of its last datagram in the capture: a command within a cycle of it may have no answer
    #: recorded only because the capture (that station's master) ended, each master stopping on its own
    ends: dict[int, int] = dataclasses.field(default_factory=dict)


@dataclasses.dataclass
class ReplayResult:
    sent: int = 0
    compared: int = 0
    equal: int = 0
    differences: list[str] = dataclasses.field(default_factory=list)
    transport_errors: int = 0

    @property
    def ok(self) -> bool:
        return not self.differences


def _key(data: bytes) -> tuple[int, int, int] | None:
    """(kind, station, cycle) of a datagram with a whole envelope header."""
    if len(data) < HEADER.size or data[0] != 0x4D:
        return None
    _, _, kind, station, cycle, _ = HEADER.unpack_from(data)
    return kind, station, cycle


def plan_replay(datagrams: list[Datagram], stations: list[int] | None = None) -> ReplayPlan:
    """The master frames (kind 01H) of *stations* (default: every station present) and the recorded answers
    (kind 02H). Raises ValueError when there is nothing to replay."""
    commands: list[tuple[int, int, int, bytes]] = []
    recorded: dict[tuple[int, int], bytes] = {}
    present: set[int] = set()
    ends: dict[int, int] = {}
    for d in datagrams:
        key = _key(d.data)
        if key is None:
            continue
        kind, station, cycle = key
        present.add(station)
        if stations is not None and station not in stations:
            continue
        ends[station] = max(ends.get(station, d.ts_ns), d.ts_ns)
        if kind == 1:
            commands.append((d.ts_ns, station, cycle, d.data))
        elif kind == 2:
            recorded.setdefault((station, cycle), d.data)
    if not commands:
        wanted = "" if stations is None else " of station(s) " + ", ".join(f"{s:02X}H" for s in stations)
        raise ValueError(f"no master frames{wanted} in the capture (stations present: "
                         f"{', '.join(f'{s:02X}H' for s in sorted(present)) or 'none'})")
    t0 = commands[0][0]
    return ReplayPlan([(ts - t0, st, cy, data) for ts, st, cy, data in commands], recorded,
                      sorted({st for _, st, _, _ in commands}), {st: ts - t0 for st, ts in ends.items()})


def _flatten(d: dict[str, Any], prefix: str = "") -> dict[str, Any]:
    out: dict[str, Any] = {}
    for k, v in d.items():
        if isinstance(v, dict):
            out.update(_flatten(v, f"{prefix}{k}."))
        else:
            out[f"{prefix}{k}"] = v
    return out


def _moving(fields: dict[str, Any]) -> bool:
    """The answer shows the drive turning: output frequency, a run status, or ZSP clear on an INV_CTL answer."""
    if fields.get("main.output_freq"):
        return True
    for name, mask in _RUN_BITS.items():
        for key in (name, f"main.{name}"):
            if isinstance(fields.get(key), int) and fields[key] & mask:
                return True
    stat = fields.get("main.invcmd_stat")
    if isinstance(stat, int) and not stat & (1 << 4):  # INVCMD_STAT ZSP clear
        return True
    return fields.get("main.command") == "INV_CTL" and isinstance(fields.get("status"), int) and \
        not fields["status"] & (1 << 6)  # STATUS ZSP clear


def _without_timing_warning(fields: dict[str, Any]) -> dict[str, Any]:
    """*fields* with a reception-timing warning removed – ML-II ALARM 96H (first reception failure, SI-T3 Tables
    22/23) and its WARNG bit; ML-III COMM_ALM 1–3 (warnings, SI-ET3 "COMM_ALM") and its D_WAR bit – and the
    ML-III reception alarms 9H, AH, BH made one (the alarm is compared, not which of the three)."""
    out = dict(fields)
    if out.get("alarm") == _COMM_WARNING:
        out["alarm"], out["alarm_name"] = 0, None
        out["status"] = out.get("status", 0) & ~_WARNG
    if out.get("cmd_stat.comm_alm") in (1, 2, 3):
        out["cmd_stat.comm_alm"], out["cmd_stat.comm_alm_name"], out["cmd_stat.d_war"] = 0, "NORMAL", False
    elif out.get("cmd_stat.comm_alm") in _RECEPTION_ALARMS:  # which one depends on the instant a datagram was due
        out["cmd_stat.comm_alm"], out["cmd_stat.comm_alm_name"] = 9, "a reception alarm (9H-BH)"
    return out


def _view(data: bytes) -> dict[str, Any] | str:
    try:
        return _flatten(describe(decode(data)))
    except WireError as exc:
        return f"rejected ({exc})"


def answer_moving(data: bytes) -> bool:
    """*data* is an answer showing the drive turning (see :func:`compare`)."""
    view = _view(data)
    return not isinstance(view, str) and _moving(view)


def scope(strict: bool = False) -> str:
    """What :func:`compare` compares and what it leaves out (with *strict* or not), in one line for the user."""
    compared = "status, alarm, every field of each command's answer (parameters, I/O, phase)"
    left = ["RWDT", "reception-timing warnings", "the ramp's status bits while the drive moves"]
    if strict:
        return f"compared: {compared}, output frequency, monitors; not compared: {', '.join(left)}"
    return f"compared: {compared}; not compared: {', '.join(left)}, output frequency, monitors – use --strict"


def compare(recorded: bytes, live: bytes, *, moving: bool = False, strict: bool = False) -> list[str]:
    """The differences between two answers, as ``field: recorded X, live Y``. Left out: :data:`VOLATILE`,
    the reception-timing warnings, :data:`MONITORS` unless *strict*, and, when either answer shows the drive
    turning or *moving* says it turned a moment ago, the speed-derived status bits."""
    if recorded == live:
        return []
    a, b = _view(recorded), _view(live)
    if isinstance(a, str) or isinstance(b, str):
        return [] if a == b else [f"frame: recorded {a if isinstance(a, str) else 'valid'}, "
                                  f"live {b if isinstance(b, str) else 'valid'}"]
    a, b = _without_timing_warning(a), _without_timing_warning(b)
    moving = moving or _moving(a) or _moving(b)
    skip = set(VOLATILE) | (set() if strict else {f"{region}.{n}" for region in ("main", "sub") for n in MONITORS})
    out = []
    for key in sorted(set(a) | set(b)):
        if key in skip or key.endswith("_bits"):  # *_bits are names of the masked integers compared below
            continue
        va, vb = a.get(key), b.get(key)
        if moving:
            mask = _MOVING_BITS.get(key.split(".", 1)[-1])
            if mask is not None and isinstance(va, int) and isinstance(vb, int):
                va, vb = va & ~mask, vb & ~mask
        if va != vb:
            out.append(f"{key}: recorded {va!r}, live {vb!r}")
    return out


def _describe_cmd(data: bytes) -> str:
    try:
        d = describe(decode(data))
        sub = f"/{d['sub']['command']}" if "sub" in d else ""
        return f"{d['main']['command']}{sub}"
    except WireError as exc:
        return f"rejected command ({exc.reason.name})"


def run_replay(plan: ReplayPlan, targets: dict[int, tuple[str, int]], *, grace_s: float = 0.3,
               max_differences: int = 10, spin_ns: int = 200_000, speed: float | None = 1.0,
               strict: bool = False) -> ReplayResult:
    """Send every planned command to its station's slave (*targets*: station -> ``(host, port)``) at its original
    offset divided by *speed* (None: each as soon as the answer to the one before came, or *grace_s* after it
    when it does not come; a command the capture has no answer to is not waited for), collect the answers,
    compare (*strict*: the monitors too). OSError when a host does not resolve."""
    resolved: dict[int, Any] = {}
    family = socket.AF_INET
    for station, (host, port) in targets.items():
        family, _, _, _, resolved[station] = socket.getaddrinfo(host, port, type=socket.SOCK_DGRAM)[0]
    sock = socket.socket(family, socket.SOCK_DGRAM)
    sock.bind(("::" if family == socket.AF_INET6 else "0.0.0.0", 0))
    sock.setblocking(False)
    answers: dict[tuple[int, int], bytes] = {}
    result = ReplayResult()

    def drain() -> None:
        while True:
            try:
                data = sock.recv(4096)
            except BlockingIOError:
                return
            except OSError:
                result.transport_errors += 1
                return
            key = _key(data)
            if key is not None and key[0] == 2:
                answers.setdefault((key[1], key[2]), data)

    try:
        t0 = time.monotonic_ns()
        waiting: tuple[int, int] | None = None  #: speed None: the answer the next command waits for
        for offset, station, cycle, data in plan.commands:
            due = t0 + round(offset / speed) if speed is not None else time.monotonic_ns() + round(grace_s * 1e9)
            while True:
                drain()
                if speed is None and (waiting is None or waiting in answers):
                    break
                left = due - time.monotonic_ns()
                if left <= 0:
                    break
                if left > spin_ns:
                    select.select([sock], [], [], (left - spin_ns) / 1e9)
            try:
                sock.sendto(data, resolved[station])
                result.sent += 1
            except OSError:
                result.transport_errors += 1
            waiting = (station, cycle) if (station, cycle) in plan.recorded else None
        end = time.monotonic() + grace_s
        while time.monotonic() < end:
            select.select([sock], [], [], max(0.0, end - time.monotonic()))
            drain()
    finally:
        sock.close()
    last_moving: dict[int, int] = {}
    for offset, station, cycle, data in plan.commands:
        recorded = plan.recorded.get((station, cycle))
        live = answers.get((station, cycle))
        if any(x is not None and answer_moving(x) for x in (recorded, live)):
            last_moving[station] = offset
        settling = station in last_moving and offset - last_moving[station] < SETTLE_NS
        where = f"cycle {cycle} station {station:02X}H {_describe_cmd(data)}"
        if recorded is None and live is None:
            continue
        if recorded is None and plan.ends.get(station, offset) - offset < HEADER.unpack_from(data)[5]:
            continue  # the station's part of the capture ended within a cycle of this command: no answer could be in it
        if recorded is None:
            diffs = ["answered now, not answered in the capture"]
        elif live is None:
            diffs = ["no answer (the capture has one)"]
        else:
            result.compared += 1
            diffs = compare(recorded, live, moving=settling, strict=strict)
            result.equal += not diffs
        if diffs and len(result.differences) < max_differences:
            result.differences.append(f"{where}: {'; '.join(diffs)}")
        elif diffs:
            result.differences.append("…")
            break
    return result
