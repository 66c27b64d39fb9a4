"""A config on the two nodes of ``scripts/swarm-testbed --nodes 2``, and the run's checks that only two nodes have.

* ``place CONFIG OUT --prefix P`` writes the config the stack is made from and prints, as shell assignments, the node label
  and the two node names to label the engines with, and the ``mlink-sim compose`` options that give each node
  its address on the link of the second node *P* (:mod:`.swarmnode`). A config that places nothing gets a ``[deploy]`` of the testbed's:
  the master on ``node-a`` (this host's engine) and every station, a worker of its own, on ``node-b`` (the second
  engine). A config with its own ``[deploy]`` keeps it when it names two nodes, the master's and one other: the
  master's is node A, the other node B, and ``--node-address`` gives each its address here.
* ``probe CONFIG [--node-address NODE=ADDR …]`` sends every station on node B a NOP from this host, at the address the master reaches it at
  (the image's health probe, :mod:`.health`, from the other node): each must answer.
* ``check REPORT CONFIG --delay D`` holds when the RTT median of every station on node B is at least twice the
  link's delay: its datagrams crossed the delayed link both ways.

Exit codes: 0 held, 1 a check failed, 2 a usage error or a config these two nodes cannot run.
"""

from __future__ import annotations

import argparse
import json
import shlex
import sys
import tomllib
from pathlib import Path
from typing import Any

from .._files import write_atomically
from ..config import Config, ConfigError, load_config, resolve_config_path
from ..config.deploy import parse_node_address, with_node_addresses
from ..units import format_ns, parse_duration_ns
from . import health
from .placement import Placement, plan
from .swarmnode import SecondNode

__all__ = ["place", "remote_workers", "far_stations", "rtt_shows_the_link", "NODE_A", "NODE_B", "main"]

NODE_A, NODE_B = "node-a", "node-b"  #: the node label values of this host's engine and the second one


class PlaceError(ValueError):
    """The config cannot run on these two nodes; the message says why."""


def _nodes(config: Config) -> set[str | None]:
    deploy = config.deploy
    served = {a for w in deploy.worker for a in w.stations}
    return ({w.node or deploy.master.node for w in deploy.worker}
            | {st.node or deploy.master.node for st in config.station if st.address not in served})  # fmt: skip


def place(config: Config, text: str, host_ip: str, node_ip: str) -> tuple[str, str, str, str, list[str]]:
    """The config text for the stack, the node label, node A's and node B's label values and the ``mlink-sim
    compose`` options for *config* (read from *text*), node A at *host_ip* and node B at *node_ip*. PlaceError
    when it cannot run on two nodes."""
    deploy = config.deploy
    master = deploy.master.node
    if master is None and not any(w.node for w in deploy.worker) and not any(st.node for st in config.station):
        if "deploy" in tomllib.loads(text):
            raise PlaceError("its [deploy] places nothing: remove it (the testbed writes one: the master on this "
                             "host, every station on the second node) or place the master and the stations")
        lines = [f"\n# written by scripts/swarm-testbed --nodes 2: the master on {NODE_A} (this host), every "
                 f"station on {NODE_B} (the second engine)", "[deploy]",
                 f'nodes = {{ {NODE_A} = "{host_ip}", {NODE_B} = "{node_ip}" }}',
                 f'master = {{ node = "{NODE_A}" }}']  # fmt: skip
        for st in config.station:
            lines += ["", "[[deploy.worker]]", f"stations = [0x{st.address:02X}]", f'node = "{NODE_B}"']
        return text.rstrip("\n") + "\n" + "\n".join(lines) + "\n", deploy.label, NODE_A, NODE_B, []
    others = sorted(n for n in _nodes(config) if n != master and n is not None)
    if len(others) != 1:
        raise PlaceError(f"it places its stations on {len(others)} node(s) besides the master's "
                         f"({', '.join(others) or 'none'}): this testbed has one, the second node")
    assert master is not None  # check_deploy: stations elsewhere need a placed master
    options = ["--node-address", f"{master}={host_ip}", "--node-address", f"{others[0]}={node_ip}"]
    return text, deploy.label, master, others[0], options


def remote_workers(placement: Placement) -> list[list[str]]:
    """The health probe, from the master's node, of every worker on another node."""
    return [w.probe_argv(remote=True) for w in placement.workers if w.node != placement.master_node]


def far_stations(placement: Placement) -> list[str]:
    """The report's keys (``0x21``) of the stations on another node than the master's."""
    return [f"0x{st.address:02x}" for w in placement.workers if w.node != placement.master_node for st in w.stations]


def rtt_shows_the_link(report: dict[str, Any], delay_ns: int, stations: list[str]) -> tuple[bool, str]:
    """Whether the RTT median of every one of *stations* (the report's keys) is at least twice *delay_ns*, and the
    sentence that says so."""
    per = report.get("station")
    medians: dict[str, int] = {}
    for key in stations:
        rtt = per.get(key, {}).get("rtt") if isinstance(per, dict) else None
        p50 = rtt.get("p50") if isinstance(rtt, dict) else None
        if not isinstance(p50, int):
            return False, f"the report has no RTT median of station {key} (station.{key}.rtt.p50)"
        medians[key] = p50
    if not medians:
        return False, "no station runs on another node than the master's"
    figures = ", ".join(f"{k[2:].upper()}H {format_ns(v)}" for k, v in medians.items())
    if min(medians.values()) >= 2 * delay_ns:
        return True, f"RTT p50 {figures}: each at least twice the link's delay ({format_ns(delay_ns)} each way)"
    return False, f"RTT p50 {figures}: not each at least twice the link's delay ({format_ns(delay_ns)} each way)"


def _load(path: str) -> Config:
    try:
        return load_config(path)
    except ConfigError as exc:
        raise PlaceError(str(exc)) from None


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m mlink_sim.testbed.twonodes", description=__doc__.split("\n\n")[0])
    sub = parser.add_subparsers(dest="action", required=True)
    p = sub.add_parser("place", help="the config for the stack, the node labels, the compose options")
    p.add_argument("config")
    p.add_argument("output", type=Path)
    p.add_argument("--prefix", required=True, help="the second node's prefix (its link's addresses)")
    p = sub.add_parser("probe", help="a NOP from this host to every station on the second node")
    p.add_argument("config")
    p.add_argument("--port", type=int, required=True, help="the first station's UDP port")
    p.add_argument("--node-address", action="append", default=[], metavar="NODE=ADDR",
                   help="a node's address in place of the config's (place's options)")
    p = sub.add_parser("check", help="the RTT of every station on the second node shows the link's delay")
    p.add_argument("report", type=Path)
    p.add_argument("config")
    p.add_argument("--delay", required=True)
    args = parser.parse_args(argv)
    try:
        if args.action == "place":
            source = Path(resolve_config_path(args.config)).read_text(encoding="utf-8")
            link = SecondNode(args.prefix, Path("."))
            config = _load(args.config)
            try:
                text, label, node_a, node_b, options = place(config, source, link.host_ip, link.node_ip)
            except PlaceError as exc:
                raise PlaceError(f"{args.config}: {exc}") from None
            write_atomically(args.output, text, mode=0o644)
            print(f"node_label={shlex.quote(label)}\nnode_a={shlex.quote(node_a)}\nnode_b={shlex.quote(node_b)}\n"
                  f"place_args=({shlex.join(options)})")
            return 0
        if args.action == "probe":
            failed = 0
            config = with_node_addresses(_load(args.config), dict(map(parse_node_address, args.node_address)))
            for probe in remote_workers(plan(config, args.port)):
                if health.main(probe[1:]) != 0:
                    print(f"twonodes: no answer to a NOP from this host at {probe[1]}", file=sys.stderr)
                    failed += 1
            return 1 if failed else 0
        delay = parse_duration_ns(args.delay)
        stations = far_stations(plan(_load(args.config)))
        held, sentence = rtt_shows_the_link(json.loads(args.report.read_text(encoding="utf-8")), delay, stations)
        print(f"twonodes: {sentence}", file=sys.stderr)
        return 0 if held else 1
    except (PlaceError, ValueError) as exc:
        print(f"twonodes: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:
        print(f"twonodes: {exc.strerror or exc}: {exc.filename or ''}", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
