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
import re
import select
import socket
import time
from typing import Any

from ..wire import WireError, decode, describe
from ..wire.codes import InvCmdStat, M2Status, M2SubStatus
from ..wire.frame import HEADER
from .reader import Datagram

__all__ = ["ReplayPlan", "ReplayResult", "Pacing", "VOLATILE", "MONITORS", "SETTLE_NS", "HINTS",
           "plan_replay", "compare", "answer_moving", "run_replay", "scope", "hints_for"]

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
#: the status fields whose differing bits a difference names (SI-T3 "STATUS Field", "SUBSTATUS Field"; SI-ET3
#: "INVCMD_STAT")
_STATUS_FLAGS: dict[str, Any] = {"status": M2Status, "substatus": M2SubStatus, "main.invcmd_stat": InvCmdStat}
#: a status bit whose difference a setting of the slave usually explains -> what to check
HINTS = {
    "REMOTE": "REMOTE differs: it is set while the drive takes its run command from the network, b1-02 = 3 on the "
              "A1000 (with b1-01 = 3 for the reference; SI-T3 Table 4, SI-ET3 Table 7), n003 = 3 on the VS-606V7 "
              "(n004 = 9 for the reference; SI-T/V7 section 6): was the slave started with the capture's settings "
              "(mlink-sim slave … --param b1-01=3 --param b1-02=3)?",
    "OPE": "OPE differs: one of the two drives has a parameter setting error (oPE) the other has not: the slave's "
           "parameters (--param, its --state-dir) are not the capture's",
}


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
    received: int = 0  #: answers that came (every one, compared or not)
    compared: int = 0
    equal: int = 0
    differences: list[str] = dataclasses.field(default_factory=list)
    transport_errors: int = 0
    loops: int = 0  #: passes over the capture done

    @property
    def ok(self) -> bool:
        return not self.differences

    @property
    def hints(self) -> list[str]:
        """What to check for the differences found (:func:`hints_for`)."""
        return hints_for(self.differences)


@dataclasses.dataclass(frozen=True)
class Pacing:
    """When each frame goes: at its offset in the capture divided by *speed* (None: as soon as the answer to the
    one before came, or *grace_s* after it), and never less than *gap_ns* after the frame before (can.player's
    ``--gap``); *spin_ns*: the last stretch before a frame is due is waited by polling, not by sleeping."""

    speed: float | None = 1.0
    gap_ns: int = 0
    grace_s: float = 0.3
    spin_ns: int = 200_000


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
            out.append(f"{key}: recorded {va!r}, live {vb!r}{_bits_differing(key, va, vb)}")
    return out


def _bits_differing(key: str, recorded: Any, live: Any) -> str:
    """`` (recorded only: AGREE, REMOTE; live only: RUNX)`` for a status field, by the manuals' bit names."""
    flags = _STATUS_FLAGS.get(key)
    if flags is None or not isinstance(recorded, int) or not isinstance(live, int):
        return ""
    parts = []
    for label, mask in (("recorded only", recorded & ~live), ("live only", live & ~recorded)):
        names = [m.name for m in flags if m.name and m.value.bit_count() == 1 and mask & m.value]
        if names:
            parts.append(f"{label}: {', '.join(names)}")
    return f" ({'; '.join(parts)})" if parts else ""


def hints_for(differences: list[str]) -> list[str]:
    """The settings that explain the usual differences (:data:`HINTS`), for the status bits *differences* name."""
    return [hint for bit, hint in HINTS.items()
            if any(re.search(rf"(only: [^)]*\b{bit}\b)", line) for line in differences)]


def _describe_cmd(data: bytes) -> str:
    try:
        d = describe(decode(data))
        sub = f"/{d['sub']['command']}" if "sub" in d else ""
        return f"{d['main']['command']}{sub}"
    except WireError as exc:
        return f"rejected command ({exc.reason.name})"


def _open(targets: dict[int, tuple[str, int]]) -> tuple[socket.socket, dict[int, Any]]:
    """One non-blocking UDP socket for every target, and each target's resolved address. OSError when a host
    does not resolve."""
    resolved: dict[int, Any] = {}
    family = socket.AF_INET
    for station, (host, port) in targets.items():
        family, _, _, _, resolved[station] = socket.getaddrinfo(host, port, type=socket.SOCK_DGRAM)[0]
    sock = socket.socket(family, socket.SOCK_DGRAM)
    sock.bind(("::" if family == socket.AF_INET6 else "0.0.0.0", 0))
    sock.setblocking(False)
    return sock, resolved


def _play(plan: ReplayPlan, sock: socket.socket, resolved: dict[int, Any], pacing: Pacing,
          result: ReplayResult) -> dict[tuple[int, int], bytes]:
    """Send the planned commands once, as *pacing* says; the answers that came, by (station, cycle)."""
    answers: dict[tuple[int, int], bytes] = {}
    speed, gap, spin_ns = pacing.speed, pacing.gap_ns, pacing.spin_ns

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
                result.received += 1
                answers.setdefault((key[1], key[2]), data)

    t0 = time.monotonic_ns()
    last_sent = t0 - gap
    waiting: tuple[int, int] | None = None  #: speed None: the answer the next command waits for
    for offset, station, cycle, data in plan.commands:
        due = t0 + round(offset / speed) if speed is not None else time.monotonic_ns() + round(pacing.grace_s * 1e9)
        due = max(due, last_sent + gap)
        while True:
            drain()
            now = time.monotonic_ns()
            if speed is None and (waiting is None or waiting in answers) and now >= last_sent + gap:
                break
            left = due - now
            if left <= 0:
                break
            if left > spin_ns:
                select.select([sock], [], [], (left - spin_ns) / 1e9)
        try:
            sock.sendto(data, resolved[station])
            result.sent += 1
        except OSError:
            result.transport_errors += 1
        last_sent = time.monotonic_ns()
        waiting = (station, cycle) if (station, cycle) in plan.recorded else None
    end = time.monotonic() + pacing.grace_s
    while time.monotonic() < end:
        select.select([sock], [], [], max(0.0, end - time.monotonic()))
        drain()
    return answers


def _compare_all(plan: ReplayPlan, answers: dict[tuple[int, int], bytes], result: ReplayResult, *,
                 max_differences: int, strict: bool) -> None:
    """Compare each command's live answer with the recorded one (see :func:`compare`) into *result*."""
    last_moving: dict[int, int] = {}
    for offset, station, cycle, data in plan.commands:
        if len(result.differences) > max_differences:
            return
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


def run_replay(plan: ReplayPlan, targets: dict[int, tuple[str, int]], *, pacing: Pacing | None = None,
               max_differences: int = 10, strict: bool = False, check: bool = True, loops: int = 1,
               result: ReplayResult | None = None) -> ReplayResult:
    """Send every planned command to its station's slave (*targets*: station -> ``(host, port)``) as *pacing*
    says (a command the capture has no answer to is not waited for), *loops* times (0: until interrupted, each
    pass from the capture's start), collect the answers and, with *check*, compare them (*strict*: the monitors
    too). *result* is filled as the passes go (a caller interrupted between two reads what was done). OSError
    when a host does not resolve."""
    pacing = pacing or Pacing()
    result = result if result is not None else ReplayResult()
    sock, resolved = _open(targets)
    try:
        while loops == 0 or result.loops < loops:
            answers = _play(plan, sock, resolved, pacing, result)
            if check:
                _compare_all(plan, answers, result, max_differences=max_differences, strict=strict)
            result.loops += 1
            if check and len(result.differences) > max_differences:
                break
    finally:
        sock.close()
    return result
