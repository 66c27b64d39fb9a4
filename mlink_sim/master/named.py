"""Parameters by name for the master's requests: ``prm_rd(0x21, "C1-01")`` and ``prm_wr(0x21, "C1-01", 5.0)``.

The station's card picks the table (its profile's, :func:`mlink_sim.params.for_card`: the A1000 rows for SI-T3 and
SI-ET3, the VS-606V7 n-numbers for SI-T/V7; docs/parameters.md). A name is turned into its MEMOBUS register and a value in
engineering units into the register's raw count by the table's scale, checked against the row's range; every
problem raises :class:`~mlink_sim.master.types.ParamRequestError` before a request exists. A register given as a
number keeps the raw API: PRM_RD returns the unsigned word, PRM_WR writes the int given.
"""

from __future__ import annotations

from ..params import Param, ParamError, ParamTable, for_card
from ..profiles import default_for
from .plan import StationPlan
from .types import ParamRequestError, ParamValue

__all__ = ["table_for", "read_target", "write_target", "value_of", "SIZES"]

#: PRM_RD / PRM_WR SIZE: 2, 4, 6 or 8 bytes (SI-T3 Tables 8/9, SI-ET3 "PRM_RD" / "PRM_WR").
SIZES = (2, 4, 6, 8)


def _where(plan: StationPlan) -> str:
    profile = plan.profile
    return f"station {plan.address:02X}H ({profile.label if profile is not None else plan.link.label})"


def table_for(plan: StationPlan) -> ParamTable | None:
    """The parameter table of *plan*'s card; a station without a card name is the card its link is taken for
    (:func:`mlink_sim.profiles.default_for`: an SI-ET3 on ML-III, an SI-T/V7 on ML-I); None when the card is not
    known (ML-II: SI-T3 or SI-T/V7)."""
    profile = plan.profile or default_for(plan.link)
    return None if profile is None else for_card(profile)


def _register(plan: StationPlan, target: object, size: int) -> int:
    if size not in SIZES:
        raise ParamRequestError(plan.address, str(target), "SIZE 2, 4, 6 or 8",
                                f"{_where(plan)}: SIZE {size!r} is not 2, 4, 6 or 8 bytes")
    if isinstance(target, bool) or not isinstance(target, int) or not 0 <= target <= 0xFFFF:
        raise ParamRequestError(plan.address, repr(target), "a parameter name or a register 0000H…FFFFH",
                                f"{_where(plan)}: {target!r} is neither a parameter name (e.g. 'C1-01') nor a "
                                f"register number 0000H…FFFFH")
    return target


def _param(plan: StationPlan, name: str) -> Param:
    table = table_for(plan)
    if table is None:
        raise ParamRequestError(plan.address, name, "a register number",
                                f"{_where(plan)}: its card is not known, so '{name}' cannot be looked up; give "
                                f"the register number instead (docs/parameters.md)")
    try:
        return table.resolve(name)
    except ParamError as exc:
        raise ParamRequestError(plan.address, name, f"a parameter of {table.where}",
                                f"{_where(plan)}: {exc}") from None


def read_target(plan: StationPlan, target: str | int, size: int = 2) -> tuple[int, Param | None]:
    """``(register, row)`` for PRM_RD of *target*: a name ("C1-01"; the row comes along) or a register number
    (row None: the raw API)."""
    if isinstance(target, str):
        param = _param(plan, target)
        _register(plan, param.register, size)
        return param.register, param
    return _register(plan, target, size), None


def write_target(plan: StationPlan, target: str | int, value: object, size: int = 2) -> tuple[int, bytes,
                                                                                                Param | None]:
    """``(register, data, row)`` for PRM_WR: *value* in engineering units (a number, or text as the keypad takes
    it: "5.0", "5 s", "24H") for a name, converted by the row's scale and checked against its range and
    resolution; a raw int (or the bytes) for a register number. *data* is *size* bytes, LSB first."""
    if not isinstance(target, str):
        register = _register(plan, target, size)
        if isinstance(value, (bytes, bytearray)):
            return register, bytes(value), None
        if isinstance(value, bool) or not isinstance(value, int):
            raise ParamRequestError(plan.address, f"{register:04X}H", "a raw int or bytes",
                                    f"{_where(plan)}: register {register:04X}H takes a raw int (or the bytes); "
                                    f"{value!r} is not one (give the parameter's name for a value in units)")
        return register, (value % (1 << (8 * size))).to_bytes(size, "little"), None
    param = _param(plan, target)
    table = table_for(plan)
    assert table is not None  # _param found the row in it
    allowed = "read-only" if param.read_only else param.format_range()
    try:
        if isinstance(value, str):
            raw = table.parse_value(param, value)
        elif isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ParamError(f"{param.name}: {value!r} is not a number (expected e.g. "
                             f"{param.format(param.default)})")
        else:
            raw = param.to_raw(float(value))
            if abs(raw * param.scale - value) > param.scale * 1e-6:
                raise ParamError(f"{param.name}: {param.with_unit(f'{value:g}')} is finer than the setting "
                                 f"resolution of {param.format(1)}")
            table.check(param, raw)
    except ParamError as exc:
        text = str(exc) if param.read_only or allowed in str(exc) else f"{exc} (allowed: {allowed})"
        raise ParamRequestError(plan.address, param.name, allowed, f"{_where(plan)}: {text}") from None
    _register(plan, param.register, size)
    return param.register, param.encode(raw).to_bytes(2, "little").ljust(size, b"\0"), param


def value_of(param: Param, data: bytes) -> ParamValue:
    """The PRM_RD answer *data* (LSB first) of *param* as a :class:`ParamValue`."""
    raw = param.decode(int.from_bytes(data[:2], "little"))
    return ParamValue(param.name, param.to_eng(raw), param.eng_unit, raw, param.register, param.format(raw))
