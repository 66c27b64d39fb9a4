"""The answer first (docs/timing.md, "When each command is answered"): a card's answer does not wait for the work its
command leaves for after it (``Station.finish``: log lines, the settings a PRM_WR's values will take at CONFIG, the
values CONFIG_MOD = 1 stores, an SI-T/V7 PRM_WR reaching the drive), and that work changes no answer.

The manuals: SI-ET3 "The option sends response data timed to the reception of command data for the local station
address from the master in each transmission cycle"; "the phase moves to phase 2 or phase 3 after a response to the
CONNECT command is returned" (SI-ET3 and SI-T3 §"Communication Phases"). The CMDRDY sequences of the commands are
pinned where they are tested (test_eeprom_settings.py, test_commands.py); here the same commands are answered alike
whether the card finished in between or not.
"""

from __future__ import annotations

import logging
from typing import Any

import pytest

from mlink_sim.cards.parameters import prepare_settings
from mlink_sim.drive.settings import DriveSettings
from mlink_sim.wire import encode, ml2, ml3

from .helpers import MS, Master, station


def _word(v: int) -> bytes:
    return v.to_bytes(2, "little").ljust(8, b"\0")


def _ml3_script() -> list[tuple[Any, Any]]:
    """Every main command of SI-ET3 Table 11 and every sub-command of Table 12, the phase changes among them."""
    return [
        (ml3.Nop(), None), (ml3.Connect(0x30, 0x80, 1, 0x20), None), (ml3.Nop(), ml3.Nop()),
        (ml3.IdRd(0x01, 0, 4), None), (ml3.PrmRd(0x0200, 2), None), (ml3.PrmWr(0x0200, 2, _word(50)), None),
        (ml3.PrmWr(0x0201, 2, _word(70)), None), (ml3.Config(0), None), (ml3.PrmRd(0x0200, 2), None),
        (ml3.SyncSet(), None), (ml3.InvCtl(invcmd_ctrl=1, speed_ref=3000), None),
        (ml3.InvCtl(invcmd_ctrl=1, speed_ref=3000), ml3.PrmRd(0x0200, 2)),
        (ml3.InvCtl(invcmd_ctrl=1, speed_ref=3000), ml3.PrmWr(0x0201, 2, _word(80))),
        (ml3.Config(1), None), (ml3.AlmRd(0, 0), ml3.AlmRd(1, 0)),
        (ml3.InvCtl(invcmd_ctrl=1, speed_ref=3000), ml3.InvIo(0, 0, 0x41, 0x41)),
        (ml3.AlmClr(0), None), (ml3.PrmWr(0x0200, 2, _word(60001)), None), (ml3.Disconnect(), None),
        (ml3.Nop(), None), (ml3.Connect(0x30, 0x80, 1, 0x20), None), (ml3.Nop(), None),
    ]


def _ml2_script(v7: bool) -> list[tuple[Any, Any]]:
    """Every main command of SI-T3 Table 5 (SI-T/V7 Table 1) and every sub-command of Table 6 (Table 2 and the
    CONFIG sub-command of §7.2), the phase changes among them. The SI-T/V7 takes PRM_RD / PRM_WR as sub-commands
    only in 32-byte mode (its main PRM_RD / PRM_WR are refused, which is answered too)."""
    reg, value = (0x0113, 50) if v7 else (0x0200, 50)
    script = [
        (ml2.Nop(), None), (ml2.Connect(0x21, 0x80, 1), None), (ml2.Nop(), ml2.Nop()),
        (ml2.IdRd(0x00, 0, 8), None), (ml2.PrmRd(reg, 2), None), (ml2.PrmWr(reg, 2, _word(value)), None),
        (ml2.Config(0), None), (ml2.SyncSet(), None), (ml2.InvCtl(signals=1, speed_ref=3000), None),
        (ml2.InvCtl(signals=1, speed_ref=3000), ml2.PrmRd(reg, 2)),
        (ml2.InvCtl(signals=1, speed_ref=3000), ml2.PrmWr(reg, 2, _word(value + 10))),
        (ml2.InvCtl(signals=1, speed_ref=3000), ml2.InvIo(0, 0, 0x41, 0x41)),
        (ml2.AlmRd(0, 0), ml2.AlmRd(1, 0)), (ml2.Config(1), None), (ml2.AlmClr(0), None),
        (ml2.Disconnect(), None), (ml2.Nop(), None), (ml2.Connect(0x21, 0x80, 1), None), (ml2.Nop(), None),
    ]
    if v7:
        script.insert(12, (ml2.InvCtl(signals=1, speed_ref=3000), ml2.Config(0)))
    return script


_CARDS = [("si-et3", 64, 250_000), ("si-et3", 32, 250_000), ("si-t3", 32, MS), ("si-t3", 17, MS // 2),
          ("si-t-v7", 32, MS), ("si-t-v7", 17, MS // 2)]


@pytest.mark.parametrize(("card", "size", "tcycle"), _CARDS)
def test_every_command_is_answered_alike_whether_the_card_finished_before_the_next_or_not(
        card: str, size: int, tcycle: int) -> None:
    """Two cards take the same commands at the card's shortest transmission cycle (SI-ET3 Table 28, SI-T3 Table 29,
    SI-T/V7 §3.5): one finishes after each answer as the I/O layer has it do, the other never (each command finishes
    what the one before left, before it is taken). Their answers are the same byte for byte, and so is what they
    end in."""
    params = ("n003=3", "n004=9") if card == "si-t-v7" else ("b1-01=3", "b1-02=3")
    if card == "si-et3":
        script = _ml3_script() if size == 64 else [(b, None) for b, _ in _ml3_script()]
    else:
        script = _ml2_script(card == "si-t-v7")
        if size == 17:
            script = [(b, None) for b, _ in script]
    finished, unfinished = (Master(station(card, station=0x23 if card == "si-et3" else 0x21, frame_size=size,
                                           params=params), tcycle_ns=tcycle, finish=f) for f in (True, False))
    for body, sub in script:
        for m in (finished, unfinished):
            m.send(body, sub)
        a, b = finished.last, unfinished.last
        assert (None if a is None else encode(a)) == (None if b is None else encode(b)), (body, sub)
    unfinished.st.finish()
    assert finished.st.snapshot() == unfinished.st.snapshot()
    assert finished.st.drive.settings == unfinished.st.drive.settings
    assert finished.st.saved_params == unfinished.st.saved_params


def test_what_a_command_logs_is_written_once_its_answer_is_out(caplog: pytest.LogCaptureFixture) -> None:
    """A CONNECT's "connected" and "phase_changed" (SI-ET3 "Communication Phases": the phase moves after the
    response) are written by ``finish``, after the answer; nothing of them before."""
    m = Master(station("si-et3", station=0x23), tcycle_ns=250_000, finish=False)
    with caplog.at_level(logging.INFO, logger="mlink_sim.cards"):
        assert m.connect() is not None
        assert m.st.phase == 2 and m.st.unfinished
        assert "connected" not in caplog.text and "phase_changed" not in caplog.text
        m.st.finish()
    assert not m.st.unfinished
    assert "connected" in caplog.text and "phase_changed" in caplog.text


@pytest.mark.parametrize("card", ["si-et3", "si-t3"])
def test_config_applies_the_settings_built_after_the_prm_wr(card: str) -> None:
    """SI-ET3 PRM_WR / CONFIG ("The CONFIG command forces the parameters written using PRM_WR to become effective",
    Table 15), SI-T3 Tables 9/12: the drive settings of the pending values are built once the PRM_WR's answer is out;
    CONFIG applies them, and they are the settings the values give."""
    ml = ml3 if card == "si-et3" else ml2
    m = Master(station(card, station=0x23 if card == "si-et3" else 0x21), tcycle_ns=MS)
    m.connect()
    m.send(ml.PrmWr(0x0200, 2, _word(50)))  # C1-01 5.0 s
    assert m.st.store.pending == {"C1-01": 50}
    version, built = prepare_settings(m.st)
    assert built == DriveSettings.from_params(m.st.drive.family, {**m.st.store.active, "C1-01": 50})
    assert m.st.drive.settings.accel_s == pytest.approx(10.0)  # pending until CONFIG
    m.send(ml.Config(0))
    assert m.st.drive.settings == built and m.st.drive.settings.accel_s == pytest.approx(5.0)


def test_settings_built_for_other_values_are_not_applied() -> None:
    """A PRM_WR after the one the settings were built for (the card not finished in between) changes the store: CONFIG
    builds the settings of the values as they are, not the stale ones."""
    m = Master(station("si-et3", station=0x23), tcycle_ns=MS)
    m.connect()
    m.send(ml3.PrmWr(0x0200, 2, _word(50)))
    m.finish = False
    m.send(ml3.PrmWr(0x0200, 2, _word(70)))  # C1-01 7.0 s, its settings not built yet
    m.send(ml3.Config(0))
    assert m.st.drive.settings.accel_s == pytest.approx(7.0)


def test_an_si_t_v7_prm_wr_reaches_the_drive_after_its_answer() -> None:
    """SI-T/V7 PRM_WR ("Not required. The setting value is enabled after PRM_WR is executed", CONFIG_MOD 0): the value
    is in effect in the card's store with the answer, and in the drive model once the card finished, before it takes
    its next command."""
    m = Master(station("si-t-v7", frame_size=32), finish=False)
    m.connect()
    m.st.finish()
    m.send(ml2.InvCtl(), ml2.PrmWr(0x0113, 2, _word(50)))  # n019 acceleration time 1: 5.0 s
    assert m.st.store.active["n019"] == 50
    assert m.st.unfinished and m.st.drive.settings.accel_s == pytest.approx(10.0)
    m.send(ml2.InvCtl(), ml2.PrmRd(0x0113, 2))  # the next command finds it done
    assert m.st.drive.settings.accel_s == pytest.approx(5.0)


def test_config_mod_1_stores_the_values_in_effect_when_it_was_taken() -> None:
    """SI-ET3 Table 15 CONFIG_MOD 1 "The setting value is stored in EEPROM": the values stored are those in effect
    when CONFIG was taken, listed once its answer is out; the EEPROM image holds them."""
    m = Master(station("si-et3", station=0x23), tcycle_ns=MS, finish=False)
    m.connect()
    m.send(ml3.PrmWr(0x0200, 2, _word(50)))
    m.send(ml3.Config(1))
    assert m.st.eeprom_pending
    image = m.st.take_eeprom()
    assert image is not None and b'"C1-01": 50' in image
    assert m.st.saved_params["C1-01"] == 50
