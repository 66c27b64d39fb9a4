"""The ``mlink-sim`` command line (click). Every command exits 0 on success, 1 when a check, an assertion or a
datagram failed, 2 on a usage or configuration error; bad input never produces a traceback."""

from __future__ import annotations

import os
import signal
import sys

import click

from .. import __version__, _accel
from .decode import decode_cmd

__all__ = ["main", "cli", "SHORT_HELP"]


#: One line per command in ``mlink-sim --help`` (click's ``short_help``: whole sentences, never cut).
SHORT_HELP = {
    "up": "Bring a network up (slaves, master, timeline) and check it; exit 0 if every check held.",
    "master": "Run only the master of a network against slaves started elsewhere.",
    "slave": "Serve one station (--card, --station) or the stations of a --config over UDP.",
    "validate": "Check a config without starting anything.",
    "examples": "List the shipped example networks; 'examples copy NAME' copies one to edit.",
    "probe": "Send a NOP to a station; exit 0 only on a valid answer (health checks).",
    "decode": "Decode a datagram given as hex, or every datagram of a capture (--pcap).",
    "replay": "Send a capture's master frames to live slaves and compare their answers, or only send (--no-compare).",
    "watch": "Show a capture's frames live, one line per station and command (a pcapng stream: --capture -).",
    "proxy": "Forward datagrams between a master and slaves through loss, delay and corruption.",
    "control": "Send an operation to a running network, slave or proxy (run, set-param, impair, fault …).",
    "param": "Read or write a station's drive parameter by name, on a running network or slave (get, set).",
    "status": "Print the status of a running network or slave (phase, Hz, current, LEDs, alarms); --watch.",
    "wireshark": "Install or locate the Wireshark dissector of mlink-sim's datagrams.",
    "compose": "Write a docker-compose testbed: one container per station and a master.",
    "report": "Write the HTML report of a finished run from its JSON report and trace.",
    "web": "Serve the live page and HTTP API of a network running with --control.",
}

_EPILOG = """\b
Examples:
  mlink-sim up quickstart
      run the quickstart network and its checks
  mlink-sim examples copy quickstart my-net.toml
      start a network of your own from an example
  mlink-sim slave --card si-t3 --station 21H --listen 127.0.0.1:47001
      one SI-T3 station for a master of your own

'mlink-sim COMMAND --help' says more; docs/README.md is the manual."""


@click.group(context_settings={"help_option_names": ["-h", "--help"], "max_content_width": 110}, epilog=_EPILOG)
@click.version_option(__version__, prog_name="mlink-sim",
                      message=f"%(prog)s, version %(version)s; cores: {_accel.describe()}")
def cli() -> None:
    """mlink-sim – a real-time MECHATROLINK-I/II/III master/slave simulator (SI-T3, SI-ET3, SI-T/V7) over UDP."""


def _add(cmd: click.Command) -> None:
    cmd.short_help = SHORT_HELP.get(cmd.name or "", cmd.short_help)
    cli.add_command(cmd)


_add(decode_cmd)


def _register_optional() -> None:
    # Commands are imported here so that a slow import of one does not slow `mlink-sim decode`.
    from .examples import examples_cmd
    from .network import master_cmd, up_cmd, validate_cmd
    from .probe import probe_cmd
    from .control import control_cmd
    from .proxy import proxy_cmd
    from .remote import param_cmd, status_cmd
    from .replay import replay_cmd
    from .report import report_cmd
    from .slave import slave_cmd
    from .web import web_cmd
    from .watch import watch_cmd
    from .wireshark import wireshark_cmd

    for cmd in (slave_cmd, up_cmd, master_cmd, probe_cmd, validate_cmd, replay_cmd, wireshark_cmd, proxy_cmd,
                control_cmd, param_cmd, status_cmd, examples_cmd, report_cmd, web_cmd, watch_cmd):
        _add(cmd)
    try:
        from .compose import compose_cmd
    except ImportError:  # pragma: no cover
        return
    _add(compose_cmd)


def _terminated(signum: int, frame: object) -> None:
    raise SystemExit(128 + signum)


def main() -> None:
    """Console-script entry point. SIGTERM, and Ctrl-C outside a run, end the command with 143 / 130 and no
    traceback; during a run the commands handle both themselves (an orderly stop, docs/master.md)."""
    # click turns KeyboardInterrupt into "Aborted!" and exit 1: a signal ends the command as SystemExit instead
    signal.signal(signal.SIGINT, _terminated)
    signal.signal(signal.SIGTERM, _terminated)
    _register_optional()
    try:
        cli.main(prog_name="mlink-sim", standalone_mode=True)
    except KeyboardInterrupt:
        sys.exit(130)
    except Exception as exc:  # last line of defence: one line, not a traceback
        if os.environ.get("MLINK_SIM_DEBUG"):
            raise
        click.echo(f"mlink-sim: internal error: {type(exc).__name__}: {exc} (set MLINK_SIM_DEBUG=1 for details)",
                   err=True)
        sys.exit(70)
