"""VS-606V7 family table against the SI-T/V7 manual's own figures."""

from __future__ import annotations

import pytest

from mlink_sim.params import VS606V7, ParamError


def test_si_t_v7_initial_setup_n003_n004() -> None:
    # §6 Initial Setup: n003 0…3 (3: Communications Card), n004 0…9 (9: Communications Card),
    # both default 0.
    n003 = VS606V7.by_name("n003")
    n004 = VS606V7.by_name("n004")
    assert (n003.minimum, n003.maximum, n003.default) == (0, 3, 0)
    assert (n004.minimum, n004.maximum, n004.default) == (0, 9, 0)
    assert VS606V7.parse_assignment("n003=3") == (n003, 3)
    assert VS606V7.parse_assignment("n004=9") == (n004, 9)
    assert "SI-T/V7 manual §6" in n003.source


def test_si_t_v7_n024_and_n035_named() -> None:
    assert VS606V7.by_name("n024").title == "Frequency Reference 1"
    n035 = VS606V7.by_name("n035")
    assert (n035.minimum, n035.default) == (0, 0)
    assert "SI-T/V7" in n035.source


def test_register_rule_0100h_plus_n() -> None:
    for row in VS606V7:
        if row.name.startswith("n"):
            assert row.register == 0x0100 + int(row.name[1:]), row.name
    assert VS606V7.by_register(0x0113).name == "n019"


def test_si_t_v7_table_3_input_defaults() -> None:
    # Table 3: S3 External fault (3), S4 Fault reset (5), S5/S6 Multi-step 1/2 (6, 7), S7 Jog (10).
    expected = {"n052": 3, "n053": 5, "n054": 6, "n055": 7, "n056": 10}
    for name, default in expected.items():
        assert VS606V7.by_name(name).default == default
        assert "SI-T/V7 Table 3" in VS606V7.by_name(name).source


def test_si_t_v7_table_4_outputs_accept_setting_18() -> None:
    for name in ("n057", "n058", "n059"):
        assert VS606V7.parse_assignment(f"{name}=18")[1] == 18


def test_si_t_v7_table_5_monitors() -> None:
    u01 = VS606V7.by_name("U-01")
    u08 = VS606V7.by_name("U-08")
    assert u01.read_only and u08.read_only and u08.signed
    with pytest.raises(ParamError, match=r"U-01 \(Frequency Reference\) is read-only"):
        VS606V7.parse_assignment("U-01=1")


def test_si_t_v7_alm_rd_n178_fault_history() -> None:
    n178 = VS606V7.by_name("n178")
    assert n178.read_only and n178.register == 0x01B2
    assert "n178" not in VS606V7.defaults()


@pytest.mark.parametrize(
    "names",
    [
        ["n011", "n012", "n013"],
        ["n019", "n020", "n023"],
        [f"n{k:03d}" for k in range(24, 33)],
        [f"n{k:03d}" for k in range(120, 128)],
        ["n036", "n106", "n107", "n110"],
        [f"n{k:03d}" for k in range(50, 57)],
        ["n092", "n093", "n094", "n095"],
    ],
)
def test_model_constants_present(names: list[str]) -> None:
    for name in names:
        assert not VS606V7.by_name(name).read_only


def test_engineering_values() -> None:
    assert VS606V7.parse_assignment("n011=60") == (VS606V7.by_name("n011"), 600)
    assert VS606V7.parse_assignment("n024=6.00")[1] == 600
    assert VS606V7.by_name("n107").format(1233) == "1.233 Ω"


def test_speed_search_n101_n102() -> None:
    """VS-606V7 speed search: n101 decel time 2.0 s (0.1…10.0 s), n102 operation level 150 % (0…200 %)."""
    n101, n102 = VS606V7.by_name("n101"), VS606V7.by_name("n102")
    assert (n101.register, n101.minimum, n101.maximum, n101.default) == (0x0165, 1, 100, 20)
    assert (n102.register, n102.minimum, n102.maximum, n102.default) == (0x0166, 0, 200, 150)
    assert n101.to_eng(n101.default) == pytest.approx(2.0)
    assert n101.unverified and n102.unverified
