"""Wire layer: the UDP datagram envelope and the MECHATROLINK-I/II/III frame codecs (bytes <-> frames). Pure.

>>> from mlink_sim.wire import Frame, Link, Kind, encode, decode, ml2
>>> f = Frame(Link.ML2, Kind.COMMAND, 0x21, 1, 2_000_000, ml2.M2Command(ml2.PrmRd(0x0200, 2), wdt=0x10))
>>> decode(encode(f)) == f
True
"""

from . import ml2, ml3
from .codes import (
    CmdAlm,
    CommAlm,
    ConnectVersion,
    InvCmdCtrl,
    InvCmdStat,
    Kind,
    Link,
    M2Alarm,
    M2Cmd,
    M2ComMod,
    M2Status,
    M2SubStatus,
    M3Cmd,
    M3ComMod,
    OperationSignal,
    PROFILE_TYPE_INVERTER,
    SubCmdAlm,
)
from .describe import describe, format_frame, format_line
from .fcs import crc16_x25
from .frame import FCS_SIZE, HEADER_SIZE, MAGIC, DropReason, Frame, Message, WireError, datagram_size, decode, encode
from .layout import Unknown

__all__ = [
    "ml2",
    "ml3",
    "Frame",
    "Message",
    "Unknown",
    "encode",
    "decode",
    "describe",
    "format_frame",
    "format_line",
    "datagram_size",
    "crc16_x25",
    "WireError",
    "DropReason",
    "MAGIC",
    "HEADER_SIZE",
    "FCS_SIZE",
    "Link",
    "Kind",
    "M2Cmd",
    "M3Cmd",
    "M2Alarm",
    "M2Status",
    "M2SubStatus",
    "M2ComMod",
    "M3ComMod",
    "OperationSignal",
    "CmdAlm",
    "CommAlm",
    "SubCmdAlm",
    "InvCmdCtrl",
    "InvCmdStat",
    "ConnectVersion",
    "PROFILE_TYPE_INVERTER",
]
