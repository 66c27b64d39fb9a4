"""A delay line on a link, for kernels without ``tc netem``: every packet that iptables hands to an NFQUEUE is held
for a fixed delay, then accepted (or dropped, with a seeded probability), in the order it came.

``scripts/swarm-testbed --nodes 2`` puts the second swarm node behind a veth pair and gives the link its delay with
``tc qdisc … netem`` where the kernel has netem. Where it has not (``CONFIG_NET_SCH_NETEM`` off, no modules to
load), this process does the same job from user space: inside the node's network namespace, ::

    iptables -t mangle -A PREROUTING  -i eth0 -j NFQUEUE --queue-num 0     # host -> node
    iptables -t mangle -A POSTROUTING -o eth0 -j NFQUEUE --queue-num 0     # node -> host

send every packet crossing the link, either way, to this queue; the kernel keeps the packet until a verdict
names its id. The delay is constant, so the packets leave in the order they came and a batch verdict (every id up
to the newest one due) releases them. No queue bypass: while no delay line listens, the link carries nothing, so
a run can never pass over a link without its delay.

The netfilter queue is spoken over a netlink socket with the standard library (``AF_NETLINK``,
``NETLINK_NETFILTER``; the messages of ``linux/netfilter/nfnetlink_queue.h``): the Python bindings on PyPI wrap
libnetfilter_queue or need a C build, and the five messages used here are a few structs each.

``python -m mlink_sim.testbed.delayline --delay 200us [--loss 1%] [--seed N] [--queue 0]`` prints ``ready`` once
bound (and how it is scheduled), runs until SIGTERM/SIGINT and then prints one JSON line: packets accepted, dropped, the hold time's
minimum, median and maximum in µs. Needs CAP_NET_ADMIN in the namespace. Exit: 0, 1 when the queue could not be
bound or the socket failed, 2 on a usage error.
"""

from __future__ import annotations

import argparse
import ctypes
import json
import os
import random
import select
import signal
import socket
import struct
import sys
import time
from collections import deque
from dataclasses import dataclass, field

from ..impair.spec import parse_probability
from ..units import parse_duration_ns

__all__ = ["NfQueue", "DelayLine", "Counters", "main"]

NETLINK_NETFILTER = 12
NFNL_SUBSYS_QUEUE = 3
NFQNL_MSG_PACKET, NFQNL_MSG_VERDICT, NFQNL_MSG_CONFIG, NFQNL_MSG_VERDICT_BATCH = 0, 1, 2, 3
NFQA_PACKET_HDR = 1
NFQA_VERDICT_HDR = 2
NFQA_CFG_CMD, NFQA_CFG_PARAMS, NFQA_CFG_QUEUE_MAXLEN = 1, 2, 3
NFQNL_CFG_CMD_BIND, NFQNL_CFG_CMD_UNBIND = 1, 2
NFQNL_COPY_META = 1  #: the packet's metadata only: the delay line never reads a payload
NF_DROP, NF_ACCEPT = 0, 1
NLM_F_REQUEST, NLM_F_ACK = 1, 4
NLMSG_ERROR = 2
NLMSG_HDR = struct.Struct("=IHHII")  #: length, type, flags, sequence, port id (host order)
NFGENMSG = struct.Struct("!BBH")  #: family, version, resource id (the queue number, big-endian)
NLATTR = struct.Struct("=HH")
QUEUE_MAXLEN = 4096
PR_SET_TIMERSLACK = 29
RT_PRIORITY = 50  #: above the master's 40 (aio/timing/realtime.py): the link is not one of the hosts' processes


def _attr(kind: int, payload: bytes) -> bytes:
    body = NLATTR.pack(NLATTR.size + len(payload), kind) + payload
    return body + b"\0" * (-len(body) % 4)


def _attrs(data: bytes) -> dict[int, bytes]:
    out: dict[int, bytes] = {}
    i = 0
    while i + NLATTR.size <= len(data):
        length, kind = NLATTR.unpack_from(data, i)
        if length < NLATTR.size:
            break
        out[kind & 0x7FFF] = data[i + NLATTR.size:i + length]
        i += (length + 3) & ~3
    return out


class NfQueue:
    """One netfilter queue, bound over a netlink socket: packet ids in, verdicts out."""

    def __init__(self, queue: int) -> None:
        self.queue = queue
        self.sock = socket.socket(socket.AF_NETLINK, socket.SOCK_RAW, NETLINK_NETFILTER)
        self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4 << 20)
        self.sock.bind((0, 0))
        self._seq = 0

    def _send(self, msg: int, payload: bytes, flags: int = NLM_F_REQUEST) -> int:
        self._seq += 1
        body = NFGENMSG.pack(socket.AF_UNSPEC, 0, self.queue) + payload
        kind = (NFNL_SUBSYS_QUEUE << 8) | msg
        self.sock.send(NLMSG_HDR.pack(NLMSG_HDR.size + len(body), kind, flags, self._seq, 0) + body)
        return self._seq

    def _ack(self, seq: int) -> None:
        """Wait for the kernel's answer to request *seq*; OSError when it refused it."""
        while True:
            data = self.sock.recv(65536)
            for kind, msg_seq, payload in _messages(data):
                if kind == NLMSG_ERROR and msg_seq == seq:
                    (errno,) = struct.unpack_from("=i", payload)
                    if errno:
                        raise OSError(-errno, os.strerror(-errno))
                    return

    def bind(self, maxlen: int = QUEUE_MAXLEN) -> None:
        self._ack(self._send(NFQNL_MSG_CONFIG, _attr(NFQA_CFG_CMD, struct.pack("!BxH", NFQNL_CFG_CMD_BIND,
                                                                                 socket.AF_INET)),
                             NLM_F_REQUEST | NLM_F_ACK))
        params = _attr(NFQA_CFG_PARAMS, struct.pack("!IB", 0, NFQNL_COPY_META))
        params += _attr(NFQA_CFG_QUEUE_MAXLEN, struct.pack("!I", maxlen))
        self._ack(self._send(NFQNL_MSG_CONFIG, params, NLM_F_REQUEST | NLM_F_ACK))
        self.sock.setblocking(False)

    def unbind(self) -> None:
        self.sock.setblocking(True)
        try:
            self._send(NFQNL_MSG_CONFIG, _attr(NFQA_CFG_CMD, struct.pack("!BxH", NFQNL_CFG_CMD_UNBIND, 0)))
        except OSError:
            pass

    def packet_ids(self) -> list[int]:
        """The ids of the packets queued since the last call (none: an empty list)."""
        ids: list[int] = []
        while True:
            try:
                data = self.sock.recv(1 << 16)
            except BlockingIOError:
                return ids
            for kind, _, payload in _messages(data):
                if kind == (NFNL_SUBSYS_QUEUE << 8) | NFQNL_MSG_PACKET:
                    hdr = _attrs(payload[NFGENMSG.size:]).get(NFQA_PACKET_HDR)
                    if hdr is not None:
                        ids.append(struct.unpack_from("!I", hdr)[0])

    def verdict(self, packet_id: int, verdict: int, *, batch: bool = False) -> None:
        """*verdict* for *packet_id* (with *batch*: for every queued packet up to it)."""
        msg = NFQNL_MSG_VERDICT_BATCH if batch else NFQNL_MSG_VERDICT
        self._send(msg, _attr(NFQA_VERDICT_HDR, struct.pack("!II", verdict, packet_id)))

    def close(self) -> None:
        self.sock.close()


def _messages(data: bytes) -> list[tuple[int, int, bytes]]:
    out = []
    i = 0
    while i + NLMSG_HDR.size <= len(data):
        length, kind, _flags, seq, _pid = NLMSG_HDR.unpack_from(data, i)
        if length < NLMSG_HDR.size:
            break
        out.append((kind, seq, data[i + NLMSG_HDR.size:i + length]))
        i += (length + 3) & ~3
    return out


@dataclass
class Counters:
    accepted: int = 0
    dropped: int = 0
    holds_us: list[float] = field(default_factory=list)  #: a sample of the hold times (every 16th packet)

    def summary(self) -> dict[str, object]:
        holds = sorted(self.holds_us)
        figure = (lambda q: round(holds[min(len(holds) - 1, int(q * len(holds)))], 1)) if holds else (lambda q: None)
        return {"accepted": self.accepted, "dropped": self.dropped, "hold_us_min": figure(0.0),
                "hold_us_p50": figure(0.5), "hold_us_max": figure(1.0)}  # fmt: skip


class DelayLine:
    """Hold each packet of *queue* for *delay_ns*, then accept it; drop it at once with probability *loss*."""

    def __init__(self, queue: NfQueue, delay_ns: int, loss: float = 0.0, seed: int = 0) -> None:
        self.queue = queue
        self.delay_ns = delay_ns
        self.loss = loss
        self.rng = random.Random(seed)
        self.held: deque[tuple[int, int, int]] = deque()  #: (due, packet id, arrival), oldest first
        self.counters = Counters()
        self.stopping = False

    def take(self, now: int) -> None:
        for packet_id in self.queue.packet_ids():
            if self.loss and self.rng.random() < self.loss:
                self.queue.verdict(packet_id, NF_DROP)
                self.counters.dropped += 1
            else:
                self.held.append((now + self.delay_ns, packet_id, now))

    def release(self, now: int) -> None:
        last = None
        while self.held and self.held[0][0] <= now:
            _, last, arrived = self.held.popleft()
            self.counters.accepted += 1
            if self.counters.accepted % 16 == 1:
                self.counters.holds_us.append((now - arrived) / 1e3)
        if last is not None:
            self.queue.verdict(last, NF_ACCEPT, batch=True)

    def run(self) -> None:
        fd = self.queue.sock.fileno()
        while not self.stopping:
            now = time.monotonic_ns()
            timeout = max(0.0, (self.held[0][0] - now) / 1e9) if self.held else 0.5
            readable, _, _ = select.select([fd], [], [], timeout)
            now = time.monotonic_ns()
            if readable:
                self.take(now)
            self.release(now)
        if self.held:  # what is still held goes on its way: a stopped line is a plain link
            self.queue.verdict(self.held[-1][1], NF_ACCEPT, batch=True)
            self.counters.accepted += len(self.held)
            self.held.clear()


def _timely() -> str:
    """Release packets on time: a select() timeout that ends within a microsecond of its time (the default slack
    is 50 µs), and SCHED_FIFO above the master's priority where granted, since a link delivers whatever the hosts
    run. What was granted, for the ready line."""
    try:
        ctypes.CDLL(None, use_errno=True).prctl(PR_SET_TIMERSLACK, 1000, 0, 0, 0)
    except (OSError, AttributeError):  # pragma: no cover - not Linux
        pass
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(RT_PRIORITY))
    except OSError as exc:
        return f"ordinary scheduling (SCHED_FIFO refused: {exc.strerror or exc})"
    return f"SCHED_FIFO {RT_PRIORITY}"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m mlink_sim.testbed.delayline", description=__doc__.split("\n\n")[0])
    parser.add_argument("--delay", default="200us", help="the hold time of every packet (default 200us)")
    parser.add_argument("--loss", default="0%", help="the share of packets dropped (default 0%%)")
    parser.add_argument("--seed", type=int, default=0, help="the seed of the loss (default 0)")
    parser.add_argument("--queue", type=int, default=0, help="the NFQUEUE number (default 0)")
    args = parser.parse_args(argv)
    try:
        delay, loss = parse_duration_ns(args.delay), parse_probability(args.loss, "--loss")
    except ValueError as exc:
        print(f"delayline: {exc}", file=sys.stderr)
        return 2
    if not 0 <= args.queue <= 65535:
        print(f"delayline: --queue is 0…65535, got {args.queue}", file=sys.stderr)
        return 2
    try:
        queue = NfQueue(args.queue)
        queue.bind()
    except OSError as exc:
        print(f"delayline: cannot bind NFQUEUE {args.queue}: {exc.strerror or exc}", file=sys.stderr)
        return 1
    scheduling = _timely()
    line = DelayLine(queue, delay, loss, args.seed)

    def stop(*_: object) -> None:
        line.stopping = True

    signal.signal(signal.SIGTERM, stop)
    signal.signal(signal.SIGINT, stop)
    print(f"ready: {scheduling}", flush=True)
    try:
        line.run()
    except OSError as exc:
        print(f"delayline: the queue's socket failed: {exc.strerror or exc}", file=sys.stderr)
        return 1
    finally:
        queue.unbind()
        queue.close()
    print(json.dumps(line.counters.summary()), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
