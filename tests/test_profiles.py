"""mlink_sim.profiles: one record per card, looked up in any spelling, and every built-in record complete and
consistent with the tables of the layers that read it (docs/architecture.md, "Card profiles")."""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator
from pathlib import Path

import pytest

from mlink_sim import _accel, profiles
from mlink_sim.cards import Station, station_class
from mlink_sim.drive import Family
from mlink_sim.params import FAMILIES, ParamError, for_card
from mlink_sim.profiles import BUILTIN, CardProfile, default_for, lookup, register
from mlink_sim.wire import Link
from mlink_sim.wire.selections import SEL_MON_TABLES, SEL_REF_TABLES

MANUALS = Path(__file__).resolve().parents[2] / "shared" / "manuals"
FLAGS = ("prm_as_subcommand", "config_subcommand", "status_bits_e_f", "set_by_switches")


@pytest.fixture
def registry(monkeypatch: pytest.MonkeyPatch) -> Iterator[None]:
    """The registry as it is, restored after the test (a test's register() stays in the test)."""
    for name in ("_PROFILES", "_SPELLINGS", "_ASSUMED"):
        monkeypatch.setattr(profiles, name, dict(getattr(profiles, name)))
    yield


@pytest.mark.parametrize("spelling", ["si-t-v7", "SI-T/V7", "si-t/v7", "sitv7", "SI_T_V7", " Si-T-v7 "])
def test_every_spelling_of_a_card_is_one_profile(spelling: str) -> None:
    assert lookup(spelling) is lookup("si-t-v7")
    assert lookup(spelling).key == "si-t-v7" and lookup(spelling).label == "SI-T/V7"


def test_the_keys_and_labels_of_the_built_in_cards() -> None:
    assert [(p.key, p.label) for p in BUILTIN] == [("si-t3", "SI-T3"), ("si-et3", "SI-ET3"), ("si-t-v7", "SI-T/V7")]
    assert all(lookup(p.label) is p and lookup(p.key.upper()) is p for p in BUILTIN)


def test_an_unknown_card_is_refused_listing_the_cards() -> None:
    with pytest.raises(ValueError, match=r"unknown option card 'si-x9' \(known cards: si-t3, si-et3, si-t-v7"):
        lookup("si-x9")
    with pytest.raises(ParamError, match="unknown option card 'SI-X'"):
        for_card("SI-X")


def test_the_card_a_station_of_unknown_card_is_taken_for() -> None:
    assert default_for(Link.ML3) is lookup("si-et3") and default_for("ML1") is lookup("si-t-v7")
    assert default_for(Link.ML2) is None  # SI-T3 or SI-T/V7: neither is assumed


def test_register_refuses_a_key_label_or_link_another_card_has(registry: None) -> None:
    t3 = lookup("si-t3")
    with pytest.raises(ValueError, match="'si-t3' is already the card 'si-t3'"):
        register(dataclasses.replace(t3, label="SI-T3 bis"))
    with pytest.raises(ValueError, match="'SI-T3' is already the card 'si-t3'"):
        register(dataclasses.replace(t3, key="si-t3-bis"))
    with pytest.raises(ValueError, match="'Si-T-3' is already"):
        register(dataclasses.replace(t3, key="si-t3-bis", label="Si-T-3"))  # another spelling of the same name
    with pytest.raises(ValueError, match="ML3 is already taken to be SI-ET3"):
        register(dataclasses.replace(lookup("si-et3"), key="si-et3-bis", label="SI-ET3 bis"))
    new = register(dataclasses.replace(t3, key="si-t3-bis", label="SI-T3 bis"))
    assert lookup("SI-T3 BIS") is new and profiles.profiles()[-1] is new


@pytest.mark.parametrize(("change", "match"), [
    ({"key": "SI T3"}, "lower-case words"),
    ({"station": "mlink_sim.cards.si_t3.SiT3"}, "not 'module:Class'"),
    ({"frames": {}}, "speaks no link"),
    ({"frames": {"ML4": (32,)}}, "frames 'ML4'"),
    ({"assumed_on": ("ML3",)}, "a link it does not speak"),
    ({"addresses": (0x40, 0x21)}, "not a range of one byte"),
])
def test_a_malformed_profile_is_refused(change: dict[str, object], match: str) -> None:
    with pytest.raises(ValueError, match=match):
        dataclasses.replace(lookup("si-t3"), **change)


# -- every built-in profile is complete and consistent -------------------------------------------------------


@pytest.mark.parametrize("profile", BUILTIN, ids=lambda p: p.key)
def test_its_station_class_is_a_compiled_card_of_its_own(profile: CardProfile) -> None:
    cls = station_class(profile)
    assert issubclass(cls, Station) and cls.__module__ == profile.module
    assert profile.module in _accel.COMPILED_MODULES  # the build compiles it (setup.py reads the same profiles)


@pytest.mark.parametrize("profile", BUILTIN, ids=lambda p: p.key)
def test_its_tables_exist_where_it_names_them(profile: CardProfile) -> None:
    table = for_card(profile)
    assert table.family == profile.family and FAMILIES[profile.family].family == profile.family
    assert Family(profile.family).value == profile.family
    for name in (profile.max_frequency, profile.frequency_units):
        assert table.by_name(name).name == name  # the speed checks and the frequency units read them
    assert len(SEL_MON_TABLES[profile.selections]) == 16 and len(SEL_REF_TABLES[profile.selections]) == 16
    assert profile.motor_speed is None or profile.motor_speed in SEL_MON_TABLES[profile.selections]


@pytest.mark.parametrize("profile", BUILTIN, ids=lambda p: p.key)
def test_its_links_and_frame_sizes_are_the_wires(profile: CardProfile) -> None:
    assert profile.default_link == profile.links[0]
    for name, sizes in profile.frames.items():
        assert set(sizes) <= set(Link[name].data_sizes), (name, sizes)
    lo, hi = profile.addresses
    assert 0 < lo <= hi < 0xFF
    assert all(link in profile.links for link in profile.assumed_on)


@pytest.mark.parametrize("profile", BUILTIN, ids=lambda p: p.key)
def test_its_facts_and_flags_cite_the_manual(profile: CardProfile) -> None:
    defaults = {f.name: f.default for f in dataclasses.fields(CardProfile)}
    cited = {"frames", "addresses", "motor_speed"} | {f for f in FLAGS if getattr(profile, f) != defaults[f]}
    assert cited <= set(profile.sources), cited - set(profile.sources)
    prefix = "V7" if profile.label == "SI-T/V7" else profile.label
    assert all(text.startswith(prefix) for text in profile.sources.values()), profile.sources


@pytest.mark.parametrize("profile", BUILTIN, ids=lambda p: p.key)
def test_its_manual_is_one_of_the_manuals(profile: CardProfile) -> None:
    if not MANUALS.is_dir():
        pytest.skip(f"manuals not available: {MANUALS}")
    name = profile.manual.replace("/", "-").replace(" ", "_") + ".txt"
    assert (MANUALS / name).is_file(), name


def test_the_defaults_of_a_card_follow_its_record(registry: None) -> None:
    """A card whose factory setting is 17-byte on MECHATROLINK-II: the master's plan and the config take it."""
    from mlink_sim.config import parse_config
    from mlink_sim.master import StationPlan

    register(dataclasses.replace(lookup("si-t3"), key="si-t3-17", label="SI-T3/17", frames={"ML2": (17, 32)}))
    assert StationPlan(0x21, Link.ML2, card="SI-T3/17").data_size == 17
    assert StationPlan(0x21, Link.ML2, card="si-t3").data_size == 32 == StationPlan(0x21, Link.ML2).data_size
    config = parse_config('[network]\ntransmission_cycle = "2ms"\n[[station]]\naddress = 0x21\ncard = "si-t3-17"\n')
    assert (config.station[0].link, config.station[0].frame_size) == (Link.ML2, 17)
    with pytest.raises(ValueError, match="unknown option card 'si-x9'"):
        StationPlan(0x21, Link.ML2, card="si-x9")
