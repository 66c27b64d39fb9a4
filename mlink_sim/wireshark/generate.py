"""Build the Wireshark dissector ``mlink.lua`` from the package's own tables, so that the two cannot drift.

The shipped file is the generated table section (every command code, body layout, data-area framing, status and
control bit, alarm code and the CRC-16/X-25 table, each taken from :mod:`mlink_sim.wire`; the parameter names,
units and scales from :mod:`mlink_sim.params`) followed by the
hand-written dissector code in ``dissector.lua``. ``tests/wireshark/test_generate.py`` checks that the shipped
``mlink.lua`` equals :func:`build`'s output; after changing a wire table run::

    python -m mlink_sim.wireshark.generate        # rewrites mlink_sim/wireshark/mlink.lua
"""

from __future__ import annotations

import dataclasses
import enum
import re
import struct
import sys
from importlib import resources
from pathlib import Path
from typing import Any

from ..params import FAMILIES, Param, ParamTable
from ..profiles import BUILTIN, spelling
from ..wire import codes, fcs, ml2, ml3
from ..wire.drive_codes import SiT3DriveAlarm, SiT3DriveWarning
from ..wire.frame import ENVELOPE, FCS_SIZE, HEADER_SIZE, MAGIC
from ..wire.layout import Slot, fast_format

__all__ = ["build", "lua_tables", "shipped_path", "main"]

_KIND = {"B": "u8", "b": "s8", "H": "u16", "h": "s16", "I": "u32", "i": "s32", "L": "u32", "l": "s32"}
#: body fields shown in hex (register numbers, bit fields, mode bytes)
_HEX = {"no", "signals", "invcmd_ctrl", "invcmd_stat", "invcmd_io", "com_mod", "ver", "profile_type", "sel_ref",
        "sel_mon", "sel_ref34", "sel_ref56", "sel_mon34", "sel_mon56", "device_code"}
#: body fields whose bits are named: field -> table of bits
_BITS = {"signals": codes.OperationSignal, "invcmd_ctrl": codes.InvCmdCtrl, "invcmd_stat": codes.InvCmdStat}
#: names the dissector uses for the envelope and the data-area framing; a body field may not reuse one
_RESERVED = {"magic", "link", "kind", "station", "cycle", "tcycle_ns", "data_size", "fcs", "code", "cmd", "subcmd",
             "wdt", "rwdt", "alarm", "status", "substatus", "cmd_ctrl", "cmd_stat", "sub_ctrl", "sub_stat", "main",
             "sub"}


def _fields(declaration: Any, size: int) -> list[tuple[str, int, int, str]]:
    """``(name, offset, size, kind)`` of every named field of a construct ``Struct`` (via ``fast_format``)."""
    fmt, names = fast_format(declaration, size)
    out: list[tuple[str, int, int, str]] = []
    offset, it = 0, iter(names)
    for count, char in re.findall(r"(\d*)([a-zA-Z])", fmt[1:]):
        n = int(count) if count else 1
        if char == "x":
            offset += n
        elif char == "s":
            out.append((next(it), offset, n, "bytes"))
            offset += n
        else:
            width = struct.calcsize("<" + char)
            for _ in range(n):
                out.append((next(it), offset, width, _KIND[char]))
                offset += width
    return out


def _slot(slot: Slot) -> dict[int, list[tuple[str, int, int, str]]]:
    return {code: _fields(layout.struct.subcon, slot.size) for code, layout in sorted(slot.by_code.items())}


def _names(enum_type: type[enum.Enum]) -> dict[int, str]:
    return {int(m.value): m.name for m in enum_type}


def _bits(flag_type: type[enum.IntFlag]) -> list[tuple[int, str]]:
    return [(int(m.value), str(m.name)) for m in flag_type if m.name and int(m.value).bit_count() == 1]


def _packed(cls: Any) -> list[tuple[str, int]]:
    """``(field, mask)`` of a packed status/control dataclass (``to_int``), found by setting each field alone."""
    out = []
    for f in dataclasses.fields(cls):
        value = True if f.type in ("bool", bool) else 0xFFFF
        base = {g.name: (False if g.type in ("bool", bool) else 0) for g in dataclasses.fields(cls)}
        mask = cls(**{**base, f.name: value}).to_int()
        out.append((f.name, mask))
    return out


def _commands() -> dict[int, str]:
    out = _names(codes.M2Cmd)
    for code, name in _names(codes.M3Cmd).items():
        if out.setdefault(code, name) != name:
            raise ValueError(f"command code {code:#04x} is {out[code]} on ML-II and {name} on ML-III")
    return dict(sorted(out.items()))


def _crc_table() -> list[int]:
    """The reflected CRC-16/X-25 table (polynomial 0x8408), checked against :func:`fcs.crc16_x25`."""
    table = []
    for i in range(256):
        crc = i
        for _ in range(8):
            crc = (crc >> 1) ^ 0x8408 if crc & 1 else crc >> 1
        table.append(crc)
    crc = 0xFFFF
    for b in b"123456789":
        crc = (crc >> 8) ^ table[(crc ^ b) & 0xFF]
    if crc ^ 0xFFFF != fcs.crc16_x25(b"123456789"):
        raise AssertionError("CRC table disagrees with mlink_sim.wire.fcs")
    return table


def _body_fields(gens: dict[str, dict[str, Any]]) -> dict[str, tuple[str, str]]:
    """Every body field name -> (Wireshark field type, base): ``bytes``, or ``uintN``/``intN`` wide enough for
    every layout that uses the name."""
    kinds: dict[str, set[str]] = {}
    widths: dict[str, int] = {}
    for slots in gens.values():
        for slot in slots.values():
            for fields in slot.values():
                for name, _, size, kind in fields:
                    kinds.setdefault(name, set()).add(kind)
                    widths[name] = max(widths.get(name, 0), size)
    out = {}
    for name, ks in sorted(kinds.items()):
        if name in _RESERVED:
            raise ValueError(f"body field {name!r} clashes with an envelope field of the dissector")
        if "bytes" in ks and len(ks) > 1:
            raise ValueError(f"body field {name!r} is bytes in one layout and a number in another")
        signed = any(k.startswith("s") for k in ks)
        wtype = "bytes" if "bytes" in ks else f"{'int' if signed else 'uint'}{8 * widths[name]}"
        out[name] = (wtype, "hex" if name in _HEX else "dec")
    return out


def _param_row(param: Param) -> list[Any]:
    """``{name, format, scale, signed, unit suffix}`` of a row: the value is ``string.format(format, raw * scale)``
    (``raw`` alone for a hex row) followed by the suffix, as :meth:`Param.format` writes it ("1.0 s", "150%",
    "24H")."""
    if param.radix == 16:
        fmt, scale = f"%0{len(f'{param.maximum:X}')}XH", 1.0
    else:
        fmt, scale = f"%.{param.decimals}f", float(param.scale)
    suffix = param.with_unit("")
    return [param.name, fmt, scale, param.signed, suffix]


def _params(table: ParamTable) -> dict[int, list[Any]]:
    """Register -> :func:`_param_row`, every register of *table* (alternative registers too)."""
    return {reg: _param_row(row) for row in table for reg in row.registers}


def _lua(value: Any, indent: int = 0) -> str:
    pad = "  " * indent
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        return repr(value)
    if isinstance(value, str):
        return '"' + value.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(value, (list, tuple)):
        if all(isinstance(v, (int, str)) for v in value):
            return "{" + ", ".join(_lua(v) for v in value) + "}"
        return "{\n" + "".join(f"{pad}  {_lua(v, indent + 1)},\n" for v in value) + pad + "}"
    if isinstance(value, dict):
        items = []
        for k, v in value.items():
            key = f"[{k}]" if isinstance(k, int) else (k if re.fullmatch(r"[A-Za-z_]\w*", k) else f"[{_lua(k)}]")
            items.append(f"{pad}  {key} = {_lua(v, indent + 1)},\n")
        return "{\n" + "".join(items) + pad + "}"
    raise TypeError(f"cannot write {type(value).__name__} as Lua")


def lua_tables() -> dict[str, Any]:
    """The tables the dissector carries, as Python data."""
    gens = {
        "ml2": {"cmd_main": _slot(ml2.COMMAND_MAIN), "rsp_main": _slot(ml2.RESPONSE_MAIN),
                "cmd_sub": _slot(ml2.COMMAND_SUB), "rsp_sub": _slot(ml2.RESPONSE_SUB)},
        "ml3": {"cmd_main": _slot(ml3.COMMAND_MAIN), "rsp_main": _slot(ml3.RESPONSE_MAIN),
                "cmd_sub": _slot(ml3.COMMAND_SUB), "rsp_sub": _slot(ml3.RESPONSE_SUB)},
    }
    frames = {
        "ml2": {"cmd": {17: _fields(ml2.COMMAND_FRAME_17, 17), 32: _fields(ml2.COMMAND_FRAME_32, 32)},
                "rsp": {17: _fields(ml2.RESPONSE_FRAME_17, 17), 32: _fields(ml2.RESPONSE_FRAME_32, 32)}},
        "ml3": {"cmd": {32: _fields(ml3.COMMAND_FRAME_32, 32), 64: _fields(ml3.COMMAND_FRAME_64, 64)},
                "rsp": {32: _fields(ml3.RESPONSE_FRAME_32, 32), 64: _fields(ml3.RESPONSE_FRAME_64, 64)}},
    }
    return {
        "magic": MAGIC,
        "header_size": HEADER_SIZE,
        "fcs_size": FCS_SIZE,
        "envelope": _fields(ENVELOPE, HEADER_SIZE),
        "links": {int(link): link.label for link in codes.Link},
        "link_gen": {int(link): ("ml3" if link is codes.Link.ML3 else "ml2") for link in codes.Link},
        "data_sizes": {int(link): list(link.data_sizes) for link in codes.Link},
        "kinds": {1: "command", 2: "response"},
        "commands": _commands(),
        "gen_commands": {"ml2": _names(codes.M2Cmd), "ml3": _names(codes.M3Cmd)},
        "bodies": gens,
        "frames": frames,
        "body_fields": {name: list(v) for name, v in _body_fields(gens).items()},
        "body_bits": {name: _bits(flags) for name, flags in _BITS.items()},
        "status_bits": _bits(codes.M2Status),
        "substatus_bits": _bits(codes.M2SubStatus),
        "cmd_ctrl": _packed(ml3.CmdCtrl),
        "cmd_stat": _packed(ml3.CmdStat),
        "sub_stat": _packed(ml3.SubStat),
        "m2_alarm": _names(codes.M2Alarm),
        "drive_alarm": _names(SiT3DriveAlarm),
        "drive_warning": _names(SiT3DriveWarning),
        "cmd_alm": _names(codes.CmdAlm),
        "comm_alm": _names(codes.CommAlm),
        "subcmd_alm": _names(codes.SubCmdAlm),
        "status_alm_bit": int(codes.M2Status.ALM),
        "status_warng_bit": int(codes.M2Status.WARNG),
        "crc_table": _crc_table(),
        # parameters by name (docs/parameters.md): the card picks its family's table; a station of unknown card is
        # taken for the card its link assumes (ML-III: SI-ET3, ML-I: SI-T/V7); an ML-II station's card comes from the
        # preference mlink.cards or the capture's card note. The package's cards (profiles.BUILTIN), any spelling.
        "params": {family: _params(FAMILIES[family]) for family in sorted({p.family for p in BUILTIN})},
        "card_family": {spelling(name): p.family for p in BUILTIN for name in (p.key, p.label)},
        "link_card": {int(codes.Link[link]): spelling(p.key) for p in BUILTIN for link in p.assumed_on},
        "prm_commands": ["PRM_RD", "PRM_WR"],
        "refusals_ml2": [int(codes.M2Alarm.DATA_SETTING_WARNING), int(codes.M2Alarm.COMMAND_WARNING)],
        "substatus_errors": int(codes.M2SubStatus.SUBALM | codes.M2SubStatus.SUBWARNG),
    }


def build() -> str:
    """The complete ``mlink.lua``: generated tables, then ``dissector.lua``."""
    code = resources.files(__package__).joinpath("dissector.lua").read_text(encoding="utf-8")
    return (
        "-- mlink.lua - Wireshark dissector for mlink-sim's MECHATROLINK-I/II/III over UDP (Wireshark 4.0+).\n"
        "-- GENERATED by `python -m mlink_sim.wireshark.generate` from mlink_sim/wire (tables) and\n"
        "-- mlink_sim/wireshark/dissector.lua (code). Do not edit: change those and regenerate.\n"
        "-- Manuals: SI-T3 (SIEP C730600 50), SI-ET3 (SIEP C730600 88), SI-T/V7; see docs/wire-format.md.\n\n"
        f"local T = {_lua(lua_tables())}\n\n{code}"
    )


def shipped_path() -> Path:
    """Where the package keeps ``mlink.lua``."""
    return Path(str(resources.files(__package__).joinpath("mlink.lua")))


def main() -> None:
    target = shipped_path()
    text = build()
    tmp = target.with_suffix(".lua.tmp")
    tmp.write_text(text, encoding="utf-8")
    tmp.replace(target)
    print(f"wrote {target} ({len(text)} characters)", file=sys.stderr)


if __name__ == "__main__":
    main()
