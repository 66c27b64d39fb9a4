"""Readable and JSON views of a decoded frame (``mlink-sim decode``, logs, the live status)."""

from __future__ import annotations

import dataclasses
import enum
from typing import Any

from . import ml2, ml3
from .codes import CmdAlm, CommAlm, Link, M2Alarm, M2Cmd, M2Status, M2SubStatus, M3Cmd, SubCmdAlm
from .drive_codes import SiT3DriveAlarm, SiT3DriveWarning
from .frame import Frame
from .layout import Unknown

__all__ = ["describe", "format_frame", "format_line"]


def _flag_names(flag_type: type[enum.IntFlag], value: int) -> list[str]:
    return [m.name for m in flag_type if m.value & value and m.value.bit_count() == 1 and m.name]


def _enum_name(enum_type: type[enum.IntEnum], value: int) -> str:
    try:
        return enum_type(value).name
    except ValueError:
        return f"{value:#04x}"


def _body(body: Any, commands: type[enum.IntEnum], slot_code: int) -> dict[str, Any]:
    name = _enum_name(commands, slot_code)
    if isinstance(body, Unknown):
        return {"command": name, "code": slot_code, "unknown": True, "raw": body.raw.hex()}
    out: dict[str, Any] = {"command": name, "code": slot_code}
    for f in dataclasses.fields(body):
        v = getattr(body, f.name)
        out[f.name] = v.hex() if isinstance(v, bytes) else v
    return out


def _alarm_name(code: int, status: int) -> str:
    """Name of an ALARM byte: the card's own codes first (SI-T3 Tables 23/25), then the drive table that the STATUS
    bits point at – Table 26 (alarm) with ALM, Table 27 (minor fault) with WARNG only – since the two tables
    reuse the same values."""
    tables: tuple[type[enum.IntEnum], ...] = (M2Alarm,)
    if status & M2Status.ALM:
        tables += (SiT3DriveAlarm,)
    elif status & M2Status.WARNG:
        tables += (SiT3DriveWarning,)
    for table in tables:
        try:
            return table(code).name
        except ValueError:
            continue
    return f"{code:#04x}"


def describe(frame: Frame) -> dict[str, Any]:
    """A JSON-serialisable dict of every field of *frame*, with code and flag names."""
    msg = frame.message
    out: dict[str, Any] = {
        "link": frame.link.name,
        "kind": frame.kind.name.lower(),
        "station": frame.station,
        "cycle": frame.cycle,
        "tcycle_ns": frame.tcycle_ns,
        "data_size": frame.data_size,
    }
    if isinstance(msg, ml2.M2Command):
        out["main"] = _body(msg.body, M2Cmd, msg.code)
        out["wdt"] = msg.wdt
        if msg.sub is not None:
            out["sub"] = _body(msg.sub, M2Cmd, ml2.COMMAND_SUB.code_of(msg.sub))
    elif isinstance(msg, ml2.M2Response):
        out["main"] = _body(msg.body, M2Cmd, msg.code)
        out["alarm"] = msg.alarm
        out["alarm_name"] = _alarm_name(msg.alarm, msg.status) if msg.alarm else None
        out["status"] = msg.status
        out["status_bits"] = _flag_names(M2Status, msg.status)
        out["rwdt"] = msg.rwdt
        if msg.sub is not None:
            out["sub"] = _body(msg.sub, M2Cmd, ml2.RESPONSE_SUB.code_of(msg.sub))
            out["substatus"] = msg.substatus
            out["substatus_bits"] = _flag_names(M2SubStatus, msg.substatus)
    elif isinstance(msg, ml3.M3Command):
        out["main"] = _body(msg.body, M3Cmd, msg.code)
        out["wdt"] = msg.wdt
        out["cmd_ctrl"] = dataclasses.asdict(msg.ctrl)
        if msg.sub is not None:
            out["sub"] = _body(msg.sub, M3Cmd, ml3.COMMAND_SUB.code_of(msg.sub))
    else:
        assert isinstance(msg, ml3.M3Response)
        out["main"] = _body(msg.body, M3Cmd, msg.code)
        out["rwdt"] = msg.rwdt
        stat = dataclasses.asdict(msg.stat)
        stat["cmd_alm_name"] = _enum_name(CmdAlm, msg.stat.cmd_alm)
        stat["comm_alm_name"] = _enum_name(CommAlm, msg.stat.comm_alm)
        out["cmd_stat"] = stat
        if msg.sub is not None:
            out["sub"] = _body(msg.sub, M3Cmd, ml3.RESPONSE_SUB.code_of(msg.sub))
            sub_stat = dataclasses.asdict(msg.substat)
            sub_stat["subcmd_alm_name"] = _enum_name(SubCmdAlm, msg.substat.subcmd_alm)
            out["sub_stat"] = sub_stat
    return out


#: Keys a body dict may carry beyond describe()'s, added by a reader that knows the station's card
#: (``mlink-sim decode``): ``param`` (the parameter a PRM_RD/PRM_WR addresses: its ``text``, e.g.
#: ``"C1-01 (0200H) = 1.0 s"``, stands for NO, SIZE and the data) and ``<field>_bits`` (the names of a status
#: field's bits, shown instead of its hex value).
_PARAM_FIELDS = ("no", "size", "parameter", "data")


def _fmt_body(d: dict[str, Any]) -> str:
    param = d.get("param")
    hidden = {"command", "code", "param", *(k for k in d if k.endswith("_bits"))}
    if param is not None:
        hidden.update(_PARAM_FIELDS)
    fields = " ".join(
        f"{k}={'|'.join(d[k + '_bits']) or '0'}" if k + "_bits" in d
        else f"{k}={v:#x}" if isinstance(v, int) and k in ("no", "signals", "invcmd_ctrl", "invcmd_stat")
        else f"{k}={v}"
        for k, v in d.items()
        if k not in hidden
    )
    if param is not None:
        fields = f"{param['text']} {fields}".rstrip()
    return f"{d['command']}({d['code']:02X}H){(' ' + fields) if fields else ''}"


def format_frame(frame: Frame, d: dict[str, Any] | None = None) -> str:
    """A compact multi-line human-readable rendering of *frame* (of *d*, its :func:`describe` with names added,
    when given)."""
    d = describe(frame) if d is None else d
    link = Link(frame.link).label
    lines = [
        f"{link} {d['kind']} station {frame.station:#04x} ({frame.station:02X}H) cycle {frame.cycle} "
        f"tcycle {frame.tcycle_ns / 1e6:g} ms, {frame.data_size}-byte data",
        f"  main: {_fmt_body(d['main'])}",
    ]
    if "wdt" in d:
        lines.append(f"  WDT: {d['wdt']:#04x}")
    if "rwdt" in d:
        lines.append(f"  RWDT: {d['rwdt']:#04x}")
    if "alarm" in d:
        alarm = f"{d['alarm']:02X}H {d['alarm_name']}" if d["alarm"] else "00H"
        lines.append(f"  ALARM: {alarm}   STATUS: {d['status']:#06x} {' '.join(d['status_bits'])}")
    if "cmd_ctrl" in d:
        lines.append(f"  CMD_CTRL: {d['cmd_ctrl']}")
    if "cmd_stat" in d:
        lines.append(f"  CMD_STAT: {d['cmd_stat']}")
    if "sub" in d:
        lines.append(f"  sub: {_fmt_body(d['sub'])}")
    if "substatus" in d:
        lines.append(f"  SUBSTATUS: {' '.join(d['substatus_bits']) or '0'}")
    if "sub_stat" in d:
        lines.append(f"  SUB_STAT: {d['sub_stat']}")
    return "\n".join(lines)


def format_line(frame: Frame, d: dict[str, Any] | None = None) -> str:
    """*frame* on one line (``mlink-sim decode --pcap``): link, kind, station, cycle, main [+ sub] command with their
    fields, WDT/RWDT and the status/alarm fields that are set (from *d*, its :func:`describe` with names added,
    when given)."""
    d = describe(frame) if d is None else d
    kind = "cmd" if frame.kind == 1 else "rsp"
    parts = [f"{d['link']} {kind} {frame.station:02X}H cycle {frame.cycle}", _fmt_body(d["main"])]
    if "sub" in d:
        parts.append("sub " + _fmt_body(d["sub"]))
    if "wdt" in d:
        parts.append(f"WDT {d['wdt']:02X}H")
    if "rwdt" in d:
        parts.append(f"RWDT {d['rwdt']:02X}H")
    if d.get("alarm"):
        parts.append(f"ALARM {d['alarm']:02X}H {d['alarm_name']}")
    if "status_bits" in d:
        parts.append("STATUS " + ("|".join(d["status_bits"]) or "0"))
    if "cmd_ctrl" in d and (d["cmd_ctrl"]["alm_clr"] or d["cmd_ctrl"]["cmd_id"]):
        parts.append(f"CMD_CTRL {d['cmd_ctrl']}")
    stat = d.get("cmd_stat")
    if stat is not None:
        flags = [k.upper() for k in ("d_alm", "d_war", "cmdrdy", "alm_clr_cmp") if stat[k]]
        if stat["cmd_alm"]:
            flags.append(f"CMD_ALM {stat['cmd_alm_name']}")
        if stat["comm_alm"]:
            flags.append(f"COMM_ALM {stat['comm_alm_name']}")
        parts.append("CMD_STAT " + ("|".join(flags) or "0"))
    sub_stat = d.get("sub_stat")
    if sub_stat is not None and sub_stat["subcmd_alm"]:
        parts.append(f"SUBCMD_ALM {sub_stat['subcmd_alm_name']}")
    return "  ".join(parts)
