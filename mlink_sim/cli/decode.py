"""``mlink-sim decode HEX`` – print a decoded datagram, or reject it with a one-line reason (exit 1);
``mlink-sim decode --pcap FILE`` – a capture, one line per datagram, filtered by station, command and time, or
counted per station and command (``--stats``). Parameters are named, with their values in units, where the card
of the station is known (:mod:`mlink_sim.cli.frame_names`)."""

from __future__ import annotations

import json
import re
import sys
from typing import Any

import click

from ..wire import M2Cmd, M3Cmd, WireError, decode, format_frame
from .frame_names import FrameNames, parse_card

__all__ = ["decode_cmd", "parse_hex"]

#: the command names ``--command`` takes (SI-T3 Tables 5/6, SI-ET3 Tables 11/12, V7 Tables 1/2)
COMMANDS = frozenset(m.name for m in (*M2Cmd, *M3Cmd) if m.name)


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


def _names(cards: tuple[str, ...]) -> FrameNames:
    by_station: dict[int, str] = {}
    every: str | None = None
    for text in cards:
        try:
            station, card = parse_card(text)
        except ValueError as exc:
            raise click.BadParameter(str(exc), param_hint="--card") from None
        if station is None:
            every = card
        else:
            by_station[station] = card
    return FrameNames(by_station, every)


def _selection(station: str | None, commands: tuple[str, ...], t_from: str | None, t_to: str | None) -> Any:
    from ..capture.text import Selection
    from ..units import parse_address, parse_duration_ns

    try:
        wanted = parse_address(station) if station else None
    except ValueError as exc:
        raise click.BadParameter(str(exc), param_hint="--station") from None
    names = set()
    for name in commands:
        key = name.strip().upper().replace("-", "_")
        if key not in COMMANDS:
            raise click.BadParameter(f"{name!r} is not a command name (one of {', '.join(sorted(COMMANDS))})",
                                     param_hint="--command")
        names.add(key)
    bounds = []
    for option, text in (("--from", t_from), ("--to", t_to)):
        try:
            bounds.append(None if text is None else parse_duration_ns(text))
        except ValueError as exc:
            raise click.BadParameter(str(exc), param_hint=option) from None
    if bounds[0] is not None and bounds[1] is not None and bounds[1] < bounds[0]:
        raise click.BadParameter(f"{t_to} is before --from {t_from}", param_hint="--to")
    return Selection(wanted, frozenset(names), bounds[0], bounds[1])


def _print_stats(stats: dict[str, Any]) -> None:
    click.echo(f"{'station':8} {'command':16} {'commands':>9} {'responses':>9}")
    for station, per in stats["stations"].items():
        for command, counts in per.items():
            click.echo(f"{station:8} {command:16} {counts['cmd']:9} {counts['rsp']:9}")
    click.echo(f"{stats['datagrams']} datagram(s), {stats['rejected']} rejected")


def _decode_pcap(path: str, selection: Any, names: FrameNames, as_json: bool, stats: bool) -> None:
    from ..capture import CaptureError, CaptureFile
    from ..capture.text import datagram_lines, datagram_records, datagram_stats

    capture = CaptureFile(path)
    rejected = shown = 0
    try:
        if stats:
            counts = datagram_stats(capture, selection)
            if as_json:
                click.echo(json.dumps(counts))
            else:
                _print_stats(counts)
        elif as_json:
            for rec in datagram_records(capture, selection=selection, names=names):
                shown += not rec.get("note_only")
                rejected += "error" in rec
                click.echo(json.dumps(rec, separators=(",", ":")))
        else:
            for line, ok in datagram_lines(capture, selection=selection, names=names):
                shown += "#" not in line[:14]
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
@click.option("--card", "cards", multiple=True, metavar="[ADDR=]CARD",
              help="The card of a station (si-t3, si-et3, si-t-v7), for parameter names and units; ADDR= for one "
                   "station, repeatable. Default: the capture's notes, and the link (ML-III: SI-ET3, ML-I: "
                   "SI-T/V7).")
@click.option("--pcap", "pcap", type=click.Path(dir_okay=False), metavar="FILE",
              help="Decode every datagram of this pcap/pcapng capture: one line each, relative time, addresses, "
                   "frame.")
@click.option("--station", metavar="ADDR", help="With --pcap: only this station's datagrams and notes (0x21 or 21H).")
@click.option("--command", "commands", multiple=True, metavar="NAME",
              help="With --pcap: only datagrams carrying this main or sub-command (PRM_WR, INV_CTL …); repeatable.")
@click.option("--from", "t_from", metavar="DURATION", help="With --pcap: from this time since the first datagram "
              "(e.g. 2.5s).")
@click.option("--to", "t_to", metavar="DURATION", help="With --pcap: up to this time since the first datagram.")
@click.option("--stats", is_flag=True, help="With --pcap: counts per station and command instead of the datagrams.")
def decode_cmd(hexdata: tuple[str, ...], as_json: bool, frame_size: str | None, cards: tuple[str, ...],
               pcap: str | None, station: str | None, commands: tuple[str, ...], t_from: str | None,
               t_to: str | None, stats: bool) -> None:
    """Decode one datagram given as HEX (spaces and colons allowed), or a capture with --pcap FILE."""
    names = _names(cards)
    if pcap is not None:
        if hexdata or frame_size:
            raise click.UsageError("give either HEX or --pcap FILE (and --frame-size only with HEX)")
        _decode_pcap(pcap, _selection(station, commands, t_from, t_to), names, as_json, stats)
        return
    for option, value in (("--station", station), ("--command", commands), ("--from", t_from), ("--to", t_to),
                          ("--stats", stats)):
        if value:
            raise click.UsageError(f"{option} goes with --pcap FILE")
    if not hexdata:
        raise click.UsageError("give a datagram as HEX, or --pcap FILE")
    try:
        datagram = parse_hex(" ".join(hexdata))
        frame = decode(datagram, data_size=int(frame_size) if frame_size else None)
    except (ValueError, WireError) as exc:
        click.echo(f"mlink-sim decode: {exc}", err=True)
        sys.exit(1)
    described = names.describe(frame)
    if as_json:
        click.echo(json.dumps(described, indent=2))
    else:
        click.echo(format_frame(frame, described))
