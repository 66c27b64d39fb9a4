"""Replay: the comparison rules (pure) and a real slave process on loopback (recorded -> 0, modified -> 1)."""

from __future__ import annotations

import dataclasses
import json
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from mlink_sim.capture import CaptureWriter, Datagram, read_capture
from mlink_sim.capture.replay import compare, plan_replay, scope
from mlink_sim.wire import Frame, Kind, Link, M2Alarm, M2Status, decode, encode, ml2, ml3

HERE = Path(__file__).parent
CONFIG = HERE / "one_station.toml"
MLINK = [sys.executable, "-m", "mlink_sim"]


def _rsp(body: object, *, status: int = int(M2Status.CMDRDY), alarm: int = 0, rwdt: int = 1, cycle: int = 5) -> bytes:
    return encode(Frame(Link.ML2, Kind.RESPONSE, 0x21, cycle, 2_000_000,
                        ml2.M2Response(body, alarm=alarm, status=status, rwdt=rwdt)))


def test_equal_answers_and_rwdt_left_out() -> None:
    assert compare(_rsp(ml2.Nop()), _rsp(ml2.Nop())) == []
    assert compare(_rsp(ml2.Nop(), rwdt=1), _rsp(ml2.Nop(), rwdt=9)) == []


def test_a_changed_field_is_reported_by_name() -> None:
    diffs = compare(_rsp(ml2.PrmRdResponse(0x200, 2, b"\x64" + bytes(7))),
                    _rsp(ml2.PrmRdResponse(0x200, 2, b"\x65" + bytes(7))))
    assert diffs == ["main.parameter: recorded '6400000000000000', live '6500000000000000'"]


def test_monitors_left_out_and_speed_bits_while_moving_only() -> None:
    moving = int(M2Status.CMDRDY | M2Status.RUNX)
    a = _rsp(ml2.InvCtlResponse(output_freq=300, mon1=5), status=moving)
    b = _rsp(ml2.InvCtlResponse(output_freq=290, mon1=7), status=moving | int(M2Status.AGREE))
    assert compare(a, b) == []
    rest = int(M2Status.CMDRDY | M2Status.ZSP)
    assert compare(_rsp(ml2.InvCtlResponse(mon1=65503), status=rest),
                   _rsp(ml2.InvCtlResponse(mon1=65505), status=rest)) == []  # a coasting motor after a stop
    agree = int(M2Status.AGREE)
    diffs = compare(_rsp(ml2.InvCtlResponse(), status=rest), _rsp(ml2.InvCtlResponse(), status=rest | agree))
    assert diffs == ["status: recorded 68, live 580 (live only: AGREE)"]  # AGREE at rest is compared, by name
    assert compare(_rsp(ml2.InvCtlResponse(), status=rest), _rsp(ml2.InvCtlResponse(), status=rest | agree),
                   moving=True) == []  # right after a stop it is not


def test_strict_compares_the_output_frequency_and_monitors_too() -> None:
    moving = int(M2Status.CMDRDY | M2Status.RUNX)
    a = _rsp(ml2.InvCtlResponse(output_freq=300, mon1=5), status=moving)
    b = _rsp(ml2.InvCtlResponse(output_freq=290, mon1=5), status=moving)
    assert compare(a, b) == []
    assert compare(a, b, strict=True) == ["main.output_freq: recorded 300, live 290"]
    assert "not compared:" in scope() and scope().endswith("output frequency, monitors – use --strict")
    assert "output frequency, monitors; not compared: RWDT" in scope(strict=True) and "--strict" not in scope(True)


def test_reception_timing_warning_left_out_but_alarms_kept() -> None:
    warn = int(M2Status.CMDRDY | M2Status.WARNG)
    assert compare(_rsp(ml2.Nop()), _rsp(ml2.Nop(), alarm=M2Alarm.COMM_WARNING, status=warn)) == []
    diffs = compare(_rsp(ml2.Nop()), _rsp(ml2.Nop(), alarm=M2Alarm.COMM_ERROR, status=int(M2Status.ALM)))
    assert any(d.startswith("alarm:") for d in diffs)


def test_ml3_comm_alm_warning_left_out() -> None:
    def rsp(stat: ml3.CmdStat) -> bytes:
        return encode(Frame(Link.ML3, Kind.RESPONSE, 0x23, 1, 2_000_000, ml3.M3Response(ml3.Nop(),
                                                                                       cmd_stat=stat.to_int())))

    assert compare(rsp(ml3.CmdStat()), rsp(ml3.CmdStat(d_war=True, comm_alm=2))) == []
    assert compare(rsp(ml3.CmdStat()), rsp(ml3.CmdStat(d_alm=True, comm_alm=9)))
    assert compare(rsp(ml3.CmdStat(d_alm=True, comm_alm=9)), rsp(ml3.CmdStat(d_alm=True, comm_alm=0xA))) == []
    assert compare(rsp(ml3.CmdStat(d_alm=True, comm_alm=9)), rsp(ml3.CmdStat(d_alm=True, comm_alm=0xC)))  # WDT


def test_rejected_answers_compare_by_reason() -> None:
    good = _rsp(ml2.Nop())
    bad = good[:-1] + bytes([good[-1] ^ 1])
    assert compare(bad, bad) == []
    assert compare(good, bad)[0].startswith("frame: recorded valid, live rejected (bad FCS")


def test_plan_picks_the_master_frames_of_a_station() -> None:
    cmd = encode(Frame(Link.ML2, Kind.COMMAND, 0x21, 5, 2_000_000, ml2.M2Command(ml2.Nop())))
    other = encode(Frame(Link.ML2, Kind.COMMAND, 0x22, 5, 2_000_000, ml2.M2Command(ml2.Nop())))
    a, b = ("127.0.0.1", 1), ("127.0.0.1", 2)
    dgs = [Datagram(1000, a, b, cmd), Datagram(2000, b, a, _rsp(ml2.Nop())), Datagram(3000, a, b, other),
           Datagram(4000, a, b, b"junk")]
    plan = plan_replay(dgs, [0x21])
    assert plan.commands == [(0, 0x21, 5, cmd)] and plan.recorded == {(0x21, 5): _rsp(ml2.Nop())}
    assert plan.ends == {0x21: 1000}  # the last datagram of station 21H, from its first command
    assert plan_replay(dgs).ends == {0x21: 1000, 0x22: 2000}  # each station's own end (its master stops on its own)
    assert plan_replay(dgs).stations == [0x21, 0x22]
    with pytest.raises(ValueError, match="no master frames of station"):
        plan_replay(dgs, [0x30])


class _Slave:
    def __init__(self, *extra: str, config: Path = CONFIG, station: int = 0x21) -> None:
        # --host-stalls absorb, as up/master/compose run their slaves (docs/timing.md): a stall of this busy
        # machine up to 50 ms is not taken for the master's silence (bUS) on either side of the comparison
        self.proc = subprocess.Popen([*MLINK, "slave", "--config", str(config), "--only", f"0x{station:02X}",
                                      "--endpoint", f"0x{station:02X}=127.0.0.1:0", "--ready-json", "--control",
                                      "off", "--host-stalls", "absorb", *extra],
                                     stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        assert self.proc.stdout is not None
        line = self.proc.stdout.readline()
        assert line, self.proc.stderr.read() if self.proc.stderr else ""
        self.port = json.loads(line)["stations"][0]["port"]

    def stop(self) -> str:
        self.proc.send_signal(signal.SIGTERM)
        _, err = self.proc.communicate(timeout=20)
        return err


def _modified(src: Path, dst: Path) -> None:
    """*src* with the first CONNECT answer's COM_TIM changed (FCS recomputed)."""
    done = False
    with CaptureWriter(dst, epoch_offset_ns=0) as w:
        for d in read_capture(src).datagrams:
            data = d.data
            if not done and data[2] == Kind.RESPONSE and data[12] == ml2.M2Cmd.CONNECT:
                f = decode(data)
                body = dataclasses.replace(f.message.body, com_tim=f.message.body.com_tim + 1)
                data = encode(dataclasses.replace(f, message=dataclasses.replace(f.message, body=body)))
                done = True
            w.record(d.ts_ns, data, d.src, d.dst)
    assert done


@pytest.mark.e2e
def test_replay_against_a_fresh_slave(tmp_path: Path) -> None:
    recorded = tmp_path / "slave.pcapng"
    slave = _Slave("--capture", str(recorded))
    try:
        run = subprocess.run([*MLINK, "master", str(CONFIG), "--endpoint", f"0x21=127.0.0.1:{slave.port}",
                              "--duration", "2s", "--no-status", "--capture", str(tmp_path / "master.pcapng")],
                             capture_output=True, text=True, timeout=60)
    finally:
        err = slave.stop()
    assert run.returncode == 0, run.stdout + run.stderr
    assert f"capture {recorded}:" in err
    # both ends of one loopback link: what the master sent, the slave received; what the master received, the
    # slave sent (its answers to the last commands may come after the master closed its socket)
    at_slave = read_capture(recorded).datagrams
    at_master = read_capture(tmp_path / "master.pcapng").datagrams
    assert [d.data for d in at_master if d.data[2] == 1] == [d.data for d in at_slave if d.data[2] == 1]
    assert {d.data for d in at_master} <= {d.data for d in at_slave}
    assert {(d.src, d.dst) for d in at_master} == {(d.src, d.dst) for d in at_slave}
    assert any("StateChanged station 21H" in c for d in at_master for c in d.comments)
    comments = [c for d in read_capture(recorded).datagrams for c in d.comments]
    assert "station 21H: phase 1 -> 3" in comments and "station 21H: phase 3 -> 1" in comments
    # the slave names its card, so a decode of its capture names the SI-T3's parameters without --card
    assert "station 21H: card SI-T3 (MECHATROLINK-II, 32-byte), speed in 0.01 Hz counts" in comments
    writes = subprocess.run([*MLINK, "decode", "--pcap", str(recorded), "--command", "PRM_WR"],
                            capture_output=True, text=True, timeout=60)
    assert writes.returncode == 0 and "PRM_WR(02H) C1-02 (0201H) = " in writes.stdout, writes.stdout + writes.stderr

    ok = _replay_against_fresh_slave(recorded)
    assert ok.returncode == 0, ok.stdout + ok.stderr
    assert "all equal" in ok.stdout and "not compared: RWDT" in ok.stdout and "use --strict" in ok.stdout
    fast = _replay_against_fresh_slave(recorded, "--speed", "max")
    assert fast.returncode == 0, fast.stdout + fast.stderr
    assert "all equal" in fast.stdout and "as fast as answers come" in fast.stderr

    changed = tmp_path / "changed.pcapng"
    _modified(recorded, changed)
    bad = _replay_against_fresh_slave(changed)
    assert bad.returncode == 1, bad.stdout + bad.stderr
    assert "CONNECT" in bad.stdout and "main.com_tim: recorded 2, live 1" in bad.stdout


def _replay_against_fresh_slave(capture: Path, *extra: str) -> subprocess.CompletedProcess[str]:
    fresh = _Slave()
    try:
        return subprocess.run([*MLINK, "replay", str(capture), "--to", f"127.0.0.1:{fresh.port}", *extra],
                              capture_output=True, text=True, timeout=60)
    finally:
        fresh.stop()


def test_replay_usage_errors(tmp_path: Path) -> None:
    from click.testing import CliRunner

    from mlink_sim.cli.replay import replay_cmd

    assert CliRunner().invoke(replay_cmd, [str(tmp_path / "none.pcapng"), "--to", "127.0.0.1:1"]).exit_code == 2
    two = tmp_path / "two.pcapng"
    with CaptureWriter(two) as w:
        for station in (0x21, 0x22):
            w.record(0, encode(Frame(Link.ML2, Kind.COMMAND, station, 1, 2_000_000, ml2.M2Command(ml2.Nop()))),
                     ("127.0.0.1", 1), ("127.0.0.1", 2))
    result = CliRunner().invoke(replay_cmd, [str(two), "--to", "127.0.0.1:9"])
    assert result.exit_code == 2 and "no slave for station(s) 21H, 22H" in result.output
    assert CliRunner().invoke(replay_cmd, [str(two), "--to", "nonsense"]).exit_code == 2
    both = CliRunner().invoke(replay_cmd, [str(two), "--to", "127.0.0.1:9", "--to", "127.0.0.1:10"])
    assert both.exit_code == 2 and "one --to without a station" in both.output
    for speed in ("0", "fast", "-1"):
        bad = CliRunner().invoke(replay_cmd, [str(two), "--to", "127.0.0.1:9", "--speed", speed])
        assert bad.exit_code == 2 and "or 'max'" in bad.output
    one = CliRunner().invoke(replay_cmd, [str(two), "--to", "127.0.0.1:9", "--to", "0x22=127.0.0.1:0"])
    assert one.exit_code == 2 and "port cannot be 0" in one.output


@pytest.mark.e2e
def test_replay_of_an_up_capture_against_three_cards(tmp_path: Path) -> None:
    """The quickstart (SI-T3, SI-T/V7, SI-ET3) recorded by ``up``, replayed station by station to fresh slaves."""
    quickstart = HERE.parents[1] / "configs" / "quickstart.toml"
    recorded = tmp_path / "up.pcapng"
    run = subprocess.run([*MLINK, "up", str(quickstart), "--duration", "2s", "--no-status", "--capture", str(recorded)],
                         capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stdout + run.stderr
    slaves = [_Slave(config=quickstart, station=s) for s in (0x21, 0x22, 0x23)]
    try:
        result = subprocess.run([*MLINK, "replay", str(recorded),
                                 *(f"--to=0x{s:02X}=127.0.0.1:{sl.port}" for s, sl in zip((0x21, 0x22, 0x23), slaves))],
                                capture_output=True, text=True, timeout=120)
    finally:
        for slave in slaves:
            slave.stop()
    assert result.returncode == 0, result.stdout + result.stderr
    assert "all equal" in result.stdout
