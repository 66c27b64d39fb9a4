"""``mlink-sim probe HOST:PORT --station 0x21`` – send a NOP, exit 0 only on a valid answer (health checks).

The probe itself is :func:`mlink_sim.aio.tools.probe.probe` (read-only by construction: main NOPs only)."""

from __future__ import annotations

import sys
import time

import click

from ..aio.tools.probe import probe
from ..aio.transport.udp import new_event_loop
from ..config import parse_endpoint
from ..testbed.health import ATTEMPTS
from ..wire import Link
from .params import ADDR, LINK, Seconds, station_name

__all__ = ["probe_cmd"]

#: The (link, size) pairs tried when the station's are not given: the same order as the image's health check.
_ATTEMPTS: list[tuple[Link, int]] = [(Link[name.upper()], size) for name, size in ATTEMPTS]


@click.command("probe")
@click.argument("target", metavar="HOST:PORT")
@click.option("--station", "station", type=ADDR, required=True, help="Station address, e.g. 21H or 0x21.")
@click.option("--link", "link_name", type=LINK, help="Link (default: try all).")
@click.option("--frame-size", type=click.Choice(["17", "32", "64"]), help="Data size (default: try all).")
@click.option("--timeout", default="2s", show_default=True, type=Seconds(),
              help="How long to wait in all, e.g. 500ms (a bare number is seconds).")
def probe_cmd(target: str, station: int, link_name: str | None, frame_size: str | None, timeout: float) -> None:
    """Send a NOP to the station at HOST:PORT; exit 0 only on a valid answer."""
    try:
        host, port = parse_endpoint(target)
    except ValueError as exc:
        raise click.BadParameter(str(exc), param_hint="HOST:PORT") from None
    attempts = [
        (lk, sz) for lk, sz in _ATTEMPTS
        if (link_name is None or lk.name.lower() == link_name.lower()) and (frame_size is None or sz == int(frame_size))
    ]  # fmt: skip
    if not attempts:
        raise click.BadParameter(f"{link_name} has no {frame_size}-byte frames", param_hint="--frame-size")
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
        click.echo(f"mlink-sim probe: no valid answer from station {station_name(station)} at {target} within {timeout:g}s",
                   err=True)
        sys.exit(1)
    click.echo(f"station {station_name(station)} at {target} answered: {frame.link.label}, {frame.data_size}-byte data, "
               f"{(time.monotonic() - t0) * 1e3:.1f} ms")
