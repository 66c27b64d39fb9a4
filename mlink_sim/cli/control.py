"""``mlink-sim control HOST:PORT OP …``: every operation of the table (:data:`mlink_sim.operations.OPERATIONS`) as a
command, built from it: its arguments (a station, a parameter, a spec) as arguments, the others as options
(``run 21H --hz 30 --reverse``), checked by the table before anything is sent; the reply printed as JSON
(docs/control.md). ``mlink-sim param`` and ``mlink-sim status`` print the same operations' replies for a person.
"""

from __future__ import annotations

import json
import sys
from typing import Any

import click

from ..operations import ENDPOINTS, OPERATIONS, Arg, Operation, request_of
from .client import USAGE_KINDS, ask, endpoint, no_answer, usage
from .control_token import control_token as resolve_token
from .control_token import control_token_options
from .params import Seconds

__all__ = ["control_cmd", "ANSWERED_BY"]

#: Who answers, by endpoint, as the command line starts each one.
ANSWERED_BY = {"network": "up/master --control", "slave": "slave --control", "proxy": "proxy --control"}


def _params(op: Operation) -> list[click.Parameter]:
    """The command-line parameters of *op*'s arguments (:attr:`~mlink_sim.operations.Kind.cli` says which form)."""
    out: list[click.Parameter] = []
    for arg in op.args:
        if not arg.cli:
            continue
        kind = arg.kind
        if kind.cli == "argument":
            metavar = kind.metavar + ("|NAME" if arg.name == "station" and _takes_a_name_there(op) else "")
            out.append(click.Argument([arg.python], required=arg.required, metavar=metavar))
        elif kind.cli == "flag":
            out.append(click.Option([arg.option, arg.python], is_flag=True, default=None, help=arg.help))
        elif kind.cli == "switch":  # one flag per choice, the default first: --forward / --reverse
            for choice in kind.choices:
                out.append(click.Option([f"--{choice}", arg.python], flag_value=choice,
                                        default=choice == arg.default or None,
                                        help=f"{arg.help.rstrip('.')}: {choice}." if choice != arg.default else None,
                                        hidden=choice == arg.default))
        else:
            out.append(click.Option([arg.option, arg.python], metavar=kind.metavar,
                                    help=f"{arg.help} ({kind.describe})", default=None))
    return out


def _help(op: Operation) -> str:
    who = ", ".join(ANSWERED_BY[e] for e in ENDPOINTS if e in op.endpoints)
    named = _takes_a_name_there(op)
    args = "\n".join(f"  {a.kind.metavar + ('|NAME' if named else ''):<18} {a.help}"
                     + (" Or the name of an impairment or a fault in force: that one." if named else "")
                     for a in op.args if a.cli and a.kind.cli == "argument")
    cites = f"\n\n({op.cites})" if op.cites else ""
    return f"{op.summary}\n\nAnswered by {who}." + (f"\n\n\b\n{args}" if args else "") + cites


#: The group's options, taken after the operation too (``control HOST:PORT stop 21H --timeout 1s``).
_SHARED = ("timeout", "control_token", "control_token_file")


def _shared_params() -> list[click.Parameter]:
    return [click.Option(["--timeout"], type=Seconds(60.0), default=None, metavar="DURATION",
                         help="As the group's --timeout."),
            click.Option(["--control-token", "control_token"], metavar="TOKEN", default=None,
                         help="As the group's --control-token."),
            click.Option(["--control-token-file", "control_token_file"], metavar="FILE", default=None,
                         type=click.Path(dir_okay=False), help="As the group's --control-token-file.")]


def _command(op: Operation) -> click.Command:
    def callback(**values: Any) -> None:
        ctx = click.get_current_context()
        where, address, timeout, token = ctx.obj
        shared = {name: values.pop(name) for name in _SHARED}
        if shared["timeout"] is not None:
            timeout = shared["timeout"]
        if shared["control_token"] is not None or shared["control_token_file"] is not None:
            token = resolve_token(shared["control_token"], shared["control_token_file"])
        args = {name: value for name, value in values.items() if value is not None}
        if _name_in_station_place(op, args):
            args["name"] = args.pop("station")
        request = usage(request_of(op.name, **args))
        station = _station(op, args)
        reply = ask(where, request, timeout, token, station=station)
        if reply is None:
            no_answer("control", address, timeout)
        assert reply is not None
        click.echo(json.dumps(reply, indent=2))
        if not reply.get("ok"):
            click.echo(f"mlink-sim control: {address} refused {op.name}: {reply.get('error', 'no reason given')}",
                       err=True)
            sys.exit(2 if reply.get("kind") in USAGE_KINDS else 1)

    return click.Command(op.name, callback=callback, params=[*_params(op), *_shared_params()], help=_help(op),
                         short_help=op.summary)


def _takes_a_name_there(op: Operation) -> bool:
    """``heal loss-21H-1``: an operation whose one positional argument is an optional station and which takes a
    ``name`` takes the name in the station's place (a name never reads as a station: mlink_sim.impair.names)."""
    positional = [a for a in op.args if a.cli and a.kind.cli == "argument"]
    return (len(positional) == 1 and positional[0].name == "station" and not positional[0].required
            and any(a.name == "name" for a in op.args))


def _name_in_station_place(op: Operation, args: dict[str, Any]) -> bool:
    """The station argument given is a name (:func:`_takes_a_name_there`)."""
    from ..impair import check_name

    given = args.get("station")
    return (_takes_a_name_there(op) and isinstance(given, str) and "name" not in args
            and check_name(given) is None)


def _station(op: Operation, args: dict[str, Any]) -> int | None:
    """The station a request names (for the probe of a silent address), when it names one."""
    from ..units import parse_address

    arg: Arg | None = next((a for a in op.args if a.name == "station"), None)
    try:
        return None if arg is None or args.get("station") in (None, "all") else parse_address(args["station"])
    except ValueError:
        return None


class _Group(click.Group):
    """The operations in the table's order, under the endpoint that answers them."""

    def list_commands(self, ctx: click.Context) -> list[str]:
        return list(OPERATIONS)

    def format_commands(self, ctx: click.Context, formatter: click.HelpFormatter) -> None:
        for endpoint_name in ENDPOINTS:
            rows = [(op.name, op.summary) for op in OPERATIONS.values() if endpoint_name in op.endpoints]
            with formatter.section(f"Answered by {ANSWERED_BY[endpoint_name]}"):
                formatter.write_dl(rows)


@click.group("control", cls=_Group, short_help="Send an operation to a running network, slave or proxy.")
@click.argument("address", metavar="HOST:PORT")
@click.option("--timeout", default="3s", show_default=True, type=Seconds(60.0),
              help="How long to wait for the answer (the request is sent up to three times, with the same id).")
@control_token_options
@click.pass_context
def control_cmd(ctx: click.Context, address: str, timeout: float, control_token: str | None,
                control_token_file: str | None) -> None:
    """Send the operation OP to the control endpoint at HOST:PORT and print its reply (JSON): a network (mlink-sim
    up/master --control), a standalone slave (slave --control, printed at its start) or the impairing proxy (proxy
    --control). 'mlink-sim control HOST:PORT OP --help' says what OP takes; docs/control.md is the reference.

    \b
      mlink-sim control 127.0.0.1:47100 run 21H --hz 30 --reverse
      mlink-sim control 127.0.0.1:47100 impair all 'loss=10%,for=2s'
      mlink-sim control 127.0.0.1:47100 set-param 22H n019 3.5 --eeprom

    Exit 0 if it was done, 1 if refused or unanswered, 2 for a bad request."""
    ctx.obj = (endpoint(address), address, timeout, resolve_token(control_token, control_token_file))


for _op in OPERATIONS.values():
    control_cmd.add_command(_command(_op))
