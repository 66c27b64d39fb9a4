"""A slave worker's per-read path (mlink_sim.aio.bus), on real card cores and without sockets: the station byte
picks the station, each station's datagrams keep their order, a backlog beyond *keep* per source is superseded,
datagrams for no station are counted, and the tick's scan names exactly the stations whose poll is due."""

from __future__ import annotations

from typing import Any

from mlink_sim.aio.bus import Bus, Port, due
from mlink_sim.aio.slave import HostedStation
from mlink_sim.cards import Station, create_card, settings_for
from mlink_sim.wire import Frame, Kind, Link, decode, encode, ml2

TCYCLE = 1_000_000
SOURCE = ("127.0.0.1", 40000)
OTHER = ("127.0.0.1", 40001)


class Clock:
    """Each datagram 1 µs after the one before (what ``time.monotonic_ns`` gives the worker)."""

    def __init__(self) -> None:
        self.now = 0

    def __call__(self) -> int:
        self.now += 1_000
        return self.now


def _station(address: int) -> Station:
    return create_card("si-t3", settings=settings_for("si-t3", address, 17, []), now=0)


def _command(address: int, cycle: int, body: object) -> bytes:
    return encode(Frame(Link.ML2, Kind.COMMAND, address, cycle, TCYCLE, ml2.M2Command(body, 0)))


def _nop(address: int, cycle: int) -> bytes:
    """NOP (SI-T3 Table 6: allowed in phase 1) to *address*."""
    return _command(address, cycle, ml2.Nop())


def _port(address: int, keep: int = 8, eeprom: list[Any] | None = None) -> Port:
    station = _station(address)
    return Port(station, HostedStation(station, "127.0.0.1", 0), keep,
                (eeprom if eeprom is not None else []).append, Clock())


def _answered(out: list[tuple[bytes, Any]]) -> list[tuple[int, int, Any]]:
    """(station, cycle, destination) of each answer, in order."""
    return [(f.station, f.cycle, addr) for f, addr in ((decode(d, kind=Kind.RESPONSE), a) for d, a in out)]


def test_the_station_byte_picks_the_station_and_the_stations_keep_their_first_order() -> None:
    """docs/wire-format.md, byte 3: the station address (F6-20, SI-T3 Table 4). Stations are served in the order
    they first appear in the read, each station's datagrams in arrival order."""
    ports = [_port(a) for a in (0x21, 0x22, 0x23)]
    bus = Bus(ports)
    batch = [(_nop(0x23, 1), SOURCE), (_nop(0x21, 1), SOURCE), (_nop(0x23, 2), SOURCE), (_nop(0x22, 1), SOURCE)]
    assert _answered(bus.serve(batch)) == [(0x23, 1, SOURCE), (0x23, 2, SOURCE), (0x21, 1, SOURCE),
                                           (0x22, 1, SOURCE)]
    assert [p.hosted.responses for p in ports] == [1, 1, 2]
    assert bus.unaddressed == 0


def test_a_read_with_one_datagram_per_station_is_served_in_its_order() -> None:
    """The common read (each station's command of one cycle, served in one pass): the stations in arrival order,
    each answer to its datagram's source, a datagram for no station here counted, the answers counted per station,
    an EEPROM image handed over after the read that left it."""
    taken: list[Any] = []
    ports = [_port(a, eeprom=taken) for a in (0x21, 0x22, 0x23)]
    bus = Bus(ports)
    ports[1].station.eeprom.dirty = True
    batch = [(_nop(0x23, 1), SOURCE), (_nop(0x30, 1), SOURCE), (_nop(0x21, 1), OTHER), (_nop(0x22, 1), SOURCE)]
    assert _answered(bus.serve(batch)) == [(0x23, 1, SOURCE), (0x21, 1, OTHER), (0x22, 1, SOURCE)]
    assert [p.hosted.responses for p in ports] == [1, 1, 1]
    assert bus.unaddressed == 1
    assert taken == [ports[1].hosted]


def test_datagrams_for_no_station_here_are_counted_not_answered() -> None:
    bus = Bus([_port(0x21)])
    out = bus.serve([(_nop(0x30, 1), SOURCE), (b"\x01\x02\x03", SOURCE), (b"", SOURCE), (_nop(0x21, 1), SOURCE)])
    assert _answered(out) == [(0x21, 1, SOURCE)]
    assert bus.unaddressed == 3


def test_a_backlog_beyond_keep_per_source_is_superseded() -> None:
    """The newest *keep* of each source are answered, in order; the older ones count as SUPERSEDED drops."""
    port = _port(0x21, keep=3)
    batch = [(_nop(0x21, c), SOURCE) for c in range(1, 7)] + [(_nop(0x21, 50), OTHER)]
    out: list[tuple[bytes, Any]] = []
    port.serve(batch, out)
    assert _answered(out) == [(0x21, 4, SOURCE), (0x21, 5, SOURCE), (0x21, 6, SOURCE), (0x21, 50, OTHER)]
    assert port.station.counters.as_dict()["dropped_by_reason"]["SUPERSEDED"] == 3
    assert port.hosted.responses == 4


def test_an_eeprom_image_the_card_holds_after_a_read_is_handed_over() -> None:
    """docs/cards.md, "EEPROM": the worker writes the image the card hands over (``take_eeprom``); the read that
    left one pending calls *on_eeprom* with its hosted station, a read that left none does not."""
    taken: list[Any] = []
    port = _port(0x21, eeprom=taken)
    port.serve([(_nop(0x21, 1), SOURCE)], [])
    assert taken == []
    port.station.eeprom.dirty = True  # what a CONFIG to EEPROM (or a fault-history change) leaves behind
    port.serve([(_nop(0x21, 2), SOURCE)], [])
    assert taken == [port.hosted]


def test_a_backlog_within_keep_is_answered_in_full() -> None:
    port = _port(0x21, keep=3)
    out: list[tuple[bytes, Any]] = []
    port.serve([(_nop(0x21, c), SOURCE) for c in (1, 2, 3)], out)
    assert [c for _, c, _ in _answered(out)] == [1, 2, 3]
    assert "SUPERSEDED" not in port.station.counters.as_dict()["dropped_by_reason"]


def test_due_names_the_stations_whose_poll_has_come() -> None:
    """A station's next deadline: its silence deadline in phase 2/3 (SI-T3 Table 22), the drive's next step while
    the drive is not steady. The scan names the stations whose deadline is at or before *now*, in their order."""
    fresh, up = _station(0x21), _station(0x22)
    # CONNECT (SI-T3 Table 6; version 21H, COM_TIM 1): phase 2, whose silence deadline counts from this command
    assert up.receive(_command(0x22, 1, ml2.Connect(0x21, 0, 1)), SOURCE, TCYCLE) is not None and up.phase == 2
    deadlines = [fresh.next_deadline(), up.next_deadline()]
    assert None not in deadlines and deadlines[0] != deadlines[1]
    first, last = sorted(d for d in deadlines if d is not None)
    assert due([fresh, up], first - 1) == []
    assert due([fresh, up], first) == [deadlines.index(first)]
    assert due([fresh, up], last) == [0, 1]
    assert due([up, fresh, up], last) == [0, 1, 2]
