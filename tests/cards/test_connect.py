"""CONNECT validation per card and generation (SI-T3 CONNECT and its errata, SI-T/V7 CONNECT, SI-ET3 CONNECT
Tables 18/19 with ID_CODE 16H–1AH), the transmission cycle before/after CONNECT and the CyC/CYC minor fault."""

from __future__ import annotations

import pytest

from mlink_sim.cards import CardOptions
from mlink_sim.wire import CmdAlm, M2Alarm, decode, encode, ml2, ml3

from .helpers import MS, Master, alarm, cmd_alm, station

US = 1_000


def _t3(**kw: object) -> Master:
    return Master(station("si-t3", **kw))  # type: ignore[arg-type]


@pytest.mark.parametrize("com_tim, ok", [(1, True), (2, False), (4, False), (0, False), (32, False)])
def test_si_t3_errata_com_tim(com_tim: int, ok: bool) -> None:
    """Errata (1): MECHATROLINK-II "When the transmission cycle is not equal to the communications time
    (COM_TIM ≠ 1): A warning (Data setting warning: A.94) is generated"."""
    m = _t3()
    r = m.send(ml2.Connect(0x21, 0x80, com_tim))
    assert (alarm(r) == 0) is ok
    assert m.st.phase == (2 if ok else 1)
    if not ok:
        assert alarm(r) == M2Alarm.DATA_SETTING_WARNING
        assert "CyC" not in m.st.snapshot().drive.minors  # not a transmission-cycle error


@pytest.mark.parametrize("com_tim, ok", [(2, True), (1, False), (4, False), (64, False)])
def test_si_t3_errata_com_tim_mechatrolink_1(com_tim: int, ok: bool) -> None:
    """Errata (2): MECHATROLINK-I "If COM_TIM ≠ 2: Data setting warning (A.94)"."""
    m = Master(station("si-t3", frame_size=17, link_speed_mbps=4), tcycle_ns=2 * MS)
    r = m.send(ml2.Connect(0x10, 0x00, com_tim))
    assert (alarm(r) == 0) is ok
    assert m.st.phase == (2 if ok else 1)


@pytest.mark.parametrize(
    "size, tcycle_ns, ok",
    [
        (32, 1 * MS, True), (32, 8 * MS, True), (32, 2 * MS, True), (32, 1500 * US, False),
        (32, 500 * US, False), (32, 9 * MS, False),
        (17, 500 * US, True), (17, 1500 * US, True), (17, 8 * MS, True), (17, 750 * US, False),
        (17, 250 * US, False), (17, 8500 * US, False),
    ],
)
def test_si_t3_connect_transmission_cycle_range(size: int, tcycle_ns: int, ok: bool) -> None:
    """32-byte: 1–8 ms, whole ms; 17-byte: 0.5–8 ms in 0.5 ms steps ("such as 0.75" -> A.94)."""
    m = Master(station("si-t3", frame_size=size), tcycle_ns=tcycle_ns)
    r = m.send(ml2.Connect(0x21, 0x80 if size == 32 else 0, 1))
    assert alarm(r) == (0 if ok else M2Alarm.DATA_SETTING_WARNING)
    assert ("CyC" in m.st.snapshot().drive.minors) is (not ok)  # SI-T3 Table 27 33H, after the A.94
    if ok:
        assert m.st.tcycle_ns == tcycle_ns
    else:
        r = m.nop()  # from now on the drive's minor fault is the lowest-coded warning (Table 21)
        assert alarm(r) == 0x33 and r.message.status & 0x2


def test_si_t3_cyc_cleared_by_a_good_connect() -> None:
    m = Master(station("si-t3"), tcycle_ns=1500 * US)
    m.send(ml2.Connect(0x21, 0x80, 1))
    m.tcycle_ns = 1 * MS
    assert "CyC" in m.st.snapshot().drive.minors
    assert alarm(m.send(ml2.Connect(0x21, 0x80, 1))) == 0
    assert "CyC" not in m.st.snapshot().drive.minors


@pytest.mark.parametrize(
    "ver, com_mod, ok",
    [
        (0x21, 0x80, True), (0x21, 0x82, True), (0x21, 0x00, True),
        (0x10, 0x00, False),  # VER must match the 10 Mbps link
        (0x30, 0x80, False),
        (0x21, 0x81, False), (0x21, 0x90, False), (0x21, 0xA0, False), (0x21, 0xC0, False),  # bits 0, 4, 5, 6
        (0x21, 0x84, False), (0x21, 0x88, False),  # DTMOD other than 00
    ],
)
def test_si_t3_connect_ver_and_com_mod(ver: int, com_mod: int, ok: bool) -> None:
    m = _t3()
    r = m.send(ml2.Connect(ver, com_mod, 1))
    assert alarm(r) == (0 if ok else M2Alarm.DATA_SETTING_WARNING)
    assert r.message.body == ml2.Connect(ver, com_mod, 1)  # echoed either way


def test_si_t3_subcmd_needs_32_byte_frames() -> None:
    """"If SUBCMD is set to 1 in 17-byte data transmission: Data setting warning (A.94)"."""
    m = Master(station("si-t3", frame_size=17))
    assert alarm(m.send(ml2.Connect(0x21, 0x80, 1))) == M2Alarm.DATA_SETTING_WARNING
    assert alarm(m.send(ml2.Connect(0x21, 0x00, 1))) == 0


@pytest.mark.parametrize("com_mod, ok", [(0x00, True), (0x02, True), (0x80, False), (0x08, False), (0x01, False)])
def test_si_t3_connect_ver_10h(com_mod: int, ok: bool) -> None:
    """VER 10H: SUBCMD for Ver. 1.0, "Bit6, Bit5, Bit4, Bit3, or Bit0" -> A.94 (EXMOD: see the option)."""
    m = Master(station("si-t3", frame_size=17, link_speed_mbps=4), tcycle_ns=2 * MS)
    assert (alarm(m.send(ml2.Connect(0x10, com_mod, 2))) == 0) is ok


def test_ml1_exmod_option_forces_asynchronous() -> None:
    m = Master(station("si-t3", frame_size=17, link_speed_mbps=4, options=CardOptions(ml1_exmod_accepted=True)),
               tcycle_ns=2 * MS)
    assert alarm(m.send(ml2.Connect(0x10, 0x03, 2))) == 0
    assert m.st.phase == 2  # "Even if SYNCMOD = 1, SYNCMOD will be set to 0"


def test_v7_ver_must_match_the_switch_setting() -> None:
    st = station("si-t-v7", frame_size=17, link_speed_mbps=4)
    m = Master(st, tcycle_ns=2 * MS)
    assert alarm(m.send(ml2.Connect(0x21, 0x00, 1))) == M2Alarm.DATA_SETTING_WARNING
    assert alarm(m.send(ml2.Connect(0x10, 0x00, 2))) == 0
    assert st.link.name == "ML1" and st.data_size == 17


def test_transmission_cycle_default_2ms_then_header() -> None:
    """"Operation proceeds with a default transmission cycle of 2 ms"; CONNECT takes the header's."""
    m = Master(station("si-et3"), tcycle_ns=500 * US)
    assert m.st.tcycle_ns == 2 * MS
    m.connect(com_tim=4)
    assert m.st.tcycle_ns == 500 * US and m.st.comm_cycle_ns == 2 * MS
    m.send(ml3.Disconnect())
    assert m.st.tcycle_ns == 2 * MS


def test_response_echoes_cycle_and_transmission_cycle() -> None:
    m = Master(station("si-t3"), tcycle_ns=3 * MS)
    r = m.connect()
    assert r.cycle == m.cycle and r.tcycle_ns == 3 * MS and r.data_size == 32


@pytest.mark.parametrize(
    "tcycle_ns, com_tim, ok",
    [
        (250 * US, 1, True), (500 * US, 1, True), (750 * US, 1, True), (1 * MS, 1, True), (1500 * US, 1, True),
        (8 * MS, 1, True), (8 * MS, 4, True), (250 * US, 128, True), (1 * MS, 32, True),
        (125 * US, 2, False),  # granularity lists 125 µs but the minimum is 250 µs (ID_CODE 16H)
        (300 * US, 1, False), (1250 * US, 1, False), (8500 * US, 1, False),
        (8 * MS, 5, False),  # communication cycle 40 ms > 32 ms (ID_CODE 1AH)
        (1 * MS, 0, False),  # COM_TIM 1–255
    ],
)
def test_si_et3_table_14_transmission_cycle_granularity(tcycle_ns: int, com_tim: int, ok: bool) -> None:
    m = Master(station("si-et3"), tcycle_ns=tcycle_ns)
    r = m.send(ml3.Connect(0x30, 0x80, com_tim, 0x20))
    assert cmd_alm(r) == (CmdAlm.NORMAL if ok else CmdAlm.INVALID_DATA)
    assert ("CyC" in m.st.snapshot().drive.minors) is (not ok)  # SI-ET3 Table 26 CYC


@pytest.mark.parametrize(
    "ver, com_mod, profile, ok",
    [
        (0x30, 0x80, 0x20, True), (0x30, 0x00, 0x20, True), (0x21, 0x80, 0x20, False), (0x30, 0x80, 0x10, False),
        (0x30, 0x81, 0x20, False), (0x30, 0x90, 0x20, False), (0x30, 0x84, 0x20, False),
    ],
)
def test_si_et3_table_18_com_mod_ver_profile(ver: int, com_mod: int, profile: int, ok: bool) -> None:
    m = Master(station("si-et3"))
    r = m.send(ml3.Connect(ver, com_mod, 1, profile))
    assert cmd_alm(r) == (0 if ok else CmdAlm.INVALID_DATA)
    assert r.message.body == ml3.Connect(ver, com_mod, 1, profile)


def test_si_et3_subcmd_needs_64_byte_frames() -> None:
    m = Master(station("si-et3", frame_size=32))
    assert cmd_alm(m.send(ml3.Connect(0x30, 0x80, 1, 0x20))) == CmdAlm.INVALID_DATA
    assert cmd_alm(m.send(ml3.Connect(0x30, 0x00, 1, 0x20))) == 0


@pytest.mark.parametrize("table19, syncmode, phase", [(False, 1, 3), (False, 0, 2), (True, 0, 3), (True, 1, 2)])
def test_si_et3_table_19_syncmode(table19: bool, syncmode: int, phase: int) -> None:
    """Default: SYNCMODE 1 = synchronous (MECHATROLINK-II convention); the option reads Table 19 (0 = sync)."""
    m = Master(station("si-et3", options=CardOptions(et3_syncmode_table19=table19)))
    m.send(ml3.Connect(0x30, 0x80 | syncmode << 1, 1, 0x20))
    assert m.st.phase == phase


def test_si_et3_connect_response_offsets_option() -> None:
    """Default: echo at the command's bytes 4–7; the option follows the printed response table (VER at 5)."""
    m = Master(station("si-et3", options=CardOptions(et3_connect_echo_at_byte5=True)))
    raw = m.st.receive(encode(m.command(ml3.Connect(0x30, 0x80, 1, 0x20))), m.source, 1)
    assert raw is not None
    data = raw[12:-2]
    assert data[4:9] == bytes((0, 0x30, 0x80, 1, 0x20))
    m2 = Master(station("si-et3"))
    raw = m2.st.receive(encode(m2.command(ml3.Connect(0x30, 0x80, 1, 0x20))), m2.source, 1)
    assert raw is not None and raw[12 + 4 : 12 + 8] == bytes((0x30, 0x80, 1, 0x20))
    assert decode(raw).message.body == ml3.Connect(0x30, 0x80, 1, 0x20)
