"""The second swarm node of ``scripts/swarm-testbed --nodes 2``: a Docker engine in a network namespace of its own,
behind a veth pair whose link has a delay (and a loss) each way.

::

      this host (node A: the first engine, the swarm's manager)        namespace <prefix> (node B)
      <prefix>h 198.19.X.Y+1/30  ─── veth, the link: delay, loss ───  eth0 198.19.X.Y+2/30
                                                                      dockerd -H unix://ROOT/docker.sock

The engine has its own data root, exec root, pid file, socket, containerd namespace and cgroup parent
(``/<prefix>``), no bridge and no iptables rules of its own (every task uses the host's network: the
namespace's), and ``DOCKER_SERVICE_PREFER_OFFLINE_IMAGE=1``, so that a task runs the image loaded into it
(``docker save | docker -H … load``) without asking a registry first. It is started with ``nsenter --net``, not
``ip netns exec``, whose private mount of ``/sys`` would hide the cgroup hierarchy from it.

The addresses are a /30 of 198.19.0.0/16 (RFC 2544 benchmarking, never routed; the network-namespace testbed,
:mod:`.netns`, uses 198.18.0.0/24), chosen by the prefix, so that two runs side by side have links of their own. The link's delay: ``tc qdisc … netem delay D loss L`` on
both ends where the kernel has netem, else the user-space delay line (:mod:`.delayline`) on an NFQUEUE of the
namespace, which holds every packet crossing the link either way. Which of the two carried the run is printed
(``link=``).

``python -m mlink_sim.testbed.swarmnode up --prefix P --root DIR --delay 200us --loss 0%`` builds it all and
prints shell assignments (``node_host=…``); ``down --prefix P --root DIR`` removes it all again – the engine
(stopped, its containers with it), its mounts, files and cgroups, the delay line, the namespace and the veth –
and names on stderr what it could not remove (exit 1). Both are idempotent; ``up`` first removes what runs of
``mlsw<pid>`` whose process is gone left behind. :class:`SecondNode` is pure (names and commands) and tested
without privileges.
"""

from __future__ import annotations

import argparse
import ipaddress
import json
import os
import re
import shlex
import shutil
import subprocess
import sys
import time
import zlib
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from ..impair.spec import parse_probability
from ..units import format_ns, parse_duration_ns
from .netns import list_links, list_netns, pid_alive, stop_pids

__all__ = ["SecondNode", "NodeError", "LINK_NET", "link_up", "start", "stop", "stale", "main"]

LINK_NET = ipaddress.IPv4Network("198.19.0.0/16")  #: the links' /30s (RFC 2544)
PREFIX_LEN = 30
QUEUE = 0  #: the NFQUEUE of the delay line inside the namespace
ENGINE_START_S = 60.0
_PREFIX = re.compile(r"^mlsw(\d+)$")  #: the prefixes scripts/swarm-testbed gives (mlsw<its pid>)
_CGROUP_ROOT = Path("/sys/fs/cgroup")


class NodeError(RuntimeError):
    """Building the node failed; the message says which step and why."""


@dataclass(frozen=True)
class SecondNode:
    """Every name, path and command of the second node."""

    prefix: str  #: names the namespace, the veth's host end (``<prefix>h``) and the cgroup parent
    root: Path  #: the engine's files: data root, exec root, socket, pid file, logs
    delay_ns: int = 200_000  #: the link's delay each way
    loss: float = 0.0  #: the share of packets the link drops each way

    def __post_init__(self) -> None:
        if not re.fullmatch(r"[a-z][a-z0-9]{0,13}", self.prefix):
            raise ValueError(f"prefix: 1–14 lower-case letters and digits, a letter first, got {self.prefix!r}")

    @property
    def netns(self) -> str:
        return self.prefix

    @property
    def host_ip(self) -> str:
        """Node A's end of the link (the host)."""
        return str(LINK_NET[4 * self._block + 1])

    @property
    def node_ip(self) -> str:
        """Node B's end (the namespace)."""
        return str(LINK_NET[4 * self._block + 2])

    @property
    def _block(self) -> int:
        return zlib.crc32(self.prefix.encode()) % (LINK_NET.num_addresses // 4)

    @property
    def veth(self) -> str:
        return f"{self.prefix}h"

    @property
    def socket(self) -> Path:
        return self.root / "docker.sock"

    @property
    def host(self) -> str:
        """``docker -H`` of the node's engine."""
        return f"unix://{self.socket}"

    @property
    def cgroup_parent(self) -> str:
        return f"/{self.prefix}"

    def nsenter(self, *argv: str) -> list[str]:
        return ["nsenter", f"--net=/run/netns/{self.netns}", "--", *argv]

    def link_commands(self) -> list[list[str]]:
        """``ip`` invocations that make the namespace and the link, in order."""
        ns = self.netns
        return [
            ["ip", "netns", "add", ns],
            ["ip", "-n", ns, "link", "set", "lo", "up"],
            ["ip", "link", "add", self.veth, "type", "veth", "peer", "name", "eth0", "netns", ns],
            ["ip", "addr", "add", f"{self.host_ip}/{PREFIX_LEN}", "dev", self.veth],
            ["ip", "link", "set", self.veth, "up"],
            ["ip", "-n", ns, "addr", "add", f"{self.node_ip}/{PREFIX_LEN}", "dev", "eth0"],
            ["ip", "-n", ns, "link", "set", "eth0", "up"],
            ["ip", "-n", ns, "route", "add", "default", "via", self.host_ip],
        ]

    def netem_commands(self) -> list[list[str]]:
        """``tc`` invocations that give both ends of the link its delay and loss."""
        spec = ["netem", "delay", f"{self.delay_ns / 1000:g}us"]
        if self.loss:
            spec += ["loss", f"{self.loss * 100:g}%"]
        return [["tc", "qdisc", "replace", "dev", self.veth, "root", *spec],
                self.nsenter("tc", "qdisc", "replace", "dev", "eth0", "root", *spec)]  # fmt: skip

    def queue_rules(self) -> list[list[str]]:
        """The namespace's iptables rules that hand every packet crossing the link to the delay line."""
        nfq = ["-j", "NFQUEUE", "--queue-num", str(QUEUE)]
        return [self.nsenter("iptables", "-w", "-t", "mangle", "-A", "PREROUTING", "-i", "eth0", *nfq),
                self.nsenter("iptables", "-w", "-t", "mangle", "-A", "POSTROUTING", "-o", "eth0", *nfq)]  # fmt: skip

    def delayline_argv(self, python: str = sys.executable) -> list[str]:
        return self.nsenter(python, "-m", "mlink_sim.testbed.delayline", "--delay", f"{self.delay_ns}ns",
                            "--loss", f"{self.loss * 100:g}%", "--queue", str(QUEUE))  # fmt: skip

    def dockerd_argv(self) -> list[str]:
        r = self.root
        return self.nsenter(
            "dockerd", "--config-file", str(r / "daemon.json"), "--data-root", str(r / "data"),
            "--exec-root", str(r / "exec"), "--pidfile", str(r / "docker.pid"), "-H", self.host,
            "--containerd-namespace", self.prefix, "--containerd-plugins-namespace", f"{self.prefix}p",
            "--cgroup-parent", self.cgroup_parent, "--bridge=none", "--iptables=false", "--ip-masq=false",
            "--userland-proxy=false", "--log-level", "warn",
        )  # fmt: skip

    def docker(self, *argv: str) -> list[str]:
        return ["docker", "-H", self.host, *argv]


# -- running it ----------------------------------------------------------------------------------------------


def _run(argv: list[str], *, check: bool = True, timeout: float = 60) -> subprocess.CompletedProcess[str]:
    result = subprocess.run(argv, capture_output=True, text=True, timeout=timeout)
    if check and result.returncode != 0:
        raise NodeError(f"`{' '.join(argv)}` failed: {result.stderr.strip() or f'exit {result.returncode}'}")
    return result


def _spawn(argv: list[str], log: Path, env: dict[str, str] | None = None) -> int:
    """Start *argv* in a session of its own (a Ctrl-C to the testbed reaches the teardown, not it); its pid."""
    with log.open("ab") as out:
        proc = subprocess.Popen(argv, stdin=subprocess.DEVNULL, stdout=out, stderr=subprocess.STDOUT,
                                start_new_session=True, env=env)  # fmt: skip
    return proc.pid


def _wait_for(what: str, ready: Callable[[], bool], pid: int, log: Path, seconds: float) -> None:
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        if ready():
            return
        if not pid_alive(pid) or _zombie(pid):
            break
        time.sleep(0.2)
    tail = log.read_text(encoding="utf-8", errors="replace").strip().splitlines()[-3:] if log.exists() else []
    raise NodeError(f"{what} did not start within {seconds:.0f} s ({log}): {' | '.join(tail) or 'no output'}")


def _zombie(pid: int) -> bool:
    try:
        return Path(f"/proc/{pid}/stat").read_text().split(")")[-1].split()[0] == "Z"
    except (OSError, IndexError):
        return True


def _delay_link(node: SecondNode, python: str) -> str:
    """Give the link its delay and loss; which way: ``netem``, ``delay line, <its scheduling>`` or ``none``."""
    if not node.delay_ns and not node.loss:
        return "none"
    first, second = node.netem_commands()
    if _run(first, check=False).returncode == 0:
        _run(second)
        return "netem"
    log = node.root / "delayline.out"
    pid = _spawn(node.delayline_argv(python), log)
    (node.root / "delayline.pid").write_text(f"{pid}\n")
    _wait_for("the delay line", lambda: log.read_text().startswith("ready"), pid, log, 20)
    for rule in node.queue_rules():
        _run(rule)
    scheduling = log.read_text().splitlines()[0].partition(": ")[2]
    return f"delay line, {scheduling}" if scheduling else "delay line"


def link_up(node: SecondNode, python: str = sys.executable) -> str:
    """The namespace and the link with its delay (no engine yet); the link's kind (:func:`_delay_link`)."""
    for tool in ("ip", "nsenter"):
        if shutil.which(tool) is None:
            raise NodeError(f"needs {tool} on PATH")
    if node.netns in list_netns():
        raise NodeError(f"a network namespace {node.netns} exists already")
    taken = _run(["ip", "-o", "addr", "show", "to", f"{node.host_ip}/{PREFIX_LEN}"], check=False).stdout.strip()
    if taken:
        raise NodeError(f"the link's addresses {node.host_ip}/{PREFIX_LEN} are in use: {taken.split()[1]}")
    node.root.mkdir(parents=True, exist_ok=True)
    for argv in node.link_commands():
        _run(argv)
    return _delay_link(node, python)


def start(node: SecondNode, python: str = sys.executable) -> str:
    """Build the node: namespace, link, its delay, the engine. The link's kind (:func:`_delay_link`)."""
    for tool in ("dockerd", "docker"):
        if shutil.which(tool) is None:
            raise NodeError(f"needs {tool} on PATH")
    link = link_up(node, python)
    (node.root / "daemon.json").write_text("{}\n")  # not the host's /etc/docker/daemon.json
    log = node.root / "dockerd.log"
    env = {**os.environ, "DOCKER_SERVICE_PREFER_OFFLINE_IMAGE": "1"}
    pid = _spawn(node.dockerd_argv(), log, env)

    def answers() -> bool:
        return _run(node.docker("version", "--format", "{{.Server.Version}}"), check=False, timeout=10).returncode == 0

    _wait_for("the second Docker engine", answers, pid, log, ENGINE_START_S)
    return link


#: the node's own processes, in the order they are stopped: the engine first (it stops its containers, then its
#: containerd), the link's delay line last (the engine's goodbyes cross the link)
_PIDFILES = (("docker.pid", 30.0), ("exec/containerd/containerd.pid", 5.0), ("delayline.pid", 2.0))


def _pid(root: Path, name: str) -> int | None:
    try:
        pid = int((root / name).read_text().split()[0])
    except (OSError, ValueError, IndexError):
        return None
    return pid if pid_alive(pid) else None


def _mounts_under(root: Path) -> list[str]:
    prefix = f"{os.path.realpath(root)}/"
    found = []
    for line in Path("/proc/self/mountinfo").read_text().splitlines():
        point = line.split()[4].replace("\\040", " ")
        if point.startswith(prefix):
            found.append(point)
    return sorted(found, key=len, reverse=True)


def _cgroups(prefix: str) -> list[Path]:
    return [p for p in [_CGROUP_ROOT / prefix, *_CGROUP_ROOT.glob(f"*/{prefix}")] if p.is_dir()]


def _remove_cgroup(top: Path) -> None:
    for dirpath, _dirs, _files in os.walk(top, topdown=False):
        try:
            os.rmdir(dirpath)
        except OSError:
            pass


def stop(node: SecondNode) -> list[str]:
    """Remove everything :func:`start` made (idempotent); what could not be removed."""
    summary = node.root / "delayline.out"
    for name, grace in _PIDFILES:
        pid = _pid(node.root, name)
        if pid is not None:
            stop_pids([pid], grace=grace)
    if node.netns in list_netns():
        stop_pids([int(p) for p in _run(["ip", "netns", "pids", node.netns], check=False).stdout.split()
                   if p.isdigit()])  # fmt: skip
    if summary.exists():
        lines = summary.read_text(encoding="utf-8", errors="replace").strip().splitlines()
        if len(lines) > 1 and lines[-1].startswith("{"):
            figures = json.loads(lines[-1])
            print(f"swarmnode: the delay line held {figures['accepted']} packets for {figures['hold_us_min']}–"
                  f"{figures['hold_us_max']} µs (median {figures['hold_us_p50']} µs), dropped {figures['dropped']}",
                  file=sys.stderr)  # fmt: skip
    for point in _mounts_under(node.root):
        if _run(["umount", point], check=False).returncode != 0:
            _run(["umount", "-l", point], check=False)
    for top in _cgroups(node.prefix):
        _remove_cgroup(top)
    _run(["ip", "netns", "delete", node.netns], check=False)
    if node.veth in list_links():
        _run(["ip", "link", "delete", node.veth], check=False)
    if not _mounts_under(node.root):
        shutil.rmtree(node.root, ignore_errors=True)
    left = [f"process {p}" for p in (_pid(node.root, name) for name, _ in _PIDFILES) if p is not None]
    left += [f"network namespace {node.netns}"] * (node.netns in list_netns())
    left += [f"link {node.veth}"] * (node.veth in list_links())
    left += [f"mount {m}" for m in _mounts_under(node.root)]
    left += [f"cgroup {c}" for c in _cgroups(node.prefix)]
    left += [f"directory {node.root}"] * node.root.exists()
    return left


def stale() -> list[SecondNode]:
    """The nodes of ``mlsw<pid>`` runs whose process is gone (killed before their teardown ran)."""
    found = []
    for ns in list_netns():
        m = _PREFIX.match(ns)
        if not m or pid_alive(int(m.group(1))):
            continue
        root = None
        for pid in _run(["ip", "netns", "pids", ns], check=False).stdout.split():
            try:
                argv = Path(f"/proc/{pid}/cmdline").read_bytes().split(b"\0")
            except OSError:
                continue
            if b"--data-root" in argv:
                root = Path(os.fsdecode(argv[argv.index(b"--data-root") + 1])).parent
        found.append(SecondNode(ns, root or Path("/nonexistent") / ns))
    return found


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m mlink_sim.testbed.swarmnode", description=__doc__.split("\n\n")[0])
    parser.add_argument("action", choices=["up", "down"])
    parser.add_argument("--prefix", required=True, help="the node's names (mlsw<pid>)")
    parser.add_argument("--root", type=Path, required=True, help="the directory of the engine's files")
    parser.add_argument("--delay", default="200us", help="the link's delay each way (default 200us; 0: none)")
    parser.add_argument("--loss", default="0%", help="the share of packets the link drops each way (default 0%%)")
    args = parser.parse_args(argv)
    try:
        delay = parse_duration_ns(args.delay, default_unit="us" if args.delay.strip() == "0" else None)
        node = SecondNode(args.prefix, args.root.absolute(), delay, parse_probability(args.loss, "--loss"))
    except ValueError as exc:
        print(f"swarmnode: {exc}", file=sys.stderr)
        return 2
    if args.action == "down":
        left = stop(node)
        for what in left:
            print(f"swarmnode: could not remove {what}", file=sys.stderr)
        return 1 if left else 0
    for old in stale():
        for what in stop(old):
            print(f"swarmnode: a run that was killed left {what}", file=sys.stderr)
    try:
        link = start(node)
    except (NodeError, OSError, subprocess.TimeoutExpired) as exc:
        print(f"swarmnode: {exc}", file=sys.stderr)
        return 1
    print(f"node_host={node.host}\nnode_ip={node.node_ip}\nhost_ip={node.host_ip}\nlink={shlex.quote(link)}\n"
          f"link_delay={format_ns(node.delay_ns) if node.delay_ns else '0'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
