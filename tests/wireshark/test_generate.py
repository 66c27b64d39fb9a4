"""The dissector's tables are generated from mlink_sim.wire: the shipped mlink.lua is the generator's output."""

from __future__ import annotations

from click.testing import CliRunner

from mlink_sim.cli.wireshark import wireshark_cmd
from mlink_sim.wire import CmdAlm, M2Alarm, M2Cmd, M2Status, M3Cmd, ml2, ml3
from mlink_sim.wireshark.generate import build, lua_tables, shipped_path


def test_shipped_dissector_is_the_generators_output() -> None:
    assert shipped_path().read_text(encoding="utf-8") == build(), "run: python -m mlink_sim.wireshark.generate"


def test_tables_come_from_the_wire_package() -> None:
    t = lua_tables()
    assert t["gen_commands"]["ml2"] == {int(c): c.name for c in M2Cmd}  # SI-T3 Tables 5/6
    assert t["gen_commands"]["ml3"] == {int(c): c.name for c in M3Cmd}  # SI-ET3 Tables 11/12
    assert t["m2_alarm"] == {int(a): a.name for a in M2Alarm}  # SI-T3 Tables 23/25
    assert t["cmd_alm"] == {int(a): a.name for a in CmdAlm}
    assert (int(M2Status.ALM), "ALM") in t["status_bits"]
    # SI-T3 Table 8: PRM_RD command NO at manual bytes 5-6 = main-body offset 2, SIZE at byte 7
    assert t["bodies"]["ml2"]["cmd_main"][1] == [("no", 2, 2, "u16"), ("size", 4, 1, "u8")]
    assert set(t["bodies"]["ml3"]["rsp_main"]) == set(ml3.RESPONSE_MAIN.by_code)
    assert set(t["bodies"]["ml2"]["cmd_sub"]) == set(ml2.COMMAND_SUB.by_code)
    # SI-ET3 "Command Status": CMD_ALM bits 8-11, COMM_ALM bits 12-15
    assert dict(t["cmd_stat"])["cmd_alm"] == 0x0F00 and dict(t["cmd_stat"])["comm_alm"] == 0xF000


def test_crc_table_checks_against_the_catalogue_value() -> None:
    table = lua_tables()["crc_table"]
    crc = 0xFFFF
    for b in b"123456789":
        crc = (crc >> 8) ^ table[(crc ^ b) & 0xFF]
    assert crc ^ 0xFFFF == 0x906E  # CRC-16/X-25 check value (docs/wire-format.md §2)


def test_wireshark_path_and_install(tmp_path) -> None:
    result = CliRunner().invoke(wireshark_cmd, ["--path"])
    assert result.exit_code == 0 and result.output.strip() == str(shipped_path())
    result = CliRunner().invoke(wireshark_cmd, ["--install", "--dest", str(tmp_path / "plugins")])
    assert result.exit_code == 0, result.output
    assert (tmp_path / "plugins" / "mlink.lua").read_bytes() == shipped_path().read_bytes()


def test_wireshark_install_into_the_personal_folder(tmp_path, monkeypatch) -> None:
    monkeypatch.setenv("HOME", str(tmp_path))
    result = CliRunner().invoke(wireshark_cmd, ["--install"])
    assert result.exit_code == 0, result.output
    assert (tmp_path / ".local" / "lib" / "wireshark" / "plugins" / "mlink.lua").is_file()


def test_wireshark_usage_errors(tmp_path) -> None:
    assert CliRunner().invoke(wireshark_cmd, []).exit_code == 2
    assert CliRunner().invoke(wireshark_cmd, ["--path", "--dest", str(tmp_path)]).exit_code == 2
    blocker = tmp_path / "file"
    blocker.write_text("x")
    result = CliRunner().invoke(wireshark_cmd, ["--install", "--dest", str(blocker / "sub")])
    assert result.exit_code == 2 and "cannot install" in result.output
