"""The second swarm node of ``scripts/swarm-testbed --nodes 2`` (mlink_sim.testbed.swarmnode) and its link's delay
line (mlink_sim.testbed.delayline): the plan is pure and runs everywhere; the link with its delay line runs in a
real network namespace as root (skipped with the reason otherwise – CI runs the suite as root), and leaves
nothing behind."""

from __future__ import annotations

import ipaddress
import os
import socket
import subprocess
import time
from pathlib import Path

import pytest

from mlink_sim.testbed import delayline, swarmnode
from mlink_sim.testbed.delayline import NF_ACCEPT, NF_DROP, DelayLine
from mlink_sim.testbed.netns import list_links, list_netns
from mlink_sim.testbed.swarmnode import LINK_NET, SecondNode

REPO = Path(__file__).resolve().parents[2]


def test_the_node_has_names_and_files_of_its_own(tmp_path):
    node = SecondNode("mlsw42", tmp_path, 200_000)
    argv = node.dockerd_argv()
    assert argv[:3] == ["nsenter", "--net=/run/netns/mlsw42", "--"]  # not ip netns exec: it hides the cgroups
    for flag, value in (("--data-root", f"{tmp_path}/data"), ("--exec-root", f"{tmp_path}/exec"),
                        ("--pidfile", f"{tmp_path}/docker.pid"), ("-H", f"unix://{tmp_path}/docker.sock"),
                        ("--cgroup-parent", "/mlsw42"), ("--containerd-namespace", "mlsw42"),
                        ("--config-file", f"{tmp_path}/daemon.json")):
        assert argv[argv.index(flag) + 1] == value, flag
    assert "--bridge=none" in argv and "--iptables=false" in argv  # the first engine's docker0 and rules untouched
    assert node.docker("info") == ["docker", "-H", f"unix://{tmp_path}/docker.sock", "info"]


def test_the_link_is_a_veth_pair_with_an_address_at_each_end(tmp_path):
    node = SecondNode("mlsw42", tmp_path)
    cmds = node.link_commands()
    assert ["ip", "link", "add", "mlsw42h", "type", "veth", "peer", "name", "eth0", "netns", "mlsw42"] in cmds
    assert ["ip", "addr", "add", f"{node.host_ip}/30", "dev", "mlsw42h"] in cmds
    assert ["ip", "-n", "mlsw42", "addr", "add", f"{node.node_ip}/30", "dev", "eth0"] in cmds
    assert cmds[0] == ["ip", "netns", "add", "mlsw42"]
    host, peer = ipaddress.IPv4Address(node.host_ip), ipaddress.IPv4Address(node.node_ip)
    assert host in LINK_NET and int(host) % 4 == 1 and int(peer) == int(host) + 1  # one /30 of 198.19.0.0/16
    assert SecondNode("mlsw43", tmp_path).host_ip != node.host_ip  # runs side by side: links of their own


def test_the_delay_is_netem_on_both_ends_or_every_packet_through_the_delay_line(tmp_path):
    node = SecondNode("mlsw42", tmp_path, 200_000, 0.01)
    host_end, node_end = node.netem_commands()
    assert host_end == ["tc", "qdisc", "replace", "dev", "mlsw42h", "root", "netem", "delay", "200us", "loss", "1%"]
    assert node_end[:3] == ["nsenter", "--net=/run/netns/mlsw42", "--"]
    assert node_end[-8:] == ["dev", "eth0", "root", "netem", "delay", "200us", "loss", "1%"]
    rules = node.queue_rules()
    assert [r[r.index("-A") + 1] for r in rules] == ["PREROUTING", "POSTROUTING"]  # both ways
    assert all("--queue-bypass" not in r for r in rules)  # no delay line listening: no link, never a fast one
    argv = node.delayline_argv("/py")
    assert argv[argv.index("--delay") + 1] == "200000ns" and argv[argv.index("--loss") + 1] == "1%"


def test_a_prefix_makes_valid_names():
    with pytest.raises(ValueError, match="prefix"):
        SecondNode("Bad-Prefix", Path("/tmp"))
    with pytest.raises(ValueError, match="prefix"):
        SecondNode("mlsw" + "9" * 20, Path("/tmp"))


def test_usage_errors_exit_2(tmp_path, capsys):
    assert swarmnode.main(["up", "--prefix", "mlsw1", "--root", str(tmp_path), "--delay", "soon"]) == 2
    assert "expected a duration" in capsys.readouterr().err
    assert swarmnode.main(["up", "--prefix", "mlsw1", "--root", str(tmp_path), "--loss", "200%"]) == 2
    assert delayline.main(["--delay", "1 parsec"]) == 2


# -- the delay line's order and verdicts, on a fake queue ------------------------------------------------------


class FakeQueue:
    def __init__(self):
        self.incoming: list[int] = []
        self.verdicts: list[tuple[int, int, bool]] = []

    def packet_ids(self):
        ids, self.incoming = self.incoming, []
        return ids

    def verdict(self, packet_id, verdict, *, batch=False):
        self.verdicts.append((packet_id, verdict, batch))


def test_each_packet_is_held_for_the_delay_and_released_in_order():
    q = FakeQueue()
    line = DelayLine(q, delay_ns=200_000)  # type: ignore[arg-type]
    q.incoming = [1, 2]
    line.take(now=1_000_000)
    q.incoming = [3]
    line.take(now=1_100_000)
    line.release(now=1_199_999)
    assert q.verdicts == []  # nothing before its time
    line.release(now=1_200_000)
    assert q.verdicts == [(2, NF_ACCEPT, True)]  # 1 and 2 at once: a batch verdict up to the newest one due
    line.release(now=1_300_000)
    assert q.verdicts[-1] == (3, NF_ACCEPT, True) and line.counters.accepted == 3


def test_loss_drops_a_seeded_share_at_once():
    q = FakeQueue()
    line = DelayLine(q, delay_ns=0, loss=0.25, seed=7)  # type: ignore[arg-type]
    q.incoming = list(range(1, 4001))
    line.take(now=0)
    dropped = [v for v in q.verdicts if v[1] == NF_DROP]
    assert 800 < len(dropped) < 1200 and all(not batch for _, _, batch in dropped)
    again = FakeQueue()
    other = DelayLine(again, delay_ns=0, loss=0.25, seed=7)  # type: ignore[arg-type]
    again.incoming = list(range(1, 4001))
    other.take(now=0)
    assert again.verdicts == q.verdicts  # the same seed, the same packets lost


# -- in a real namespace -----------------------------------------------------------------------------------------


def _unusable() -> str | None:
    if os.geteuid() != 0:
        return "needs root for a network namespace, a veth pair and an NFQUEUE (CI runs the suite as root)"
    for tool in ("ip", "nsenter", "iptables"):
        if subprocess.run(["which", tool], capture_output=True).returncode != 0:
            return f"needs {tool} (iproute2, util-linux, iptables)"
    return None


ECHO = """
import socket
s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
s.bind(("{ip}", 0))
print(s.getsockname()[1], flush=True)
s.settimeout(20)
while True:
    data, peer = s.recvfrom(64)
    if data == b"end":
        break
    s.sendto(data, peer)
"""


def test_the_link_delays_every_datagram_both_ways_and_goes_without_a_trace(tmp_path):
    reason = _unusable()
    if reason:
        pytest.skip(reason)
    node = SecondNode(f"mlsw{os.getpid()}", tmp_path / "node", delay_ns=1_000_000)
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    try:
        link = swarmnode.link_up(node)
        assert link.startswith(("netem", "delay line"))
        echo = subprocess.Popen(node.nsenter("python3", "-c", ECHO.format(ip=node.node_ip)), stdout=subprocess.PIPE,
                                text=True, env=env)  # fmt: skip
        assert echo.stdout is not None
        port = int(echo.stdout.readline())
        s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        s.settimeout(5)
        rtts = []
        for i in range(20):
            t0 = time.monotonic_ns()
            s.sendto(b"%d" % i, (node.node_ip, port))
            assert s.recvfrom(64)[0] == b"%d" % i
            rtts.append(time.monotonic_ns() - t0)
        s.sendto(b"end", (node.node_ip, port))
        echo.wait(timeout=10)
        assert min(rtts) >= 2 * node.delay_ns  # held the delay each way, every datagram
    finally:
        left = swarmnode.stop(node)
    assert left == []
    assert node.netns not in list_netns() and node.veth not in list_links() and not node.root.exists()
