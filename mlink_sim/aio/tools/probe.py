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

__all__ = ["nop_command", "probe", "find_station", "ADDRESSES"]

#: Every address a station of the three cards can have (SI-ET3 Table 7 F6-20 03H–EFH covers SI-T3 Table 4 F6-20 and
#: the SI-T/V7 switches, 21H–3EH).
ADDRESSES = range(0x03, 0xF0)
#: The frames a NOP is tried in when nothing says which: 32-byte MECHATROLINK-II, 64-byte MECHATROLINK-III, 17-byte.
_FIND = ((Link.ML2, 32), (Link.ML3, 64), (Link.ML2, 17))
_BATCH = 6  #: NOPs sent together (fewer than the backlog a slave answers of one source: 8)
_PAUSE_S = 0.001  #: between two batches


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


async def find_station(host: str, port: int, station: int | None, timeout: float) -> Frame | None:
    """Whether a station answers MECHATROLINK at *host*:*port*: NOPs to *station* (None: to every address of
    :data:`ADDRESSES`, 21H–3EH first) in the frames of :data:`_FIND`, a few at a time (a slave answers the newest
    of a source's backlog only); the first valid response, or None within *timeout* s."""
    loop = asyncio.get_running_loop()
    host, port = await resolve(host, port)
    found: asyncio.Future[Frame] = loop.create_future()

    def on_datagram(data: bytes, addr: Any) -> None:
        if found.done():
            return
        try:
            found.set_result(decode(data, kind=Kind.RESPONSE))
        except WireError:
            pass

    ep = await open_endpoint(on_datagram, *bind_address_for([(host, port)]))
    addresses = [station] if station is not None else sorted(ADDRESSES, key=lambda a: not 0x21 <= a <= 0x3E)
    datagrams = [nop_command(link, size, a, 1) for a in addresses for link, size in _FIND]
    end = loop.time() + timeout
    try:
        for i in range(0, len(datagrams), _BATCH):
            for datagram in datagrams[i:i + _BATCH]:
                ep.sendto(datagram, (host, port))
            try:
                return await asyncio.wait_for(asyncio.shield(found), min(_PAUSE_S, max(0.0, end - loop.time())))
            except TimeoutError:
                if loop.time() >= end:
                    return None
        return await asyncio.wait_for(found, max(0.0, end - loop.time()))
    except TimeoutError:
        return None
    finally:
        ep.close()
