"""EEPROM image (CONFIG_MOD = 1, fault history), power-up settings, the registry and the LEDs."""

from __future__ import annotations

import json

import pytest

from mlink_sim.cards import CardOptions, CardSettings, EepromError, EepromImage, create_card, settings_for
from mlink_sim.params import ParamError
from mlink_sim.profiles import profiles
from mlink_sim.wire import Link, ml2, ml3

from .helpers import MS, Master, station


def _word(v: int) -> bytes:
    return v.to_bytes(2, "little").ljust(8, b"\0")


def test_eeprom_round_trip_saved_parameter_and_fault_history() -> None:
    """CONFIG_MOD = 1 saves; the fault history is saved by itself (SI-T3 ALM_RD: "kept even when the control
    power is interrupted"); a card powered up from take_eeprom() reads both back."""
    m = Master(station("si-t3"))
    m.connect()
    m.send(ml2.PrmWr(0x0200, 2, _word(55)))
    assert m.st.take_eeprom() is None
    m.send(ml2.Config(1))
    image = m.st.take_eeprom()
    assert image is not None and m.st.take_eeprom() is None
    m.send(ml2.InvCtl(signals=0x0100))  # EF0 fault -> history changes -> a new image
    image = m.st.take_eeprom()
    assert image is not None
    doc = json.loads(image)
    assert doc["version"] == 1 and doc["params"] == {"C1-01": 55} and doc["fault_history"] == ["EF0"]

    again = Master(station("si-t3", eeprom=image))
    r = again.send(ml2.PrmRd(0x0200, 2))
    assert r.message.body.parameter == _word(55)
    assert again.st.snapshot().drive.fault_history == ("EF0",)
    r = again.send(ml2.AlmRd(1))
    assert r.message.body.alm_data[0] == 0x27


def test_eeprom_history_appends_after_restart() -> None:
    image = EepromImage("si-et3", {}, ("oC", "EF0")).to_bytes()
    m = Master(station("si-et3", eeprom=image))
    m.connect()
    m.send(ml3.InvCtl(invcmd_ctrl=0x0400))
    assert m.st.snapshot().drive.fault_history == ("EF0", "oC", "EF0")
    assert json.loads(m.st.take_eeprom())["fault_history"] == ["EF0", "oC", "EF0"]


def test_v7_config_mod_1_persists_immediate_write() -> None:
    m = Master(station("si-t-v7", frame_size=17))
    m.connect()
    m.send(ml2.PrmWr(0x0113, 2, _word(30)))
    m.send(ml2.Config(1))
    again = station("si-t-v7", frame_size=17, eeprom=m.st.take_eeprom())
    assert again.store.active["n019"] == 30


def test_cli_params_win_over_eeprom() -> None:
    image = EepromImage("si-t3", {"C1-01": 55, "b1-01": 3}).to_bytes()
    st = station("si-t3", eeprom=image, params=("C1-01=7.0",))
    assert st.store.active["C1-01"] == 70 and st.store.active["b1-01"] == 3


@pytest.mark.parametrize(
    "blob",
    [b"not json", b"[]", b'{"version": 2, "card": "si-t3"}', b'{"version": 1, "card": "si-et3"}',
     b'{"version": 1, "card": "si-t3", "params": {"C1-01": "x"}}'],
)
def test_bad_eeprom_is_ignored(blob: bytes) -> None:
    st = station("si-t3", eeprom=blob)
    assert st.snapshot().eeprom_error is not None and st.store.active["C1-01"] == 100
    with pytest.raises(EepromError):
        EepromImage.from_bytes(blob, card="si-t3")


def test_eeprom_out_of_range_value_is_skipped() -> None:
    image = EepromImage("si-t3", {"C1-01": 999999, "Z9-99": 1, "C1-02": 20}).to_bytes()
    st = station("si-t3", eeprom=image)
    assert st.store.active["C1-01"] == 100 and st.store.active["C1-02"] == 20


def test_create_card_unknown_name_lists_the_cards() -> None:
    with pytest.raises(ValueError, match="si-t3, si-et3, si-t-v7"):
        create_card("si-x9", settings=CardSettings(), now=0)
    assert {p.key for p in profiles()} >= {"si-t3", "si-et3", "si-t-v7"}


def test_settings_for_per_card() -> None:
    s = settings_for("si-t3", 0x25, 17, ["C1-01=5.0"])
    assert s.params == {"F6-20": 0x25, "F6-21": 1, "C1-01": 50}
    st = create_card("si-t3", settings=s, now=0)
    assert (st.address, st.data_size, st.link) == (0x25, 17, Link.ML2)
    s = settings_for("si-et3", 0x03, 32, [])
    st = create_card("si-et3", settings=s, now=0)
    assert (st.address, st.data_size, st.link) == (0x03, 32, Link.ML3)
    s = settings_for("si-t-v7", 0x3A, None, ["n019=3.0"], link_speed_mbps=4)
    assert (s.s1_1_10mbps, s.s1_2_32byte, s.s1_3, s.s2) == (False, False, True, 0xA)
    st = create_card("si-t-v7", settings=s, now=0)
    assert (st.address, st.data_size, st.link) == (0x3A, 17, Link.ML1)


@pytest.mark.parametrize(
    "card, station_, size, assignments, speed, match",
    [
        ("si-t3", 0x21, 64, [], None, "frame size 64"),
        ("si-et3", 0x21, 17, [], None, "frame size 17"),
        ("si-t3", 0x40, None, [], None, "outside the F6-20 range"),
        ("si-et3", 0xF0, None, [], None, "outside the F6-20 range"),
        ("si-t-v7", 0x41, None, [], None, "S1-3 and S2"),
        ("si-t3", 0x21, 32, [], 4, "17-byte frames only"),
        ("si-t-v7", 0x21, 32, [], 4, "17-byte frames only"),
        ("si-t3", 0x21, None, ["C1-01=9999"], None, "out of range"),
        ("si-t3", 0x21, None, ["nonsense"], None, "NAME=VALUE"),
        ("si-et3", 0x21, None, [], 10, "100 Mbps"),
    ],
)
def test_settings_for_errors(card: str, station_: int, size: int | None, assignments: list[str],
                             speed: int | None, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        settings_for(card, station_, size, assignments, link_speed_mbps=speed)


def test_settings_for_accepts_aer_addresses() -> None:
    for card in ("si-t3", "si-t-v7"):
        for addr in (0x20, 0x3F):
            st = create_card(card, settings=settings_for(card, addr, None, []), now=0)
            assert st.snapshot().station_error == "AEr"


def test_si_et3_aer_20_3f_option() -> None:
    assert station("si-et3", station=0x20).snapshot().station_error is None
    st = station("si-et3", station=0x3F, options=CardOptions(et3_aer_on_20_3f=True))
    assert st.snapshot().station_error == "AEr"


def test_unknown_param_name_in_settings_is_an_error() -> None:
    with pytest.raises(ParamError):
        create_card("si-t3", settings=CardSettings(params={"Q9-99": 1}), now=0)


def test_si_t3_ml1_with_32_byte_f6_21_powers_up_with_17() -> None:
    st = create_card("si-t3", settings=CardSettings(params={"F6-22": 1, "F6-21": 0}), now=0)
    assert st.link is Link.ML1 and st.data_size == 17


def test_leds_si_t3_table_3() -> None:
    m = Master(station("si-t3"))
    assert m.st.snapshot().leds == {"RUN": "on", "ERR": "off", "TX": "off", "RX": "off"}
    m.connect()
    assert m.st.snapshot().leds == {"RUN": "on", "ERR": "off", "TX": "on", "RX": "on"}
    m.tick(3)
    m.nop()
    assert m.st.snapshot().leds["ERR"] == "on"  # communications alarm E6 (Table 20)
    m.st.poll(m.now + 500 * MS)
    assert m.st.snapshot().leds["TX"] == "off" and m.st.snapshot().leds["RX"] == "off"


def test_leds_si_et3_table_4() -> None:
    m = Master(station("si-et3"))
    snap = m.st.snapshot()
    assert snap.leds == {"R/E": "on", "CON": "off", "LK1": "off", "LK2": "off"}
    assert snap.led_colors["R/E"] == "green"
    m.connect()
    snap = m.st.snapshot()
    assert snap.leds["CON"] == "on" and snap.leds["LK1"] == "on"
    m.send(ml3.PrmRd(0x0200, 3))
    assert m.st.snapshot().led_colors["R/E"] == "red"


def test_snapshot_fields() -> None:
    m = Master(station("si-t3"))
    m.connect()
    snap = m.st.snapshot()
    assert snap.card == "si-t3" and snap.address == 0x21 and snap.phase == 2 and snap.link == "ML2"
    assert snap.subcommands and snap.tcycle_ns == MS and snap.counters["rx_ok"] == 1
    assert snap.drive.fault is None and snap.alarm_code == 0 and snap.cmd_alm == 0


@pytest.mark.parametrize("card", ["si-t3", "si-t-v7", "si-et3"])
def test_config_to_eeprom_busy_until_durable_then_completed_once(card: str) -> None:
    """SI-T3 / SI-T/V7 "STATUS Field" CMDRDY "0 Busy" (SUBCMDRDY for the V7 CONFIG sub-command, §7.2), SI-ET3
    CMD_STAT.CMDRDY: with an I/O layer persisting the images, CONFIG_MOD 1 is answered busy until its image is
    durable; commands of that slot meanwhile are not executed; the repetition after durable() completes it without
    storing again (docs/cards.md, "EEPROM")."""
    from mlink_sim.wire import M2Status

    m = Master(station(card))
    m.st.persist_eeprom(True)  # what the slave server does when it writes the images
    m.connect()
    sub = card == "si-t-v7"
    mod = ml3 if m.ml3 else ml2
    reg = 0x0113 if card == "si-t-v7" else 0x0200

    def ready(r) -> bool:
        if m.ml3:
            return bool(r.message.stat.cmdrdy)
        return bool(r.message.substatus & 0x04 if sub else r.message.status & M2Status.CMDRDY)

    def config():
        return m.send(mod.Nop(), mod.Config(1)) if sub else m.send(mod.Config(1))

    def write(value: int):
        body = mod.PrmWr(reg, 2, _word(value))
        return m.send(mod.Nop(), body) if sub else m.send(body)

    write(55)
    assert not ready(config()) and not ready(config())
    generation = m.st.eeprom.generation
    write(66)  # busy: not executed
    value = m.st.store.value("n019" if sub else "C1-01")
    assert value == 55
    image = m.st.take_eeprom()
    assert image is not None and not ready(config())  # taken, not yet durable
    m.st.eeprom_durable(m.st.eeprom_generation)
    done = config()
    assert ready(done) and m.st.eeprom.generation == generation  # completed, not stored again
    assert m.st.take_eeprom() is None
    assert not ready(config())  # a new CONFIG afterwards is a new store, busy again
    assert m.st.eeprom.generation == generation + 1


def test_config_to_eeprom_completes_at_once_without_persistence() -> None:
    """A bare core (no I/O layer, no ``persist_eeprom(True)``) has nothing to wait for."""
    from mlink_sim.wire import M2Status

    m = Master(station("si-t3"))
    m.connect()
    assert m.send(ml2.Config(1)).message.status & M2Status.CMDRDY
