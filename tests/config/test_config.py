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


def test_defaults_follow_card_and_link() -> None:
    config = parse_config(BASE + '[[station]]\naddress = 0x23\ncard = "si-et3"\n')
    t3, et3 = config.station
    assert (t3.link, t3.frame_size, t3.com_tim) == (Link.ML2, 32, 1)  # F6-21 = 0; errata COM_TIM = 1
    assert (et3.link, et3.frame_size, et3.com_tim) == (Link.ML3, 64, 1)  # SI-ET3 F6-21 = 0 -> 64-byte


@pytest.mark.parametrize(
    "extra, message",
    [
        ('[[station]]\naddress = 0x21\ncard = "si-t3"\n', "station[1].address: 0x21 is already used by station[0]"),
        ('[[station]]\naddress = 0x22\ncard = "si-t4"\n', "station[1].card"),
        ('[[station]]\naddress = 0x20\ncard = "si-t3"\n', "outside si-t3's range 21H–3EH"),
        ('[[station]]\naddress = 0x22\ncard = "si-t3"\nframe_size = 64\n', "station[1].frame_size"),
        ('[[station]]\naddress = 0x22\ncard = "si-t3"\nlink = "ML3"\n', "station[1].link: si-t3 speaks"),
        ('[[station]]\naddress = 0x22\ncard = "si-t3"\nparams = { "C1-01" = 99999 }\n', "station[1].params: C1-01"),
        ('[[station]]\naddress = 0x22\ncard = "si-t3"\nbogus = 1\n', "station[1].bogus: unknown field"),
        ('[[timeline]]\nat = "1s"\ndo = "run"\n', "needs speed_hz"),
        ('[[timeline]]\nat = "1s"\nstation = 0x30\nexpect = "running"\n', "timeline[0].station: 0x30 is not"),
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
