"""The manual tables in mlink_sim.wire (combinations.py, selections.py) against the manuals.

Each table is checked twice: against a transcription written here by hand from the manual (always), and that
transcription against the manual text in ``../shared/manuals`` (skipped when the manuals are not beside the
repository).
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from mlink_sim.wire import M2Cmd, M3Cmd
from mlink_sim.wire.combinations import (
    ML2_COLUMNS,
    ML2_COMBINATIONS,
    ML3_COLUMNS,
    ML3_COMBINATIONS,
    V7_COMBINATIONS,
    combination_ok,
    forbids,
)
from mlink_sim.wire.selections import SEL_MON_TABLES, SEL_REF_TABLES

MANUALS = Path(__file__).resolve().parents[2].parent / "shared" / "manuals"
SI_T3 = "SI-T3_MECHATROLINK-II_technical_manual.txt"
SI_ET3 = "SI-ET3_MECHATROLINK-III_technical_manual.txt"
SI_T_V7 = "SI-T-V7_MECHATROLINK-I-II_technical_manual.txt"


def manual(name: str) -> str:
    path = MANUALS / name
    if not path.is_file():
        pytest.skip(f"manual not found: {path}")
    return path.read_text(encoding="utf-8")


def section(text: str, start: str, end: str) -> str:
    """The manual text from the first *start* after which *end* follows, up to *end*."""
    i = text.index(start)
    return text[i:text.index(end, i)]


# --- main/sub-command combinations ----------------------------------------------------------------------------

#: Transcribed by hand: main command -> marks for the columns NOP, PRM_RD, PRM_WR, ALM_RD, INV_I/O (SI-T3 Table 7
#: "OK"/"NG (A.95)", SI-ET3 Table 13 "OK"/"-"). Both manuals have the same rows.
COMBINATION_ROWS = {
    "NOP": "OOOOO", "PRM_RD": "O--OO", "PRM_WR": "O--OO", "ID_RD": "OOOOO", "CONFIG": "O----", "ALM_RD": "O----",
    "ALM_CLR": "O----", "SYNC_SET": "OOOOO", "CONNECT": "O----", "DISCONNECT": "O----", "INV_CTL": "OOOOO",
}


@pytest.mark.parametrize(("table", "cmd", "columns"), [
    (ML2_COMBINATIONS, M2Cmd, ML2_COLUMNS), (ML3_COMBINATIONS, M3Cmd, ML3_COLUMNS),
], ids=["si_t3_table_7", "si_et3_table_13"])
def test_combination_tables_match_the_transcription(table, cmd, columns):
    assert set(table) == {int(cmd[name]) for name in COMBINATION_ROWS}
    for name, marks in COMBINATION_ROWS.items():
        assert table[cmd[name]] == {int(c) for c, m in zip(columns, marks) if m == "O"}, name


def test_si_t3_table_7_transcription_matches_the_manual():
    text = section(manual(SI_T3), "00H NOP OK", "8  MECHATROLINK-II Commands")
    rows = dict(re.findall(r"^[0-9A-F]{2}H (\w+) ((?:(?:OK|NG \(A\.95\)) ?){5})$", text, re.M))
    assert {n: m.replace("NG (A.95)", "-").replace("OK", "O").replace(" ", "") for n, m in rows.items()} == \
        COMBINATION_ROWS


def test_si_et3_table_13_transcription_matches_the_manual():
    text = section(manual(SI_ET3), "Table 13 Main Commands and Sub-Commands\n", "Note: CMD_ALM = BH")
    rows = {}
    for line in text.splitlines():
        cells = line.split("\t")
        if len(cells) == 7 and re.fullmatch(r"[0-9A-F]{2}", cells[0]):
            rows[cells[1]] = "".join("O" if c == "OK" else "-" for c in cells[2:])
    assert rows == COMBINATION_ROWS


def test_v7_combinations_add_a_config_column_marked_like_prm_wr():
    """SI-T/V7 §7.2 has a CONFIG sub-command but no combination table (docs/cards.md)."""
    for main, allowed in ML2_COMBINATIONS.items():
        extra = {M2Cmd.CONFIG} if M2Cmd.PRM_WR in allowed else set()
        assert V7_COMBINATIONS[main] == allowed | extra


def test_slave_and_master_readings_of_a_combination_table():
    """The slave refuses what the table does not allow (unknown mains allow NOP only); the master holds back
    only what the table marks NG."""
    assert not combination_ok(ML2_COMBINATIONS, M2Cmd.PRM_RD, M2Cmd.PRM_WR)
    assert forbids(ML2_COMBINATIONS, M2Cmd.PRM_RD, M2Cmd.PRM_WR)
    assert combination_ok(ML3_COMBINATIONS, M3Cmd.INV_CTL, M3Cmd.INV_IO)
    assert not combination_ok(ML3_COMBINATIONS, 0x30, M3Cmd.PRM_RD) and not forbids(ML3_COMBINATIONS, 0x30, 1)
    assert not forbids(ML2_COMBINATIONS, M2Cmd.INV_CTL, 0x77)  # an all-OK row forbids nothing
    assert forbids(ML2_COMBINATIONS, M2Cmd.CONFIG, 0x77)


# --- SEL_MON ---------------------------------------------------------------------------------------------------

#: code -> (the manual's words, the monitor the table reads). SI-T3 Table 18 and SI-ET3 Table 22 agree; "" =
#: nothing selected or not simulated (the PG counters).
A1000_SEL_MON = {
    0x0: ("Nothing Selected", ""), 0x1: ("U1-05", "U1-05"), 0x2: ("U1-09", "U1-09"), 0x3: ("PG 1 Counter", ""),
    0x4: ("U1-01", "U1-01"), 0x5: ("U1-14", "U1-14"), 0x6: ("U1-07", "U1-07"), 0x7: ("alarm", "ALARM"),
    0x8: ("warning", "WARNING"), 0x9: ("U1-11", "U1-11"), 0xA: ("U1-15", "U1-15"), 0xB: ("U1-10", "U1-10"),
    0xC: ("U1-13", "U1-13"), 0xD: ("2 Counter", ""), 0xE: ("F6-23", "F6-23"), 0xF: ("F6-24", "F6-24"),
}
#: SI-T/V7 Table 5 (its code 1 is the output frequency, U-02; 5 pulse train and C analog input not simulated).
V7_SEL_MON = {
    0x0: ("Nothing selected", ""), 0x1: ("Output frequency", "U-02"), 0x2: ("Torque reference (U-08)", "U-08"),
    0x3: ("Not used", ""), 0x4: ("Frequency reference (U-01)", "U-01"), 0x5: ("Pulse train reference RP", ""),
    0x6: ("Main circuit current voltage", "U-05"), 0x7: ("Inverter alarm", "ALARM"),
    0x8: ("Inverter warning", "WARNING"), 0x9: ("Not used", ""), 0xA: ("Not used", ""),
    0xB: ("INV terminal DI input", "U-06"), 0xC: ("INV analog input FR", ""), 0xD: ("Not used", ""),
    0xE: ("Not used", ""), 0xF: ("Not used", ""),
}


@pytest.mark.parametrize(("card", "rows"), [
    ("SI-T3", A1000_SEL_MON), ("SI-ET3", A1000_SEL_MON), ("SI-T/V7", V7_SEL_MON),
], ids=["si_t3_table_18", "si_et3_table_22", "v7_table_5"])
def test_sel_mon_tables_match_the_transcription(card, rows):
    assert SEL_MON_TABLES[card] == tuple(monitor for _, monitor in (rows[c] for c in range(16)))


def _rows(text: str, pattern: str) -> dict[int, str]:
    """Manual table rows whose line starts with a hex code (``pattern`` matches the code and the rest)."""
    return {int(m[1], 16): m[2] for m in re.finditer(pattern, text, re.M)}


@pytest.mark.parametrize(("name", "start", "end", "row"), [
    (SI_T3, "MON1/2 Item Remarks", "Byte Command Response", r"^([0-9A-F]) (.+)$"),
    (SI_ET3, "Table 22 SEL_MON Monitor Data Codes", "■ INV_CTL Response", r"^([0-9A-F])\t(.+)$"),
], ids=["si_t3_table_18", "si_et3_table_22"])
def test_a1000_sel_mon_transcription_matches_the_manual(name, start, end, row):
    rows = _rows(section(manual(name), start, end), row)
    assert sorted(rows) == list(range(16))
    for code, (words, _) in A1000_SEL_MON.items():
        assert words.lower() in rows[code].lower(), (code, rows[code])


def test_v7_table_5_transcription_matches_the_manual():
    text = section(manual(SI_T_V7), "Table 5  SEL MON1/2 Selection Range", "Start Synchronous Communications")
    rows = _rows(text, r"^([0-9A-F]) (.+)$")
    assert sorted(rows) == list(range(14)) and "E, F Not used. Always 0." in text
    for code, (words, _) in V7_SEL_MON.items():
        assert words.lower() in rows.get(code, "Not used").lower(), (code, rows.get(code))


# --- SEL_REF ---------------------------------------------------------------------------------------------------

#: code -> (the manual's words, the item recorded). SI-T3 Table 17 and SI-ET3 Table 21 agree (9 is "Command
#: selection" in SI-T3, "Control Selection Setting" in SI-ET3); A–F are not used.
A1000_SEL_REF = {
    0x0: ("Nothing selected", ""), 0x1: ("Torque Compensation", "torque compensation"),
    0x2: ("Analog output terminal 1", "analog output 1"), 0x3: ("Analog output terminal 2", "analog output 2"),
    0x4: ("terminal output", "terminal outputs"), 0x5: ("PID", "PID setpoint"), 0x6: ("Pulse", "pulse output"),
    0x7: ("V/f gain", "V/f gain"), 0x8: ("", ""), 0x9: ("selection", "control selection"),
}


@pytest.mark.parametrize("card", ["SI-T3", "SI-ET3"], ids=["si_t3_table_17", "si_et3_table_21"])
def test_sel_ref_a1000_tables_match_the_transcription(card):
    table = SEL_REF_TABLES[card]
    assert table[:10] == tuple(item for _, item in (A1000_SEL_REF[c] for c in range(10)))
    assert table[10:] == ("",) * 6


def test_v7_table_4_sel_ref_only_terminal_outputs():
    assert SEL_REF_TABLES["SI-T/V7"] == ("",) * 4 + ("terminal outputs",) + ("",) * 11
    text = section(manual(SI_T_V7), "Table 4  SEL REF1/2 Selection Range", "5 to F Not used.")
    assert "4 INV terminal output" in text and text.count("Not used.") == 3  # codes 1-3


def test_si_t3_table_17_transcription_matches_the_manual():
    text = section(manual(SI_T3), "Bit Item Remarks\n0 Nothing selected", "A to F Not used.")
    rows = _rows(text, r"^([0-9A-F])(?: (.+))?$")
    for code, (words, _) in A1000_SEL_REF.items():
        if code in (0x8, 0x4):
            continue  # 8 "Reserved"; 4's words are on the next lines
        assert words.lower() in (rows.get(code) or "").lower(), (code, rows.get(code))
    assert "Drive terminal output" in text and "8 Reserved" in text


def test_si_et3_table_21_transcription_matches_the_manual():
    text = section(manual(SI_ET3), "Table 21 SEL_REF Reference Data Codes", "Table 22 SEL_MON")
    rows = _rows(text, r"^([0-9A-F])\t(.+)$")
    for code, (words, _) in A1000_SEL_REF.items():
        assert words.lower() in rows[code].lower(), (code, rows[code])
    assert "Not used" in rows[8]
