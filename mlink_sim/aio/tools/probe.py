"""Probe a station: NOPs over UDP until it answers (``mlink-sim probe``, the netns testbed's reachability check).

Read-only by construction: the probe sends only main NOPs with no (or a NOP) sub-command, which a card answers as a
status query when a master owns it or lost it (nothing executed, nothing bound, RWDT not advanced) and as a plain NOP
in phase 1 (docs/cards.md, "Who may change a station"); tests/e2e/test_protocol_e2e.py checks the station looks the
same afterwards.

Touches: one UDP socket of its own; sends main NOPs only.
"""

from __future__ import annotations

import asyncio
from typing import Any

from ...wire import Frame, Kind, Link, WireError, decode, encode, ml2, ml3
from ..transport.udp import bind_address_for, open_endpoint, resolve

__all__ = ["nop_command", "probe"]


def nop_command(link: Link, size: int, station: int, cycle: int) -> bytes:
    """The NOP command datagram for *station* on *link* with *size*-byte data (a NOP sub-command in the
    32-/64-byte frames)."""
    msg: Any
    if link is Link.ML3:
        msg = ml3.M3Command(ml3.Nop(), sub=ml3.Nop() if size == 64 else None)
    else:
        msg = ml2.M2Command(ml2.Nop(), sub=ml2.Nop() if size == 32 else None)
    return encode(Frame(link, Kind.COMMAND, station, cycle, 2_000_000, msg))


async def probe(host: str, port: int, station: int, attempts: list[tuple[Link, int]], timeout: float) -> Frame | None:
    """Send NOPs in each (link, size) until one gets a valid response from *station*; the response or None."""
    loop = asyncio.get_running_loop()
    host, port = await resolve(host, port)
    answers: asyncio.Queue[bytes] = asyncio.Queue()
    ep = await open_endpoint(lambda data, addr: answers.put_nowait(data), *bind_address_for([(host, port)]))
    try:
        per_try = max(timeout / len(attempts), 0.05)
        for cycle, (link, size) in enumerate(attempts, start=1):
            ep.sendto(nop_command(link, size, station, cycle), (host, port))
            end = loop.time() + per_try
            while (left := end - loop.time()) > 0:
                try:
                    data = await asyncio.wait_for(answers.get(), left)
                except TimeoutError:
                    break
                try:
                    frame = decode(data, kind=Kind.RESPONSE)
                except WireError:
                    continue
                if frame.station == station and frame.cycle == cycle:
                    return frame
        return None
    finally:
        ep.close()
