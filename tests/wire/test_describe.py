"""describe() (the ``--json`` view) and format_frame() (the human view of ``mlink-sim decode``)."""

from __future__ import annotations

import json

from hypothesis import given, settings

from mlink_sim.wire import (
    CmdAlm,
    CommAlm,
    Frame,
    Kind,
    Link,
    M2Alarm,
    M2Status,
    M2SubStatus,
    Unknown,
    describe,
    format_frame,
    ml2,
    ml3,
)
from mlink_sim.wire.drive_codes import SiT3DriveAlarm, SiT3DriveWarning

from wire_strategies import frames


def _ml2(kind: Kind, msg: object) -> Frame:
    return Frame(Link.ML2, kind, 0x21, 16, 2_000_000, msg)  # type: ignore[arg-type]


def _ml3(kind: Kind, msg: object) -> Frame:
    return Frame(Link.ML3, kind, 0x2A, 5, 1_000_000, msg)  # type: ignore[arg-type]


@settings(max_examples=120, deadline=None)
@given(frames())
def test_describe_is_json_serialisable(frame: Frame) -> None:
    d = describe(frame)
    text = json.dumps(d, allow_nan=False)
    assert json.loads(text) == d
    assert d["link"] == frame.link.name and d["kind"] == frame.kind.name.lower()
    assert d["station"] == frame.station and d["cycle"] == frame.cycle and d["tcycle_ns"] == frame.tcycle_ns
    assert d["data_size"] == frame.data_size
    assert d["main"]["code"] == frame.message.code
    assert ("sub" in d) == (frame.message.sub is not None)


@settings(max_examples=60, deadline=None)
@given(frames())
def test_format_frame_names_link_station_and_command(frame: Frame) -> None:
    text = format_frame(frame)
    assert frame.link.label in text
    assert f"station {frame.station:#04x} ({frame.station:02X}H)" in text
    assert f"({frame.message.code:02X}H)" in text


def test_ml2_response_alarm_and_status_names() -> None:
    frame = _ml2(
        Kind.RESPONSE,
        ml2.M2Response(
            ml2.PrmRdResponse(0x0200, 2), alarm=M2Alarm.DATA_SETTING_WARNING, status=M2Status.WARNG | M2Status.CMDRDY
        ),
    )
    d = describe(frame)
    assert d["main"]["command"] == "PRM_RD" and d["main"]["no"] == 0x0200
    assert d["alarm"] == 0x94 and d["alarm_name"] == "DATA_SETTING_WARNING"
    assert d["status_bits"] == ["WARNG", "CMDRDY"]
    text = format_frame(frame)
    assert "PRM_RD(01H)" in text and "no=0x200" in text
    assert "station 0x21 (21H)" in text
    assert "ALARM: 94H DATA_SETTING_WARNING" in text
    assert "WARNG CMDRDY" in text


def test_ml2_drive_alarm_name_from_si_t3_table_26() -> None:
    frame = _ml2(Kind.RESPONSE, ml2.M2Response(ml2.Nop(), alarm=SiT3DriveAlarm.OC, status=M2Status.ALM))
    assert describe(frame)["alarm_name"] == "OC"
    assert "ALARM: 07H OC" in format_frame(frame)


def test_ml2_no_alarm() -> None:
    frame = _ml2(Kind.RESPONSE, ml2.M2Response(ml2.Nop(), status=M2Status.CMDRDY))
    assert describe(frame)["alarm_name"] is None
    assert "ALARM: 00H" in format_frame(frame)


def test_ml2_drive_warning_name_from_si_t3_table_27() -> None:
    frame = _ml2(
        Kind.RESPONSE,
        ml2.M2Response(ml2.Nop(), alarm=SiT3DriveWarning.OV, status=M2Status.WARNG | M2Status.CMDRDY),
    )
    assert describe(frame)["alarm_name"] == "OV"


def test_ml2_sub_command_and_substatus_names() -> None:
    frame = _ml2(
        Kind.RESPONSE,
        ml2.M2Response(ml2.Nop(), sub=ml2.InvIoResponse(sel_mon34=0xB9, mon3=0x11), substatus=M2SubStatus.SUBCMDRDY),
    )
    d = describe(frame)
    assert d["sub"]["command"] == "INV_IO" and d["substatus_bits"] == ["SUBCMDRDY"]
    text = format_frame(frame)
    assert "sub: INV_IO(41H)" in text and "SUBSTATUS: SUBCMDRDY" in text


def test_ml3_command_names_and_cmd_ctrl() -> None:
    frame = _ml3(Kind.COMMAND, ml3.M3Command(ml3.InvCtl(invcmd_ctrl=1, speed_ref=6000), wdt=3, cmd_ctrl=0x08))
    d = describe(frame)
    assert d["main"]["command"] == "INV_CTL" and d["main"]["code"] == 0x50
    assert d["cmd_ctrl"] == {"alm_clr": True, "cmd_id": 0}
    text = format_frame(frame)
    assert "MECHATROLINK-III command station 0x2a (2AH)" in text
    assert "INV_CTL(50H)" in text and "invcmd_ctrl=0x1" in text and "speed_ref=6000" in text


def test_ml3_cmd_stat_alarm_names() -> None:
    stat = ml3.CmdStat(cmdrdy=True, cmd_alm=CmdAlm.INVALID_DATA, comm_alm=CommAlm.FCS_ERROR)
    sub_stat = ml3.SubStat(subcmd_alm=0x8)
    frame = _ml3(
        Kind.RESPONSE,
        ml3.M3Response(ml3.PrmRdResponse(0x0200, 2), cmd_stat=stat.to_int(), sub=ml3.Nop(), sub_stat=sub_stat.to_int()),
    )
    d = describe(frame)
    assert d["cmd_stat"]["cmd_alm"] == 9 and d["cmd_stat"]["cmd_alm_name"] == "INVALID_DATA"
    assert d["cmd_stat"]["comm_alm_name"] == "FCS_ERROR"
    assert d["sub_stat"]["subcmd_alm_name"] == "UNSUPPORTED_COMMAND"
    text = format_frame(frame)
    assert "PRM_RD(01H)" in text and "INVALID_DATA" in text and "FCS_ERROR" in text
    assert "UNSUPPORTED_COMMAND" in text


def test_unknown_body_is_flagged_with_its_raw_bytes() -> None:
    frame = _ml3(Kind.COMMAND, ml3.M3Command(Unknown(0x40, bytes([1]) + bytes(27))))
    d = describe(frame)
    assert d["main"]["unknown"] is True and d["main"]["code"] == 0x40
    assert d["main"]["raw"] == "01" + "00" * 27
    assert "(40H)" in format_frame(frame)
