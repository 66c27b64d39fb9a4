"""``mlink-health`` (mlink_sim/testbed/health.py), the containers' health check: the NOP it sends is the wire
codec's NOP, the answers it accepts are a card's NOP answers and nothing else, it reports on one line with an
honest exit code, and it loads nothing but builtin modules (what keeps a probe at ~15 ms of CPU)."""

from __future__ import annotations

import re
import socket
import subprocess
import sys
import threading
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from mlink_sim.cards import create_card
from mlink_sim.cards.settings import CardSettings
from mlink_sim.profiles import BUILTIN
from mlink_sim.testbed import health
from mlink_sim.wire import Frame, Kind, Link, decode, encode, ml2, ml3
from mlink_sim.wire.fcs import crc16_x25

HEALTH = Path(health.__file__)
MS = 1_000_000


def _codec_nop(link: Link, size: int, station: int, cycle: int) -> bytes:
    """The NOP command as the wire codec encodes it (a NOP sub-command in the 32- and 64-byte frames), 2 ms cycle."""
    if link is Link.ML3:
        msg: object = ml3.M3Command(ml3.Nop(), sub=ml3.Nop() if size == 64 else None)
    else:
        msg = ml2.M2Command(ml2.Nop(), sub=ml2.Nop() if size == 32 else None)
    return encode(Frame(link, Kind.COMMAND, station, cycle, 2_000_000, msg))  # type: ignore[arg-type]


@pytest.mark.parametrize(("link", "size"), health.ATTEMPTS)
def test_nop_command_is_the_wire_codecs_nop(link, size):
    for station, cycle in ((0x21, 1), (0x03, 0xFFFF_FFFF), (0xEF, 77)):
        datagram = health.nop_command(link, size, station, cycle)
        assert datagram == _codec_nop(Link[link.upper()], size, station, cycle)
        frame = decode(datagram, kind=Kind.COMMAND)
        assert frame.message.code == 0x00 and frame.station == station and frame.cycle == cycle


@given(st.binary(max_size=80))
def test_fcs_is_the_wire_contracts_crc16_x25(data):
    assert health._fcs(data) == crc16_x25(data).to_bytes(2, "little")


def _card(name: str):
    return create_card(name, settings=CardSettings(), now=0)


@pytest.mark.parametrize("name", sorted(p.key for p in BUILTIN))
def test_a_cards_nop_answer_is_accepted_and_nothing_else(name):
    card = _card(name)
    link = card.link.name.lower()
    nop = health.nop_command(link, card.data_size, card.address, 7)
    answer = card.receive(nop, ("127.0.0.1", 40000), 10 * MS)
    assert answer is not None
    assert health.is_nop_answer(answer, link, card.data_size, card.address, 7)
    assert not health.is_nop_answer(answer, link, card.data_size, card.address, 8)  # another cycle's
    assert not health.is_nop_answer(answer, link, card.data_size, card.address + 1, 7)  # another station's
    assert not health.is_nop_answer(nop, link, card.data_size, card.address, 7)  # a command is no answer
    for i in range(len(answer)):  # any byte changed: the FCS (or the envelope) no longer holds
        bad = bytearray(answer)
        bad[i] ^= 0x10
        assert not health.is_nop_answer(bytes(bad), link, card.data_size, card.address, 7), i
    assert not health.is_nop_answer(answer[:-1], link, card.data_size, card.address, 7)


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        ([], "required"),
        (["127.0.0.1:47001"], "required"),
        (["127.0.0.1:47001", "--station"], "needs a value"),
        (["127.0.0.1", "--station", "0x21"], "HOST:PORT"),
        (["127.0.0.1:99999", "--station", "0x21"], "HOST:PORT"),
        (["127.0.0.1:47001", "--station", "zz"], "station address"),
        (["127.0.0.1:47001", "--station", "0x100"], "station address"),
        (["127.0.0.1:47001", "--station", "0x21", "--frame-size", "31"], "--frame-size"),
        (["127.0.0.1:47001", "--station", "0x21", "--link", "ml4"], "--link"),
        (["127.0.0.1:47001", "--station", "0x21", "--link", "ml1", "--frame-size", "64"], "carries"),
        (["127.0.0.1:47001", "--station", "0x21", "--timeout", "0"], "--timeout"),
        (["127.0.0.1:47001", "--station", "0x21", "--timeout", "soon"], "--timeout"),
        (["127.0.0.1:47001", "--station", "0x21", "--verbose"], "unexpected"),
    ],
)
def test_usage_errors_exit_2_with_a_reason(capsys, argv, message):
    assert health.main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith("mlink-health: ") and message in err and "Traceback" not in err


def test_station_addresses_are_read_as_mlink_sim_reads_them():
    for text in ("0x21", "21H", "21h", "33"):
        assert health._parse(["h:1", "--station", text])[2] == 0x21


class _Station(threading.Thread):
    """A card behind a loopback UDP socket (what a station container runs)."""

    def __init__(self, name: str) -> None:
        super().__init__(daemon=True)
        self.card = _card(name)
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", 0))
        self.sock.settimeout(0.05)
        self.port = self.sock.getsockname()[1]
        self.stop = threading.Event()
        self.now = 0

    def run(self) -> None:
        while not self.stop.is_set():
            try:
                data, addr = self.sock.recvfrom(256)
            except TimeoutError:
                continue
            self.now += MS
            out = self.card.receive(data, addr, self.now)
            if out is not None:
                self.sock.sendto(out, addr)

    def __enter__(self) -> _Station:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop.set()
        self.join(5)
        self.sock.close()


@pytest.mark.parametrize("name", sorted(p.key for p in BUILTIN))
def test_probe_over_loopback_finds_the_link_and_size(capsys, name):
    with _Station(name) as server:
        code = health.main([f"127.0.0.1:{server.port}", "--station", f"{server.card.address:#04x}"])
    out = capsys.readouterr().out
    assert code == 0
    assert f"({server.card.link.name.lower()} {server.card.data_size}-byte)" in out


def test_no_answer_and_another_station_exit_1(capsys):
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as silent:  # bound, never answers
        silent.bind(("127.0.0.1", 0))
        port = silent.getsockname()[1]
        assert health.main([f"127.0.0.1:{port}", "--station", "0x21", "--timeout", "0.2"]) == 1
    assert "no valid NOP answer from station 0x21" in capsys.readouterr().err
    with _Station("si-t3") as server:  # a station answers only for its own address
        assert health.main([f"127.0.0.1:{server.port}", "--station", "0x22", "--timeout", "0.3"]) == 1


def test_unresolvable_host_exits_1(capsys):
    assert health.main(["no-such-host.invalid:47001", "--station", "0x21", "--timeout", "0.2"]) == 1
    assert "cannot reach" in capsys.readouterr().err


def test_runs_without_site_and_loads_only_builtin_modules():
    """As the image runs it (python3 -IS): nothing of mlink_sim's dependencies, none of the heavy stdlib modules
    (socket, re, enum, argparse, the idna codec a str host name would pull in through getaddrinfo)."""
    result = subprocess.run([sys.executable, "-IS", "-X", "importtime", str(HEALTH), "localhost:9", "--station",
                             "0x21", "--timeout", "0.1"], capture_output=True, text=True, timeout=30)  # fmt: skip
    assert result.returncode == 1 and "no valid NOP answer" in result.stderr
    loaded = set(re.findall(r"import time:\s+\d+ \|\s+\d+ \|\s+([\w.]+)", result.stderr))
    assert {"_socket", "struct", "binascii"} <= loaded
    heavy = {"mlink_sim", "click", "pydantic", "structlog", "construct", "yaml", "uvloop", "socket", "re", "enum",
             "argparse", "encodings.idna", "asyncio", "typing"}  # fmt: skip
    assert not loaded & heavy
