"""``mlink-sim decode HEX`` – print a decoded datagram, or reject it with a one-line reason (exit 1);
``mlink-sim decode --pcap FILE`` (``-``: standard input) – a capture, one line per datagram, filtered by station,
command and time, or its figures per station and command (``--stats``: counts, response times, cycle gaps, lost
and late answers, errors, INV_CTL's speed in Hz; :mod:`mlink_sim.capture.stats`). Parameters are named, with their
values in units, where the card of the station is known (:mod:`mlink_sim.cli.frame_names`)."""

from __future__ import annotations

import json
import re
import sys
from typing import Any

import click

from ..wire import M2Cmd, M3Cmd, WireError, decode, format_frame
from .frame_names import FrameNames, parse_card

__all__ = ["decode_cmd", "parse_hex", "card_names"]

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


def card_names(cards: tuple[str, ...]) -> FrameNames:
    """``--card`` values as the names of the stations' parameters (``[ADDR=]CARD``; a usage error for a bad one)."""
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


def _times(summary: dict[str, int] | None) -> list[str]:
    """min, p50, p99, max of a summary of ns (``format_ns``), or dashes."""
    from ..units import format_ns

    if summary is None:
        return ["-"] * 4
    return [format_ns(summary[k]) for k in ("min", "p50", "p99", "max")]


def _hz_range(values: dict[str, int] | None, scale: Any) -> str:
    if values is None:
        return "-"
    return f"{scale.hz(values['min']):.2f}…{scale.hz(values['max']):.2f}, last {scale.hz(values['last']):.2f}"


def _add_hz(stats: dict[str, Any]) -> dict[str, Any]:
    """INV_CTL's speed reference and output frequency of each station in Hz, by its units (:mod:`.speed_units`),
    beside the raw counts: ``speed_ref_hz``, ``output_freq_hz``, ``hz_per_count`` and ``units``; returns the
    stations' :class:`~.speed_units.Scale`."""
    from .speed_units import SpeedUnits

    units = SpeedUnits()
    scales = {}
    for name, timing in stats["timing"].items():
        if timing["card_note"]:
            units.learn(timing["card_note"])
        scale = units.of(timing["link"], int(name[:2], 16))
        timing["hz_per_count"], timing["units"] = scale.hz_per_count, scale.source
        for key in ("speed_ref", "output_freq"):
            raw = timing[key]
            timing[f"{key}_hz"] = None if raw is None else {k: round(scale.hz(v), 6) for k, v in raw.items()}
        scales[name] = scale
    return scales


def _print_stats(stats: dict[str, Any], scales: dict[str, Any]) -> None:
    """The figures as three tables: per station and command, per station (cycles and errors), INV_CTL in Hz."""
    right = "{:>9} {:>9} {:>5} {:>5}  {:>8} {:>8} {:>8} {:>8}"
    click.echo(f"{'station':8} {'command':16} " + right.format("commands", "responses", "lost", "late",
                                                                  "rt min", "p50", "p99", "max"))
    for station, per in stats["stations"].items():
        for command, c in per.items():
            if command.startswith("sub "):
                click.echo(f"{station:8} {command:16} {c['cmd']:9} {c['rsp']:9}")
            else:
                click.echo(f"{station:8} {command:16} " + right.format(c["cmd"], c["rsp"], c["lost"], c["late"],
                                                                          *_times(c["response_ns"])))
    if stats["timing"]:
        click.echo(f"\n{'station':8} {'link':4} {'gap min':>8} {'p50':>8} {'p99':>8} {'max':>8}  "
                   f"{'FCS errors':>10} {'sequence errors':>15} {'rejected':>8}")
        for station, t in stats["timing"].items():
            gaps = "{:>8} {:>8} {:>8} {:>8}".format(*_times(t["gap_ns"]))
            click.echo(f"{station:8} {t['link']:4} {gaps}  {t['fcs_errors']:10} {t['sequence_errors']:15} "
                       f"{t['rejected']:8}")
    inv = {k: t for k, t in stats["timing"].items() if t["speed_ref"] or t["output_freq"]}
    if inv:
        click.echo(f"\n{'station':8} {'INV_CTL speed reference (Hz)':30} {'output frequency (Hz)':30} units")
        for station, t in inv.items():
            scale = scales[station]
            click.echo(f"{station:8} {_hz_range(t['speed_ref'], scale):30} {_hz_range(t['output_freq'], scale):30} "
                       f"{scale.hz_per_count:g} Hz per count, {scale.source}")
    click.echo(f"\n{stats['datagrams']} datagram(s), {stats['rejected']} rejected")


def _decode_pcap(path: str, selection: Any, names: FrameNames, as_json: bool, stats: bool) -> None:
    from ..capture import CaptureError, CaptureFile
    from ..capture.stats import capture_stats
    from ..capture.text import datagram_lines, datagram_records

    capture = CaptureFile(path)
    rejected = shown = 0
    try:
        if stats:
            figures = capture_stats(capture, selection)
            scales = _add_hz(figures)
            if as_json:
                click.echo(json.dumps(figures))
            else:
                _print_stats(figures, scales)
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
@click.option("--pcap", "pcap", type=click.Path(dir_okay=False, allow_dash=True), metavar="FILE",
              help="Decode every datagram of this pcap/pcapng capture ('-': standard input, e.g. from "
                   "'--capture -'): one line each, relative time, addresses, frame.")
@click.option("--station", metavar="ADDR", help="With --pcap: only this station's datagrams and notes (0x21 or 21H).")
@click.option("--command", "commands", multiple=True, metavar="NAME",
              help="With --pcap: only datagrams carrying this main or sub-command (PRM_WR, INV_CTL …); repeatable.")
@click.option("--from", "t_from", metavar="DURATION", help="With --pcap: from this time since the first datagram "
              "(e.g. 2.5s).")
@click.option("--to", "t_to", metavar="DURATION", help="With --pcap: up to this time since the first datagram.")
@click.option("--stats", is_flag=True,
              help="With --pcap: the figures per station and command instead of the datagrams: counts, response "
                   "times (min/p50/p99/max), cycle gaps, lost and late answers, FCS and sequence errors, INV_CTL's "
                   "speed in Hz (docs/capture.md).")
def decode_cmd(hexdata: tuple[str, ...], as_json: bool, frame_size: str | None, cards: tuple[str, ...],
               pcap: str | None, station: str | None, commands: tuple[str, ...], t_from: str | None,
               t_to: str | None, stats: bool) -> None:
    """Decode one datagram given as HEX (spaces and colons allowed), or a capture with --pcap FILE."""
    names = card_names(cards)
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
