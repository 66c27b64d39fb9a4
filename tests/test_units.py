"""mlink_sim.units: durations with units and station addresses, read and written the same way everywhere."""

from __future__ import annotations

import pytest

from mlink_sim.units import format_ns, parse_address, parse_duration_ns


@pytest.mark.parametrize(
    "ns, text",
    [(0, "0ns"), (850, "850ns"), (731_200, "731.2us"), (500_000, "500us"), (1_250_000, "1.25ms"),
     (2_000_000_000, "2s"), (999_999, "1000us"), (-1_500, "-1.5us"), (2_500.0, "2.5us"), (90_000_000_000, "90s")],
)
def test_format_ns(ns, text):
    assert format_ns(ns) == text


@pytest.mark.parametrize("ns", [0, 1, 999, 1_234, 250_000, 1_250_000, 2_000_000_000, 731_200])
def test_format_ns_reads_back(ns):
    assert parse_duration_ns(format_ns(ns)) == ns


@pytest.mark.parametrize("value, address", [(0x21, 0x21), ("0x21", 0x21), ("21H", 0x21), ("21h", 0x21), ("33", 33),
                                            (" 0xEF ", 0xEF)])
def test_parse_address(value, address):
    assert parse_address(value) == address


@pytest.mark.parametrize("value, message", [(True, "station address"), ("fast", "0x21 or 21H"), (0x100, "one byte"),
                                            (2.5, "station address")])
def test_parse_address_refuses(value, message):
    with pytest.raises(ValueError, match=message):
        parse_address(value)
