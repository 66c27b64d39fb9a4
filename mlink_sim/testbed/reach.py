"""``python -m mlink_sim.testbed.reach 0x21=HOST:PORT/ml2/32 …`` – probe several stations at once.

Used by ``scripts/netns-testbed`` inside the master's namespace before the master starts, so that a station that
cannot be reached (a bridge whose frames a host firewall drops, say) is reported by name instead of as a failed
bring-up. Sends each station a NOP (:func:`mlink_sim.aio.tools.probe.probe`), all concurrently; prints one line per
station that did not answer and exits 1 if any did not, 0 if all did, 2 on a malformed argument.
"""

from __future__ import annotations

import asyncio
import sys

from ..aio.tools.probe import probe
from ..config import parse_address, parse_endpoint
from ..wire import Link

__all__ = ["Target", "parse_target", "reach_all", "main"]

Target = tuple[int, str, int, Link, int]  #: (station, host, port, link, frame size)


def parse_target(text: str) -> Target:
    """``0x21=198.18.0.2:47001/ml2/32`` -> ``(0x21, "198.18.0.2", 47001, Link.ML2, 32)``."""
    addr, sep, rest = text.partition("=")
    parts = rest.split("/")
    if not sep or len(parts) != 3:
        raise ValueError(f"expected ADDR=HOST:PORT/LINK/SIZE such as 0x21=198.18.0.2:47001/ml2/32, got {text!r}")
    host, port = parse_endpoint(parts[0])
    try:
        link = Link[parts[1].upper()]
        size = int(parts[2])
    except (KeyError, ValueError):
        raise ValueError(f"bad link or frame size in {text!r}") from None
    return parse_address(addr), host, port, link, size


async def reach_all(targets: list[Target], timeout: float = 2.0, rounds: int = 2) -> list[Target]:
    """The targets that did not answer a NOP in any of *rounds* tries."""
    missing = list(targets)
    for _ in range(rounds):
        answers = await asyncio.gather(
            *(probe(host, port, station, [(link, size)], timeout) for station, host, port, link, size in missing)
        )
        missing = [t for t, frame in zip(missing, answers, strict=True) if frame is None]
        if not missing:
            break
    return missing


def main(argv: list[str] | None = None) -> int:
    args = sys.argv[1:] if argv is None else argv
    try:
        targets = [parse_target(a) for a in args]
    except ValueError as exc:
        print(f"reach: {exc}", file=sys.stderr)
        return 2
    from ..aio.transport.udp import new_event_loop

    loop = new_event_loop()
    try:
        missing = loop.run_until_complete(reach_all(targets))
    finally:
        loop.close()
    for station, host, port, link, size in missing:
        print(f"station {station:#04x} at {host}:{port} did not answer a NOP ({link.name}, {size}-byte)")
    return 1 if missing else 0


if __name__ == "__main__":
    sys.exit(main())
