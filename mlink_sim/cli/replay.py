"""``mlink-sim replay FILE --to HOST:PORT``: the capture's master frames against a live slave, answers compared."""

from __future__ import annotations

import sys
from typing import Any

import click

from .params import ADDR, Seconds

__all__ = ["replay_cmd"]


class _Speed(click.ParamType):
    """``--speed``: a factor above 0 (1 = the capture's timing, 2 = twice as fast) or ``max``."""

    name = "speed"

    def get_metavar(self, param: Any, ctx: Any = None) -> str:
        return "X|max"

    def convert(self, value: Any, param: Any, ctx: Any) -> float | None:
        if value is None or isinstance(value, float):
            return value
        if str(value).strip().lower() == "max":
            return None
        try:
            speed = float(value)
        except ValueError:
            speed = 0.0
        if not 0 < speed <= 1000:
            self.fail(f"expected a factor above 0 and at most 1000 (1 = the capture's timing) or 'max', "
                      f"got {value!r}", param, ctx)
        return speed


def _targets(texts: tuple[str, ...]) -> tuple[tuple[str, int] | None, dict[int, tuple[str, int]]]:
    """``--to`` values: the one without a station (or None), and the per-station ones."""
    from ..config import parse_address, parse_endpoint

    default: tuple[str, int] | None = None
    per_station: dict[int, tuple[str, int]] = {}
    for text in texts:
        station, sep, where = text.rpartition("=")
        try:
            endpoint = parse_endpoint(where)
            if endpoint[1] == 0:
                raise ValueError(f"the slave's port cannot be 0 in {text!r}")
            if sep:
                per_station[parse_address(station)] = endpoint
            elif default is not None:
                raise ValueError("one --to without a station; give the others as ADDR=HOST:PORT")
            else:
                default = endpoint
        except ValueError as exc:
            raise click.BadParameter(str(exc), param_hint="--to") from None
    return default, per_station


@click.command("replay")
@click.argument("capture_path", metavar="FILE", type=click.Path(dir_okay=False))
@click.option("--to", "targets", required=True, multiple=True, metavar="[ADDR=]HOST:PORT",
              help="The live slave to send the frames to; ADDR=HOST:PORT per station for a capture of several "
                   "(repeatable).")
@click.option("--station", "stations", multiple=True, type=ADDR,
              help="Replay only this station's frames (repeatable).")
@click.option("--grace", default="300ms", show_default=True, type=Seconds(60.0, zero=True),
              help="How long to wait for the last answers.")
@click.option("--speed", default="1", show_default=True, type=_Speed(),
              help="1: the capture's own timing; 2: twice as fast; max: each frame as soon as the answer to the "
                   "one before came. Away from 1 a slave may warn of the reception timing, which is not "
                   "compared.")
@click.option("--strict", is_flag=True,
              help="Compare the output frequency and the monitors too (they sample the drive model at the instant "
                   "each command arrives, so they differ where the timing does).")
@click.option("--max-differences", default=10, show_default=True, type=click.IntRange(1, 10_000),
              help="How many differences to print before stopping the comparison.")
def replay_cmd(capture_path: str, targets: tuple[str, ...], stations: tuple[int, ...], grace: float,
               speed: float | None, strict: bool, max_differences: int) -> None:
    """Send the master's frames of FILE on their original timing (or --speed) to the slaves (--to) and compare
    their answers with the recorded ones; it prints what it compares (the RWDT, reception-timing warnings, and
    unless --strict the output frequency and monitors are left out; docs/capture.md). Exit 0 when every
    answer is equal, 1 with the first differences."""
    from ..capture import CaptureError, read_capture
    from ..capture.replay import plan_replay, run_replay, scope
    default, per_station = _targets(targets)
    wanted = list(stations) or None
    try:
        plan = plan_replay(read_capture(capture_path).datagrams, wanted)
    except (CaptureError, ValueError) as exc:
        click.echo(f"mlink-sim replay: {exc}", err=True)
        sys.exit(2)
    unmapped = [s for s in plan.stations if s not in per_station]
    if len(unmapped) > 1 or (unmapped and default is None):
        names = ", ".join(f"{s:02X}H" for s in unmapped)
        click.echo(f"mlink-sim replay: no slave for station(s) {names} of {capture_path}: one slave answers one "
                   "station; give --to ADDR=HOST:PORT for each, or pick one with --station", err=True)
        sys.exit(2)
    where = {s: per_station.get(s) or default for s in plan.stations}
    span = plan.commands[-1][0] / 1e9
    names = ", ".join(f"{s:02X}H to {h}:{p}" for s, (h, p) in where.items())  # type: ignore[misc]
    pace = "as fast as answers come" if speed is None else f"{span / speed:.1f} s at speed {speed:g}"
    click.echo(f"replaying {len(plan.commands)} frames ({span:.1f} s recorded, {pace}): {names}", err=True)
    try:
        result = run_replay(plan, where, grace_s=grace, max_differences=max_differences,  # type: ignore[arg-type]
                            speed=speed, strict=strict)
    except OSError as exc:
        click.echo(f"mlink-sim replay: {exc.strerror or exc}", err=True)
        sys.exit(2)
    click.echo(scope(strict))
    if result.ok:
        click.echo(f"{result.sent} frames sent, {result.compared} answers compared, all equal")
        return
    click.echo(f"{result.sent} frames sent, {result.compared} answers compared, {result.equal} equal; differences:")
    for line in result.differences:
        click.echo(f"  {line}")
    sys.exit(1)
