"""A scripted master over real UDP for end-to-end protocol tests: one command per call, the envelope cycle number and
the WDT count advancing by one each time (docs/cards.md, "Watchdog convention"), a blocking wait for the answer."""

from __future__ import annotations

import json
import socket
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from mlink_sim.wire import Frame, Kind, Link, WireError, decode, encode, ml2, ml3

MS = 1_000_000
#: The longest transmission cycle every card takes (SI-T3 / SI-T/V7 32-byte 1–8 ms, SI-ET3 Table 14 up to 8 ms).
TCYCLE_NS = 8 * MS
#: Station parameters: run and reference from the option (b1-01/b1-02 = 3; V7 n003 = 3, n004 = 9).
RUN = {"si-t3": {"b1-01": 3, "b1-02": 3}, "si-et3": {"b1-01": 3, "b1-02": 3}, "si-t-v7": {"n003": 3, "n004": 9}}
#: The acceleration time register: C1-01 (A1000 MEMOBUS 0200H, SI-T3 Table 8) / n019 (VS-606V7 0113H), and its
#: default in raw units (10.0 s).
ACCEL = {"si-t3": 0x0200, "si-et3": 0x0200, "si-t-v7": 0x0113}
ACCEL_DEFAULT = 100


def write_config(path: Path, card: str, *, silence_tolerance_ms: int = 200) -> Path:
    """A one-station network file for ``mlink-sim slave --config``: 8 ms cycle, run from the option, and a silence
    tolerance that lets a scripted master on a busy machine pause a little (SI-T3 Table 22 counts after it)."""
    params = ", ".join(f'"{k}" = {v}' for k, v in RUN[card].items())
    path.write_text(f"""
[network]
transmission_cycle = "8ms"

[[station]]
address = 0x21
card = "{card}"
params = {{ {params} }}
options = {{ silence_tolerance_ns = {silence_tolerance_ms * MS} }}
""")
    return path


def wait_for(predicate: Callable[[], Any], timeout: float = 5.0) -> bool:
    """Poll *predicate* every 20 ms until it is true (True) or *timeout* seconds pass (False)."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if predicate():
            return True
        time.sleep(0.02)
    return False


def params_saved(state: Path) -> dict:
    """The parameters a slave wrote to its EEPROM image in *state* (empty where it wrote none)."""
    files = list(state.glob("*.eeprom.json"))
    return json.loads(files[0].read_bytes())["params"] if files else {}


def word(value: int) -> bytes:
    return value.to_bytes(2, "little").ljust(8, b"\0")


class UdpMaster:
    """Talks to station 21H of *card* at 127.0.0.1:*port* from its own socket (its source address)."""

    def __init__(self, port: int, card: str) -> None:
        self.addr = ("127.0.0.1", port)
        self.card = card
        self.link = Link.ML3 if card == "si-et3" else Link.ML2
        self.size = 64 if card == "si-et3" else 32
        self.m = ml3 if self.link is Link.ML3 else ml2
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", 0))
        self.cycle = 1000
        self.count = 0
        self.echo = 0

    @property
    def source(self) -> list[Any]:
        return list(self.sock.getsockname())

    def close(self) -> None:
        self.sock.close()

    def datagram(self, body: Any, sub: Any = None) -> bytes:
        self.cycle += 1
        self.count += 1
        wdt = (self.count & 0xF) << 4 | self.echo
        if sub is None:
            sub = self.m.Nop()
        msg = ml3.M3Command(body, wdt, 0, sub) if self.link is Link.ML3 else ml2.M2Command(body, wdt, sub)
        return encode(Frame(self.link, Kind.COMMAND, 0x21, self.cycle, TCYCLE_NS, msg))

    def send(self, body: Any, sub: Any = None, timeout: float = 2.0) -> Frame | None:
        """Send one command; its answer (None if none came within *timeout*)."""
        self.sock.sendto(self.datagram(body, sub), self.addr)
        self.sock.settimeout(timeout)
        while True:
            try:
                data = self.sock.recv(4096)
            except TimeoutError:
                return None
            try:
                frame = decode(data, kind=Kind.RESPONSE)
            except WireError:
                continue
            if frame.cycle == self.cycle:
                self.echo = frame.message.rwdt & 0xF
                return frame

    def connect(self) -> Frame | None:
        """CONNECT, asynchronous (phase 2), sub-commands on."""
        if self.link is Link.ML3:
            return self.send(ml3.Connect(0x30, 0x80, 1, 0x20))
        return self.send(ml2.Connect(0x21, 0x80, 1))

    def run(self, speed: int = 3000) -> Frame | None:
        if self.link is Link.ML3:
            return self.send(ml3.InvCtl(1, 0, speed))
        return self.send(ml2.InvCtl(signals=1, speed_ref=speed))

    def ready(self, frame: Frame, sub: bool = False) -> bool:
        """CMDRDY (SUBCMDRDY with *sub*) of an answer."""
        msg = frame.message
        if self.link is Link.ML3:
            return bool(msg.substat.subcmdrdy if sub else msg.stat.cmdrdy)
        return bool(msg.substatus & 0x04 if sub else msg.status & 0x04)

    def refused(self, frame: Frame) -> bool:
        """The command was not executed: CMD_ALM ≠ 0 (ML-III), or A.94/A.95 in ALARM or, behind a latched alarm
        (SI-T3 Table 21), STATUS.WARNG (ML-II)."""
        msg = frame.message
        if self.link is Link.ML3:
            return msg.stat.cmd_alm != 0
        return msg.alarm in (0x94, 0x95) or bool(msg.status & 0x02)

    def prm_wr(self, reg: int, value: int) -> Frame | None:
        """PRM_WR; on a 32-byte SI-T/V7 as the sub-command (V7 §7.1)."""
        body = self.m.PrmWr(reg, 2, word(value))
        if self.card == "si-t-v7":
            return self.send(self.m.Nop(), body)
        return self.send(body)

    def prm_rd(self, reg: int) -> int:
        body = self.m.PrmRd(reg, 2)
        if self.card == "si-t-v7":
            r = self.send(self.m.Nop(), body)
            assert r is not None
            return int.from_bytes(r.message.sub.parameter[:2], "little")
        r = self.send(body)
        assert r is not None
        return int.from_bytes(r.message.body.parameter[:2], "little")


def control(port: int, op: str = "stats", timeout: float = 2.0) -> dict[str, Any]:
    """Ask the slave's control endpoint (``{"op": "stats"}``)."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.settimeout(timeout)
        s.sendto(json.dumps({"op": op}).encode(), ("127.0.0.1", port))
        return json.loads(s.recv(65536))


def snapshot(port: int) -> dict[str, Any]:
    """Station 21H's snapshot as the control endpoint reports it."""
    return control(port)["stations"]["0x21"]
