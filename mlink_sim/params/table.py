"""Parameter rows and the table that indexes them (pure data + lookups, no I/O).

A :class:`Param` is one drive parameter or monitor as the option manuals and the drive
technical manuals describe it: a name (``C1-01``, ``U1-05``, ``n019``, ``U-01``), the MEMOBUS
register number the cards' PRM_RD/PRM_WR use ("The register number (NO) is the same as the
register number that is set and referenced in MEMOBUS/Modbus transfers", SI-T3 PRM_RD), and
the raw 16-bit range/default with the size of one raw count.

A :class:`ParamTable` is an immutable, indexed collection of rows for one drive family (or a
card's view of it, see :meth:`ParamTable.derive`).  It also turns command-line text such as
``C1-01=5.0`` or ``0200H=50`` into a checked ``(Param, raw)`` pair.

Every problem a user can cause raises :class:`ParamError`, whose message is a complete
sentence fit for the command line or a log line.  Broken table data (duplicate names, a
default outside its range) raises plain :class:`ValueError` at import time instead.
"""

from __future__ import annotations

import difflib
import math
import re
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass, field, replace
from typing import Any

__all__ = ["Param", "ParamError", "ParamTable"]

_U16_MAX = 0xFFFF
_S16_MIN = -0x8000
_S16_MAX = 0x7FFF

# "0.1 s" -> ("0.1", "s"); "%" -> (None, "%")
_UNIT_RE = re.compile(r"^\s*([0-9]+(?:\.[0-9]+)?)?\s*(.*?)\s*$")
# Names: A1000 "C1-01"/"U1-05", VS-606V7 constants "n019" and monitors "U-01".
_NAME_RE = re.compile(r"^(?:[A-Za-z][0-9]-[0-9]{2}|[Nn][0-9]{3}|[Uu]-[0-9]{2})$")
# Register numbers: "0x0200", "0200H", "200h".
_REG_RE = re.compile(r"^(?:0[xX]([0-9A-Fa-f]{1,4})|([0-9][0-9A-Fa-f]{0,3})[hH])$")
# Integer literals accepted for raw values: decimal (signed) or hex (0x.. / ..H).
_DEC_INT_RE = re.compile(r"^[+-]?[0-9]+$")
_HEX_INT_RE = re.compile(r"^(?:0[xX]([0-9A-Fa-f]+)|([0-9A-Fa-f]+)[hH])$")


class ParamError(ValueError):
    """A user-facing problem with a parameter name, register or value.

    ``str(error)`` is a complete sentence, e.g.
    ``"C1-01: 7000.0 s is out of range 0.0 … 6000.0 s"``.
    """


def _decimals(scale: float) -> int:
    """Decimals needed to show one count of ``scale`` exactly (0.1 -> 1, 0.001 -> 3, 1 -> 0)."""
    for digits in range(7):
        scaled = scale * 10**digits
        if abs(scaled - round(scaled)) < 1e-9:
            return digits
    return 6


@dataclass(frozen=True)
class Param:
    """One parameter or monitor of a drive family.

    ``minimum``/``maximum``/``default`` are raw counts; engineering value = raw * ``scale``.
    For monitors (``read_only``) minimum/maximum are the 16-bit wire range and ``default`` is 0.

    Extensions beyond the basic row:

    * ``radix`` – 16 when the drive shows and takes the value in hex (H1-xx selections,
      F6-20 station address, fault codes).  :meth:`ParamTable.parse_assignment` then reads
      a bare ``H1-03=24`` as 24H, like the keypad.
    * ``alt_registers`` – further MEMOBUS registers that read the same datum (the A1000
      mirrors U3-01…U3-04 at 0800H…0803H, for example).
    """

    name: str
    register: int
    title: str
    unit: str
    scale: float
    minimum: int
    maximum: int
    default: int
    read_only: bool = False
    signed: bool = False
    source: str = ""
    radix: int = 10
    alt_registers: tuple[int, ...] = ()

    def __post_init__(self) -> None:
        where = f"parameter row {self.name!r}"
        if not self.name or not self.title:
            raise ValueError(f"{where}: name and title are required")
        for reg in self.registers:
            if not 0 <= reg <= _U16_MAX:
                raise ValueError(f"{where}: register {reg!r} is not a 16-bit number")
        if not (isinstance(self.scale, (int, float)) and self.scale > 0):
            raise ValueError(f"{where}: scale must be positive")
        match = _UNIT_RE.match(self.unit)
        if match and match.group(1) is not None:
            if abs(float(match.group(1)) - self.scale) > 1e-12:
                raise ValueError(f"{where}: unit {self.unit!r} disagrees with scale {self.scale}")
        if self.radix not in (10, 16):
            raise ValueError(f"{where}: radix must be 10 or 16")
        if self.radix == 16 and (self.scale != 1 or self.signed):
            raise ValueError(f"{where}: hex parameters must be unsigned with scale 1")
        lo, hi = (_S16_MIN, _S16_MAX) if self.signed else (0, _U16_MAX)
        for label in ("minimum", "maximum", "default"):
            value = getattr(self, label)
            if isinstance(value, bool) or not isinstance(value, int):
                raise ValueError(f"{where}: {label} must be an int count")
            if not lo <= value <= hi:
                raise ValueError(f"{where}: {label} {value} does not fit the 16-bit wire format")
        if self.minimum > self.maximum:
            raise ValueError(f"{where}: minimum exceeds maximum")
        if not self.minimum <= self.default <= self.maximum:
            raise ValueError(f"{where}: default {self.default} outside {self.minimum}..{self.maximum}")

    # -- derived facts ---------------------------------------------------------------------

    @property
    def registers(self) -> tuple[int, ...]:
        """The primary register followed by any alternative registers."""
        return (self.register, *self.alt_registers)

    @property
    def decimals(self) -> int:
        """Decimal places of the engineering value (0.1 s -> 1)."""
        return _decimals(self.scale)

    @property
    def eng_unit(self) -> str:
        """The engineering unit symbol without the count size ("0.1 s" -> "s")."""
        match = _UNIT_RE.match(self.unit)
        return match.group(2) if match else self.unit

    @property
    def unverified(self) -> bool:
        """True when ``source`` flags a figure that could not be checked against a manual."""
        return "unverified" in self.source

    # -- conversions -----------------------------------------------------------------------

    def to_raw(self, value: float) -> int:
        """Engineering value -> raw count, rounded to the nearest count (halves away from 0).

        No range check here; use :meth:`ParamTable.check`.  ``parse_assignment`` is stricter
        and rejects values that are not on the count grid.
        """
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ParamError(f"{self.name}: {value!r} is not a number")
        if not math.isfinite(value):
            raise ParamError(f"{self.name}: {value!r} is not a finite number")
        counts = value / self.scale
        magnitude = math.floor(abs(counts) + 0.5 + 1e-9)
        return magnitude if counts >= 0 else -magnitude

    def to_eng(self, raw: int) -> float:
        """Raw count -> engineering value (rounded to the count's decimals)."""
        return round(raw * self.scale, self.decimals)

    def encode(self, raw: int) -> int:
        """Raw count -> the unsigned 16-bit word on the wire (two's complement if signed)."""
        return raw & _U16_MAX

    def decode(self, word: int) -> int:
        """Unsigned 16-bit wire word -> raw count (sign-extended if ``signed``)."""
        word &= _U16_MAX
        if self.signed and word > _S16_MAX:
            return word - 0x10000
        return word

    # -- display ---------------------------------------------------------------------------

    def format_number(self, raw: int) -> str:
        """The value as the keypad shows it, without unit ("10.0", "21H", "3")."""
        if self.radix == 16:
            width = len(f"{self.maximum:X}")
            return f"{raw:0{width}X}H"
        return f"{self.to_eng(raw):.{self.decimals}f}"

    def with_unit(self, text: str) -> str:
        unit = self.eng_unit
        if not unit or self.radix == 16:
            return text
        return f"{text}{unit}" if unit == "%" else f"{text} {unit}"

    def format(self, raw: int) -> str:
        """The value with its unit ("10.0 s", "150%", "21H")."""
        return self.with_unit(self.format_number(raw))

    def format_range(self) -> str:
        """"0.0 … 6000.0 s"."""
        return self.with_unit(f"{self.format_number(self.minimum)} … {self.format_number(self.maximum)}")


#: The drive families' tables by family (``mlink_sim.params`` fills it): an unknown name is looked up in the
#: others for its hint (:meth:`ParamTable.by_name`).
FAMILY_TABLES: dict[str, ParamTable] = {}


@dataclass(frozen=True)
class ParamTable:
    """An immutable, indexed parameter table for one drive family (or a card's view of it).

    ``family`` is the key in ``FAMILIES`` ("a1000", "v7"); ``label`` is the drive name used in
    messages ("A1000"); ``variant`` names a card view ("si-t3") or is empty.
    """

    family: str
    label: str
    rows: tuple[Param, ...]
    variant: str = ""
    _by_name: Mapping[str, Param] = field(init=False, repr=False, compare=False)
    _by_register: Mapping[int, Param] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        rows = tuple(self.rows)
        by_name: dict[str, Param] = {}
        by_register: dict[int, Param] = {}
        for row in rows:
            if not isinstance(row, Param):
                raise ValueError(f"{self.label} table: {row!r} is not a Param")
            key = row.name.upper()
            if key in by_name:
                raise ValueError(f"{self.label} table: duplicate parameter name {row.name}")
            by_name[key] = row
            for reg in row.registers:
                if reg in by_register:
                    raise ValueError(
                        f"{self.label} table: register {reg:04X}H used by both "
                        f"{by_register[reg].name} and {row.name}"
                    )
                by_register[reg] = row
        object.__setattr__(self, "rows", rows)
        object.__setattr__(self, "_by_name", by_name)
        object.__setattr__(self, "_by_register", by_register)

    # -- collection protocol ---------------------------------------------------------------

    def __iter__(self) -> Iterator[Param]:
        return iter(self.rows)

    def __len__(self) -> int:
        return len(self.rows)

    def __contains__(self, item: object) -> bool:
        if isinstance(item, Param):
            return self._by_name.get(item.name.upper()) == item
        if isinstance(item, str):
            return item.strip().upper() in self._by_name
        return False

    @property
    def where(self) -> str:
        """"the A1000 family" / "the A1000 family (SI-T3 view)" for messages."""
        text = f"the {self.label} family"
        return f"{text} ({self.variant.upper()} view)" if self.variant else text

    # -- lookups ---------------------------------------------------------------------------

    def get(self, name: str) -> Param | None:
        """Like :meth:`by_name` but returns None for an unknown name."""
        return self._by_name.get(name.strip().upper())

    def by_name(self, name: str) -> Param:
        """Case-insensitive lookup; raises :class:`ParamError` for an unknown name, with a hint: the row of the
        same name of another family (:data:`FAMILY_TABLES`) and the one of the same title here, or a name close to
        it of the same kind (a monitor for a monitor, a setting for a setting)."""
        row = self.get(name)
        if row is None:
            raise ParamError(f"unknown parameter '{name.strip()}' for {self.where}{self._hint(name.strip().upper())}")
        return row

    def _hint(self, key: str) -> str:
        for other in FAMILY_TABLES.values():
            foreign = other.get(key) if other.family != self.family else None
            if foreign is not None:
                same = [r.name for r in self.rows if r.title.lower() == foreign.title.lower()]
                here = f"; the {self.label}'s is {same[0]}" if same else f"; the {self.label} has none of that title"
                return f" ({foreign.name} is the {other.label}'s {foreign.title}{here})"
        monitor = any(r.read_only and r.name.upper()[:1] == key[:1] for r in self.rows)
        pool = [n for n, r in self._by_name.items() if r.read_only == monitor]
        hint = difflib.get_close_matches(key, pool, n=1)
        return f" (did you mean {self._by_name[hint[0]].name}?)" if hint else ""

    def by_register(self, register: int) -> Param | None:
        """The row at a MEMOBUS register number (primary or alternative), or None."""
        return self._by_register.get(register)

    def resolve(self, target: str | int) -> Param:
        """The row named *target* ("C1-01", "n019", case-insensitive) or at register *target* (an int, or text as
        ``0x0200`` / ``0200H``); raises :class:`ParamError` for an unknown name or register."""
        if isinstance(target, str):
            text = target.strip()
            reg_match = _REG_RE.match(text)
            if reg_match is None or _NAME_RE.match(text):
                return self.by_name(text)
            target = int(reg_match.group(1) or reg_match.group(2), 16)
        if isinstance(target, bool) or not isinstance(target, int):
            raise ParamError(f"{target!r} is neither a parameter name (e.g. 'C1-01') nor a register number")
        row = self.by_register(target)
        if row is None:
            raise ParamError(f"no parameter at register {target:04X}H for {self.where}")
        return row

    def group(self, prefix: str) -> tuple[Param, ...]:
        """Rows whose name starts with ``prefix`` (case-insensitive), e.g. ``"F6"``, ``"U1"``."""
        key = prefix.strip().upper()
        return tuple(row for row in self.rows if row.name.upper().startswith(key))

    def defaults(self) -> dict[str, int]:
        """name -> raw default, settable parameters only."""
        return {row.name: row.default for row in self.rows if not row.read_only}

    # -- validation ------------------------------------------------------------------------

    def check(self, param: Param, raw: int) -> None:
        """Raise :class:`ParamError` if ``raw`` may not be written to ``param``."""
        if param.read_only:
            raise ParamError(f"{param.name} ({param.title}) is read-only and cannot be set")
        if isinstance(raw, bool) or not isinstance(raw, int):
            raise ParamError(f"{param.name}: {raw!r} is not a whole number of counts")
        if not param.minimum <= raw <= param.maximum:
            raise ParamError(
                f"{param.name}: {param.format(raw)} is out of range {param.format_range()}"
            )

    # -- command-line parsing --------------------------------------------------------------

    def parse_value(self, param: Param, text: str) -> int:
        """Parse a value as the keypad shows it (engineering units) into a checked raw count.

        Decimal engineering values with an optional unit ("5.0", "5 s", "150%"); for
        parameters with scale 1 also hex ("0x1F", "1FH"); for hex parameters (``radix`` 16)
        a bare value is hex ("24" means 24H).  Values finer than one count are rejected.
        """
        if param.read_only:
            self.check(param, 0)
        value_text = text.strip()
        if not value_text:
            raise ParamError(f"{param.name}: the value after '=' is missing")
        if param.radix == 16:
            match = re.fullmatch(r"(?:0[xX])?([0-9A-Fa-f]+)[hH]?", value_text)
            if not match:
                raise ParamError(
                    f"{param.name}: '{value_text}' is not a hexadecimal value "
                    f"(the drive shows {param.name} in hex, e.g. {param.format(param.default)})"
                )
            raw = int(match.group(1), 16)
            self.check(param, raw)
            return raw
        hex_match = _HEX_INT_RE.match(value_text)
        if param.scale == 1 and hex_match:
            raw = int(hex_match.group(1) or hex_match.group(2), 16)
            self.check(param, raw)
            return raw
        number_text = value_text
        unit = param.eng_unit
        if unit and number_text.lower().endswith(unit.lower()):
            number_text = number_text[: -len(unit)].strip()
        try:
            value = float(number_text)
        except ValueError:
            raise ParamError(
                f"{param.name}: '{value_text}' is not a number "
                f"(expected e.g. {param.format(param.default)})"
            ) from None
        if not math.isfinite(value):
            raise ParamError(f"{param.name}: '{value_text}' is not a finite number")
        raw = param.to_raw(value)
        if abs(raw * param.scale - value) > param.scale * 1e-6:
            raise ParamError(
                f"{param.name}: {param.with_unit(number_text)} is finer than the setting "
                f"resolution of {param.format(1)}"
            )
        self.check(param, raw)
        return raw

    def parse_raw(self, param: Param, text: str) -> int:
        """Parse a raw count: decimal ("50", "-3") or hex word ("0x32", "32H")."""
        if param.read_only:
            self.check(param, 0)
        value_text = text.strip()
        if not value_text:
            raise ParamError(f"{param.name}: the value after '=' is missing")
        if _DEC_INT_RE.match(value_text):
            raw = int(value_text)
        else:
            hex_match = _HEX_INT_RE.match(value_text)
            if not hex_match:
                raise ParamError(
                    f"register {param.register:04X}H ({param.name}) takes a raw whole number of "
                    f"{param.unit or 'counts'}, not '{value_text}'"
                )
            word = int(hex_match.group(1) or hex_match.group(2), 16)
            if word > _U16_MAX:
                raise ParamError(f"{param.name}: {value_text} does not fit in a 16-bit register")
            raw = param.decode(word)
        self.check(param, raw)
        return raw

    def parse_assignment(self, text: str) -> tuple[Param, int]:
        """Parse ``NAME=VALUE`` (engineering units) or ``REGISTER=RAW`` into ``(param, raw)``.

        Accepted: ``C1-01=5.0``, ``c1-01 = 5``, ``C1-01=5 s``, ``H1-03=24`` (hex parameter),
        ``0x0200=50``, ``0200H=50``.  Raises :class:`ParamError` for malformed text, unknown
        names or registers, read-only targets and out-of-range or off-grid values.
        """
        if not isinstance(text, str) or text.count("=") != 1:
            raise ParamError(
                f"cannot read {text!r} as a parameter setting: expected NAME=VALUE such as "
                f"'C1-01=5.0' or REGISTER=RAW such as '0x0200=50'"
            )
        left, right = (part.strip() for part in text.split("="))
        if not left:
            raise ParamError(f"cannot read {text!r} as a parameter setting: the name before '=' is missing")
        reg_match = _REG_RE.match(left)
        if reg_match and not _NAME_RE.match(left):
            register = int(reg_match.group(1) or reg_match.group(2), 16)
            param = self.by_register(register)
            if param is None:
                raise ParamError(f"no parameter at register {register:04X}H for {self.where}")
            return param, self.parse_raw(param, right)
        param = self.by_name(left)
        return param, self.parse_value(param, right)

    # -- variants --------------------------------------------------------------------------

    def derive(
        self,
        variant: str,
        overrides: Mapping[str, Mapping[str, Any]] | None = None,
        drop: Iterable[str] = (),
    ) -> ParamTable:
        """A new table (a card's view) with some rows replaced field-wise or dropped."""
        overrides = {name.upper(): dict(changes) for name, changes in (overrides or {}).items()}
        dropped = {name.upper() for name in drop}
        for name in (*overrides, *dropped):
            if name not in self._by_name:
                raise ValueError(f"{self.label} table: cannot derive, no row {name}")
        rows = tuple(
            replace(row, **overrides.get(row.name.upper(), {}))
            for row in self.rows
            if row.name.upper() not in dropped
        )
        return ParamTable(self.family, self.label, rows, variant)
