#!/usr/bin/env python3
"""``mlink-health HOST:PORT --station 0x21 [--link ml2] [--frame-size 32] [--timeout 2]`` – the container
health check: send the station a NOP, exit 0 only on its valid NOP answer.

A Docker health check runs as a new process every interval, for the whole life of the container, so it must be
cheap. ``mlink-sim probe`` does the same job but starts the whole CLI (click, pydantic, structlog, construct,
uvloop): 0.22 s of CPU per probe. This file imports only builtin modules (``_socket``, ``struct``, ``binascii``,
``time``, ``sys``) and is meant to run with ``python3 -IS`` (no ``site``): one probe costs about 15 ms of CPU, most
of it the interpreter's own start-up (docs/testbeds.md, "The health check"). The image's ``mlink-health`` is a
launcher with that shebang that puts this file's directory first on ``sys.path`` and imports it from its compiled
``.pyc`` (Dockerfile); ``python -m mlink_sim.testbed.health`` runs it from a checkout.

What it sends is the wire contract's NOP command (docs/wire-format.md §1, §4, §5: envelope, all-zero data area
= main NOP and NOP sub-command, WDT 0, FCS CRC-16/X-25). A card answers a NOP from a source other than its master
as a status query: ALARM/STATUS as they stand, nothing executed, nothing bound, no watchdog count advanced
(docs/cards.md, "Who may change a station"). The envelope and the CRC are written out here rather than imported from
``mlink_sim.wire`` because importing that package loads construct; tests/testbed/test_health.py checks every datagram
this module builds and accepts against ``mlink_sim.wire.encode``/``decode``.

Exit codes: 0 the station answered, 1 no valid answer within the timeout (or the target cannot be reached),
2 usage error. One line on stdout (answer) or stderr (failure).
"""

from __future__ import annotations

import _socket
import binascii
import struct
import sys
import time

__all__ = ["ATTEMPTS", "LINK_CODES", "nop_command", "is_nop_answer", "probe", "main"]

#: Envelope: magic 4DH, link, kind, station, cycle u32 LE, transmission cycle ns u32 LE (docs/wire-format.md §1).
_HEADER = struct.Struct("<BBBBII")
_MAGIC = 0x4D
_COMMAND, _RESPONSE = 0x01, 0x02
_TCYCLE_NS = 2_000_000  #: any value: a status query is answered whatever the transmission cycle says

#: Link byte per name (docs/wire-format.md §1) and the data sizes each link carries (SI-T3 Table 29 note <3>,
#: F6-21; SI-ET3 Table 7).
LINK_CODES = {"ml1": 0x01, "ml2": 0x02, "ml3": 0x03}
#: (link, data size) tried in this order when the station's link and frame size are not given.
ATTEMPTS = (("ml2", 32), ("ml2", 17), ("ml3", 64), ("ml3", 32), ("ml1", 17))

_REVERSED = bytes(int(f"{i:08b}"[::-1], 2) for i in range(256))


def _fcs(data: bytes) -> bytes:
    """CRC-16/X-25 of *data*, LE (docs/wire-format.md §2): the reflected CRC is the CCITT one of ``crc_hqx`` on
    bit-reversed bytes, bit-reversed back, xor FFFFH."""
    crc = binascii.crc_hqx(data.translate(_REVERSED), 0xFFFF)
    return (((_REVERSED[crc & 0xFF] << 8) | _REVERSED[crc >> 8]) ^ 0xFFFF).to_bytes(2, "little")


def nop_command(link_name: str, size: int, station: int, cycle: int) -> bytes:
    """The NOP command datagram: main NOP (00H) and, in a 32/64-byte frame, NOP sub-command; WDT 0."""
    body = _HEADER.pack(_MAGIC, LINK_CODES[link_name], _COMMAND, station, cycle, _TCYCLE_NS) + bytes(size)
    return body + _fcs(body)


def is_nop_answer(datagram: bytes, link_name: str, size: int, station: int, cycle: int) -> bool:
    """*datagram* is *station*'s response to :func:`nop_command` (*link_name*, *size*, *cycle*): same length, envelope
    echoing station and cycle, command code 00H echoed in the first data byte, FCS correct."""
    if len(datagram) != _HEADER.size + size + 2 or _fcs(datagram[:-2]) != datagram[-2:]:
        return False
    magic, link_code, kind, answered_by, echoed, _ = _HEADER.unpack_from(datagram)
    return (magic, link_code, kind, answered_by, echoed) == (_MAGIC, LINK_CODES[link_name], _RESPONSE, station, cycle) \
        and datagram[_HEADER.size] == 0x00  # fmt: skip


def probe(host: str, port: int, station: int, attempts: tuple[tuple[str, int], ...], timeout: float) -> str | None:
    """NOPs in each (link, size) of *attempts* until one is answered; the answering (link, size) as text, or None.
    *timeout* is shared by the attempts. OSError when *host* cannot be resolved or reached."""
    # an ASCII host as bytes: a str would make getaddrinfo import the idna codec (re, enum: 25 ms of CPU)
    name: str | bytes = host.encode("ascii") if host.isascii() else host
    family, _, _, _, address = _socket.getaddrinfo(name, port, 0, _socket.SOCK_DGRAM)[0]
    sock = _socket.socket(family, _socket.SOCK_DGRAM)
    try:
        per_try = max(timeout / len(attempts), 0.05)
        for cycle, (link_name, size) in enumerate(attempts, start=1):
            sock.sendto(nop_command(link_name, size, station, cycle), address)
            end = time.monotonic() + per_try
            while (left := end - time.monotonic()) > 0:
                sock.settimeout(left)
                try:
                    data = sock.recv(256)
                except TimeoutError:
                    break
                except ConnectionRefusedError:  # ICMP port unreachable: nothing listens (yet)
                    return None
                if is_nop_answer(data, link_name, size, station, cycle):
                    return f"{link_name} {size}-byte"
        return None
    finally:
        sock.close()


_USAGE = "usage: mlink-health HOST:PORT --station ADDR [--link ml1|ml2|ml3] [--frame-size 17|32|64] [--timeout S]"


class _Usage(Exception):
    pass


def _address(text: str) -> int:
    """``0x21``, ``21H`` or ``33``, as ``mlink-sim`` reads a station address."""
    text = text.strip().lower()
    if text.endswith("h"):
        return int(text[:-1], 16)
    return int(text, 16) if text.startswith("0x") else int(text, 10)


def _parse(argv: list[str]) -> tuple[str, int, int, tuple[tuple[str, int], ...], float]:
    target = None
    opts: dict[str, str] = {}
    args = iter(argv)
    for arg in args:
        name, eq, value = arg.partition("=")
        if name in ("--station", "--link", "--frame-size", "--timeout"):
            if not eq:
                following = next(args, None)
                if following is None:
                    raise _Usage(f"{name} needs a value")
                value = following
            opts[name] = value
        elif arg.startswith("-") or target is not None:
            raise _Usage(f"unexpected argument {arg!r}")
        else:
            target = arg
    if target is None or "--station" not in opts:
        raise _Usage("HOST:PORT and --station are required")
    host, sep, port_text = target.rpartition(":")
    host = host.strip("[]")
    if not sep or not host or not port_text.isdigit() or not 1 <= int(port_text) <= 65535:
        raise _Usage(f"expected HOST:PORT such as 127.0.0.1:47001, got {target!r}")
    try:
        station = _address(opts["--station"])
    except ValueError:
        station = -1
    if not 0 <= station <= 0xFF:
        raise _Usage(f"expected a station address such as 0x21, got {opts['--station']!r}")
    try:
        timeout = float(opts.get("--timeout", "2"))
    except ValueError:
        timeout = 0.0
    if not timeout > 0:
        raise _Usage(f"--timeout takes a number of seconds above 0, got {opts.get('--timeout')!r}")
    size_text = opts.get("--frame-size")
    if size_text is not None and size_text not in ("17", "32", "64"):
        raise _Usage(f"--frame-size must be 17, 32 or 64, got {size_text!r}")
    size = int(size_text) if size_text is not None else None
    link_name = opts.get("--link", "").lower() or None
    if link_name is not None and link_name not in LINK_CODES:
        raise _Usage(f"--link must be one of {', '.join(LINK_CODES)}, got {link_name!r}")
    attempts = tuple((lk, sz) for lk, sz in ATTEMPTS if link_name in (None, lk) and size in (None, sz))
    if not attempts:
        raise _Usage(f"no {link_name or 'link'} carries {size}-byte frames")
    return host, int(port_text), station, attempts, timeout


def main(argv: list[str] | None = None) -> int:
    try:
        host, port, station, attempts, timeout = _parse(sys.argv[1:] if argv is None else argv)
    except _Usage as exc:
        print(f"mlink-health: {exc}\n{_USAGE}", file=sys.stderr)
        return 2
    try:
        answered = probe(host, port, station, attempts, timeout)
    except OSError as exc:
        print(f"mlink-health: cannot reach {host}:{port}: {exc.strerror or exc}", file=sys.stderr)
        return 1
    if answered is None:
        print(f"mlink-health: no valid NOP answer from station {station:#04x} at {host}:{port} within {timeout:g}s",
              file=sys.stderr)
        return 1
    print(f"station {station:#04x} at {host}:{port} answered ({answered})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
