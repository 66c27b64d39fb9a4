"""``mlink-sim decode HEX`` – print a decoded datagram, or reject it with a one-line reason (exit 1);
``mlink-sim decode --pcap FILE`` – a capture, one line per datagram."""

from __future__ import annotations

import json
import re
import sys

import click

from ..wire import WireError, decode, describe, format_frame

__all__ = ["decode_cmd", "parse_hex"]


def parse_hex(text: str) -> bytes:
    """Hex digits, optionally separated by spaces, colons or dashes, with an optional 0x prefix."""
    cleaned = re.sub(r"[\s:\-_]", "", text)
    if cleaned.lower().startswith("0x"):
        cleaned = cleaned[2:]
    if not cleaned:
        raise ValueError("no hex digits given")
    bad = re.search(r"[^0-9a-fA-F]", cleaned)
    if bad:
        raise ValueError(f"{bad.group(0)!r} is not a hex digit")
    if len(cleaned) % 2:
        raise ValueError(f"odd number of hex digits ({len(cleaned)}): a datagram is whole bytes")
    return bytes.fromhex(cleaned)


def _decode_pcap(path: str, station: str | None, as_json: bool) -> None:
    from ..capture import CaptureError, CaptureFile
    from ..capture.text import datagram_lines, datagram_records
    from ..config import parse_address

    try:
        wanted = parse_address(station) if station else None
    except ValueError as exc:
        raise click.BadParameter(str(exc), param_hint="--station") from None
    capture = CaptureFile(path)
    rejected = shown = 0
    try:
        if as_json:
            for rec in datagram_records(capture, wanted):
                shown += 1
                rejected += "error" in rec
                click.echo(json.dumps(rec, separators=(",", ":")))
        else:
            for line, ok in datagram_lines(capture, wanted):
                shown += not line.lstrip().startswith("#")
                rejected += not ok
                click.echo(line)
    except CaptureError as exc:
        click.echo(f"mlink-sim decode: {exc}", err=True)
        sys.exit(2)
    if capture.skipped:
        click.echo(f"mlink-sim decode: {capture.skipped} packet(s) of {path} are not UDP over IP (left out)", err=True)
    if rejected:
        click.echo(f"mlink-sim decode: {rejected} of {shown} datagram(s) rejected", err=True)
        sys.exit(1)


@click.command("decode")
@click.argument("hexdata", nargs=-1)
@click.option("--json", "as_json", is_flag=True, help="Print JSON instead of the readable form (--pcap: one object "
              "per line).")
@click.option("--frame-size", type=click.Choice(["17", "32", "64"]), help="Reject other data sizes.")
@click.option("--pcap", "pcap", type=click.Path(dir_okay=False), help="Decode every datagram of this pcap/pcapng "
              "capture: one line each, relative time, addresses, frame.")
@click.option("--station", metavar="ADDR", help="With --pcap: only this station's datagrams, e.g. 21H or 0x21.")
def decode_cmd(hexdata: tuple[str, ...], as_json: bool, frame_size: str | None, pcap: str | None,
               station: str | None) -> None:
    """Decode one datagram given as HEX (spaces and colons allowed), or a capture with --pcap FILE."""
    if pcap is not None:
        if hexdata or frame_size:
            raise click.UsageError("give either HEX or --pcap FILE (and --frame-size only with HEX)")
        _decode_pcap(pcap, station, as_json)
        return
    if station is not None:
        raise click.UsageError("--station goes with --pcap FILE")
    if not hexdata:
        raise click.UsageError("give a datagram as HEX, or --pcap FILE")
    try:
        datagram = parse_hex(" ".join(hexdata))
        frame = decode(datagram, data_size=int(frame_size) if frame_size else None)
    except (ValueError, WireError) as exc:
        click.echo(f"mlink-sim decode: {exc}", err=True)
        sys.exit(1)
    if as_json:
        click.echo(json.dumps(describe(frame), indent=2))
    else:
        click.echo(format_frame(frame))
