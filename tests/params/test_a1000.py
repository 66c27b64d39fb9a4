"""A1000 family table against the SI-T3 and SI-ET3 manuals' own figures."""

from __future__ import annotations

import pytest

from mlink_sim.params import A1000, A1000_SI_ET3, A1000_SI_T3, ParamError


def _reg(name: str) -> int:
    return A1000.by_name(name).register


# -- SI-T3 ---------------------------------------------------------------------------------------

def test_si_t3_table_8_prm_rd_c1_01() -> None:
    # Table 8: NO bytes 5, 6 = 00 02 -> register 0200H is C1-01.
    assert A1000.by_register(0x0200).name == "C1-01"
    assert _reg("C1-01") == 0x0200


def test_si_t3_table_9_prm_wr_c1_01() -> None:
    param, raw = A1000_SI_T3.parse_assignment("0x0200=50")
    assert param.name == "C1-01" and param.to_eng(raw) == 5.0


# name: (minimum, maximum, default) as printed in SI-T3 Table 4
SI_T3_TABLE_4 = {
    "b1-01": (0, 4, 1),
    "b1-02": (0, 3, 1),
    "F6-01": (0, 3, 1),
    "F6-02": (0, 1, 0),
    "F6-03": (0, 3, 1),
    "F6-07": (0, 1, 0),
    "F6-08": (0, 1, 0),
    "F6-20": (0x20, 0x3F, 0x21),
    "F6-21": (0, 1, 0),
    "F6-22": (0, 1, 0),
    "F6-23": (0, 0xFFFF, 0),
    "F6-24": (0, 0xFFFF, 0),
    "F6-25": (0, 3, 1),
    "F6-26": (2, 10, 2),
}


@pytest.mark.parametrize("name", sorted(SI_T3_TABLE_4))
def test_si_t3_table_4_f6_defaults(name: str) -> None:
    row = A1000_SI_T3.by_name(name)
    assert (row.minimum, row.maximum, row.default) == SI_T3_TABLE_4[name]
    assert "SI-T3 Table 4" in row.source


def test_si_t3_table_4_station_address_limits() -> None:
    # <4>: 20H and 3FH are in range but raise AEr on the card; 40H is out of range.
    assert A1000_SI_T3.parse_assignment("F6-20=3F")[1] == 0x3F
    with pytest.raises(ParamError, match=r"F6-20: 40H is out of range 20H … 3FH"):
        A1000_SI_T3.parse_assignment("F6-20=40")
    with pytest.raises(ParamError, match=r"F6-01: 4 is out of range 0 … 3"):
        A1000_SI_T3.parse_assignment("F6-01=4")


def test_si_t3_table_4_names_c1_02_c1_09_a1_03_d1() -> None:
    for name in ("C1-02", "C1-09", "A1-03", "d1-01", "d1-17"):
        assert name in A1000


def test_si_t3_table_16_h1_defaults() -> None:
    expected = {"H1-03": 0x24, "H1-04": 0x14, "H1-05": 0x03, "H1-06": 0x04, "H1-07": 0x06}
    for name, default in expected.items():
        row = A1000.by_name(name)
        assert (row.default, row.radix) == (default, 16)
        assert "SI-T3 Table 16" in row.source


def test_si_t3_table_16_h1_08_external_bb_conflict() -> None:
    # Table 16 prints "Default = 7: External bb command"; External Baseblock N.O. is 8 on the A1000.
    row = A1000.by_name("H1-08")
    assert row.default == 0x08
    assert "conflicts" in row.source


def test_si_t3_table_17_outputs_named() -> None:
    for name in ("H2-01", "H2-02", "H2-03", "H4-01", "H4-04"):
        assert name in A1000
    assert A1000.by_name("H2-01").maximum >= 0x0F  # "Enable when H2-01 = F"
    assert A1000.by_name("H4-01").minimum == 0  # "Enable when H4-01 = 000"


# SEL_MON code -> (monitor, unit) where SI-T3 Table 18 / SI-ET3 Table 22 state one
SEL_MON = {
    1: ("U1-05", None),
    2: ("U1-09", "0.1 %"),
    4: ("U1-01", None),
    5: ("U1-14", "0.1 %"),
    6: ("U1-07", "1 V"),
    9: ("U1-11", None),
    0xA: ("U1-15", "0.1 %"),
    0xB: ("U1-10", None),
    0xC: ("U1-13", "0.1 %"),
}


@pytest.mark.parametrize("code", sorted(SEL_MON))
def test_si_t3_table_18_and_si_et3_table_22_sel_mon_monitors(code: int) -> None:
    name, unit = SEL_MON[code]
    row = A1000.by_name(name)
    assert row.read_only
    if unit is not None:
        assert row.unit == unit


def test_u1_monitors_cover_u1_01_to_u1_15() -> None:
    names = {row.name for row in A1000.group("U1")}
    assert {f"U1-{i:02d}" for i in range(1, 16)} <= names
    assert _reg("U1-01") == 0x0040 and _reg("U1-12") == 0x004B


def test_si_t3_table_14_alm_data_fault_monitors() -> None:
    for name in ("U2-01", "U2-02", *(f"U3-{i:02d}" for i in range(1, 11))):
        row = A1000.by_name(name)
        assert row.read_only and row.radix == 16
    assert len(A1000.group("U2")) == 18  # U2-01…U2-17 and U2-20
    assert len(A1000.group("U3")) == 20


def test_monitors_are_read_only_and_settings_are_not() -> None:
    for row in A1000:
        assert row.read_only == row.name.startswith("U"), row.name


# -- SI-ET3 --------------------------------------------------------------------------------------

# name: (register, minimum, maximum, default) as printed in SI-ET3 Table 7
SI_ET3_TABLE_7 = {
    "b1-01": (0x0180, 0, 4, 1),   # default "<2> differs by drive": A1000 default 1 (SI-T3 Table 4)
    "b1-02": (0x0181, 0, 3, 1),
    "d5-01": (0x029A, 0, 1, 0),
    "F6-01": (0x03A2, 0, 5, 1),
    "F6-02": (0x03A3, 0, 1, 0),
    "F6-03": (0x03A4, 0, 3, 1),
    "F6-06": (0x03A7, 0, 1, 0),
    "F6-07": (0x03A8, 0, 1, 0),
    "F6-08": (0x036A, 0, 1, 0),
    "F6-20": (0x036B, 0x03, 0xEF, 0x21),
    "F6-21": (0x036C, 0, 1, 0),
    "F6-23": (0x036E, 0, 0xFFFF, 0),
    "F6-24": (0x036F, 0, 0xFFFF, 0),
    "F6-25": (0x03C9, 0, 3, 1),
    "F6-26": (0x03CA, 2, 10, 2),
}


@pytest.mark.parametrize("name", sorted(SI_ET3_TABLE_7))
def test_si_et3_table_7_registers_ranges_defaults(name: str) -> None:
    row = A1000_SI_ET3.by_name(name)
    assert (row.register, row.minimum, row.maximum, row.default) == SI_ET3_TABLE_7[name]
    assert A1000_SI_ET3.by_register(row.register) is row
    assert "SI-ET3 Table 7" in row.source


def test_si_et3_table_7_family_table_is_union_of_both_cards() -> None:
    assert (A1000.by_name("F6-20").minimum, A1000.by_name("F6-20").maximum) == (0x03, 0xEF)
    assert A1000.by_name("F6-01").maximum == 5
    assert "64-byte" in A1000_SI_ET3.by_name("F6-21").title
    assert "17 byte" in A1000_SI_T3.by_name("F6-21").title


def test_si_et3_table_26_names_f6_15_and_f6_54() -> None:
    assert A1000.by_name("F6-15").unverified
    assert A1000.by_name("F6-54").unverified


def test_si_et3_table_16_alm_rd_u3_index() -> None:
    # ALM_RD_MOD = 2 reads U3-(ALM_INDEX); every index 1…10 must resolve.
    for index in range(1, 11):
        assert A1000.by_name(f"U3-{index:02d}").read_only


# -- what the drive model needs ------------------------------------------------------------------

@pytest.mark.parametrize(
    "names",
    [
        [f"b1-{i:02d}" for i in range(1, 5)],
        [f"C1-{i:02d}" for i in range(1, 10)],
        [f"C2-{i:02d}" for i in range(1, 5)],
        [f"d1-{i:02d}" for i in range(1, 18)],
        ["E1-01", *(f"E1-{i:02d}" for i in range(3, 14))],
        [f"E2-{i:02d}" for i in range(1, 7)],
        [f"H1-{i:02d}" for i in range(1, 9)],
        [f"L3-{i:02d}" for i in range(1, 7)],
        ["L4-01", "L4-02", "o1-03", "F6-06", "d5-01"],
    ],
)
def test_model_parameters_present(names: list[str]) -> None:
    for name in names:
        assert not A1000.by_name(name).read_only


def test_published_register_examples() -> None:
    assert _reg("b1-01") == 0x0180
    assert _reg("E1-04") == 0x0303
    assert _reg("U1-01") == 0x0040
    assert _reg("d1-17") == 0x0292


def test_d2_registers_follow_appendix_b() -> None:
    # A1000 Technical Manual Appendix B, B.6: d2-01/d2-02 sit between d1-09 (0288H) and d1-10 (028BH).
    for name, register in (("d2-01", 0x0289), ("d2-02", 0x028A)):
        row = A1000.by_name(name)
        assert row.register == register
        assert not row.unverified and "Appendix B" in row.source


def test_engineering_defaults() -> None:
    assert A1000.by_name("C1-09").to_eng(A1000.by_name("C1-09").default) == 10.0
    assert A1000.by_name("E1-04").to_eng(600) == 60.0
    assert A1000.by_name("d1-17").to_eng(A1000.by_name("d1-17").default) == 6.0
    assert A1000.by_name("E1-01").default == 200


# -- b3 speed search (A1000 TM b3 table; SI-T3 Table 26 names SEr 3BH) ---------------------------
# name: (register, minimum, maximum, default) in raw counts
B3_SPEED_SEARCH = {
    "b3-01": (0x0191, 0, 1, 0),  # off for A1-02 = 0/2
    "b3-02": (0x0192, 0, 200, 100),  # % of drive rated current, A1-02 = 2
    "b3-03": (0x0193, 1, 100, 20),  # 0.1 s: 0.1…10.0 s, 2.0 s
    "b3-05": (0x0195, 0, 1000, 2),  # 0.1 s: 0.0…100.0 s, 0.2 s
    "b3-17": (0x01F0, 0, 200, 150),
    "b3-18": (0x01F1, 0, 100, 10),  # 0.01 s: 0.00…1.00 s, 0.10 s
    "b3-19": (0x01F2, 0, 10, 3),
    "b3-24": (0x01C0, 0, 1, 0),  # 0 Current Detection, 1 Speed Estimation
    "b3-25": (0x01C8, 0, 300, 5),  # 0.1 s: 0.0…30.0 s, 0.5 s
}


@pytest.mark.parametrize("name", sorted(B3_SPEED_SEARCH))
def test_b3_speed_search_rows_registers_ranges_defaults(name: str) -> None:
    for table in (A1000, A1000_SI_T3, A1000_SI_ET3):
        row = table.by_name(name)
        assert (row.register, row.minimum, row.maximum, row.default) == B3_SPEED_SEARCH[name]
        assert table.by_register(row.register) is row
    row = A1000.by_name(name)
    assert row.unverified and "b3 Speed Search" in row.source  # not confirmed: said so in the row


def test_b3_engineering_values() -> None:
    assert A1000.by_name("b3-03").to_eng(20) == pytest.approx(2.0)
    assert A1000.by_name("b3-18").to_eng(10) == pytest.approx(0.10)
    assert A1000.parse_assignment("b3-01=1") == (A1000.by_name("b3-01"), 1)
