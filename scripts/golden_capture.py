#!/usr/bin/env python3
"""Write the golden capture tests/wireshark/golden.pcapng from the package's own encoders.

Every command and response body of the three manuals – each main command of SI-T3 Table 5 / V7 Table 1 and
SI-ET3 Table 11, each sub-command of SI-T3 Table 6 / V7 Table 2 and SI-ET3 Table 12, in every frame size of every
link (17-byte MECHATROLINK-I; 17/32-byte MECHATROLINK-II; 32/64-byte MECHATROLINK-III) – plus the frames a
dissector must flag: a bad FCS on each link, ALARM bytes (the card's SI-T3 Tables 23/25 codes, a drive alarm of
Table 26 with ALM, a minor fault of Table 27 with WARNG), every CMD_ALM, COMM_ALM and SUBCMD_ALM value, and a
command code without a layout. Field values are deterministic patterns, not a plausible session.

    python scripts/golden_capture.py [OUT]     # default tests/wireshark/golden.pcapng

The file is byte-for-byte reproducible (fixed clock and addresses); tests/wireshark/test_golden_capture.py checks
the committed file equals this script's output, then runs it through tshark with the dissector.
"""

from __future__ import annotations

import dataclasses
import itertools
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from mlink_sim.capture import CaptureWriter
from mlink_sim.wire import (CmdAlm, CommAlm, Frame, Kind, Link, M2Alarm, M2Status, SubCmdAlm, Unknown, encode, ml2,
                            ml3)
from mlink_sim.wire.drive_codes import SiT3DriveAlarm, SiT3DriveWarning
from mlink_sim.wire.layout import Slot

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_OUT = ROOT / "tests" / "wireshark" / "golden.pcapng"
MASTER = ("192.0.2.1", 40000)
PORT = 47001  #: the dissector's default port
EPOCH_NS = 1_700_000_000 * 10**9
TCYCLE = 2_000_000


def _body(slot: Slot, code: int) -> Any:
    """The body registered for *code* in *slot*, every field set to a pattern that fits it."""
    layout = slot.by_code[code]
    values: dict[str, Any] = {}
    for i, f in enumerate(dataclasses.fields(layout.cls)):
        default = f.default
        if isinstance(default, bytes):
            values[f.name] = bytes((code + i + k) & 0xFF for k in range(len(default)))
        elif f.name == "size":
            values[f.name] = 2
        else:
            values[f.name] = (code * 7 + i * 13 + 1) & 0x7F
    return layout.cls(**values)


def _codes(*slots: Slot) -> list[int]:
    return sorted(set().union(*(s.by_code for s in slots)))


def _pairs(link: Link, station: int, slots: tuple[Slot, Slot], make: tuple[Any, Any], what: str,
           cycles: Iterator[int]) -> Iterator[tuple[Frame, str]]:
    """For every code of the command/response *slots*: the command ``make[0](body, cycle)`` and the response
    ``make[1](body, cycle)`` of the same cycle, where the slot declares that code."""
    for code in _codes(*slots):
        c = next(cycles)
        for kind, slot, build, label in ((Kind.COMMAND, slots[0], make[0], "command"),
                                         (Kind.RESPONSE, slots[1], make[1], "response")):
            if code in slot.by_code:
                yield Frame(link, kind, station, c, TCYCLE, build(_body(slot, code), c)), f"{what} {label}"


def frames() -> Iterator[tuple[Frame, str]]:
    """Every frame of the golden capture, with a note saying what it stands for."""
    cycles = itertools.count(1)
    ready = int(M2Status.CMDRDY)
    # MECHATROLINK-I/II: main commands in 17-byte frames on ML1 and ML2, and with each sub-command in 32-byte ones
    for link, station in ((Link.ML1, 0x21), (Link.ML2, 0x22)):
        yield from _pairs(link, station, (ml2.COMMAND_MAIN, ml2.RESPONSE_MAIN), (
            lambda b, c: ml2.M2Command(b, wdt=c & 0xFF),
            lambda b, c: ml2.M2Response(b, status=ready, rwdt=c & 0xFF)), f"{link.name} main", cycles)
    yield from _pairs(Link.ML2, 0x23, (ml2.COMMAND_SUB, ml2.RESPONSE_SUB), (
        lambda b, c: ml2.M2Command(ml2.Nop(), wdt=1, sub=b),
        lambda b, c: ml2.M2Response(ml2.Nop(), status=ready, rwdt=2, sub=b, substatus=4)), "ML2 sub", cycles)
    # MECHATROLINK-III: main commands in 32-byte frames, sub-commands in 64-byte ones
    yield from _pairs(Link.ML3, 0x31, (ml3.COMMAND_MAIN, ml3.RESPONSE_MAIN), (
        lambda b, c: ml3.M3Command(b, wdt=c & 0xFF, cmd_ctrl=0x48),
        lambda b, c: ml3.M3Response(b, rwdt=c & 0xFF, cmd_stat=0x0044)), "ML3 main", cycles)
    yield from _pairs(Link.ML3, 0x31, (ml3.COMMAND_SUB, ml3.RESPONSE_SUB), (
        lambda b, c: ml3.M3Command(ml3.Nop(), wdt=3, sub=b),
        lambda b, c: ml3.M3Response(ml3.Nop(), rwdt=4, cmd_stat=4, sub=b, sub_stat=4)), "ML3 sub", cycles)
    nxt = cycles.__next__
    # alarms: the card's own ALARM codes, a drive alarm (Table 26, ALM) and a minor fault (Table 27, WARNG)
    for code in M2Alarm:
        flag = M2Status.WARNG if code.is_warning else M2Status.ALM
        yield (Frame(Link.ML2, Kind.RESPONSE, 0x22, nxt(), TCYCLE,
                     ml2.M2Response(ml2.Nop(), alarm=int(code), status=int(flag | M2Status.CMDRDY))),
               f"ALARM {code.name}")
    yield (Frame(Link.ML2, Kind.RESPONSE, 0x22, nxt(), TCYCLE,
                 ml2.M2Response(ml2.Nop(), alarm=int(SiT3DriveAlarm.OV), status=int(M2Status.ALM))),
           "drive alarm ov (SI-T3 Table 26)")
    yield (Frame(Link.ML2, Kind.RESPONSE, 0x22, nxt(), TCYCLE,
                 ml2.M2Response(ml2.Nop(), alarm=int(SiT3DriveWarning.EF), status=int(M2Status.WARNG))),
           "drive minor fault EF (SI-T3 Table 27)")
    for value in CmdAlm:
        yield (Frame(Link.ML3, Kind.RESPONSE, 0x31, nxt(), TCYCLE,
                     ml3.M3Response(ml3.Nop(), cmd_stat=ml3.CmdStat(cmd_alm=int(value)).to_int())),
               f"CMD_ALM {value.name}")
    for value in CommAlm:
        yield (Frame(Link.ML3, Kind.RESPONSE, 0x31, nxt(), TCYCLE,
                     ml3.M3Response(ml3.Nop(), cmd_stat=ml3.CmdStat(comm_alm=int(value)).to_int())),
               f"COMM_ALM {value.name}")
    for value in SubCmdAlm:
        yield (Frame(Link.ML3, Kind.RESPONSE, 0x31, nxt(), TCYCLE,
                     ml3.M3Response(ml3.Nop(), sub=ml3.Nop(), sub_stat=ml3.SubStat(subcmd_alm=int(value)).to_int())),
               f"SUBCMD_ALM {value.name}")
    # a command code without a layout (answered with A.95 / CMD_ALM 8 by the cards)
    yield (Frame(Link.ML2, Kind.COMMAND, 0x22, nxt(), TCYCLE, ml2.M2Command(Unknown(0x30, bytes(13)))),
           "unknown ML2 command 30H")
    yield (Frame(Link.ML3, Kind.COMMAND, 0x31, nxt(), TCYCLE, ml3.M3Command(Unknown(0x70, bytes(28)))),
           "unknown ML3 command 70H")


def bad_fcs(datagram: bytes) -> bytes:
    """*datagram* with its FCS flipped in one bit."""
    return datagram[:-1] + bytes([datagram[-1] ^ 0x01])


def datagrams() -> Iterator[tuple[bytes, str]]:
    for frame, note in frames():
        yield encode(frame), note
    for link, station, body in ((Link.ML1, 0x21, ml2.M2Command(ml2.Nop())), (Link.ML2, 0x22, ml2.M2Command(
            ml2.Nop(), sub=ml2.Nop())), (Link.ML3, 0x31, ml3.M3Command(ml3.Nop(), sub=ml3.Nop()))):
        yield bad_fcs(encode(Frame(link, Kind.COMMAND, station, 9999, TCYCLE, body))), f"bad FCS on {link.name}"


def write(path: Path) -> int:
    """Write the golden capture to *path*; returns the number of datagrams."""
    n = 0
    with CaptureWriter(path, epoch_offset_ns=EPOCH_NS, flush_s=3600) as capture:
        for i, (data, note) in enumerate(datagrams()):
            slave = (f"192.0.2.{data[3] if len(data) > 3 else 0}", PORT)
            src, dst = (MASTER, slave) if data[2] == Kind.COMMAND else (slave, MASTER)
            capture.record(i * 1_000_000, data, src, dst)
            capture.note(i * 1_000_000, note)
            n += 1
    return n


if __name__ == "__main__":
    out = Path(sys.argv[1]) if len(sys.argv) > 1 else DEFAULT_OUT
    print(f"{out}: {write(out)} datagrams", file=sys.stderr)
