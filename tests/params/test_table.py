"""ParamTable / Param behaviour: lookups, conversions, command-line parsing and its errors."""

from __future__ import annotations

import re

import pytest
from hypothesis import given
from hypothesis import strategies as st

from mlink_sim.params import A1000, FAMILIES, VS606V7, Param, ParamError, ParamTable, for_card
from mlink_sim.profiles import profiles

ALL_TABLES = (*FAMILIES.values(), *dict.fromkeys(for_card(p) for p in profiles()))
ALL_PARAMS = [(table, row) for table in ALL_TABLES for row in table]


# -- structure (every family and card view) ------------------------------------------------------

@pytest.mark.parametrize("table", ALL_TABLES, ids=lambda t: t.where)
def test_names_and_registers_unique(table: ParamTable) -> None:
    names = [row.name.upper() for row in table]
    registers = [reg for row in table for reg in row.registers]
    assert len(names) == len(set(names))
    assert len(registers) == len(set(registers))


@pytest.mark.parametrize("table", ALL_TABLES, ids=lambda t: t.where)
def test_every_default_within_range(table: ParamTable) -> None:
    for row in table:
        assert row.minimum <= row.default <= row.maximum, row.name
        if not row.read_only:
            table.check(row, row.default)


@pytest.mark.parametrize("table", ALL_TABLES, ids=lambda t: t.where)
def test_every_row_has_a_source(table: ParamTable) -> None:
    for row in table:
        assert row.source, row.name
        assert ("Table" in row.source) or ("Manual" in row.source) or ("manual" in row.source), row.name


@pytest.mark.parametrize("table", ALL_TABLES, ids=lambda t: t.where)
def test_every_unverified_row_says_why(table: ParamTable) -> None:
    for row in table:
        if row.unverified:
            assert re.search(r"\(unverified: [^)]+", row.source), row.name


def test_families_mapping() -> None:
    assert FAMILIES == {"a1000": A1000, "v7": VS606V7}
    assert A1000.family == "a1000" and VS606V7.family == "v7"
    assert for_card("SI-T3").variant == "si-t3"
    assert for_card("si_et3").variant == "si-et3"
    assert for_card("SI-T/V7") is VS606V7
    with pytest.raises(ParamError, match="unknown option card 'SI-X'"):
        for_card("SI-X")


def test_defaults_only_settable() -> None:
    defaults = A1000.defaults()
    assert defaults["C1-01"] == 100
    assert "U1-01" not in defaults
    assert all(not A1000.by_name(name).read_only for name in defaults)


def test_by_name_case_insensitive_and_unknown() -> None:
    assert A1000.by_name("c1-01") is A1000.by_name("C1-01")
    assert VS606V7.by_name("N019").name == "n019"
    assert VS606V7.by_name("u-01").name == "U-01"
    with pytest.raises(ParamError) as err:
        A1000.by_name("X1-99")
    assert str(err.value).startswith("unknown parameter 'X1-99' for the A1000 family")
    with pytest.raises(ParamError, match="for the VS-606V7 family"):
        VS606V7.by_name("C1-01")
    assert A1000.get("X1-99") is None
    assert "c1-01" in A1000 and "X1-99" not in A1000


def test_by_register_and_alternative_registers() -> None:
    assert A1000.by_register(0x0200).name == "C1-01"
    assert A1000.by_register(0x0800).name == "U3-01"  # mirror of 0090H
    assert A1000.by_register(0x0090).name == "U3-01"
    assert A1000.by_register(0x0001) is None


def test_table_rejects_duplicates_and_bad_rows() -> None:
    row = Param("X1-01", 0x1000, "Test", "0.1 s", 0.1, 0, 10, 5)
    with pytest.raises(ValueError, match="duplicate parameter name"):
        ParamTable("t", "T", (row, Param("x1-01", 0x1001, "Test", "", 1, 0, 1, 0)))
    with pytest.raises(ValueError, match="register 1000H used by both"):
        ParamTable("t", "T", (row, Param("X1-02", 0x1000, "Test", "", 1, 0, 1, 0)))
    with pytest.raises(ValueError, match="default 11 outside"):
        Param("X1-03", 0x1002, "Test", "", 1, 0, 10, 11)
    with pytest.raises(ValueError, match="disagrees with scale"):
        Param("X1-04", 0x1003, "Test", "0.01 s", 0.1, 0, 10, 0)
    with pytest.raises(ValueError, match="16-bit"):
        Param("X1-05", 0x1004, "Test", "", 1, 0, 70000, 0)


# -- conversions ---------------------------------------------------------------------------------

def test_to_raw_rounds_to_nearest_count() -> None:
    c1_01 = A1000.by_name("C1-01")
    assert c1_01.to_raw(5.0) == 50
    assert c1_01.to_raw(0.3) == 3
    assert c1_01.to_raw(5.04) == 50
    assert c1_01.to_raw(5.05) == 51  # halves away from zero
    assert c1_01.to_eng(50) == 5.0
    with pytest.raises(ParamError, match="not a finite number"):
        c1_01.to_raw(float("nan"))


def test_signed_wire_encoding() -> None:
    u1_05 = A1000.by_name("U1-05")
    assert u1_05.signed
    assert u1_05.encode(-1) == 0xFFFF
    assert u1_05.decode(0xFFFF) == -1
    assert A1000.by_name("U1-01").decode(0xFFFF) == 0xFFFF


def test_format() -> None:
    assert A1000.by_name("C1-01").format(100) == "10.0 s"
    assert A1000.by_name("F6-20").format(0x21) == "21H"
    assert A1000.by_name("L3-02").format(150) == "150%"
    assert A1000.by_name("b1-01").format(3) == "3"


@given(st.sampled_from(ALL_PARAMS).flatmap(
    lambda pair: st.tuples(st.just(pair[1]), st.integers(pair[1].minimum, pair[1].maximum))))
def test_round_trip_raw_eng_raw(case: tuple[Param, int]) -> None:
    row, raw = case
    assert row.to_raw(row.to_eng(raw)) == raw
    assert row.decode(row.encode(raw)) == raw


@given(st.sampled_from([(t, r) for t, r in ALL_PARAMS if not r.read_only]).flatmap(
    lambda pair: st.tuples(st.just(pair[0]), st.just(pair[1]),
                           st.integers(pair[1].minimum, pair[1].maximum))))
def test_round_trip_through_parse_assignment(case: tuple[ParamTable, Param, int]) -> None:
    table, row, raw = case
    assert table.parse_assignment(f"{row.name}={row.format_number(raw)}") == (row, raw)
    assert table.parse_assignment(f"0x{row.register:04X}={raw}") == (row, raw)


# -- parse_assignment ----------------------------------------------------------------------------

@pytest.mark.parametrize(
    ("text", "name", "raw"),
    [
        ("C1-01=5.0", "C1-01", 50),
        ("c1-01 = 5", "C1-01", 50),
        ("C1-01=5 s", "C1-01", 50),
        ("C1-01 = 0.1", "C1-01", 1),
        ("0x0200=50", "C1-01", 50),
        ("0x200=50", "C1-01", 50),
        ("0200H=50", "C1-01", 50),
        ("0200h = 0x32", "C1-01", 50),
        ("L3-02=120%", "L3-02", 120),
        ("E2-05=0.23", "E2-05", 230),
        ("d1-01=60", "d1-01", 6000),
        ("b1-01=3", "b1-01", 3),
        ("b1-01=0x3", "b1-01", 3),
        ("H1-03=24", "H1-03", 0x24),      # hex parameter: the keypad's 24H
        ("H1-03=0x24", "H1-03", 0x24),
        ("H1-03=24H", "H1-03", 0x24),
        ("F6-20=21", "F6-20", 0x21),
        ("036BH=33", "F6-20", 0x21),       # raw form is decimal unless marked hex
        ("F6-23=FFFF", "F6-23", 0xFFFF),
    ],
)
def test_parse_assignment_forms(text: str, name: str, raw: int) -> None:
    param, value = A1000.parse_assignment(text)
    assert (param.name, value) == (name, raw)


def test_parse_assignment_v7() -> None:
    assert VS606V7.parse_assignment("n019=2.5") == (VS606V7.by_name("n019"), 25)
    assert VS606V7.parse_assignment("0113H=25") == (VS606V7.by_name("n019"), 25)


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("C1-01=7000.0", "C1-01: 7000.0 s is out of range 0.0 … 6000.0 s"),
        ("C1-01=-1", "C1-01: -1.0 s is out of range 0.0 … 6000.0 s"),
        ("0x0200=60001", "C1-01: 6000.1 s is out of range 0.0 … 6000.0 s"),
        ("F6-20=2", "F6-20: 02H is out of range 03H … EFH"),
        ("L3-02=151", "L3-02: 151% is out of range 0 … 150%"),
        ("b1-01=5", "b1-01: 5 is out of range 0 … 4"),
        ("U1-01=5", "U1-01 (Frequency Reference) is read-only and cannot be set"),
        ("0x0040=5", "U1-01 (Frequency Reference) is read-only and cannot be set"),
        ("C1-01=5.05", "C1-01: 5.05 s is finer than the setting resolution of 0.1 s"),
        ("C1-01=abc", "C1-01: 'abc' is not a number (expected e.g. 10.0 s)"),
        ("C1-01=nan", "C1-01: 'nan' is not a finite number"),
        ("C1-01=", "C1-01: the value after '=' is missing"),
        ("H1-03=XYZ", "H1-03: 'XYZ' is not a hexadecimal value (the drive shows H1-03 in hex, e.g. 24H)"),
        ("0x0200=5.0", "register 0200H (C1-01) takes a raw whole number of 0.1 s, not '5.0'"),
        ("0x0999=1", "no parameter at register 0999H for the A1000 family"),
        ("=5", "cannot read '=5' as a parameter setting: the name before '=' is missing"),
    ],
)
def test_parse_assignment_errors(text: str, message: str) -> None:
    with pytest.raises(ParamError) as err:
        A1000.parse_assignment(text)
    assert str(err.value) == message


def test_parse_assignment_unknown_name() -> None:
    with pytest.raises(ParamError) as err:
        A1000.parse_assignment("X1-99=3")
    assert str(err.value).startswith("unknown parameter 'X1-99' for the A1000 family")


@pytest.mark.parametrize("text", ["C1-01", "C1-01=5=6", "", "C1-01 5.0"])
def test_parse_assignment_malformed(text: str) -> None:
    with pytest.raises(ParamError, match="expected NAME=VALUE such as 'C1-01=5.0'"):
        A1000.parse_assignment(text)


def test_check_rejects_non_integers() -> None:
    with pytest.raises(ParamError, match="not a whole number of counts"):
        A1000.check(A1000.by_name("C1-01"), 5.0)  # type: ignore[arg-type]


def test_derive_rejects_unknown_rows() -> None:
    with pytest.raises(ValueError, match="no row X1-99"):
        A1000.derive("x", {"X1-99": {"maximum": 1}})


def test_resolve_takes_a_name_or_a_register():
    from mlink_sim.params import A1000, ParamError

    p = A1000.by_name("C1-01")
    assert A1000.resolve("c1-01") is A1000.resolve(0x0200) is A1000.resolve("0200H") is A1000.resolve("0x0200") is p
    for bad in ("C9-99", 0x7777, 1.5):
        with pytest.raises(ParamError):
            A1000.resolve(bad)
