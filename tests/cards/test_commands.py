"""The commands: PRM_RD/PRM_WR (SI-T3 Tables 8/9, SI-ET3 PRM_RD/PRM_WR, SI-T/V7 §7.1), CONFIG (Tables 12/15),
ID_RD (SI-T3 Tables 10/11, SI-ET3 Table 14), ALM_RD (SI-T3 Tables 13/14, SI-ET3 Tables 16/17), DISCONNECT,
INV_CTL (SI-T3 Tables 16–18, SI-ET3 Tables 20–22, SI-T/V7 Tables 3–5) and INV_I/O."""

from __future__ import annotations

import pytest

from mlink_sim.cards import CardOptions
from mlink_sim.wire import CmdAlm, InvCmdStat, M2Alarm, M2Status, M2SubStatus, SubCmdAlm, ml2, ml3

from .helpers import MS, Master, alarm, cmd_alm, station, sub_alm

A = ("b1-01=3", "b1-02=3")


def _word(v: int, size: int = 2) -> bytes:
    return v.to_bytes(size, "little").ljust(8, b"\0")


def _up(card: str, *params: str, **kw: object) -> Master:
    m = Master(station(card, params=params, **kw))  # type: ignore[arg-type]
    m.connect()
    return m


# -- PRM_RD / PRM_WR / CONFIG -------------------------------------------------------------------------
def test_si_t3_table_8_prm_rd_c1_01() -> None:
    """Table 8: bytes 5–6 NO = 0200H, 7 SIZE = 2; response PARAMETER = C1-01, LSB first (default 10.0 s)."""
    m = Master(station("si-t3"))
    r = m.send(ml2.PrmRd(0x0200, 2))  # "This command can be used in all phases"
    assert r.message.body == ml2.PrmRdResponse(0x0200, 2, _word(100))
    assert r.message.status == M2Status.CMDRDY  # "only the settings for the STATUS (CMDRDY) is valid"


@pytest.mark.parametrize("size", [0, 1, 3, 5, 7, 9, 10])
def test_si_t3_table_8_prm_rd_size_a94(size: int) -> None:
    m = Master(station("si-t3"))
    r = m.send(ml2.PrmRd(0x0200, size))
    assert alarm(r) == M2Alarm.DATA_SETTING_WARNING and r.message.body.parameter == bytes(8)


def test_si_t3_table_8_prm_rd_8_bytes_and_unknown_register() -> None:
    m = Master(station("si-t3"))
    r = m.send(ml2.PrmRd(0x0200, 8))  # C1-01 … C1-04
    assert r.message.body.parameter == bytes.fromhex("6400640064006400")
    assert alarm(m.send(ml2.PrmRd(0x0001, 2))) == M2Alarm.DATA_SETTING_WARNING
    assert alarm(m.send(ml2.PrmRd(0x0209, 4))) == M2Alarm.DATA_SETTING_WARNING  # 020AH does not exist


def test_si_t3_table_9_prm_wr_then_config() -> None:
    """Table 9 and Table 12: PRM_WR is pending until CONFIG; PRM_RD reads the written value already."""
    m = _up("si-t3", *A)
    r = m.send(ml2.PrmWr(0x0200, 2, _word(50)))
    assert alarm(r) == 0 and r.message.body == ml2.PrmWr(0x0200, 2, _word(50))
    assert m.st.store.active["C1-01"] == 100 and m.st.store.value("C1-01") == 50
    assert m.send(ml2.PrmRd(0x0200, 2)).message.body.parameter == _word(50)
    assert m.st.drive.settings.accel_s == pytest.approx(10.0)
    assert alarm(m.send(ml2.Config(0))) == 0
    assert m.st.store.active["C1-01"] == 50 and m.st.drive.settings.accel_s == pytest.approx(5.0)
    assert m.st.take_eeprom() is None  # CONFIG_MOD 0: RAM only


@pytest.mark.parametrize("card", ["si-t3", "si-et3"])
def test_prm_wr_out_of_range_and_read_only(card: str) -> None:
    m = _up(card)
    msgs = ml3 if card == "si-et3" else ml2
    r1 = m.send(msgs.PrmWr(0x0200, 2, _word(60001)))  # C1-01 max 6000.0 s
    r2 = m.send(msgs.PrmWr(0x0040, 2, _word(1)))  # U1-01: a monitor
    r3 = m.send(msgs.PrmWr(0x0200, 4, ((60001 << 16) | 50).to_bytes(4, "little").ljust(8, b"\0")))  # all or none
    for r in (r1, r2, r3):
        if card == "si-et3":
            assert cmd_alm(r) == CmdAlm.INVALID_DATA
        else:
            assert alarm(r) == M2Alarm.DATA_SETTING_WARNING
    assert m.st.store.value("C1-01") == 100


def test_si_t3_prm_wr_phase_1_a95() -> None:
    m = Master(station("si-t3"))
    assert alarm(m.send(ml2.PrmWr(0x0200, 2, _word(50)))) == M2Alarm.COMMAND_WARNING


def test_si_et3_prm_rd_c1_01_and_config() -> None:
    m = _up("si-et3")
    r = m.send(ml3.PrmRd(0x0200, 2))
    assert r.message.body == ml3.PrmRdResponse(0x0200, 2, _word(100)) and cmd_alm(r) == 0
    r = m.send(ml3.PrmRd(0x0200, 5))
    assert cmd_alm(r) == CmdAlm.INVALID_DATA and r.message.body.parameter == bytes(8)  # "0 is stored"
    m.send(ml3.PrmWr(0x0201, 2, _word(30)))
    assert m.st.store.active["C1-02"] == 100
    m.send(ml3.Config(1))
    assert m.st.store.active["C1-02"] == 30
    assert m.st.take_eeprom() is not None
    assert cmd_alm(m.send(ml3.Config(2))) == CmdAlm.INVALID_DATA


def test_prm_rd_monitor_u1_and_fault_history_registers() -> None:
    m = _up("si-t3", *A)
    for _ in range(100):
        m.send(ml2.InvCtl(signals=1, speed_ref=3000))
    r = m.send(ml2.PrmRd(0x0040, 2))  # U1-01 frequency reference, o1-03 units (0.01 Hz)
    assert r.message.body.parameter == _word(3000)
    m.send(ml2.InvCtl(signals=0x0100))  # EF0
    r = m.send(ml2.PrmRd(0x0080, 2))  # U2-01 current fault
    assert r.message.body.parameter == _word(0x27)
    r = m.send(ml2.PrmRd(0x0090, 2))  # U3-01 most recent fault
    assert r.message.body.parameter == _word(0x27)


def test_v7_prm_rd_prm_wr_only_as_sub_commands_in_32_byte_mode() -> None:
    """SI-T/V7: "If received as a main command in 32-byte mode: Command alarm (A.95)"; PRM_WR takes effect at
    once (CONFIG_MOD 0 "Not required")."""
    m = _up("si-t-v7")
    n019 = 0x0113
    assert alarm(m.send(ml2.PrmRd(n019, 2))) == M2Alarm.COMMAND_WARNING
    assert alarm(m.send(ml2.PrmWr(n019, 2, _word(50)))) == M2Alarm.COMMAND_WARNING
    r = m.send(ml2.InvCtl(), ml2.PrmWr(n019, 2, _word(50)))
    assert alarm(r) == 0 and r.message.substatus == M2SubStatus.SUBCMDRDY
    assert m.st.store.active["n019"] == 50 and m.st.drive.settings.accel_s == pytest.approx(5.0)
    r = m.send(ml2.InvCtl(), ml2.PrmRd(n019, 2))
    assert r.message.sub.parameter == _word(50)
    m17 = _up("si-t-v7", frame_size=17)
    assert m17.send(ml2.PrmRd(n019, 2)).message.body.parameter == _word(100)
    mo = _up("si-t-v7", options=CardOptions(v7_prm_main_in_32byte=True))
    assert alarm(mo.send(ml2.PrmRd(n019, 2))) == 0


# -- ID_RD ----------------------------------------------------------------------------------------------
def _id(m: Master, code: int, offset: int, size: int) -> tuple[bytes, int]:
    r = m.send(ml2.IdRd(code, offset, size))
    return r.message.body.id, alarm(r)


def test_si_t3_table_10_id_rd_device_codes() -> None:
    m = Master(station("si-t3"))
    model = _id(m, 0x00, 0, 8)[0] + _id(m, 0x00, 8, 8)[0]
    assert model.startswith(b"CIMR-A") and model.rstrip(b"\0").endswith(b"0000")
    version = _id(m, 0x02, 0, 8)[0] + _id(m, 0x02, 8, 8)[0]
    assert version[0:1] == b"S" and version[5:6] == b"S" and version[10] == 0
    assert _id(m, 0x00, 2, 3) == (b"MR-" + bytes(5), 0)
    assert _id(m, 0x00, 0, 9)[1] == M2Alarm.DATA_SETTING_WARNING  # "no more than eight bytes"
    assert _id(m, 0x05, 0, 8)[1] == M2Alarm.DATA_SETTING_WARNING
    assert _id(m, 0x00, 16, 1)[1] == M2Alarm.DATA_SETTING_WARNING


def test_si_t3_table_11_vendor() -> None:
    m = Master(station("si-t3"))
    data = b"".join(_id(m, 0x0F, off, 8)[0] for off in range(0, 0x30, 8))
    assert data[0:9] == b"08100000\0"
    assert data[0x10:0x20] == b"YASKAWA ELECTRIC" and data[0x20:0x2C] == b"CORPORATION\0"


def test_v7_id_rd() -> None:
    m = Master(station("si-t-v7"))
    model = _id(m, 0x00, 0, 8)[0] + _id(m, 0x00, 8, 8)[0]
    assert model.rstrip(b"\0") == b"CIMR-V7 21P5"
    assert _id(m, 0x0F, 0, 8)[1] == M2Alarm.DATA_SETTING_WARNING


@pytest.mark.parametrize(
    "code, value",
    [(0x01, 0), (0x02, 0x04000001), (0x05, 1), (0x10, 0x20), (0x11, 0x0100), (0x12, 0xFF), (0x16, 25000),
     (0x17, 800000), (0x18, 3), (0x19, 25000), (0x1A, 3200000), (0x1B, 0x14), (0x1C, 0x10), (0x1D, 0x20),
     (0x20, 3), (0x48, 0), (0x49, 0), (0x4A, 0)],
)
def test_si_et3_table_14_id_code(code: int, value: int) -> None:
    m = _up("si-et3")
    r = m.send(ml3.IdRd(code, 0, 4))
    assert cmd_alm(r) == 0 and r.message.body.id[:4] == value.to_bytes(4, "little")


def test_si_et3_table_14_command_lists_and_errors() -> None:
    m = _up("si-et3")
    r = m.send(ml3.IdRd(0x30, 0, 24))
    bits = int.from_bytes(r.message.body.id, "little")
    assert all(bits >> c & 1 for c in (0x00, 0x01, 0x02, 0x03, 0x04, 0x05, 0x06, 0x0D, 0x0E, 0x0F))
    r = m.send(ml3.IdRd(0x30, 8, 24))
    assert r.message.body.id[2] == 0x01  # 50H: byte 10 bit 0
    r = m.send(ml3.IdRd(0x38, 0, 24))
    assert r.message.body.id[0] == 0b0010_0111 and r.message.body.id[10] == 0x02  # 00,01,02,05 / 51H
    assert cmd_alm(m.send(ml3.IdRd(0x99, 0, 4))) == CmdAlm.INVALID_DATA
    assert cmd_alm(m.send(ml3.IdRd(0x02, 4, 4))) == CmdAlm.INVALID_DATA
    assert cmd_alm(m.send(ml3.IdRd(0x02, 0, 25))) == CmdAlm.INVALID_DATA


# -- ALM_RD ---------------------------------------------------------------------------------------------
def _faults(m: Master, n: int) -> None:
    """n EF0 faults, each reset."""
    for _ in range(n):
        m.send(ml2.InvCtl(signals=0x0100) if not m.ml3 else ml3.InvCtl(invcmd_ctrl=0x0400))
        m.send(ml2.InvCtl(signals=0x0200) if not m.ml3 else ml3.InvCtl(invcmd_ctrl=0x0200))
        m.send(ml2.InvCtl() if not m.ml3 else ml3.InvCtl())


def test_si_t3_table_13_14_alm_rd_modes() -> None:
    m = _up("si-t3")
    r = m.send(ml2.AlmRd(0))
    assert r.message.body.alm_data == bytes(10)  # "During normal operation ... the value is 00H"
    _faults(m, 2)
    assert alarm(m.send(ml2.AlmRd(2, 10))) == M2Alarm.DATA_SETTING_WARNING
    assert alarm(m.send(ml2.AlmRd(3))) == M2Alarm.DATA_SETTING_WARNING
    m.send(ml2.InvCtl(signals=0x0100))  # a third one stays active
    r = m.send(ml2.AlmRd(0))
    assert r.message.body.alm_data[:2] == bytes((0x27, 0x27))  # U2-01 present, U2-02 previous
    r = m.send(ml2.AlmRd(1))
    assert r.message.body.alm_data == bytes((0x27, 0x27, 0x27)) + bytes(7)  # U3-01 …
    r = m.send(ml2.AlmRd(2, 1))
    assert r.message.body.alm_data[:3] == bytes((1, 0x27, 0))  # index, U3-(index+1) LSB, MSB
    r = m.send(ml2.AlmRd(2, 5))
    assert r.message.body.alm_data[:3] == bytes((5, 0, 0))
    r = m.send(ml2.AlmRd(3))
    assert alarm(r) == 0x27 and r.message.status & M2Status.WARNG  # the alarm has priority (Table 21)
    r = m.send(ml2.InvCtl(signals=0x0100), ml2.AlmRd(1))  # sub-command
    assert r.message.sub.alm_data[:3] == bytes((0x27, 0x27, 0x27))


def test_v7_alm_rd_modes_0_and_1() -> None:
    m = _up("si-t-v7")
    _faults(m, 3)
    r = m.send(ml2.AlmRd(1))
    assert r.message.body.alm_data == bytes((0x27, 0x27)) + bytes(8)  # two entries (n178)
    assert alarm(m.send(ml2.AlmRd(2))) == M2Alarm.DATA_SETTING_WARNING


def test_si_et3_table_16_17_alm_rd() -> None:
    m = _up("si-et3")
    _faults(m, 2)
    r = m.send(ml3.AlmRd(0, 0))
    assert r.message.body.alm_data[:4] == bytes((0, 0, 0x27, 0))  # U2-01 (none now), U2-02
    r = m.send(ml3.AlmRd(1, 0))
    assert r.message.body.alm_data[:6] == bytes((0x27, 0, 0x27, 0, 0, 0))
    r = m.send(ml3.AlmRd(2, 2))
    assert r.message.body == ml3.AlmRdResponse(2, 2, bytes((0x27, 0)) + bytes(18))  # U3-(ALM_INDEX)
    assert cmd_alm(m.send(ml3.AlmRd(2, 11))) == CmdAlm.INVALID_DATA
    r = m.send(ml3.Nop(), ml3.AlmRd(1, 0))
    assert sub_alm(r) == 0 and r.message.sub.alm_data[:2] == bytes((0x27, 0))


# -- DISCONNECT -----------------------------------------------------------------------------------------
def test_disconnect_clears_control_and_resets_faults() -> None:
    m = _up("si-t3", *A)
    for _ in range(50):
        m.send(ml2.InvCtl(signals=1, speed_ref=3000))
    m.send(ml2.InvCtl(signals=1 | 0x0100, speed_ref=3000))
    m.send(ml2.InvCtl(signals=1, speed_ref=3000))  # EF0 input gone, fault stays, RUN still on
    assert m.st.snapshot().drive.fault == "EF0"
    m.send(ml2.Disconnect())
    snap = m.st.snapshot()
    assert snap.phase == 1 and snap.drive.fault is None and snap.connected_source is None
    m.st.poll(m.now + 100 * MS)
    assert not m.st.snapshot().drive.running


# -- INV_CTL --------------------------------------------------------------------------------------------
def test_bring_up_forward_30_hz_ramps() -> None:
    """CONNECT -> SYNC_SET -> INV_CTL forward at 30 Hz; the output frequency ramps with time (C1-01 = 2 s
    to E1-04 = 60 Hz)."""
    m = Master(station("si-t3", params=(*A, "C1-01=2.0")))
    m.bring_up()
    outs = []
    for i in range(3000):
        r = m.send(ml2.InvCtl(signals=0x0001, speed_ref=3000))
        if i % 500 == 499:
            outs.append(r.message.body.output_freq)
    assert outs == sorted(outs) and outs[0] > 0 and outs[-1] == 3000
    st = r.message.status
    assert st & M2Status.RUNX and st & M2Status.REMOTE and st & M2Status.AGREE and not st & M2Status.REV
    assert r.message.body.output_current > 0


def test_si_et3_bring_up_forward_30_hz() -> None:
    m = Master(station("si-et3", params=(*A, "C1-01=2.0")))
    m.bring_up()
    for _ in range(3000):
        r = m.send(ml3.InvCtl(invcmd_ctrl=0x0001, speed_ref=3000, sel_mon=0x64))
    body = r.message.body
    assert body.output_freq == 3000
    assert body.invcmd_stat & InvCmdStat.FORWARD and body.invcmd_stat & InvCmdStat.REMOTE
    assert body.invcmd_stat & InvCmdStat.SEL_MON1 and body.invcmd_stat & InvCmdStat.SEL_MON2
    assert body.mon1 == 3000 and body.mon2 == 283  # Table 22: 4 frequency reference, 6 DC bus voltage


def test_v7_bring_up_forward_30_hz_n003_n004() -> None:
    m = Master(station("si-t-v7", params=("n003=3", "n004=9", "n019=2.0")))
    m.bring_up()
    for _ in range(3000):
        r = m.send(ml2.InvCtl(signals=0x0001, speed_ref=3000, sel_mon=0x41))
    body = r.message.body
    assert body.output_freq == 3000 and body.mon1 == 3000 and body.mon2 == 3000  # Table 5: 1 output freq
    assert r.message.status & M2Status.REMOTE and not r.message.status & (1 << 14)


def test_run_from_the_network_needs_b1_02_3() -> None:
    """SI-T3 Table 4 <1>: b1-02 = 3 to run from the master; otherwise REMOTE = 0 and a run command does nothing."""
    m = Master(station("si-t3"))
    m.bring_up()
    for _ in range(200):
        r = m.send(ml2.InvCtl(signals=0x0001, speed_ref=3000))
    assert not r.message.status & M2Status.REMOTE and not r.message.status & M2Status.RUNX
    assert r.message.body.output_freq == 0


@pytest.mark.parametrize(
    "card, code, expect",
    [
        ("si-t3", 0x7, "fault"), ("si-t3", 0x8, "minor"), ("si-t3", 0x3, 0), ("si-t3", 0xD, 0),
        ("si-et3", 0x7, "fault"), ("si-t-v7", 0x7, "fault"), ("si-t-v7", 0xE, 0), ("si-t-v7", 0x9, 0),
    ],
)
def test_sel_mon_tables_18_22_v7_5(card: str, code: int, expect: object) -> None:
    m = _up(card)
    if m.ml3:
        m.send(ml3.InvCtl(invcmd_ctrl=0x0400 | 0x1000))
        r = m.send(ml3.InvCtl(invcmd_ctrl=0x0400 | 0x1000, sel_mon=code))
    else:
        m.send(ml2.InvCtl(signals=0x0100 | 0x8000))
        r = m.send(ml2.InvCtl(signals=0x0100 | 0x8000, sel_mon=code))
    mon1 = r.message.body.mon1
    if expect == "fault":
        assert mon1 == 0x27  # EF0 (SI-T3 Table 26 / V7 Table 10)
    elif expect == "minor":
        assert mon1 == 0x08  # bb (Table 27)
    else:
        assert mon1 == expect


def test_sel_mon_e_f_read_the_f6_23_f6_24_registers() -> None:
    m = _up("si-t3", "F6-23=0046", "F6-24=0200")
    r = m.send(ml2.InvCtl(sel_mon=0xFE))
    assert r.message.body.mon1 == 283 and r.message.body.mon2 == 100  # E: U1-07 DC bus, F: C1-01


def test_inv_io_ref_and_mon_3_to_6_priority_over_inv_ctl() -> None:
    m = _up("si-t3")
    r = m.send(ml2.InvCtl(sel_ref=0x05, ref1=1000), ml2.InvIo(sel_ref34=0x05, sel_mon34=0x60, ref3=2000))
    assert r.message.substatus == M2SubStatus.SUBCMDRDY
    assert r.message.sub.mon3 == 0 and r.message.sub.mon4 == 283
    assert m.st.refs["PID setpoint"] == 2000  # "the sub-command is given priority"
    m.send(ml2.InvCtl(sel_ref=0xA8, ref1=5, ref2=6))  # 8 reserved, A not used: ignored, no alarm
    assert alarm(m.last) == 0 and m.st.refs["PID setpoint"] == 2000


def test_si_et3_inv_io_sub_command() -> None:
    m = _up("si-et3")
    r = m.send(ml3.InvCtl(), ml3.InvIo(sel_mon34=0x06, sel_mon56=0x40))
    assert sub_alm(r) == 0 and r.message.sub.mon3 == 283 and r.message.sub.mon4 == 0 and r.message.sub.mon6 == 0
    assert r.message.sub_stat == 0x04


def test_fault_history_clear_bit() -> None:
    m = _up("si-t3")
    _faults(m, 2)
    assert len(m.st.snapshot().drive.fault_history) == 2
    m.send(ml2.InvCtl(signals=0x4000))
    assert m.st.snapshot().drive.fault_history == ()
    m3 = _up("si-et3")
    _faults(m3, 1)
    m3.send(ml3.InvCtl(invcmd_ctrl=0x0800))
    assert m3.st.snapshot().drive.fault_history == ()


def test_ef0_f6_02_detection_during_run_only() -> None:
    m = _up("si-t3", "F6-02=1")
    m.send(ml2.InvCtl(signals=0x0100))
    assert m.st.snapshot().drive.fault is None


def test_sub_command_refused_sets_subwarng() -> None:
    m = _up("si-t3")
    r = m.send(ml2.InvCtl(), ml2.PrmRd(0x0200, 3))
    assert r.message.substatus & M2SubStatus.SUBWARNG and alarm(r) == M2Alarm.DATA_SETTING_WARNING
    m3 = _up("si-et3")
    r = m3.send(ml3.InvCtl(), ml3.PrmWr(0x0040, 2, _word(1)))
    assert sub_alm(r) == SubCmdAlm.INVALID_DATA and cmd_alm(r) == 0


# -- operation signals and SEL_REF, per card table ---------------------------------------------------------
def test_si_t3_table_16_operation_signals() -> None:
    """Bits 2–7 -> terminals S3–S8 (U1-10 bits 2–7), F external baseblock (bb), E history clear."""
    m = _up("si-t3")
    m.send(ml2.InvCtl(signals=0x00FC))
    assert m.send(ml2.PrmRd(0x0049, 2)).message.body.parameter == _word(0xFC)
    m = _up("si-t3")
    r = m.send(ml2.InvCtl(signals=0x0004))
    assert alarm(r) == 0x11  # S3 = H1-03 default 24H: external fault EF3 (Table 26 11H)
    m = _up("si-t3")
    r = m.send(ml2.InvCtl(signals=0x8000))
    assert alarm(r) == 0x08 and r.message.status & M2Status.WARNG  # Table 27 08H bb


def test_v7_table_3_operation_signals() -> None:
    """Bits 2–6 -> S3–S7; bit 7 "Not used" (U-06 bits 2–6)."""
    m = _up("si-t-v7", frame_size=17)
    m.send(ml2.InvCtl(signals=0x00FC))
    assert m.send(ml2.PrmRd(0x002B, 2)).message.body.parameter == _word(0x7C)


def test_si_et3_table_20_invcmd_ctrl() -> None:
    """Bits 16–21 -> S3–S8, 12 external baseblock, 10 EF0, 9 fault reset, 0/1 forward/reverse."""
    m = _up("si-et3")
    m.send(ml3.InvCtl(invcmd_ctrl=0x3F0000))
    assert m.send(ml3.PrmRd(0x0049, 2)).message.body.parameter == _word(0xFC)
    r = m.send(ml3.InvCtl(invcmd_ctrl=0x1000))
    assert r.message.stat.d_war and not r.message.body.invcmd_stat & InvCmdStat.BB_RELEASED
    r = m.send(ml3.InvCtl(invcmd_ctrl=0x0400))
    assert r.message.stat.d_alm
    r = m.send(ml3.InvCtl(invcmd_ctrl=0x0200))
    assert not r.message.stat.d_alm and r.message.body.invcmd_stat & InvCmdStat.RESET


@pytest.mark.parametrize(
    "card, code, item",
    [("si-t3", 1, "torque compensation"), ("si-t3", 5, "PID setpoint"), ("si-t3", 9, "control selection"),
     ("si-t3", 8, None), ("si-t3", 0xA, None), ("si-t-v7", 4, "terminal outputs"), ("si-t-v7", 5, None),
     ("si-t-v7", 1, None)],
)
def test_si_t3_table_17_v7_table_4_sel_ref(card: str, code: int, item: str | None) -> None:
    m = _up(card, frame_size=17) if card == "si-t-v7" else _up(card)
    r = m.send(ml2.InvCtl(sel_ref=code, ref1=1234))
    assert alarm(r) == 0 and r.message.body.sel_ref == code  # unused codes: "ignores the written data"
    assert m.st.refs == ({item: 1234} if item else {})


def test_si_et3_table_21_sel_ref() -> None:
    m = _up("si-et3")
    r = m.send(ml3.InvCtl(sel_ref=0x62, ref1=10, ref2=20))
    assert cmd_alm(r) == 0 and r.message.body.sel_ref == 0x62
    assert m.st.refs == {"analog output 1": 10, "pulse output": 20}


def test_si_t3_table_25_refused_commands_are_ignored() -> None:
    """Table 25: 94/95 "Received commands are ignored" – a refused INV_CTL (phase 1) does not run the drive."""
    m = Master(station("si-t3", params=A))
    r = m.send(ml2.InvCtl(signals=1, speed_ref=3000))
    assert alarm(r) == M2Alarm.COMMAND_WARNING
    m.st.poll(m.now + 100 * MS)
    assert not m.st.snapshot().drive.running
