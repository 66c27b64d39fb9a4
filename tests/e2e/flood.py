"""A flood process: ``python tests/e2e/flood.py COUNT PORT…`` sends COUNT datagrams to 127.0.0.1:PORT… as fast as
one process can, from four sockets of its own, round-robin: CONNECT, INV_CTL (run) and NOP of every card's link to
stations 21H–23H, and garbage. Prints one JSON line: ``{"sent": N, "seconds": S}`` (the flood's window)."""

from __future__ import annotations

import json
import socket
import sys
import time

from mlink_sim.wire import Frame, Kind, Link, encode, ml2, ml3

TCYCLE_NS = 2_000_000


def payloads() -> list[bytes]:
    """Commands from a stranger to each station of the three cards (SI-T3 / SI-T/V7 on MECHATROLINK-II, SI-ET3 on
    MECHATROLINK-III) and a datagram no card can decode."""
    out = [b"\x4d\x02\x01\x21garbage"]
    for address in (0x21, 0x22, 0x23):
        for body in (ml2.Connect(0x21, 0x80, 1), ml2.InvCtl(signals=1, speed_ref=3000), ml2.Nop()):
            out.append(encode(Frame(Link.ML2, Kind.COMMAND, address, 7, TCYCLE_NS, ml2.M2Command(body, 0x10))))
        for body3 in (ml3.Connect(0x30, 0x80, 1, 0x20), ml3.InvCtl(1, 0, 3000), ml3.Nop()):
            msg = ml3.M3Command(body3, 0x10, 0, ml3.Nop())
            out.append(encode(Frame(Link.ML3, Kind.COMMAND, address, 7, TCYCLE_NS, msg)))
    return out


def main(argv: list[str]) -> int:
    count, ports = int(argv[0]), [int(p) for p in argv[1:]]
    data = payloads()
    socks = [socket.socket(socket.AF_INET, socket.SOCK_DGRAM) for _ in range(4)]
    sent = 0
    start = time.monotonic()
    for i in range(count):
        try:
            socks[i % 4].sendto(data[i % len(data)], ("127.0.0.1", ports[i % len(ports)]))
            sent += 1
        except OSError:  # ICMP port unreachable reported back on the socket: the flood goes on
            pass
    seconds = time.monotonic() - start
    for s in socks:
        s.close()
    print(json.dumps({"sent": sent, "seconds": seconds}), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
