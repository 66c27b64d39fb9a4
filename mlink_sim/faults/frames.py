"""The bytes a master-side fault touches: the WDT byte of a command, the cyclic slot, a refused command and the card's
answer to it. Offsets and codes come from the ``wire`` declarations (nothing is declared twice).
"""

from __future__ import annotations

from dataclasses import dataclass

from ..params import FAMILIES
from ..wire import CmdAlm, Frame, Kind, Link, M2Alarm, M2Cmd, M2Status, M2SubStatus, M3Cmd, SubCmdAlm, WireError, \
    decode, encode, ml2, ml3
from ..wire.frame import FCS_SIZE, HEADER_SIZE, datagram_offset, with_fcs

__all__ = ["Answer", "wdt_offset", "set_wdt_count", "is_cyclic", "bad_command", "read_answer", "station_of",
           "command_code", "wdt_count", "rearms"]

_ML3 = int(Link.ML3)
#: Offset of the WDT byte in a command datagram, by (link is ML-III, data size).
_WDT_AT = {
    (False, 17): datagram_offset("wdt", ml2.COMMAND_FRAME_17),
    (False, 32): datagram_offset("wdt", ml2.COMMAND_FRAME_32),
    (True, 32): datagram_offset("wdt", ml3.COMMAND_FRAME_32),
    (True, 64): datagram_offset("wdt", ml3.COMMAND_FRAME_64),
}
_SUB_AT = {  # the sub-command code's offset, frames that have one
    (False, 32): datagram_offset("subcode", ml2.COMMAND_FRAME_32),
    (True, 64): datagram_offset("subcode", ml3.COMMAND_FRAME_64),
}
_LINK_AT = 1  # envelope: magic, link, kind, station (wire/frame.py ENVELOPE)
_STATION_AT = 3
_INV_CTL = {False: int(M2Cmd.INV_CTL), True: int(M3Cmd.INV_CTL)}
_DISCONNECT = {False: int(M2Cmd.DISCONNECT), True: int(M3Cmd.DISCONNECT)}
_SYNC_SET = {False: int(M2Cmd.SYNC_SET), True: int(M3Cmd.SYNC_SET)}
_CONNECT = {False: int(M2Cmd.CONNECT), True: int(M3Cmd.CONNECT)}
#: A parameter every card answers PRM_RD for: C1-01 Acceleration Time 1 (SI-T3 Table 8 / SI-ET3 PRM_RD example
#: 0200H); on the VS-606V7, n019 Acceleration Time 1 (SI-T/V7 constant list).
_PARAMETER = {"v7": "n019", "a1000": "C1-01"}


def _register(family: str) -> int:
    return FAMILIES[family].by_name(_PARAMETER[family]).register


def _key(datagram: bytes) -> tuple[bool, int]:
    return datagram[_LINK_AT] == _ML3, len(datagram) - HEADER_SIZE - FCS_SIZE


def station_of(datagram: bytes) -> int:
    return datagram[_STATION_AT]


def command_code(datagram: bytes) -> int:
    return datagram[HEADER_SIZE]


def wdt_offset(datagram: bytes) -> int | None:
    return _WDT_AT.get(_key(datagram))


def set_wdt_count(datagram: bytes, count: int) -> bytes:
    """*datagram* with the master's WDT count (bits 4–7; bits 0–3 echo the slave's) set to *count* and the FCS
    recomputed; unchanged when it has no WDT (ML-III DISCONNECT: byte 1 reserved) or an unknown size."""
    ml3_link, _ = _key(datagram)
    at = wdt_offset(datagram)
    if at is None or (ml3_link and datagram[HEADER_SIZE] == _DISCONNECT[True]):
        return datagram
    body = bytearray(datagram[:-FCS_SIZE])
    body[at] = (count & 0xF) << 4 | (body[at] & 0x0F)
    return with_fcs(body)


def wdt_count(datagram: bytes) -> int | None:
    at = wdt_offset(datagram)
    return None if at is None else datagram[at] >> 4


def rearms(datagram: bytes) -> bool:
    """CONNECT or SYNC_SET: the card takes a fresh WDT baseline from it (SI-T3/SI-ET3 "SYNC_SET", CONNECT)."""
    ml3_link = datagram[_LINK_AT] == _ML3
    return datagram[HEADER_SIZE] in (_SYNC_SET[ml3_link], _CONNECT[ml3_link])


def is_cyclic(datagram: bytes) -> bool:
    """The master's cyclic INV_CTL with no sub-command (or a NOP one): a slot a bad command may take."""
    ml3_link, size = _key(datagram)
    if len(datagram) < HEADER_SIZE + 1 or datagram[HEADER_SIZE] != _INV_CTL[ml3_link]:
        return False
    sub_at = _SUB_AT.get((ml3_link, size))
    return sub_at is None or datagram[sub_at] == 0


def bad_command(datagram: bytes, kind: str, *, subcmd: bool, family: str) -> bytes:
    """The refused command that replaces the cyclic *datagram* (same cycle, transmission cycle and WDT, so nothing but
    the refusal changes on the card): see :class:`~mlink_sim.faults.spec.BadCommand`. *subcmd*: the station has
    sub-commands (CONNECT with SUBCMD = 1)."""
    frame = decode(datagram, kind=Kind.COMMAND)
    msg = frame.message
    ml3_link = frame.link is Link.ML3
    mod = ml3 if ml3_link else ml2
    register = _register(family)
    if kind == "phase":
        main, sub = mod.Disconnect(), None
    elif kind == "combination":  # ALM_RD row, PRM_RD column: "NG (A.95)" (SI-T3 Table 7), "-" (SI-ET3 Table 13)
        main, sub = mod.AlmRd(0), mod.PrmRd(register, 2)
    elif subcmd:  # data size in the sub-command: the main command stays the master's own
        main, sub = msg.body, mod.PrmRd(register, 3)
    else:
        main, sub = mod.PrmRd(register, 3), None
    has_sub = msg.sub is not None
    if sub is None and has_sub:
        sub = mod.Nop()
    message: ml3.M3Command | ml2.M2Command
    if ml3_link:
        message = ml3.M3Command(main, 0 if kind == "phase" else msg.wdt, msg.cmd_ctrl, sub, msg.sub_ctrl)
    else:
        message = ml2.M2Command(main, msg.wdt, sub)
    return encode(Frame(frame.link, Kind.COMMAND, frame.station, frame.cycle, frame.tcycle_ns, message))


@dataclass(frozen=True)
class Answer:
    """What a card answered to a command: its refusal (``code``, ``name``, ``where`` main/sub) or acceptance."""

    code: int
    name: str
    where: str  #: "main", "sub" or "" (accepted)

    @property
    def refused(self) -> bool:
        return bool(self.where)

    def describe(self) -> str:
        if not self.refused:
            return "accepted"
        if self.name in M2Alarm.__members__:
            return f"A.{self.code:02X} {self.name}" + (" (sub-command)" if self.where == "sub" else "")
        field = "SUBCMD_ALM" if self.where == "sub" else "CMD_ALM"
        return f"{field} {self.code:X}H {self.name}"


def read_answer(datagram: bytes) -> Answer | None:
    """The card's verdict in a response datagram (None: not a well-formed response)."""
    try:
        frame = decode(datagram, kind=Kind.RESPONSE)
    except WireError:
        return None
    msg = frame.message
    if frame.link is Link.ML3:
        cmd_alm = (msg.cmd_stat >> 8) & 0xF
        if cmd_alm:
            return Answer(cmd_alm, _name(CmdAlm, cmd_alm), "main")
        sub_alm = (msg.sub_stat >> 8) & 0xF if msg.sub is not None else 0
        if sub_alm:
            return Answer(sub_alm, _name(SubCmdAlm, sub_alm), "sub")
        return Answer(0, "", "")
    alarm = msg.alarm
    if msg.status & M2Status.WARNG and alarm in (M2Alarm.DATA_SETTING_WARNING, M2Alarm.COMMAND_WARNING):
        sub = msg.sub is not None and bool(msg.substatus & (M2SubStatus.SUBWARNG | M2SubStatus.SUBALM))
        return Answer(alarm, M2Alarm(alarm).name, "sub" if sub else "main")
    return Answer(0, "", "")


def _name(table: type, code: int) -> str:
    try:
        return table(code).name
    except ValueError:
        return f"{code:X}H"
