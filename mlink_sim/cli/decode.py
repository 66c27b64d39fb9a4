"""``mlink-sim decode HEX`` – print a decoded datagram, or reject it with a one-line reason (exit 1)."""

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


@click.command("decode")
@click.argument("hexdata", nargs=-1, required=True)
@click.option("--json", "as_json", is_flag=True, help="Print JSON instead of the readable form.")
@click.option("--frame-size", type=click.Choice(["17", "32", "64"]), help="Reject other data sizes.")
def decode_cmd(hexdata: tuple[str, ...], as_json: bool, frame_size: str | None) -> None:
    """Decode one datagram given as HEX (spaces and colons allowed)."""
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
