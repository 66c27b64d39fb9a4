"""``mlink-sim replay FILE --to HOST:PORT``: the capture's master frames against a live slave, answers compared, or
only sent (``--no-compare``, as python-can's ``can.player``), once or ``--loop``-ed, at least ``--gap`` apart."""

from __future__ import annotations

import sys
from typing import Any

import click

from .params import ADDR, Duration, Seconds

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


def _loops(text: str) -> int:
    """``--loop [N]``: N passes (N >= 1), or 0 (``--loop`` alone, ``forever``): until Ctrl-C."""
    if text.strip().lower() in ("", "0", "forever"):
        return 0
    try:
        n = int(text)
    except ValueError:
        n = -1
    if n < 1:
        raise click.BadParameter(f"expected a number of passes (1 or more) or nothing (until Ctrl-C), got {text!r}",
                                 param_hint="--loop")
    return n


def _report(result: Any, check: bool, strict: bool, interrupted: bool) -> int:
    """Print what was done and compared; the exit status (an interrupted replay ends with its signal's)."""
    from ..capture.replay import scope

    passes = f" in {result.loops} pass(es)" if result.loops != 1 else ""
    cut = " (interrupted)" if interrupted else ""
    if not check:
        click.echo(f"{result.sent} frames sent{passes}{cut}, {result.received} answers received; not compared "
                   "(--no-compare)")
        return 130 if interrupted else 0
    click.echo(scope(strict))
    if result.ok:
        click.echo(f"{result.sent} frames sent{passes}{cut}, {result.compared} answers compared, all equal")
        return 130 if interrupted else 0
    click.echo(f"{result.sent} frames sent{passes}{cut}, {result.compared} answers compared, {result.equal} equal; "
               "differences:")
    for line in result.differences:
        click.echo(f"  {line}")
    for hint in result.hints:
        click.echo(f"hint: {hint}")
    return 130 if interrupted else 1


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
@click.option("--gap", "gap", default=None, type=Duration("ms"), metavar="DURATION",
              help="At least this long between two frames sent (as can.player's --gap), e.g. 5ms; a gap longer "
                   "than the capture's cycle is a reception failure to a slave in phase 3.")
@click.option("--loop", "loop", default=None, is_flag=False, flag_value="forever", metavar="[N]",
              help="Play the capture N times, each pass from its start; --loop alone: until Ctrl-C.")
@click.option("--compare/--no-compare", "check", default=True, show_default=True,
              help="--no-compare: only send the frames (as can.player), reading the answers without judging them; "
                   "exit 0.")
@click.option("--strict", is_flag=True,
              help="Compare the output frequency and the monitors too (they sample the drive model at the instant "
                   "each command arrives, so they differ where the timing does).")
@click.option("--max-differences", default=10, show_default=True, type=click.IntRange(1, 10_000),
              help="How many differences to print before stopping the comparison.")
def replay_cmd(capture_path: str, targets: tuple[str, ...], stations: tuple[int, ...], grace: float,
               speed: float | None, gap: str | None, loop: str | None, check: bool, strict: bool,
               max_differences: int) -> None:
    """Send the master's frames of FILE on their original timing (or --speed, --gap) to the slaves (--to) and
    compare their answers with the recorded ones; it prints what it compares (the RWDT, reception-timing warnings,
    and unless --strict the output frequency and monitors are left out; docs/capture.md), and names the status
    bits that differ with the setting that usually explains them. --no-compare only sends; --loop repeats. Exit 0
    when every answer is equal, 1 with the first differences."""
    from ..capture import CaptureError, read_capture
    from ..capture.replay import Pacing, ReplayResult, plan_replay, run_replay
    from ..units import parse_duration_ns

    default, per_station = _targets(targets)
    loops = 1 if loop is None else _loops(loop)
    gap_ns = 0 if gap is None else parse_duration_ns(gap, default_unit="ms")
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
    if gap_ns:
        pace += f", at least {gap} apart"
    times = "" if loops == 1 else (", until Ctrl-C" if loops == 0 else f", {loops} times")
    click.echo(f"replaying {len(plan.commands)} frames ({span:.1f} s recorded, {pace}{times}): {names}", err=True)
    result = ReplayResult()
    try:
        run_replay(plan, where, pacing=Pacing(speed=speed, gap_ns=gap_ns, grace_s=grace),  # type: ignore[arg-type]
                   max_differences=max_differences, strict=strict, check=check, loops=loops, result=result)
    except OSError as exc:
        click.echo(f"mlink-sim replay: {exc.strerror or exc}", err=True)
        sys.exit(2)
    except SystemExit as exc:  # Ctrl-C / SIGTERM (cli.main's handlers): say what was done, then end as the signal
        if exc.code not in (130, 143):
            raise
        _report(result, check, strict, True)
        sys.exit(exc.code)
    sys.exit(_report(result, check, strict, False))
