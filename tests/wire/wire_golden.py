"""The golden datagrams: (Frame, bytes) pairs, checked in both directions by test_golden.py (in the style of
h11's tests/test_io.py).

Every expected datagram below is written by hand from the manuals' byte tables – never produced by ``encode`` –
so the tests check the code against the manuals:

* MECHATROLINK-I/II (SI-T3, SI-T/V7): manual data byte *k* (numbered from 1) is datagram byte ``11 + k``;
* MECHATROLINK-III (SI-ET3): manual data byte *k* (numbered from 0) is datagram byte ``12 + k``;
* the 12-byte envelope and the trailing FCS (CRC-16/X-25, LE) are the wire contract of docs/wire-format.md.

The FCS literals were computed once with the bit-by-bit ``crc16_x25_reference`` (itself pinned to the catalogued
check value in test_fcs.py) and are kept as literals so the table can be reused verbatim by other implementations
(docs/wire-format.md quotes the first entry).

Values that the manuals leave to the reader are chosen as follows: the C1-01 value read is 0064H = 100 = 10.0 s
(source: A1000 Technical Manual, C1-01 default 10.0 s in 0.1 s units, as in mlink_sim/params/a1000.py), the value
written is 0032H = 5.0 s; WDT/RWDT, station, cycle and the monitor values are arbitrary but distinct.
"""

from __future__ import annotations

from dataclasses import dataclass

from mlink_sim.wire import (
    ConnectVersion,
    Frame,
    Kind,
    Link,
    M2Alarm,
    M2Status,
    M2SubStatus,
    OperationSignal,
    PROFILE_TYPE_INVERTER,
    Unknown,
    ml2,
    ml3,
)


def hx(text: str) -> bytes:
    """Hex digits of *text*; whitespace and ``#`` comments (to the end of a line) are ignored."""
    return bytes.fromhex("".join(line.split("#", 1)[0] for line in text.splitlines()))


def m2(datagram: bytes, k: int) -> int:
    """MECHATROLINK-I/II manual data byte *k* (1-based) of a datagram."""
    return datagram[11 + k]


def m3(datagram: bytes, k: int) -> int:
    """MECHATROLINK-III manual data byte *k* (0-based) of a datagram."""
    return datagram[12 + k]


@dataclass(frozen=True)
class Golden:
    name: str
    frame: Frame
    datagram: bytes


def _ml2(kind: Kind, msg: object) -> Frame:
    return Frame(Link.ML2, kind, 0x21, 16, 2_000_000, msg)  # type: ignore[arg-type]


def _ml3(kind: Kind, msg: object) -> Frame:
    return Frame(Link.ML3, kind, 0x21, 0x12345, 1_000_000, msg)  # type: ignore[arg-type]


def _ml1(kind: Kind, msg: object) -> Frame:
    return Frame(Link.ML1, kind, 0x03, 7, 2_000_000, msg)  # type: ignore[arg-type]


C, R = Kind.COMMAND, Kind.RESPONSE
C1_01 = 0x0200  # SI-T3 Tables 8/9, SI-ET3 "Example: Reading/Writing C1-01 (200H)"
READ_VALUE = bytes.fromhex("6400000000000000")  # 0064H = 10.0 s, LSB first, rest of PARAMETER zero
WRITE_VALUE = bytes.fromhex("3200000000000000")  # 0032H = 5.0 s

# Envelopes used below (offsets 0-11):
#   ML-II:  4D 02 kk 21  10 00 00 00  80 84 1E 00   station 21H, cycle 16, 2 ms (2 000 000 ns = 001E8480H)
#   ML-III: 4D 03 kk 21  45 23 01 00  40 42 0F 00   station 21H, cycle 12345H, 1 ms (000F4240H)
#   ML-I:   4D 01 kk 03  07 00 00 00  80 84 1E 00   station 03H, cycle 7, 2 ms

GOLDEN: list[Golden] = [
    # ---- SI-T3 Table 8: PRM_RD of C1-01 (0200H), 17-byte MECHATROLINK-II ------------------------------------
    Golden(
        "si_t3_table_8_prm_rd_c1_01_command",
        _ml2(C, ml2.M2Command(ml2.PrmRd(C1_01, 2), wdt=0x23)),
        hx("""
            4D 02 01 21  10 00 00 00  80 84 1E 00   # envelope: magic, ML-II, command, station 21H, cycle, tcycle
            01                                      # byte 1       PRM_RD
            00                                      # byte 2       0
            00 00                                   # bytes 3,4    0
            00 02                                   # bytes 5,6    NO = 0200H (C1-01), LSB first  (Table 8: 00 02)
            02                                      # byte 7       SIZE = 2                        (Table 8: 02)
            00 00 00 00 00 00 00 00                 # bytes 8-15   0                               (Table 8: 00 00)
            23                                      # byte 16      WDT
            00                                      # byte 17      reserved
            B3 37                                   # FCS
        """),
    ),
    Golden(
        "si_t3_table_8_prm_rd_c1_01_response",
        _ml2(R, ml2.M2Response(ml2.PrmRdResponse(C1_01, 2, READ_VALUE), status=M2Status.CMDRDY, rwdt=0x32)),
        hx("""
            4D 02 02 21  10 00 00 00  80 84 1E 00   # envelope: response
            01                                      # byte 1       PRM_RD
            00                                      # byte 2       ALARM
            04 00                                   # bytes 3,4    STATUS = CMDRDY (the only valid bit for PRM_RD)
            00 02                                   # bytes 5,6    NO (copy)
            02                                      # byte 7       SIZE (copy)
            64 00                                   # bytes 8,9    lower, upper byte of C1-01
            00 00 00 00 00 00                       # bytes 10-15  rest of PARAMETER
            32                                      # byte 16      RWDT
            00                                      # byte 17      reserved
            C9 28                                   # FCS
        """),
    ),
    # ---- SI-T3 Table 9: PRM_WR of C1-01 -----------------------------------------------------------------------
    Golden(
        "si_t3_table_9_prm_wr_c1_01_command",
        _ml2(C, ml2.M2Command(ml2.PrmWr(C1_01, 2, WRITE_VALUE), wdt=0x24)),
        hx("""
            4D 02 01 21  10 00 00 00  80 84 1E 00
            02                                      # byte 1       PRM_WR
            00                                      # byte 2       0
            00 00                                   # bytes 3,4    0
            00 02                                   # bytes 5,6    NO = 0200H
            02                                      # byte 7       SIZE
            32 00                                   # bytes 8,9    setting value lower, upper
            00 00 00 00 00 00                       # bytes 10-15  rest of DATA
            24                                      # byte 16      WDT
            00                                      # byte 17
            03 6C                                   # FCS
        """),
    ),
    Golden(
        "si_t3_table_9_prm_wr_c1_01_response",
        _ml2(
            R,
            ml2.M2Response(
                ml2.PrmWr(C1_01, 2, WRITE_VALUE), status=M2Status.CMDRDY | M2Status.PON | M2Status.INV_READY, rwdt=0x33
            ),
        ),
        hx("""
            4D 02 02 21  10 00 00 00  80 84 1E 00
            02                                      # byte 1       PRM_WR
            00                                      # byte 2       ALARM
            14 04                                   # bytes 3,4    STATUS = CMDRDY|PON (bits 2,4) | INV_READY (bit A)
            00 02                                   # bytes 5,6    NO (copy)
            02                                      # byte 7       SIZE (copy)
            32 00 00 00 00 00 00 00                 # bytes 8-15   DATA (copy)
            33                                      # byte 16      RWDT
            00                                      # byte 17
            A6 3B                                   # FCS
        """),
    ),
    # ---- SI-ET3 "Example: Reading C1-01 (200H)" / "Writing C1-01", 32-byte MECHATROLINK-III -------------------
    Golden(
        "si_et3_prm_rd_example_c1_01_command",
        _ml3(C, ml3.M3Command(ml3.PrmRd(C1_01, 2), wdt=0x23)),
        hx("""
            4D 03 01 21  45 23 01 00  40 42 0F 00   # envelope: magic, ML-III, command, station 21H, cycle, 1 ms
            01                                      # byte 0       PRM_RD
            23                                      # byte 1       WDT
            00 00                                   # bytes 2,3    CMD_CTRL
            00 02 02 00                             # bytes 4-7    NO = 0200H, SIZE = 2, reserved (example: 00 02 02 00)
            00 00                                   # bytes 8,9    (example: 00H 00H)
            00 00 00 00 00 00 00 00 00 00 00        # bytes 10-20
            00 00 00 00 00 00 00 00 00 00 00        # bytes 21-31
            F1 09                                   # FCS
        """),
    ),
    Golden(
        "si_et3_prm_rd_example_c1_01_response",
        _ml3(R, ml3.M3Response(ml3.PrmRdResponse(C1_01, 2, READ_VALUE), rwdt=0x32, cmd_stat=0x0004)),
        hx("""
            4D 03 02 21  45 23 01 00  40 42 0F 00
            01                                      # byte 0       PRM_RD
            32                                      # byte 1       RWDT
            04 00                                   # bytes 2,3    CMD_STAT = CMDRDY (bit 2)
            00 02 02 00                             # bytes 4-7    NO, SIZE, reserved (copies)
            64 00                                   # bytes 8,9    value of C1-01, lower, upper
            00 00 00 00 00 00 00 00 00 00 00        # bytes 10-20
            00 00 00 00 00 00 00 00 00 00 00        # bytes 21-31
            2C A6                                   # FCS
        """),
    ),
    Golden(
        "si_et3_prm_wr_example_c1_01_command",
        _ml3(C, ml3.M3Command(ml3.PrmWr(C1_01, 2, WRITE_VALUE), wdt=0x24)),
        hx("""
            4D 03 01 21  45 23 01 00  40 42 0F 00
            02                                      # byte 0       PRM_WR
            24                                      # byte 1       WDT
            00 00                                   # bytes 2,3    CMD_CTRL
            00 02 02 00                             # bytes 4-7    NO, SIZE, reserved
            32 00                                   # bytes 8,9    value to set, lower, upper
            00 00 00 00 00 00 00 00 00 00 00        # bytes 10-20
            00 00 00 00 00 00 00 00 00 00 00        # bytes 21-31
            5F C1                                   # FCS
        """),
    ),
    Golden(
        "si_et3_prm_wr_example_c1_01_response",
        _ml3(R, ml3.M3Response(ml3.PrmWr(C1_01, 2, WRITE_VALUE), rwdt=0x33, cmd_stat=0x0004)),
        hx("""
            4D 03 02 21  45 23 01 00  40 42 0F 00
            02                                      # byte 0       PRM_WR
            33                                      # byte 1       RWDT
            04 00                                   # bytes 2,3    CMD_STAT = CMDRDY
            00 02 02 00                             # bytes 4-7    copies
            32 00                                   # bytes 8,9    copy of the value
            00 00 00 00 00 00 00 00 00 00 00        # bytes 10-20
            00 00 00 00 00 00 00 00 00 00 00        # bytes 21-31
            54 D5                                   # FCS
        """),
    ),
    # ---- CONNECT ------------------------------------------------------------------------------------------------
    Golden(
        "si_t3_connect_ver_21h_command",
        _ml2(C, ml2.M2Command(ml2.Connect(ConnectVersion.ML2, 0x02, 1))),
        hx("""
            4D 02 01 21  10 00 00 00  80 84 1E 00
            0E                                      # byte 1       CONNECT
            00                                      # byte 2
            00 00                                   # bytes 3,4
            21                                      # byte 5       VER = 21H (MECHATROLINK-II)
            02                                      # byte 6       COM_MOD = SYNCMOD (bit 1): go to phase 3
            01                                      # byte 7       COM_TIM = 1
            00 00 00 00 00 00 00 00                 # bytes 8-15
            00                                      # byte 16      WDT
            00                                      # byte 17
            03 80                                   # FCS
        """),
    ),
    Golden(
        "si_t3_connect_ver_21h_response",
        _ml2(R, ml2.M2Response(ml2.Connect(0x21, 0x02, 1), status=M2Status.CMDRDY | M2Status.PON)),
        hx("""
            4D 02 02 21  10 00 00 00  80 84 1E 00
            0E                                      # byte 1       CONNECT
            00                                      # byte 2       ALARM
            14 00                                   # bytes 3,4    STATUS = CMDRDY|PON
            21 02 01                                # bytes 5-7    VER, COM_MOD, COM_TIM (copies)
            00 00 00 00 00 00 00 00                 # bytes 8-15
            00                                      # byte 16      RWDT
            00                                      # byte 17
            86 FC                                   # FCS
        """),
    ),
    Golden(
        "si_t3_connect_ver_10h_mechatrolink_i_command",
        _ml1(C, ml2.M2Command(ml2.Connect(ConnectVersion.ML1, 0x02, 2))),
        hx("""
            4D 01 01 03  07 00 00 00  80 84 1E 00   # envelope: ML-I, station 03H, cycle 7
            0E 00 00 00                             # bytes 1-4    CONNECT, 0, 0, 0
            10                                      # byte 5       VER = 10H (MECHATROLINK-I)
            02                                      # byte 6       COM_MOD = SYNCMOD
            02                                      # byte 7       COM_TIM = 2 (SI-T3 errata (2): must be 2)
            00 00 00 00 00 00 00 00                 # bytes 8-15
            00 00                                   # bytes 16,17  WDT, reserved
            B7 65                                   # FCS
        """),
    ),
    Golden(
        "si_et3_connect_ver_30h_command",
        _ml3(C, ml3.M3Command(ml3.Connect(ConnectVersion.ML3, 0x02, 4, PROFILE_TYPE_INVERTER))),
        hx("""
            4D 03 01 21  45 23 01 00  40 42 0F 00
            0E                                      # byte 0       CONNECT
            00                                      # byte 1       WDT
            00 00                                   # bytes 2,3    CMD_CTRL
            30                                      # byte 4       VER = 30H
            02                                      # byte 5       COM_MOD = SYNCMODE (bit 1; Table 19: 1 = asynchronous)
            04                                      # byte 6       COM_TIM = 4
            20                                      # byte 7       PROFILE_TYPE = 20H (inverter)
            00 00 00 00 00 00 00 00 00 00 00 00     # bytes 8-19
            00 00 00 00 00 00 00 00 00 00 00 00     # bytes 20-31
            7F 7D                                   # FCS
        """),
    ),
    Golden(
        # The manual's CONNECT response table prints VER at byte 5; the echo is taken at the command's offsets
        # (bytes 4-7), see the ml3 module docstring and docs/wire-format.md.
        "si_et3_connect_ver_30h_response",
        _ml3(R, ml3.M3Response(ml3.Connect(0x30, 0x02, 4, 0x20), cmd_stat=0x0004)),
        hx("""
            4D 03 02 21  45 23 01 00  40 42 0F 00
            0E 00                                   # bytes 0,1    CONNECT, RWDT
            04 00                                   # bytes 2,3    CMD_STAT = CMDRDY
            30 02 04 20                             # bytes 4-7    VER, COM_MOD, COM_TIM, PROFILE_TYPE (echo)
            00 00 00 00 00 00 00 00 00 00 00 00     # bytes 8-19
            00 00 00 00 00 00 00 00 00 00 00 00     # bytes 20-31
            56 11                                   # FCS
        """),
    ),
    # ---- INV_CTL ------------------------------------------------------------------------------------------------
    Golden(
        "si_t3_inv_ctl_command",
        _ml2(
            C,
            ml2.M2Command(
                ml2.InvCtl(OperationSignal.FORWARD, 6000, -100, 0x21, 0x41, 50, 500),
                wdt=0x5A,
            ),
        ),
        hx("""
            4D 02 01 21  10 00 00 00  80 84 1E 00
            40                                      # byte 1       INV_CTL
            00                                      # byte 2
            01 00                                   # bytes 3,4    operation signals: forward run (Table 16 bit 0)
            70 17                                   # bytes 5,6    speed reference 6000 (60.00 Hz at o1-03 = 0)
            9C FF                                   # bytes 7,8    torque reference -100 (-10.0 %)
            21                                      # byte 9       SEL REF1/2: REF1 = 1, REF2 = 2 (Table 17)
            41                                      # byte 10      SEL MON1/2: MON1 = 1, MON2 = 4 (Table 18)
            32 00                                   # bytes 11,12  REF1 = 50
            F4 01                                   # bytes 13,14  REF2 = 500
            00                                      # byte 15      0
            5A                                      # byte 16      WDT
            00                                      # byte 17
            57 E9                                   # FCS
        """),
    ),
    Golden(
        "si_t3_inv_ctl_response",
        _ml2(
            R,
            ml2.M2Response(
                ml2.InvCtlResponse(6000, 35, 0x21, 0x41, 1800, 6000),
                status=M2Status.CMDRDY
                | M2Status.BB_OFF
                | M2Status.PON
                | M2Status.RUNX
                | M2Status.AGREE
                | M2Status.INV_READY
                | M2Status.REMOTE,
                rwdt=0xA5,
            ),
        ),
        hx("""
            4D 02 02 21  10 00 00 00  80 84 1E 00
            40                                      # byte 1       INV_CTL
            00                                      # byte 2       ALARM
            3C 26                                   # bytes 3,4    STATUS: CMDRDY BB_OFF PON RUNX | AGREE INV_READY REMOTE
            70 17                                   # bytes 5,6    output frequency 6000
            23 00                                   # bytes 7,8    output current 35 (3.5 A)
            21                                      # byte 9       SEL REF1/2 (copy)
            41                                      # byte 10      SEL MON1/2 (copy)
            08 07                                   # bytes 11,12  MON1 = 1800 (motor speed)
            70 17                                   # bytes 13,14  MON2 = 6000 (frequency reference)
            00                                      # byte 15
            A5                                      # byte 16      RWDT
            00                                      # byte 17
            DD A4                                   # FCS
        """),
    ),
    Golden(
        "si_et3_inv_ctl_command",
        _ml3(C, ml3.M3Command(ml3.InvCtl(0x0001_0001, 0, 6000, -100, 0x21, 0x41, 50, 500), wdt=0x12)),
        hx("""
            4D 03 01 21  45 23 01 00  40 42 0F 00
            50                                      # byte 0       INV_CTL
            12                                      # byte 1       WDT
            00 00                                   # bytes 2,3    CMD_CTRL
            01 00 01 00                             # bytes 4-7    INVCMD_CTRL: forward (bit 0), terminal S3 (bit 16)
            00 00 00 00                             # bytes 8-11   INVCMD_IO
            70 17 00 00                             # bytes 12-15  speed reference 6000, not used
            9C FF 00 00                             # bytes 16-19  torque reference -100, not used
            21 41                                   # bytes 20,21  SEL_REF1/2, SEL_MON1/2
            00 00                                   # bytes 22,23  reserved
            32 00 00 00                             # bytes 24-27  REF1 = 50, not used
            F4 01 00 00                             # bytes 28-31  REF2 = 500, not used
            7A 69                                   # FCS
        """),
    ),
    Golden(
        "si_et3_inv_ctl_response",
        _ml3(
            R,
            ml3.M3Response(ml3.InvCtlResponse(0x0300_086D, 0, 6000, 35, 0x21, 0x41, 1800, 6000), 0x21, 0x0004),
        ),
        hx("""
            4D 03 02 21  45 23 01 00  40 42 0F 00
            50                                      # byte 0       INV_CTL
            21                                      # byte 1       RWDT
            04 00                                   # bytes 2,3    CMD_STAT = CMDRDY
            6D 08 00 03                             # bytes 4-7    INVCMD_STAT: fwd, BB rel., PON, agree, ready (0-6),
                                                    #              REMOTE (11), SEL_MON1/2 status (24, 25)
            00 00 00 00                             # bytes 8-11   INVCMD_IO
            70 17 00 00                             # bytes 12-15  output frequency 6000
            23 00 00 00                             # bytes 16-19  output current 35
            21 41 00 00                             # bytes 20-23  SEL_REF1/2, SEL_MON1/2 (copies), reserved
            08 07 00 00                             # bytes 24-27  MON1 = 1800
            70 17 00 00                             # bytes 28-31  MON2 = 6000
            EA ED                                   # FCS
        """),
    ),
    # ---- 32-byte MECHATROLINK-II with an INV_I/O sub-command (SI-T3 "INV_I/O: 41H") ---------------------------
    Golden(
        "si_t3_32_byte_inv_io_subcommand_command",
        _ml2(C, ml2.M2Command(ml2.Nop(), wdt=0x07, sub=ml2.InvIo(0x65, 0x09, 0xB9, 0x67, 1000, 100, 2, 0))),
        hx("""
            4D 02 01 21  10 00 00 00  80 84 1E 00
            00 00                                   # bytes 1,2    NOP, 0
            00 00 00 00 00 00 00 00 00 00 00 00 00  # bytes 3-15
            07                                      # byte 16      WDT
            41                                      # byte 17      INV_I/O
            00                                      # byte 18      0
            65                                      # byte 19      SEL REF3/4: REF3 = 5 (PID target), REF4 = 6 (pulse)
            09                                      # byte 20      SEL REF5/6: REF5 = 9 (command selection)
            B9                                      # byte 21      SEL MON3/4: MON3 = 9, MON4 = B
            67                                      # byte 22      SEL MON5/6: MON5 = 7, MON6 = 6
            E8 03                                   # bytes 23,24  REF3 = 1000 (10.00 %)
            64 00                                   # bytes 25,26  REF4 = 100
            02 00                                   # bytes 27,28  REF5 = 0002H (bit 1: PID target enable)
            00 00                                   # bytes 29,30  REF6
            00 00                                   # bytes 31,32  reserved
            5A C1                                   # FCS
        """),
    ),
    Golden(
        "si_t3_32_byte_inv_io_subcommand_response",
        _ml2(
            R,
            ml2.M2Response(
                ml2.Nop(),
                status=0x0414,
                rwdt=0x07,
                sub=ml2.InvIoResponse(0x65, 0x09, 0xB9, 0x67, 0x0011, 0x0081, 0, 280),
                substatus=M2SubStatus.SUBCMDRDY,
            ),
        ),
        hx("""
            4D 02 02 21  10 00 00 00  80 84 1E 00
            00 00                                   # bytes 1,2    NOP, ALARM
            14 04                                   # bytes 3,4    STATUS
            00 00 00 00 00 00 00 00 00 00 00        # bytes 5-15
            07                                      # byte 16      RWDT
            41                                      # byte 17      INV_I/O
            04                                      # byte 18      SUBSTATUS = SUBCMDRDY (bit 2)
            65 09 B9 67                             # bytes 19-22  selections (copies)
            11 00                                   # bytes 23,24  MON3 = 0011H (output terminals)
            81 00                                   # bytes 25,26  MON4 = 0081H (input terminals)
            00 00                                   # bytes 27,28  MON5 = 0 (no drive alarm)
            18 01                                   # bytes 29,30  MON6 = 280 (DC bus, 1 V)
            00 00                                   # bytes 31,32  reserved
            3D 83                                   # FCS
        """),
    ),
    # ---- 64-byte MECHATROLINK-III with a PRM_RD sub-command (SI-ET3 §10 PRM_RD) --------------------------------
    Golden(
        "si_et3_64_byte_prm_rd_subcommand_command",
        _ml3(C, ml3.M3Command(ml3.Nop(), wdt=0x05, sub=ml3.PrmRd(C1_01, 2))),
        hx("""
            4D 03 01 21  45 23 01 00  40 42 0F 00
            00 05 00 00                             # bytes 0-3    NOP, WDT, CMD_CTRL
            00 00 00 00 00 00 00 00 00 00 00 00 00 00   # bytes 4-17
            00 00 00 00 00 00 00 00 00 00 00 00 00 00   # bytes 18-31
            01                                      # byte 32      SUBCMD = PRM_RD
            00 00 00                                # bytes 33-35  SUB_CTRL (Table 23)
            00 02                                   # bytes 36,37  NO = 0200H
            02                                      # byte 38      SIZE
            00                                      # byte 39      reserved
            00 00 00 00 00 00 00 00 00 00 00 00     # bytes 40-51
            00 00 00 00 00 00 00 00 00 00 00 00     # bytes 52-63
            97 68                                   # FCS
        """),
    ),
    Golden(
        "si_et3_64_byte_prm_rd_subcommand_response",
        _ml3(
            R,
            ml3.M3Response(ml3.Nop(), 0x05, 0x0004, sub=ml3.PrmRdResponse(C1_01, 2, READ_VALUE), sub_stat=0x000004),
        ),
        hx("""
            4D 03 02 21  45 23 01 00  40 42 0F 00
            00 05 04 00                             # bytes 0-3    NOP, RWDT, CMD_STAT = CMDRDY
            00 00 00 00 00 00 00 00 00 00 00 00 00 00   # bytes 4-17
            00 00 00 00 00 00 00 00 00 00 00 00 00 00   # bytes 18-31
            01                                      # byte 32      RSUBCMD = PRM_RD
            04 00 00                                # bytes 33-35  SUB_STAT = SUBCMDRDY (Table 24 bit 2)
            00 02 02 00                             # bytes 36-39  NO, SIZE, reserved (copies)
            64 00                                   # bytes 40,41  PARAMETER: C1-01 lower, upper
            00 00 00 00 00 00 00 00 00 00           # bytes 42-51
            00 00 00 00 00 00 00 00 00 00 00 00     # bytes 52-63
            DA A5                                   # FCS
        """),
    ),
    # ---- MECHATROLINK-I, 17 bytes (SI-T/V7 §7.1 NOP) ------------------------------------------------------------
    Golden(
        "v7_mechatrolink_i_nop_command",
        _ml1(C, ml2.M2Command(ml2.Nop(), wdt=0x01)),
        hx("""
            4D 01 01 03  07 00 00 00  80 84 1E 00   # envelope: ML-I, command, station 03H, cycle 7, 2 ms
            00 00                                   # bytes 1,2    NOP
            00 00 00 00 00 00 00 00 00 00 00 00 00  # bytes 3-15
            01                                      # byte 16      WDT
            00                                      # byte 17
            7C 6F                                   # FCS
        """),
    ),
    Golden(
        "v7_mechatrolink_i_nop_response",
        _ml1(R, ml2.M2Response(ml2.Nop(), status=0x0414, rwdt=0x01)),
        hx("""
            4D 01 02 03  07 00 00 00  80 84 1E 00
            00 00                                   # bytes 1,2    NOP, ALARM
            14 04                                   # bytes 3,4    STATUS
            00 00 00 00 00 00 00 00 00 00 00        # bytes 5-15
            01 00                                   # bytes 16,17  RWDT, reserved
            40 E0                                   # FCS
        """),
    ),
    # ---- ALARM byte: SI-T3 Table 25 A.94 data setting warning --------------------------------------------------
    Golden(
        "si_t3_table_25_a94_response",
        _ml2(R, ml2.M2Response(ml2.Nop(), alarm=M2Alarm.DATA_SETTING_WARNING, status=0x0006, rwdt=0x5B)),
        hx("""
            4D 02 02 21  10 00 00 00  80 84 1E 00
            00                                      # byte 1       NOP
            94                                      # byte 2       ALARM = 94H (A.94)
            06 00                                   # bytes 3,4    STATUS = WARNG|CMDRDY
            00 00 00 00 00 00 00 00 00 00 00        # bytes 5-15
            5B 00                                   # bytes 16,17  RWDT, reserved
            EB 53                                   # FCS
        """),
    ),
    # ---- Unknown command codes ----------------------------------------------------------------------------------
    Golden(
        # 41H exists as a sub-command only (SI-T3 Tables 5/6): as a main command it is undeclared.
        "si_t3_table_5_unknown_main_41h_command",
        _ml2(C, ml2.M2Command(Unknown(0x41, bytes.fromhex("6509B967E80364000200000000")), wdt=0x09)),
        hx("""
            4D 02 01 21  10 00 00 00  80 84 1E 00
            41                                      # byte 1       41H: no main command (Table 5)
            00                                      # byte 2
            65 09 B9 67 E8 03 64 00 02 00 00 00 00  # bytes 3-15   kept raw
            09                                      # byte 16      WDT
            00                                      # byte 17
            90 D7                                   # FCS
        """),
    ),
    Golden(
        # 40H is the MECHATROLINK-II INV_CTL code; SI-ET3 Table 11 has no 40H (INV_CTL is 50H).
        "si_et3_table_11_unknown_40h_command",
        _ml3(C, ml3.M3Command(Unknown(0x40, bytes.fromhex("010070179CFF21413200F401") + bytes(16)), wdt=0x0A)),
        hx("""
            4D 03 01 21  45 23 01 00  40 42 0F 00
            40 0A 00 00                             # bytes 0-3    40H (not in Table 11), WDT, CMD_CTRL
            01 00 70 17 9C FF 21 41 32 00 F4 01     # bytes 4-15   kept raw
            00 00 00 00 00 00 00 00                 # bytes 16-23
            00 00 00 00 00 00 00 00                 # bytes 24-31
            B9 AA                                   # FCS
        """),
    ),
    Golden(
        "si_et3_cmd_alm_8_unsupported_response",
        _ml3(R, ml3.M3Response(Unknown(0x40, bytes(28)), rwdt=0x0A, cmd_stat=0x0804)),
        hx("""
            4D 03 02 21  45 23 01 00  40 42 0F 00
            40 0A                                   # bytes 0,1    RCMD 40H, RWDT
            04 08                                   # bytes 2,3    CMD_STAT: CMDRDY, CMD_ALM = 8 (unsupported command)
            00 00 00 00 00 00 00 00 00 00 00 00 00 00   # bytes 4-17
            00 00 00 00 00 00 00 00 00 00 00 00 00 00   # bytes 18-31
            C3 5F                                   # FCS
        """),
    ),
]

BY_NAME = {g.name: g for g in GOLDEN}
assert len(BY_NAME) == len(GOLDEN), "golden names must be unique"
