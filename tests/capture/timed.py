"""A capture of known timing, written with the capture writer on explicit times: what the ``--stats`` figures,
tshark's ``-z mlink,srt`` and ``watch`` are checked against.

Station 21H (SI-T3, MECHATROLINK-II 32-byte, its note naming 0.006 Hz counts): twelve INV_CTL commands every
2 ms at cycles 1…12 (12 repeats cycle 11: a sequence error), answered 100 µs + 10 µs × i later, except cycle 4
(lost) and cycle 7 (answered 2.5 ms later: after the next command, late); one answer twice (cycle 9: a sequence
error); one datagram with a bad FCS. The speed reference runs 0, 500, … 5500 counts, the output frequency 0, 400,
… Station 23H (SI-ET3, MECHATROLINK-III 64-byte, no note of its speed units): three PRM_RD every 4 ms, answered
in 150 µs; its last command is within a cycle of the end of the capture and unanswered: not lost.
"""

from __future__ import annotations

from pathlib import Path

from mlink_sim.capture import CaptureWriter
from mlink_sim.capture.text import card_note
from mlink_sim.wire import Frame, Kind, Link, M2Status, encode, ml2, ml3

MASTER = ("192.0.2.1", 40000)
SLAVES = {0x21: ("192.0.2.33", 47001), 0x23: ("192.0.2.35", 47001)}
T0 = 1_700_000_000 * 10**9  #: the capture's first datagram, Unix ns
CYCLE = 2_000_000
#: (cycle, command time, answer time or None), station 21H
EXCHANGES_21 = [(c, (c - 1) * CYCLE, (c - 1) * CYCLE + 100_000 + 10_000 * (c - 1)) for c in range(1, 12)]
EXCHANGES_21[3] = (4, 3 * CYCLE, None)  # lost
EXCHANGES_21[6] = (7, 6 * CYCLE, 6 * CYCLE + 2_500_000)  # late: after cycle 8's command
EXCHANGES_21.append((11, 11 * CYCLE, 11 * CYCLE + 200_000))  # a repeated cycle number
#: answer times of 21H in ns, as --stats computes them (cycle 4 lost)
RT_21 = sorted((a - c) for _, c, a in EXCHANGES_21 if a is not None)


def _ml2(kind: Kind, cycle: int, body: object) -> bytes:
    if kind is Kind.COMMAND:
        return encode(Frame(Link.ML2, kind, 0x21, cycle, CYCLE, ml2.M2Command(body, 0, ml2.Nop())))
    status = int(M2Status.CMDRDY | M2Status.REMOTE)
    return encode(Frame(Link.ML2, kind, 0x21, cycle, CYCLE, ml2.M2Response(body, 0, status, 0, ml2.Nop(), 0)))


def _ml3(kind: Kind, cycle: int, body: object) -> bytes:
    msg = ml3.M3Command(body, 0, 0, ml3.Nop()) if kind is Kind.COMMAND else ml3.M3Response(body, 0, 4, ml3.Nop())
    return encode(Frame(Link.ML3, kind, 0x23, cycle, CYCLE, msg))


def write_timed_capture(path: Path) -> Path:
    """The capture of the module docstring at *path*."""
    items: list[tuple[int, bytes, int]] = []  # (time, datagram, station)
    for i, (cycle, sent, answered) in enumerate(EXCHANGES_21):
        items.append((sent, _ml2(Kind.COMMAND, cycle, ml2.InvCtl(signals=1, speed_ref=500 * i)), 0x21))
        if answered is not None:
            answer = _ml2(Kind.RESPONSE, cycle, ml2.InvCtlResponse(output_freq=400 * i))
            items.append((answered, answer, 0x21))
            if cycle == 9:
                items.append((answered + 5_000, answer, 0x21))  # the same answer twice
    bad = bytearray(_ml2(Kind.RESPONSE, 99, ml2.InvCtlResponse()))
    bad[-1] ^= 0xFF
    items.append((5 * CYCLE + 900_000, bytes(bad), 0x21))
    for k in range(3):
        at = 1_000_000 + 4_000_000 * k
        items.append((at, _ml3(Kind.COMMAND, 100 + k, ml3.PrmRd(0x0201, 2)), 0x23))
        if k < 2:
            items.append((at + 150_000, _ml3(Kind.RESPONSE, 100 + k, ml3.PrmRdResponse(0x0201, 2, b"\x0a" + bytes(7))),
                          0x23))
    # 23H's last datagram is its last command (9 ms): within a cycle of the end of its part of the capture
    items.sort(key=lambda item: item[0])
    with CaptureWriter(path, epoch_offset_ns=T0) as w:
        w.note(0, card_note(0x21, "SI-T3", "(MECHATROLINK-II, 32-byte)", 0.006))
        w.note(0, card_note(0x23, "SI-ET3", "(MECHATROLINK-III, 64-byte)"))
        for at, data, station in items:
            kind = data[2]
            src, dst = (MASTER, SLAVES[station]) if kind == Kind.COMMAND else (SLAVES[station], MASTER)
            w.record(at, data, src, dst)
    return path
