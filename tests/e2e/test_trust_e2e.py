"""Who may change a station, what a peer's numbers can do to its counters, and who may steer a run, from outside:
real ``mlink-sim slave`` / ``proxy`` / ``control`` processes on loopback, a scripted master and a stranger over UDP
(docs/cards.md, "Who may change a station"; docs/faults.md, "Who can reach a station")."""

from __future__ import annotations

import json
import socket
from pathlib import Path

import pytest

from .conftest import MLINK, run_cli
from .udp_master import ACCEL, ACCEL_DEFAULT, UdpMaster, control, params_saved, snapshot, wait_for, write_config

pytestmark = pytest.mark.e2e

CARDS = ["si-t3", "si-t-v7", "si-et3"]
FLOOD = 20_000  #: datagrams of the flood, from a few local sockets


def _flood(port: int, stranger: UdpMaster, sockets: int = 4) -> None:
    """FLOOD datagrams at the station from *sockets* sockets: CONNECT, INV_CTL run, NOP and garbage."""
    m = stranger.m
    connect = m.Connect(0x30, 0x80, 1, 0x20) if stranger.link.name == "ML3" else m.Connect(0x21, 0x80, 1)
    payloads = [stranger.datagram(connect), stranger.datagram(m.InvCtl()), stranger.datagram(m.Nop()),
                b"\x4d\x02\x01\x21garbage"]
    socks = [socket.socket(socket.AF_INET, socket.SOCK_DGRAM) for _ in range(sockets)]
    try:
        for i in range(FLOOD):
            socks[i % sockets].sendto(payloads[i % len(payloads)], ("127.0.0.1", port))
    finally:
        for s in socks:
            s.close()


def _stranger_after_the_loss(master: UdpMaster, stranger: UdpMaster, ctl: int, card: str) -> None:
    """The master falls silent until the station is released (bUS), then the stranger sends CONNECT, PRM_WR
    (acceleration 77.7 s) and CONFIG to EEPROM: none is answered."""
    assert wait_for(lambda: snapshot(ctl)["connected_source"] is None, timeout=10.0), \
        "the station never lost its master"
    stranger.cycle += 100
    connect = stranger.m.Connect(0x30, 0x80, 1, 0x20) if card == "si-et3" else stranger.m.Connect(0x21, 0x80, 1)
    assert stranger.send(connect, timeout=0.5) is None
    body = stranger.m.PrmWr(ACCEL[card], 2, (777).to_bytes(2, "little").ljust(8, b"\0"))
    assert stranger.send(body, timeout=0.5) is None
    assert stranger.send(stranger.m.Config(1), timeout=0.5) is None


def _master_gets_its_station_back(master: UdpMaster, ctl: int, card: str, state: Path) -> None:
    """The master CONNECTs again, clears the alarm, reads the old acceleration and runs; nothing was saved."""
    master.cycle += 1000
    assert master.connect() is not None
    assert snapshot(ctl)["connected_source"] == master.source
    assert master.send(master.m.AlmClr(0)) is not None
    assert master.prm_rd(ACCEL[card]) == ACCEL_DEFAULT
    for _ in range(10):
        answer = master.run()
        assert answer is not None and not master.refused(answer)
    assert params_saved(state) == {}


@pytest.mark.parametrize(("card", "rules"), [("si-t3", 1), ("si-t-v7", 2), ("si-et3", 1)])
def test_the_kernel_drops_a_flood_and_a_stranger_s_connect_so_the_station_never_sees_them(
        card: str, rules: int, slave, tmp_path: Path) -> None:
    """``--allow-master 127.0.0.1:PORT`` (the socket connected to the master) or with a second rule (a socket
    filter): a flood from other sockets and, once the master's silence released the station, the stranger's
    CONNECT, PRM_WR, CONFIG to EEPROM and NOP are dropped by the kernel: unanswered, not counted in foreign_source
    or status_queries (the slave never read them), the state dir empty; a socket filter counts them in the
    slave's socket_drops. The master gets the station back with CONNECT and reads the old value."""
    state = tmp_path / "state"
    master = UdpMaster(0, card)
    stranger = UdpMaster(0, card)
    try:
        extra = ["--allow-master", "192.0.2.1"] if rules == 2 else []
        proc = slave("--config", str(write_config(tmp_path / "net.toml", card)), "--state-dir", str(state),
                     "--allow-master", f"127.0.0.1:{master.source[1]}", *extra)
        port, ctl = proc.port, proc.ready["control"]
        master.addr = stranger.addr = ("127.0.0.1", port)
        assert master.connect() is not None and master.run() is not None
        assert snapshot(ctl)["connected_source"] == master.source
        _flood(port, stranger)
        _stranger_after_the_loss(master, stranger, ctl, card)
        assert stranger.send(stranger.m.Nop(), timeout=0.5) is None
        stats = control(ctl)
        counters = stats["stations"]["0x21"]["counters"]
        assert counters["foreign_source"] == 0 and counters["status_queries"] == 0, counters
        assert params_saved(state) == {}
        if rules == 2:
            assert stats["socket_drops"] >= FLOOD + 4
        assert run_cli("probe", f"127.0.0.1:{port}", "--station", "0x21", "--timeout", "1").returncode == 1
        _master_gets_its_station_back(master, ctl, card, state)
    finally:
        master.close()
        stranger.close()


@pytest.mark.parametrize("card", CARDS)
def test_a_status_source_is_answered_read_only_and_its_other_commands_are_counted_and_ignored(
        card: str, slave, tmp_path: Path) -> None:
    """``--allow-status 127.0.0.1`` beside ``--allow-master 127.0.0.1:PORT``: the kernel lets the stranger on
    loopback through and the slave's own check keeps the station: after the flood and the loss its CONNECT, PRM_WR
    and CONFIG to EEPROM are counted in foreign_source and unanswered, nothing reaches the state dir, its NOP and
    ``mlink-sim probe`` are answered read-only; the master gets the station back."""
    state = tmp_path / "state"
    master = UdpMaster(0, card)
    stranger = UdpMaster(0, card)
    try:
        proc = slave("--config", str(write_config(tmp_path / "net.toml", card)), "--state-dir", str(state),
                     "--allow-master", f"127.0.0.1:{master.source[1]}", "--allow-status", "127.0.0.1")
        port, ctl = proc.port, proc.ready["control"]
        master.addr = stranger.addr = ("127.0.0.1", port)
        assert master.connect() is not None and master.run() is not None
        _flood(port, stranger)
        _stranger_after_the_loss(master, stranger, ctl, card)
        assert stranger.send(stranger.m.Nop(), timeout=2.0) is not None  # a status query: read-only
        snap = snapshot(ctl)
        assert snap["connected_source"] is None and params_saved(state) == {}
        assert snap["counters"]["foreign_source"] >= 3 and snap["counters"]["status_queries"] >= 1
        assert run_cli("probe", f"127.0.0.1:{port}", "--station", "0x21", "--timeout", "3").returncode == 0
        _master_gets_its_station_back(master, ctl, card, state)
    finally:
        master.close()
        stranger.close()


def test_allow_status_without_allow_master_is_a_usage_error() -> None:
    r = run_cli("slave", "--card", "si-t3", "--station", "0x21", "--allow-status", "127.0.0.1", timeout=30)
    assert r.returncode == 2 and "--allow-status needs --allow-master" in r.stderr, r.stderr


def test_a_host_name_in_the_allow_list_lets_its_master_connect(slave, tmp_path: Path) -> None:
    """``--allow-master localhost:PORT``: the name is resolved in a worker thread once the slave listens; the
    master's CONNECT binds the station, another socket's does not."""
    master = UdpMaster(0, "si-t3")
    stranger = UdpMaster(0, "si-t3")
    try:
        proc = slave("--card", "si-t3", "--station", "0x21", "--allow-master", f"localhost:{master.source[1]}")
        master.addr = stranger.addr = ("127.0.0.1", proc.port)
        assert stranger.send(stranger.m.Connect(0x21, 0x80, 1), timeout=0.5) is None
        assert any(master.connect() is not None for _ in range(3))
        assert snapshot(proc.ready["control"])["connected_source"] == master.source
    finally:
        master.close()
        stranger.close()


def test_a_slave_without_allow_master_says_it_accepts_any_master(slave) -> None:
    proc = slave("--card", "si-t3", "--station", "0x21")
    proc.stop()
    assert proc.proc.stderr is not None
    lines = [ln for ln in proc.proc.stderr.read().splitlines() if "--allow-master" in ln]
    assert len(lines) == 1 and "any source" in lines[0]


@pytest.mark.parametrize("card", CARDS)
def test_a_cycle_number_ten_to_the_twelve_ahead_adds_one_failure(card: str, slave, tmp_path: Path) -> None:
    """SI-T3 Table 22 / SI-T/V7 Table 7 / SI-ET3 COMM_ALM: a gap counts at most the cycles the elapsed time allows;
    a command 10^12 cycles ahead (its u32 residue in the envelope) is one reception failure, as is a jump of
    2^31 − 1, however little time passed."""
    proc = slave("--config", str(write_config(tmp_path / "net.toml", card)))
    port, ctl = proc.port, proc.ready["control"]
    master = UdpMaster(port, card)
    try:
        assert master.connect() is not None
        for _ in range(3):
            assert master.send(master.m.Nop()) is not None
        before = snapshot(ctl)["counters"]["reception_failures"]
        master.cycle = (master.cycle + 10**12 - 1) & 0xFFFF_FFFF
        assert master.send(master.m.Nop()) is not None
        assert snapshot(ctl)["counters"]["reception_failures"] == before + 1
        master.cycle = (master.cycle + 2**31 - 2) & 0xFFFF_FFFF
        assert master.send(master.m.Nop()) is not None
        counters = snapshot(ctl)["counters"]
        assert counters["reception_failures"] == before + 2 and counters["bus_alarms"] <= 2
    finally:
        master.close()


def test_up_tells_every_worker_its_master_s_address(tmp_path: Path) -> None:
    """``mlink-sim up``: each slave worker takes commands only from its link's master (``--allow-master``), and the
    masters bring every station up through it."""
    run_dir = tmp_path / "run"
    report = tmp_path / "report.json"
    r = run_cli("up", "quickstart", "--duration", "1s", "--no-status", "--workers", "station", "--run-dir",
                str(run_dir), "--report", str(report), timeout=120)
    assert r.returncode in (0, 1), r.stderr  # the timeline is cut short; bring-up is what counts here
    logs = sorted(run_dir.glob("worker-*.log"))
    assert len(logs) == 3
    for path in logs:
        text = path.read_text()
        assert "allow_master" in text and "127.0.0.1:" in text and "foreign_source_ignored" not in text
        assert "no --allow-master" not in text
    doc = json.loads(report.read_text())
    assert "bring-up" not in " ".join(doc.get("problems", []))


def _ask(port: int, request: dict, timeout: float = 0.5) -> dict | None:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.settimeout(timeout)
        s.sendto(json.dumps(request).encode(), ("127.0.0.1", port))
        try:
            return json.loads(s.recv(65536))
        except TimeoutError:
            return None


def test_a_slave_s_control_endpoint_off_loopback_answers_only_requests_with_its_token(slave, tmp_path: Path) -> None:
    """``--control 0.0.0.0:0 --control-token-file FILE``: a stats or fault request without the token, or with
    another, gets no answer and applies nothing (counted in control_refused); with it, the endpoint answers."""
    token = tmp_path / "token"
    token.write_text("s3cret-token\n")
    proc = slave("--card", "si-t3", "--station", "0x21", "--control", "0.0.0.0:0", "--control-token-file", str(token))
    ctl = proc.ready["control"]
    plant = {"op": "fault", "station": 0x21, "do": "load", "torque": 5}
    assert _ask(ctl, {"op": "stats"}) is None
    assert _ask(ctl, {**plant, "token": "wrong"}) is None
    assert _ask(ctl, plant) is None
    assert _ask(ctl, {"op": "release", "station": 0x21, "handle": 1}) is None
    reply = _ask(ctl, {"op": "release", "station": 0x21, "handle": 1, "token": "s3cret-token"}, timeout=2.0)
    assert reply is not None and reply["ok"] is False  # nothing was planted
    stats = _ask(ctl, {"op": "stats", "token": "s3cret-token"}, timeout=2.0)
    assert stats is not None and stats["control_refused"] == 4
    reply = _ask(ctl, {**plant, "token": "s3cret-token"}, timeout=2.0)  # the same request, with the token
    assert reply is not None and reply["ok"] is True, reply


@pytest.mark.parametrize("command", [
    ["slave", "--card", "si-t3", "--station", "0x21", "--control", "0.0.0.0:0"],
    ["up", "quickstart", "--control", "0.0.0.0:0"],
    ["master", "quickstart", "--endpoint", "0x21=127.0.0.1:9", "--endpoint", "0x22=127.0.0.1:9",
     "--endpoint", "0x23=127.0.0.1:9", "--control", "0.0.0.0:0"],
    ["proxy", "--listen", "127.0.0.1:0", "--to", "127.0.0.1:9", "--control", "0.0.0.0:0"],
])
def test_a_control_endpoint_off_loopback_without_a_token_is_a_usage_error(command: list[str]) -> None:
    """Exit 2 and one line, before anything starts."""
    r = run_cli(*command, timeout=30)
    assert r.returncode == 2, r.stderr
    assert r.stderr.strip().splitlines() == [
        "mlink-sim: --control 0.0.0.0:0 is reachable from other hosts: give --control-token or --control-token-file "
        "(or bind 127.0.0.1)"]


def test_mlink_sim_control_sends_the_token_and_the_proxy_answers_nothing_else(tmp_path: Path) -> None:
    import subprocess

    proxy = subprocess.Popen([*MLINK, "proxy", "--listen", "127.0.0.1:0", "--to", "127.0.0.1:9", "--control",
                              "0.0.0.0:0", "--control-token", "tok-123"], stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, text=True)
    try:
        assert proxy.stdout is not None
        ready = ""
        while "ready" not in ready:
            ready = proxy.stdout.readline()
            assert ready, proxy.stderr.read() if proxy.stderr else ""
        port = ready.rsplit(":", 1)[1].strip()
        where = f"127.0.0.1:{port}"
        r = run_cli("control", where, "heal", "--timeout", "1")
        assert r.returncode == 1 and "no answer" in r.stderr
        r = run_cli("control", where, "heal", "--control-token", "nope", "--timeout", "1")
        assert r.returncode == 1
        token = tmp_path / "token"
        token.write_text("tok-123\n")
        r = run_cli("control", where, "heal", "--control-token-file", str(token))
        assert r.returncode == 0 and json.loads(r.stdout)["ok"] is True
    finally:
        proxy.terminate()
        proxy.wait(10)
