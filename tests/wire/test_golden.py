"""The golden datagrams (wire_golden.py, written by hand from the manuals' byte tables) against the codec: the
whole table in both directions, then the entries named after the manual tables they encode and single byte
positions (docs/wire-format.md)."""

from __future__ import annotations

import pytest
from wire_golden import BY_NAME, GOLDEN, C, Golden, R, _ml2, _ml3, m2, m3

from mlink_sim.wire import CmdAlm, CommAlm, Frame, Kind, Link, M2Cmd, M2Status, M2SubStatus, M3Cmd, Unknown, \
    decode, encode, ml2, ml3
from mlink_sim.wire.fcs import crc16_x25_reference


def _check(name: str) -> bytes:
    """Both directions for one golden entry; returns the datagram for further byte checks."""
    g = BY_NAME[name]
    assert encode(g.frame) == g.datagram
    assert decode(g.datagram) == g.frame
    return g.datagram


# --- the whole table, both directions ----------------------------------------------------------------------------


@pytest.mark.parametrize("g", GOLDEN, ids=[g.name for g in GOLDEN])
def test_encode(g: Golden) -> None:
    assert encode(g.frame).hex(" ") == g.datagram.hex(" ")


@pytest.mark.parametrize("g", GOLDEN, ids=[g.name for g in GOLDEN])
def test_decode(g: Golden) -> None:
    assert decode(g.datagram) == g.frame


@pytest.mark.parametrize("g", GOLDEN, ids=[g.name for g in GOLDEN])
def test_golden_table_is_consistent(g: Golden) -> None:
    """The hand-written FCS literal and length agree with the contract (guards typos in the table itself)."""
    n = len(g.datagram)
    assert n == 12 + g.frame.data_size + 2
    assert int.from_bytes(g.datagram[-2:], "little") == crc16_x25_reference(g.datagram[:-2])


# --- named after the manual tables they encode ---------------------------------------------------------------------


def test_si_t3_table_8_prm_rd_c1_01() -> None:
    cmd = _check("si_t3_table_8_prm_rd_c1_01_command")
    assert m2(cmd, 1) == M2Cmd.PRM_RD
    assert [m2(cmd, k) for k in (5, 6, 7)] == [0x00, 0x02, 0x02]
    assert [m2(cmd, k) for k in (8, 9)] == [0x00, 0x00]
    rsp = _check("si_t3_table_8_prm_rd_c1_01_response")
    assert [m2(rsp, k) for k in (5, 6, 7)] == [0x00, 0x02, 0x02]
    assert m2(rsp, 8) | m2(rsp, 9) << 8 == 100  # lower, upper byte of C1-01


def test_si_t3_table_9_prm_wr_c1_01() -> None:
    cmd = _check("si_t3_table_9_prm_wr_c1_01_command")
    assert m2(cmd, 1) == M2Cmd.PRM_WR
    assert [m2(cmd, k) for k in (5, 6, 7, 8, 9)] == [0x00, 0x02, 0x02, 0x32, 0x00]
    rsp = _check("si_t3_table_9_prm_wr_c1_01_response")
    assert [m2(rsp, k) for k in (5, 6, 7, 8, 9)] == [0x00, 0x02, 0x02, 0x32, 0x00]


def test_si_et3_example_reading_c1_01() -> None:
    cmd = _check("si_et3_prm_rd_example_c1_01_command")
    assert m3(cmd, 0) == M3Cmd.PRM_RD
    assert [m3(cmd, k) for k in range(4, 10)] == [0x00, 0x02, 0x02, 0x00, 0x00, 0x00]
    rsp = _check("si_et3_prm_rd_example_c1_01_response")
    assert [m3(rsp, k) for k in range(4, 8)] == [0x00, 0x02, 0x02, 0x00]
    assert m3(rsp, 8) | m3(rsp, 9) << 8 == 100


def test_si_et3_example_writing_c1_01() -> None:
    cmd = _check("si_et3_prm_wr_example_c1_01_command")
    assert [m3(cmd, k) for k in range(4, 10)] == [0x00, 0x02, 0x02, 0x00, 0x32, 0x00]
    rsp = _check("si_et3_prm_wr_example_c1_01_response")
    assert [m3(rsp, k) for k in range(4, 10)] == [0x00, 0x02, 0x02, 0x00, 0x32, 0x00]


def test_si_t3_connect_ver_21h() -> None:
    cmd = _check("si_t3_connect_ver_21h_command")
    assert [m2(cmd, k) for k in (1, 5, 6, 7)] == [0x0E, 0x21, 0x02, 0x01]
    _check("si_t3_connect_ver_21h_response")


def test_si_t3_connect_ver_10h_on_mechatrolink_i() -> None:
    dg = _check("si_t3_connect_ver_10h_mechatrolink_i_command")
    assert dg[1] == Link.ML1 and len(dg) == 12 + 17 + 2
    assert [m2(dg, k) for k in (5, 6, 7)] == [0x10, 0x02, 0x02]


def test_si_et3_connect_ver_30h_profile_type_20h() -> None:
    cmd = _check("si_et3_connect_ver_30h_command")
    assert [m3(cmd, k) for k in (0, 4, 5, 6, 7)] == [0x0E, 0x30, 0x02, 0x04, 0x20]
    rsp = _check("si_et3_connect_ver_30h_response")
    assert [m3(rsp, k) for k in (4, 5, 6, 7)] == [0x30, 0x02, 0x04, 0x20]


def test_si_t3_inv_ctl() -> None:
    cmd = _check("si_t3_inv_ctl_command")
    assert m2(cmd, 1) == M2Cmd.INV_CTL
    assert (m2(cmd, 9), m2(cmd, 10)) == (0x21, 0x41)
    rsp = _check("si_t3_inv_ctl_response")
    assert (m2(rsp, 9), m2(rsp, 10)) == (0x21, 0x41)  # SEL REF1/2, SEL MON1/2 echoed at the same bytes


def test_si_et3_inv_ctl() -> None:
    cmd = _check("si_et3_inv_ctl_command")
    assert m3(cmd, 0) == M3Cmd.INV_CTL
    assert int.from_bytes(cmd[12 + 4 : 12 + 8], "little") == 0x0001_0001  # INVCMD_CTRL bytes 4-7 (Table 20)
    assert (m3(cmd, 20), m3(cmd, 21)) == (0x21, 0x41)
    _check("si_et3_inv_ctl_response")


def test_si_t3_32_byte_frame_with_inv_io_subcommand() -> None:
    cmd = _check("si_t3_32_byte_inv_io_subcommand_command")
    assert len(cmd) == 12 + 32 + 2
    assert m2(cmd, 17) == M2Cmd.INV_IO
    assert [m2(cmd, k) for k in (19, 20, 21, 22)] == [0x65, 0x09, 0xB9, 0x67]
    rsp = _check("si_t3_32_byte_inv_io_subcommand_response")
    assert m2(rsp, 18) == M2SubStatus.SUBCMDRDY


def test_si_et3_64_byte_frame_with_prm_rd_subcommand() -> None:
    cmd = _check("si_et3_64_byte_prm_rd_subcommand_command")
    assert len(cmd) == 12 + 64 + 2
    assert m3(cmd, 32) == M3Cmd.PRM_RD
    assert [m3(cmd, k) for k in range(36, 40)] == [0x00, 0x02, 0x02, 0x00]
    rsp = _check("si_et3_64_byte_prm_rd_subcommand_response")
    assert (m3(rsp, 40), m3(rsp, 41)) == (0x64, 0x00)


def test_v7_mechatrolink_i_17_byte_nop() -> None:
    cmd = _check("v7_mechatrolink_i_nop_command")
    assert cmd[:3] == bytes([0x4D, Link.ML1, Kind.COMMAND]) and len(cmd) == 31
    _check("v7_mechatrolink_i_nop_response")


def test_si_t3_table_25_a94_in_alarm_byte() -> None:
    dg = _check("si_t3_table_25_a94_response")
    assert dg[13] == m2(dg, 2) == 0x94


def test_unknown_command_codes_are_kept_raw() -> None:
    for name in ("si_t3_table_5_unknown_main_41h_command", "si_et3_table_11_unknown_40h_command"):
        dg = _check(name)
        assert isinstance(decode(dg).message.body, Unknown)
    rsp = _check("si_et3_cmd_alm_8_unsupported_response")
    assert decode(rsp).message.stat.cmd_alm == CmdAlm.UNSUPPORTED_COMMAND


# --- individual byte positions -------------------------------------------------------------------------------------


def test_envelope_fields_are_little_endian_at_fixed_offsets() -> None:
    dg = encode(Frame(Link.ML2, Kind.COMMAND, 0xAB, 0x0403_0201, 0x0807_0605, ml2.M2Command(ml2.Nop())))
    assert dg[0] == 0x4D and dg[1] == 0x02 and dg[2] == 0x01 and dg[3] == 0xAB
    assert dg[4:8] == bytes([1, 2, 3, 4]) and dg[8:12] == bytes([5, 6, 7, 8])
    assert int.from_bytes(dg[-2:], "little") == crc16_x25_reference(dg[:-2])


def test_ml2_17_byte_command_wdt_is_datagram_byte_27() -> None:
    dg = encode(_ml2(C, ml2.M2Command(ml2.Nop(), wdt=0xA5)))
    assert len(dg) == 31
    assert dg[11 + 16] == dg[27] == 0xA5
    assert dg[12:27] == bytes(15) and dg[28] == 0  # nothing else set; byte 17 reserved


def test_ml2_response_alarm_byte_13_status_bytes_14_15() -> None:
    status = M2Status.ALM | M2Status.REMOTE  # bit 0 in byte 3, bit D in byte 4
    dg = encode(_ml2(R, ml2.M2Response(ml2.Nop(), alarm=0xE6, status=status, rwdt=0x77)))
    assert dg[13] == 0xE6
    assert dg[14] == 0x01 and dg[15] == 0x20
    assert dg[27] == 0x77


def test_ml2_32_byte_subcommand_code_is_datagram_byte_28_substatus_29() -> None:
    dg = encode(_ml2(R, ml2.M2Response(ml2.Nop(), rwdt=0x11, sub=ml2.Nop(), substatus=0x07)))
    assert len(dg) == 12 + 32 + 2
    assert dg[27] == 0x11  # RWDT still at byte 16 in a 32-byte frame
    assert dg[28] == M2Cmd.NOP and dg[29] == 0x07


def test_ml3_wdt_is_datagram_byte_13_and_subcmd_byte_44() -> None:
    dg = encode(_ml3(C, ml3.M3Command(ml3.Nop(), wdt=0x5C, cmd_ctrl=0x08, sub=ml3.PrmRd(1, 2), sub_ctrl=0)))
    assert dg[13] == 0x5C
    assert dg[14] == 0x08  # CMD_CTRL ALM_CLR (bit 3) in byte 2
    assert dg[12 + 32] == dg[44] == M3Cmd.PRM_RD
    assert dg[12 + 36] == 0x01 and dg[12 + 38] == 0x02  # sub body starts at byte 36


def test_ml3_cmd_stat_cmd_alm_in_bits_8_to_11_of_bytes_14_15() -> None:
    stat = ml3.CmdStat(cmdrdy=True, cmd_alm=CmdAlm.INVALID_DATA, comm_alm=CommAlm.FCS_ERROR)
    dg = encode(_ml3(R, ml3.M3Response(ml3.Nop(), cmd_stat=stat.to_int())))
    word = int.from_bytes(dg[14:16], "little")
    assert (word >> 8) & 0xF == CmdAlm.INVALID_DATA  # CMD_ALM bits 8-11
    assert (word >> 12) & 0xF == CommAlm.FCS_ERROR  # COMM_ALM bits 12-15
    assert dg[14] == 0x04 and dg[15] == 0x89
    assert decode(dg).message.stat == stat


def test_ml3_sub_stat_subcmd_alm_in_bits_8_to_11() -> None:
    sub_stat = ml3.SubStat(subcmdrdy=True, subcmd_alm=0x9).to_int()
    dg = encode(_ml3(R, ml3.M3Response(ml3.Nop(), sub=ml3.Nop(), sub_stat=sub_stat)))
    assert dg[12 + 33] == 0x04 and dg[12 + 34] == 0x09 and dg[12 + 35] == 0x00
