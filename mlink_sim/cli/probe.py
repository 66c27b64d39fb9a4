"""``mlink-sim probe HOST:PORT --station 0x21`` – send a NOP, exit 0 only on a valid answer (health checks).

Read-only by construction: the probe sends only main NOPs with no (or a NOP) sub-command, which a card answers as a
status query when a master owns it or lost it (nothing executed, nothing bound, RWDT not advanced) and as a plain NOP
in phase 1 (docs/cards.md, "Who may change a station"); tests/e2e/test_protocol_e2e.py checks the station looks the
same afterwards."""

from __future__ import annotations

import asyncio
import sys
import time
from typing import Any

import click

from ..aio.udp import bind_address_for, new_event_loop, open_endpoint, resolve
from ..config import parse_address, parse_endpoint
from ..testbed.health import ATTEMPTS
from ..wire import Frame, Kind, Link, WireError, decode, encode, ml2, ml3

__all__ = ["probe_cmd", "probe"]

#: The (link, size) pairs tried when the station's are not given: the same order as the image's health check.
_ATTEMPTS: list[tuple[Link, int]] = [(Link[name.upper()], size) for name, size in ATTEMPTS]


def _nop(link: Link, size: int, station: int, cycle: int) -> bytes:
    if link is Link.ML3:
        msg: Any = ml3.M3Command(ml3.Nop(), sub=ml3.Nop() if size == 64 else None)
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
            ep.sendto(_nop(link, size, station, cycle), (host, port))
            end = loop.time() + per_try
            while (left := end - loop.time()) > 0:
                try:
                    data = await asyncio.wait_for(answers.get(), left)
                except asyncio.TimeoutError:
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


@click.command("probe")
@click.argument("target")
@click.option("--station", "station_text", required=True, help="Station address, e.g. 0x21.")
@click.option("--link", type=click.Choice(["ml1", "ml2", "ml3"], case_sensitive=False), help="Link (default: try all).")
@click.option("--frame-size", type=click.Choice(["17", "32", "64"]), help="Data size (default: try all).")
@click.option("--timeout", default=2.0, show_default=True, type=click.FloatRange(min=0, min_open=True),
              help="Seconds to wait in all (> 0).")
def probe_cmd(target: str, station_text: str, link: str | None, frame_size: str | None, timeout: float) -> None:
    """Send a NOP to the station at TARGET (HOST:PORT); exit 0 only on a valid answer."""
    try:
        host, port = parse_endpoint(target)
        station = parse_address(station_text)
    except ValueError as exc:
        raise click.BadParameter(str(exc)) from None
    attempts = [
        (lk, sz) for lk, sz in _ATTEMPTS
        if (link is None or lk.name.lower() == link.lower()) and (frame_size is None or sz == int(frame_size))
    ]  # fmt: skip
    if not attempts:
        raise click.BadParameter(f"{link} has no {frame_size}-byte frames", param_hint="--frame-size")
    loop = new_event_loop()
    t0 = time.monotonic()
    try:
        frame = loop.run_until_complete(probe(host, port, station, attempts, timeout))
    except OSError as exc:
        click.echo(f"mlink-sim probe: cannot reach {target}: {getattr(exc, 'strerror', None) or exc}", err=True)
        sys.exit(1)
    finally:
        loop.close()
    if frame is None:
        click.echo(f"mlink-sim probe: no valid answer from station {station:#04x} at {target} within {timeout:g}s",
                   err=True)
        sys.exit(1)
    click.echo(f"station {station:#04x} at {target} answered: {frame.link.label}, {frame.data_size}-byte data, "
               f"{(time.monotonic() - t0) * 1e3:.1f} ms")
