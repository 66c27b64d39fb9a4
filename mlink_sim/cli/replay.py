"""``mlink-sim replay FILE --to HOST:PORT``: the capture's master frames against a live slave, answers compared."""

from __future__ import annotations

import sys

import click

__all__ = ["replay_cmd"]


@click.command("replay")
@click.argument("capture_path", metavar="FILE", type=click.Path(dir_okay=False))
@click.option("--to", "target", required=True, metavar="HOST:PORT", help="The live slave to send the frames to.")
@click.option("--station", "stations", multiple=True, metavar="ADDR",
              help="Replay only this station's frames (repeatable); needed when the capture holds several.")
@click.option("--grace", default=0.3, show_default=True, type=click.FloatRange(0.0, 60.0),
              help="Seconds to wait for the last answers.")
@click.option("--max-differences", default=10, show_default=True, type=click.IntRange(1, 10_000),
              help="How many differences to print before stopping the comparison.")
def replay_cmd(capture_path: str, target: str, stations: tuple[str, ...], grace: float, max_differences: int) -> None:
    """Send the master's frames of FILE on their original timing to the slave at HOST:PORT and compare its answers
    with the recorded ones (RWDT and the monitors of a moving drive left out; docs/wire-format.md §10).
    Exit 0 when every answer is equal, 1 with the first differences."""
    from ..capture import CaptureError, read_capture
    from ..capture.replay import MOVING_VOLATILE, VOLATILE, plan_replay, run_replay
    from ..config import parse_address, parse_endpoint

    try:
        host, port = parse_endpoint(target)
        wanted = [parse_address(s) for s in stations] or None
    except ValueError as exc:
        raise click.BadParameter(str(exc)) from None
    if port == 0:
        raise click.BadParameter("the slave's port cannot be 0", param_hint="--to")
    try:
        plan = plan_replay(read_capture(capture_path).datagrams, wanted)
    except (CaptureError, ValueError) as exc:
        click.echo(f"mlink-sim replay: {exc}", err=True)
        sys.exit(2)
    if len(plan.stations) > 1:
        names = ", ".join(f"{s:02X}H" for s in plan.stations)
        click.echo(f"mlink-sim replay: {capture_path} holds stations {names}; one slave answers one station: pick "
                   "it with --station", err=True)
        sys.exit(2)
    span = plan.commands[-1][0] / 1e9
    click.echo(f"replaying {len(plan.commands)} frames of station {plan.stations[0]:02X}H ({span:.1f} s) to "
               f"{host}:{port}", err=True)
    try:
        result = run_replay(plan, (host, port), grace_s=grace, max_differences=max_differences)
    except OSError as exc:
        click.echo(f"mlink-sim replay: {exc.strerror or exc}", err=True)
        sys.exit(2)
    ignored = ", ".join(VOLATILE) + "; while moving: " + ", ".join(MOVING_VOLATILE) + ", ZSP, AGREE"
    if result.ok:
        click.echo(f"{result.sent} frames sent, {result.compared} answers compared, all equal (left out: {ignored})")
        return
    click.echo(f"{result.sent} frames sent, {result.compared} answers compared, {result.equal} equal; "
               f"differences (left out: {ignored}):")
    for line in result.differences:
        click.echo(f"  {line}")
    sys.exit(1)
