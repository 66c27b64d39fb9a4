"""The network-namespace testbed's own firewall rules: frames between its namespaces cross the host's FORWARD chain.

With ``br_netfilter`` loaded (``/proc/sys/net/bridge/bridge-nf-call-iptables`` = 1) the frames a bridge forwards
between its ports go through iptables' FORWARD chain, and a running Docker engine sets that chain's policy to
DROP (it does so when it turns ``net.ipv4.ip_forward`` on). The testbed's bridge then carries nothing and every
station is unreachable. So :class:`~mlink_sim.testbed.netns.Testbed` inserts, for its own bridge only::

    iptables -I FORWARD -i <prefix>br -o <prefix>br -m comment --comment mlink-sim-netns:<prefix> -j ACCEPT

(in and out on the same bridge: traffic between its namespaces, nothing from or to the outside, which the testbed
has no route to anyway) and deletes it with the namespaces. The comment names the run, so a cleanup after a run
that was killed with SIGKILL finds its rule by the prefix alone, and the rules of other testbeds, of Docker and of
the administrator are never touched. Without an ``iptables`` command there is nothing to open and nothing is
done.
"""

from __future__ import annotations

import os
import shutil
import subprocess

__all__ = ["iptables", "rule_spec", "allow_bridge", "remove_rules", "rules_of"]

_COMMENT = "mlink-sim-netns:"


def iptables() -> str | None:
    """The ``iptables`` command, or None when the host has none."""
    return shutil.which("iptables") or next(
        (p for p in ("/usr/sbin/iptables", "/sbin/iptables") if os.access(p, os.X_OK)), None
    )


def rule_spec(bridge: str, prefix: str) -> list[str]:
    """The FORWARD rule (after ``-I``/``-D FORWARD``) that accepts what *bridge* forwards between its ports."""
    return ["-i", bridge, "-o", bridge, "-m", "comment", "--comment", f"{_COMMENT}{prefix}", "-j", "ACCEPT"]


def _run(cmd: list[str]) -> subprocess.CompletedProcess[str]:
    return subprocess.run(cmd, capture_output=True, text=True, timeout=30)


def allow_bridge(bridge: str, prefix: str, ipt: str | None = None) -> str | None:
    """Insert :func:`rule_spec` at the top of FORWARD; an error message if iptables refused it, else None."""
    ipt = ipt or iptables()
    if ipt is None:
        return None
    result = _run([ipt, "-w", "-I", "FORWARD", *rule_spec(bridge, prefix)])
    return None if result.returncode == 0 else f"`iptables -I FORWARD` failed: {result.stderr.strip()}"


def rules_of(prefix: str, ipt: str | None = None) -> list[list[str]]:
    """The FORWARD rules this testbed *prefix* inserted, as ``iptables -S`` lists them (without ``-A FORWARD``)."""
    ipt = ipt or iptables()
    if ipt is None:
        return []
    listing = _run([ipt, "-w", "-S", "FORWARD"])
    tag = f"{_COMMENT}{prefix}"
    found = []
    for line in listing.stdout.splitlines():
        words = line.split()
        if words[:2] == ["-A", "FORWARD"] and tag in (w.strip('"') for w in words):
            found.append([w.strip('"') for w in words[2:]])
    return found


def remove_rules(prefix: str, ipt: str | None = None) -> list[str]:
    """Delete every FORWARD rule of *prefix* (idempotent); a description of each one removed."""
    ipt = ipt or iptables()
    removed: list[str] = []
    if ipt is None:  # no iptables: no rule of ours either (rules_of says so too)
        return removed
    for spec in rules_of(prefix, ipt):
        if _run([ipt, "-w", "-D", "FORWARD", *spec]).returncode == 0:
            removed.append(f"iptables FORWARD rule {_COMMENT}{prefix}")
    return removed
