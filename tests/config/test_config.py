"""The network TOML model: defaults, validation messages that name the file and the field."""

from pathlib import Path

import pytest

from mlink_sim.config import ConfigError, check_cycle, load_config, parse_config, parse_duration_ns, parse_endpoint
from mlink_sim.wire import Link

CONFIGS = sorted((Path(__file__).resolve().parents[2] / "configs").glob("*.toml"))

BASE = """
[network]
transmission_cycle = "2ms"
[[station]]
address = 0x21
card = "si-t3"
"""


@pytest.mark.parametrize("path", CONFIGS, ids=lambda p: p.name)
def test_shipped_configs_load(path: Path) -> None:
    config = load_config(path)
    assert config.station
    assert all(st.link is not None and st.frame_size and st.com_tim for st in config.station)


def test_largest_networks_named_by_the_manuals() -> None:
    root = Path(__file__).resolve().parents[2] / "configs"
    assert len(load_config(root / "ml2-30-max.toml").station) == 30  # SI-T3 Table 29: 30 stations max
    assert len(load_config(root / "ml3-62-max.toml").station) == 62  # SI-ET3 Table 28: 62 stations max


def _stations(card: str, first: int, n: int, link: str = "") -> str:
    extra = f'\nlink = "{link}"' if link else ""
    return "".join(f'[[station]]\naddress = {first + i}\ncard = "{card}"{extra}\n' for i in range(n))


@pytest.mark.parametrize(("stations", "message"), [
    (_stations("si-et3", 0x03, 63), "station: 63 MECHATROLINK-III stations, but one link carries at most 62 "
                                    "(SI-ET3 Table 28)"),
    (_stations("si-t3", 0x21, 30) + _stations("si-t-v7", 0x21, 1), "station: 31 MECHATROLINK-II stations, but one "
                                                                   "link carries at most 30 (SI-T3 Table 29)"),
    (_stations("si-t3", 0x21, 29) + _stations("si-t-v7", 0x3E, 1) + _stations("si-et3", 0x40, 62), None),
])
def test_stations_per_link_at_most_the_manuals_maximum(stations: str, message: str | None) -> None:
    """SI-ET3 Table 28 "Maximum number of stations 62", SI-T3 Table 29 "30" (SI-T/V7 §9: 30 slaves max.)."""
    text = '[network]\ntransmission_cycle = "2ms"\n' + stations
    if message is None:
        parse_config(text, "net.toml")
        return
    with pytest.raises(ConfigError) as err:
        parse_config(text, "net.toml")
    assert str(err.value) == f"net.toml: {message}"


def test_a_card_is_read_in_any_spelling_as_its_key_and_the_schema_lists_the_cards() -> None:
    """One spelling in the model: the key (mlink_sim.profiles); "SI-T/V7" and "sitv7" are read as it."""
    from mlink_sim.config import StationConfig

    text = BASE.replace('card = "si-t3"', 'card = "SI-T/V7"') + '[[station]]\naddress = 0x22\ncard = "sitv7"\n'
    v7, other = parse_config(text).station
    assert v7.card == other.card == "si-t-v7" and v7.label == "SI-T/V7@21H" and v7.subcmd  # V7 §7.1
    schema = StationConfig.model_json_schema()["properties"]["card"]
    assert schema["enum"][:3] == ["si-t3", "si-et3", "si-t-v7"] and "si-t-v7 (SI-T/V7)" in schema["description"]


def test_defaults_follow_card_and_link() -> None:
    config = parse_config(BASE + '[[station]]\naddress = 0x23\ncard = "si-et3"\n')
    t3, et3 = config.station
    assert (t3.link, t3.frame_size, t3.com_tim) == (Link.ML2, 32, 1)  # F6-21 = 0; errata COM_TIM = 1
    assert (et3.link, et3.frame_size, et3.com_tim) == (Link.ML3, 64, 1)  # SI-ET3 F6-21 = 0 -> 64-byte


@pytest.mark.parametrize(
    "extra, message",
    [
        ('[[station]]\naddress = 0x21\ncard = "si-t3"\n', "station[1].address: 21H is already used by station[0]"),
        ('[[station]]\naddress = 0x22\ncard = "si-t4"\n', "station[1].card"),
        ('[[station]]\naddress = 0x20\ncard = "si-t3"\n', "outside si-t3's range 21H–3EH"),
        ('[[station]]\naddress = 0x22\ncard = "si-t3"\nframe_size = 64\n', "station[1].frame_size"),
        ('[[station]]\naddress = 0x22\ncard = "si-t3"\nlink = "ML3"\n', "station[1].link: si-t3 speaks"),
        ('[[station]]\naddress = 0x22\ncard = "si-t3"\nparams = { "C1-01" = 99999 }\n', "station[1].params: C1-01"),
        ('[[station]]\naddress = 0x22\ncard = "si-t3"\nbogus = 1\n', "station[1].bogus: unknown field"),
        ('[[timeline]]\nat = "1s"\ndo = "run"\n', "timeline[0]: hz is missing"),
        ('[[timeline]]\nat = "1s"\nstation = 0x30\nexpect = "running"\n', "timeline[0].station: 30H is not"),
        ('[[timeline]]\nat = "soon"\nexpect = "running"\n', "timeline[0].at"),
    ],
)
def test_errors_name_file_and_field(extra: str, message: str) -> None:
    with pytest.raises(ConfigError) as err:
        parse_config(BASE + extra, "net.toml")
    assert str(err.value).startswith("net.toml: ")
    assert message in str(err.value)


def test_bad_toml_and_missing_file(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="not valid TOML"):
        parse_config("[network\n", "x.toml")
    with pytest.raises(ConfigError, match="no such file"):
        load_config(tmp_path / "absent.toml")


@pytest.mark.parametrize(
    "link, size, ns, ok",
    [
        (Link.ML2, 32, 1_000_000, True),
        (Link.ML2, 32, 1_500_000, False),  # SI-T3 CONNECT: 32-byte whole ms only
        (Link.ML2, 17, 500_000, True),
        (Link.ML2, 17, 750_000, False),  # "such as 0.75" -> A.94
        (Link.ML1, 17, 2_000_000, True),
        (Link.ML1, 17, 1_000_000, False),
        (Link.ML3, 32, 250_000, True),  # SI-ET3 Table 14 ID_CODE 16H
        (Link.ML3, 64, 8_000_000, True),
        (Link.ML3, 64, 9_000_000, False),
        (Link.ML3, 64, 1_250_000, False),  # granularity 18H: 0.5 ms steps above 1 ms
    ],
)
def test_transmission_cycle_ranges(link: Link, size: int, ns: int, ok: bool) -> None:
    assert (check_cycle(link, size, ns) is None) is ok


def test_units_and_endpoints() -> None:
    assert parse_duration_ns("250us") == 250_000
    assert parse_duration_ns("2ms") == 2_000_000
    assert parse_duration_ns("0.5s") == 500_000_000
    assert parse_duration_ns(30, default_unit="s") == 30_000_000_000
    with pytest.raises(ValueError, match="expected a duration"):
        parse_duration_ns("fast")
    assert parse_endpoint("127.0.0.1:47001") == ("127.0.0.1", 47001)
    assert parse_endpoint("[::1]:5") == ("::1", 5)
    with pytest.raises(ValueError, match="HOST:PORT"):
        parse_endpoint("localhost")


# -- card options, timeline names and ranges, file encoding: checked when the config loads ------------------------

ET3 = BASE.replace('address = 0x21\ncard = "si-t3"', 'address = 0x23\ncard = "si-et3"')


def _error(text: str) -> str:
    with pytest.raises(ConfigError) as exc:
        parse_config(text, "net.toml")
    return str(exc.value)


def test_card_options_are_typed_and_checked_by_name() -> None:
    assert parse_config(ET3 + "options = { et3_syncmode_table19 = true }").station[0].options == {
        "et3_syncmode_table19": True}
    msg = _error(ET3 + "options = { et3_syncmode_tabel19 = false }")
    assert msg.startswith("net.toml: station[0].options: unknown card option 'et3_syncmode_tabel19'")
    assert "did you mean 'et3_syncmode_table19'?" in msg and "\n" not in msg
    assert "expects true or false (default false), got 1" in _error(ET3 + "options = { et3_syncmode_table19 = 1 }")
    assert "expects int" in _error(ET3 + "options = { silence_tolerance_ns = 'soon' }")


def test_every_card_option_of_the_cards_is_accepted() -> None:
    import dataclasses

    from mlink_sim.cards.settings import CardOptions

    for f in dataclasses.fields(CardOptions):
        value = 1_000_000 if f.name == "silence_tolerance_ns" else True
        parse_config(ET3 + f"options = {{ {f.name} = {str(value).lower()} }}")


@pytest.mark.parametrize(("step", "message"), [
    ('do = "set-param"\nparam = "QQ-12"\nvalue = 1', "net.toml: timeline[0].param: unknown parameter 'QQ-12'"),
    ('do = "set-param"\nparam = "C1-01"\nvalue = 99999', "net.toml: timeline[0].param: C1-01: 99999.0 s is out of"),
    ('station = 0x21\ndo = "set-param"\nparam = "n020"\nvalue = 1', "unknown parameter 'n020'"),  # V7 name on SI-T3
    ('expect = "alarm"\nalarm = "E55"', "net.toml: timeline[0].alarm: expected an alarm name"),
])
def test_timeline_names_and_ranges_are_checked_before_the_run(step: str, message: str) -> None:
    assert message in _error(BASE + f'[[timeline]]\nat = "1s"\n{step}\n')


@pytest.mark.parametrize("alarm", ["E5", "bUS", "oL1", "COMM_ERROR", "WDT_ERROR", "94H", "CPF23"])
def test_alarm_names_a_station_reports_are_accepted(alarm: str) -> None:
    parse_config(BASE + f'[[timeline]]\nat = "1s"\nexpect = "alarm"\nalarm = "{alarm}"\n')


def test_a_config_that_is_not_utf8_is_a_config_error(tmp_path: Path) -> None:
    path = tmp_path / "latin1.toml"
    path.write_bytes((BASE + 'name = "caf\xe9"\n').encode("latin-1"))
    with pytest.raises(ConfigError, match=r"latin1.toml: not a UTF-8 text file \(byte 0xe9"):
        load_config(path)


def test_shipped_examples_load_by_name_and_configs_is_the_package_folder(tmp_path: Path, monkeypatch) -> None:
    from mlink_sim.examples import EXAMPLES_DIR, example_names

    repo = Path(__file__).resolve().parents[2]
    assert (repo / "configs").resolve() == EXAMPLES_DIR  # one copy: configs/ links to the package's examples
    assert "quickstart" in example_names()
    monkeypatch.chdir(tmp_path)
    assert load_config("quickstart").network.name == "quickstart"
    assert load_config("quickstart.toml").network.name == "quickstart"
    assert load_config("configs/quickstart.toml").network.name == "quickstart"
    with pytest.raises(ConfigError, match="shipped examples, usable by name: .*quickstart"):
        load_config("quickstrat")


def test_arrival_poll_reaches_the_workers_flags() -> None:
    """``[network] arrival_poll`` (docs/configuration.md): "auto" by default, passed to every slave worker as
    ``--arrival-poll`` with the host-stall flags; anything but auto, off or a lead of 1 µs–1 ms is refused."""
    assert parse_config(BASE).network.slave_flags()[-2:] == ["--arrival-poll", "auto"]
    config = parse_config(BASE.replace('"2ms"', '"2ms"\narrival_poll = "60us"'))
    assert config.network.slave_flags()[-2:] == ["--arrival-poll", "60us"]
    with pytest.raises(ConfigError, match=r"network\.arrival_poll.*'auto', 'off' or a lead"):
        parse_config(BASE.replace('"2ms"', '"2ms"\narrival_poll = "always"'), "net.toml")
