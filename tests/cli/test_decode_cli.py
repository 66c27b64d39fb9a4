"""``mlink-sim decode``: readable and JSON output, one-line rejection with exit 1."""

import json

from click.testing import CliRunner

from mlink_sim.cli.decode import decode_cmd
from mlink_sim.wire import Frame, Kind, Link, encode, ml2

HEX = encode(Frame(Link.ML2, Kind.COMMAND, 0x21, 7, 2_000_000, ml2.M2Command(ml2.PrmRd(0x0200, 2), wdt=0x10))).hex()


def test_decode_readable_si_t3_table_8() -> None:
    result = CliRunner().invoke(decode_cmd, [HEX])
    assert result.exit_code == 0
    assert "PRM_RD(01H) no=0x200 size=2" in result.output
    assert "station 0x21" in result.output


def test_decode_json_with_separators() -> None:
    spaced = " ".join(HEX[i : i + 2] for i in range(0, len(HEX), 2))
    result = CliRunner().invoke(decode_cmd, ["--json", spaced])
    assert result.exit_code == 0
    doc = json.loads(result.output)
    assert doc["main"] == {"command": "PRM_RD", "code": 1, "no": 0x200, "size": 2}
    assert doc["link"] == "ML2" and doc["wdt"] == 0x10


def test_decode_rejects_bad_fcs_in_one_line() -> None:
    bad = HEX[:-2] + ("00" if HEX[-2:] != "00" else "01")
    result = CliRunner().invoke(decode_cmd, [bad])
    assert result.exit_code == 1
    assert result.output.count("\n") == 1 and "bad FCS" in result.output


def test_decode_rejects_malformed_hex_and_wrong_size() -> None:
    for arg, reason in (("4d0", "odd number"), ("zz", "not a hex digit"), ("4d02", "too short")):
        result = CliRunner().invoke(decode_cmd, [arg])
        assert result.exit_code == 1 and reason in result.output
    result = CliRunner().invoke(decode_cmd, ["--frame-size", "32", HEX])
    assert result.exit_code == 1 and "32-byte frames" in result.output
