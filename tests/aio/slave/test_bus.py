"""A slave worker's per-read path (mlink_sim.aio.slave.bus), on real card cores and without sockets: the station byte
picks the station, each station's datagrams keep their order, a backlog beyond *keep* per source is superseded,
datagrams for no station are counted, the tick's scan names exactly the stations whose poll is due, and the answers
made ahead from the cards' predictions are the cards' own."""

from __future__ import annotations

from typing import Any

import pytest

from mlink_sim.aio.slave.bus import Bus, Port, due
from mlink_sim.aio.slave.server import HostedStation
from mlink_sim.cards import Station, create_card, settings_for
from mlink_sim.cards.prediction import Prediction
from mlink_sim.master import MasterCore, NetworkPlan, StationPlan
from mlink_sim.wire import Frame, Kind, Link, decode, encode, ml2
from mlink_sim.wire.codes import CommAlm
from mlink_sim.wire.frame import CYCLE_AT, cycle_of, steady_delta

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


def test_a_station_counts_its_answers_on_across_the_ports_that_serve_it() -> None:
    """The count lives on the Port (a native int); the HostedStation reads it, and a Port made again for the same
    station (a socket set up again) goes on from it."""
    first = _port(0x21)
    hosted = first.hosted
    assert hosted.responses == 0
    first.serve([(_nop(0x21, 1), SOURCE), (_nop(0x21, 2), SOURCE)], [])
    assert hosted.responses == 2 and first.responses == 2
    again = Port(first.station, hosted, 8, [].append, Clock())
    again.serve([(_nop(0x21, 3), SOURCE)], [])
    assert hosted.responses == 3 and hosted.bus_port is again


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
    an EEPROM image handed over once the answers of the read that left it are sent (settle), not before."""
    taken: list[Any] = []
    ports = [_port(a, eeprom=taken) for a in (0x21, 0x22, 0x23)]
    bus = Bus(ports)
    ports[1].station.eeprom.dirty = True
    batch = [(_nop(0x23, 1), SOURCE), (_nop(0x30, 1), SOURCE), (_nop(0x21, 1), OTHER), (_nop(0x22, 1), SOURCE)]
    assert _answered(bus.serve(batch)) == [(0x23, 1, SOURCE), (0x21, 1, OTHER), (0x22, 1, SOURCE)]
    assert [p.hosted.responses for p in ports] == [1, 1, 1]
    assert bus.unaddressed == 1
    assert taken == []
    bus.settle()
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
    """docs/cards.md, "EEPROM": the worker writes the image the card hands over (``take_eeprom``); once the answers
    of a read that left one pending are sent (``after_send``) *on_eeprom* has its hosted station, not before; a read
    that left none does not call it."""
    taken: list[Any] = []
    port = _port(0x21, eeprom=taken)
    port.serve([(_nop(0x21, 1), SOURCE)], [])
    port.after_send()
    assert taken == []
    port.station.eeprom.dirty = True  # what a CONFIG to EEPROM (or a fault-history change) leaves behind
    port.serve([(_nop(0x21, 2), SOURCE)], [])
    assert taken == []
    port.after_send()
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


def _line(link: Link, stations: int, com_tim: int = 0) -> tuple[MasterCore, dict[int, Station]]:
    """A master core and its cards (SI-T3 on ML-II, SI-ET3 on ML-III), as the exchange benchmark builds them;
    *com_tim*: CONNECT's communication cycle in transmission cycles (0: the master's default)."""
    card, size, first = ("si-t3", 17, 0x21) if link is Link.ML2 else ("si-et3", 32, 0x03)
    plan = NetworkPlan(link, TCYCLE, tuple(StationPlan(first + i, link, data_size=size, com_tim=com_tim)
                                           for i in range(stations)))
    cards = {sp.address: create_card(card, settings=settings_for(card, sp.address, size, []), now=0)
             for sp in plan.stations}
    return MasterCore(plan), cards


def test_answers_made_ahead_are_the_cards_own_and_the_cards_take_every_command() -> None:
    """docs/cards.md, "The answer made ahead": over a bring-up and a steady run of 6 SI-ET3 stations (Table 28's
    line, shortened), the bus answers most commands from the cards' predictions; every answer it sends equals the one
    the same card, fed the same commands at the same times without predictions, gives; after each read's settle the
    cards' counters and drives are the reference cards' too."""
    core, cards = _line(Link.ML3, 6)
    _, reference = _line(Link.ML3, 6)
    now = {"t": 0}
    bus = Bus([Port(st, HostedStation(st, "127.0.0.1", 0), 8, [].append, lambda: now["t"]) for st in cards.values()],
              lambda: now["t"])
    for cycle in range(1, 1501):
        t = cycle * TCYCLE
        now["t"] = t + 50_000
        batch = [(dg, SOURCE) for _, dg in core.on_cycle(cycle, t)]
        out = bus.serve(batch)
        want = [reference[dg[3]].receive(dg, SOURCE, now["t"]) for dg, _ in batch]
        assert [a for a, _ in out] == [w for w in want if w is not None]
        bus.settle()
        for answer, _ in out:
            core.on_response(answer, t + 100_000)
        core.drain_events()
        for st, ref in zip(cards.values(), reference.values()):
            deadline = ref.next_deadline()
            if deadline is not None and deadline <= t + 900_000:  # the worker's tick: poll the due ones
                bus.ports[st.address].forget()
                st.poll(t + 900_000)
                ref.poll(t + 900_000)
    assert {v.state.value for v in core.views().values()} == {"phase3"}
    assert bus.mispredicted == 0 and bus.ahead > 0.8 * 6 * 1500, bus.ahead
    for st, ref in zip(cards.values(), reference.values()):
        assert st.counters.as_dict() == ref.counters.as_dict()
        assert st.snapshot().drive == ref.snapshot().drive


def test_an_answer_that_was_not_the_cards_is_counted_and_logged(caplog: Any) -> None:
    """A prediction that the card's own answer then contradicts (a bug) is counted on its port, in the card's
    ``internal_errors`` (the report's counters), and logged."""
    core, cards = _line(Link.ML2, 1)
    (st,) = cards.values()
    port = Port(st, HostedStation(st, "127.0.0.1", 0), 8, [].append, lambda: 5 * TCYCLE)
    bus = Bus([port])
    dg = next(iter(core.on_cycle(1, TCYCLE)))[1]  # the master's first command (phase 1): the card answers it
    wdt_at = st._cmd_wdt_at
    port.pred = Prediction(SOURCE, dg, wdt_at, steady_delta(dg, dg, CYCLE_AT, wdt_at) & 0xF0_FFFF_FFFF, b"forged",
                           10 * TCYCLE)
    assert bus.serve([(dg, SOURCE)]) == [(b"forged", SOURCE)]
    bus.settle()
    assert bus.mispredicted == 1 == st.counters.internal_errors and bus.ahead == 1
    assert "answer_mispredicted" in caplog.text


def _by_station(datagrams: list[bytes]) -> dict[int, list[bytes]]:
    out: dict[int, list[bytes]] = {}
    for dg in datagrams:
        out.setdefault(dg[3], []).append(dg)
    return out


@pytest.mark.parametrize("com_tim", [1, 2])
def test_a_backlog_is_answered_ahead_and_the_cards_take_every_command_in_order(com_tim: int) -> None:
    """docs/cards.md, "The answer made ahead": reads holding 2-5 cycles' commands at once (the master catching up
    after a stall of its own, or a worker held up), now and then with another SEL_MON partway through. The bus
    answers each station's run ahead as far as its card's prediction carries it, the rest in the chain, each
    station's answers to its commands in their order; every answer equals the one the same card, fed the same commands
    at the same time without predictions, gives, and after each read's settle the cards are the reference cards. Reads
    3-5 ms after the one before (past the cards' silence deadline: one communication cycle and 2 ms,
    mlink_sim.cards.reception) are answered ahead too: no poll came between. With a communication cycle of two
    transmission cycles (COM_TIM 2) each station's commands are two cycles apart, and so are its predictions."""
    core, cards = _line(Link.ML3, 6, com_tim)
    _, reference = _line(Link.ML3, 6, com_tim)
    now = {"t": 0}
    bus = Bus([Port(st, HostedStation(st, "127.0.0.1", 0), 8, [].append, lambda: now["t"]) for st in cards.values()],
              lambda: now["t"])
    cycle = 0
    backlogs = dict.fromkeys(range(2, 6), 0)
    ahead_in = dict.fromkeys(range(2, 6), 0)
    while cycle < 2400:
        k = 1 if cycle < 600 or cycle % 7 else 2 + cycle % 4
        t = (cycle + k) * TCYCLE
        now["t"] = t + 50_000
        batch = []
        for i in range(k):
            cycle += 1
            if k > 1 and i == 1 and cycle % 3 == 0:  # another monitor selected partway through the backlog
                core.set_control(0x03 + cycle % 6, sel_mon=0x41 if cycle % 2 else 0x21)
            batch += [(dg, SOURCE) for _, dg in core.on_cycle(cycle, t)]
        ahead = bus.ahead
        out = bus.serve(batch)
        want = [reference[dg[3]].receive(dg, SOURCE, now["t"]) for dg, _ in batch]
        got = _by_station([a for a, _ in out])  # the order on the wire: the test after this one
        assert {st: sorted(a, key=cycle_of) for st, a in got.items()} == _by_station([w for w in want if w is not None])
        bus.settle()
        if k > 1:
            backlogs[k] += 1
            ahead_in[k] += bus.ahead - ahead
        for answer, _ in out:
            core.on_response(answer, t + 100_000)
        core.drain_events()
        for st, ref in zip(cards.values(), reference.values()):
            deadline = ref.next_deadline()
            if deadline is not None and deadline <= t + 900_000:
                bus.ports[st.address].forget()
                st.poll(t + 900_000)
                ref.poll(t + 900_000)
    assert min(backlogs.values()) > 50 and bus.mispredicted == 0
    for k, n in backlogs.items():  # nearly all of them ran ahead (a station's new SEL_MON stops its run)
        assert ahead_in[k] > 0.9 * n * 6 * k / com_tim, (ahead_in, backlogs)
    for st, ref in zip(cards.values(), reference.values()):
        assert st.counters.as_dict() == ref.counters.as_dict()
        assert st.snapshot().drive == ref.snapshot().drive


def _steady_line(stations: int) -> tuple[MasterCore, Bus, dict[str, int]]:
    """A line of *stations* SI-ET3 stations run to phase 3 and a steady state through a :class:`Bus` (one read per
    cycle), with the time the reads are stamped with."""
    core, cards = _line(Link.ML3, stations)
    now = {"t": 0, "cycle": 0}
    bus = Bus([Port(st, HostedStation(st, "127.0.0.1", 0), 8, [].append, lambda: now["t"]) for st in cards.values()],
              lambda: now["t"])
    for cycle in range(1, 1201):
        t = cycle * TCYCLE
        now["t"] = t + 50_000
        out = bus.serve([(dg, SOURCE) for _, dg in core.on_cycle(cycle, t)])
        bus.settle()
        for answer, _ in out:
            core.on_response(answer, t + 100_000)
        core.drain_events()
    now["cycle"] = 1200
    assert {v.state.value for v in core.views().values()} == {"phase3"}
    return core, bus, now


def _backlog(core: MasterCore, bus: Bus, now: dict[str, int], k: int) -> list[tuple[int, int]]:
    """The next *k* cycles' commands in one read; (station, cycle) of the answers, in the order they go out."""
    batch = []
    for _ in range(k):
        now["cycle"] += 1
        batch += [(dg, SOURCE) for _, dg in core.on_cycle(now["cycle"], now["cycle"] * TCYCLE)]
    now["t"] = now["cycle"] * TCYCLE + 50_000
    out = bus.serve(batch)
    bus.settle()
    return [(a[3], cycle_of(a)) for a, _ in out]


def test_a_backlog_answered_ahead_goes_out_newest_cycle_first() -> None:
    """A read holding three cycles' commands for each of three stations, all answered ahead: every station's answer
    to the newest cycle goes out first (the stations in their order), then the cycle before, the oldest last. The
    oldest were due at the master before this read was even made; the newest still can be in time (docs/cards.md,
    "A backlog's answers"). The cards still take the commands in their order (the test before this one)."""
    core, bus, now = _steady_line(3)
    ahead = bus.ahead
    k = now["cycle"]
    assert _backlog(core, bus, now, 3) == [(s, k + c) for c in (3, 2, 1) for s in (3, 4, 5)]
    assert bus.ahead - ahead == 9 and bus.mispredicted == 0


def test_a_backlog_keeps_its_order_where_it_was_not_all_answered_ahead() -> None:
    """A station whose prediction stops partway (another SEL_MON: the card answers the rest itself) keeps its answers
    in its commands' order, ahead of the older answers of the others."""
    core, bus, now = _steady_line(3)
    k = now["cycle"]
    now["cycle"] += 1
    batch = [(dg, SOURCE) for _, dg in core.on_cycle(k + 1, (k + 1) * TCYCLE)]
    core.set_control(4, sel_mon=0x21)
    now["cycle"] += 1
    batch += [(dg, SOURCE) for _, dg in core.on_cycle(k + 2, (k + 2) * TCYCLE)]
    now["t"] = (k + 2) * TCYCLE + 50_000
    out = bus.serve(batch)
    bus.settle()
    assert [(a[3], cycle_of(a)) for a, _ in out] == [(3, k + 2), (4, k + 1), (4, k + 2), (5, k + 2), (3, k + 1),
                                                     (5, k + 1)]


def test_a_backlog_after_a_poll_is_answered_ahead_after_each_cards_first_command() -> None:
    """docs/cards.md, "A backlog": a worker held up past its cards' silence deadline while the master was held too
    polls its stations before their commands come (each card counts its reception failures and drops its
    prediction: ``Station.poll``), then reads the master's catch-up, three cycles' commands at once. Each card takes
    its station's first command in the chain, at the read's time, and the second (the first answer after the
    failure is not the steady one); the prediction the card offers right after answers the third ahead. Every
    answer is the reference card's (the same commands at the same times, no predictions); after the settle the cards
    are the reference cards, and the answers answered ahead do not wait for the cards' work. (The cards here keep the
    default silence tolerance; under "absorb" it is the stall bound, and such a backlog comes only with a card
    silence tolerance shorter than the stall: docs/cards.md, "A backlog".)"""
    core, cards = _line(Link.ML3, 6)
    _, reference = _line(Link.ML3, 6)
    now = {"t": 0}
    bus = Bus([Port(st, HostedStation(st, "127.0.0.1", 0), 8, [].append, lambda: now["t"]) for st in cards.values()],
              lambda: now["t"])

    def read(batch: list[tuple[bytes, Any]]) -> list[tuple[bytes, Any]]:
        out = bus.serve(batch)
        want = [reference[dg[3]].receive(dg, SOURCE, now["t"]) for dg, _ in batch]
        assert {st: sorted(a, key=cycle_of) for st, a in _by_station([a for a, _ in out]).items()} == _by_station(
            [w for w in want if w is not None])
        bus.settle()
        for answer, _ in out:
            core.on_response(answer, now["t"] + 50_000)
        core.drain_events()
        return out

    for cycle in range(1, 1201):
        now["t"] = cycle * TCYCLE + 50_000
        read([(dg, SOURCE) for _, dg in core.on_cycle(cycle, cycle * TCYCLE)])
    assert {v.state.value for v in core.views().values()} == {"phase3"}
    polled = 1204 * TCYCLE  # the worker's tick after four cycles held up: past every card's silence deadline
    for st, ref in zip(cards.values(), reference.values()):
        assert st.silence_due(polled) and bus.ports[st.address].pred is not None
        bus.ports[st.address].forget()
        st.poll(polled)
        ref.poll(polled)
    assert all(st.counters.reception_failures > 0 for st in cards.values())  # the silence, counted by the poll
    ahead = bus.ahead
    now["t"] = polled + 100_000
    out = read([(dg, SOURCE) for cycle in range(1201, 1204)
                for _, dg in core.on_cycle(cycle, polled + 20_000 * (cycle - 1200))])
    # SI-ET3 CMD_STAT, COMM_ALM: the silence in phase 3 is warning 3 ("Synchronous frame not received"), cleared
    # only by ALM_CLR, so every answer carries it, the ones made ahead too
    assert [decode(a).message.stat.comm_alm for a, _ in out] == [CommAlm.SYNC_NOT_RECEIVED_WARNING] * 18
    # the card's first answer after the failure differs from the one before, so its prediction comes after the
    # second command (a fixed point: two equal answers in a row, mlink_sim.cards.prediction): the third goes ahead
    assert bus.mispredicted == 0 and bus.ahead - ahead == 6, bus.ahead - ahead
    for st, ref in zip(cards.values(), reference.values()):
        assert st.counters.as_dict() == ref.counters.as_dict()
        assert st.snapshot().drive == ref.snapshot().drive


def test_untrusted_datagrams_reach_the_station_their_byte_names_read_only() -> None:
    """``Bus.serve_untrusted`` (a source ``--allow-master`` does not name): a NOP is answered by the station its
    address byte names, CONNECT binds nothing and is counted in foreign_source, a datagram for no station is
    counted in ``unaddressed``."""
    ports = [_port(0x21), _port(0x22)]
    bus = Bus(ports)
    out: list[tuple[bytes, Any]] = []
    bus.serve_untrusted([(_nop(0x22, 5), OTHER), (_command(0x21, 6, ml2.Connect(0x21, 0, 1)), OTHER),
                         (_nop(0x30, 7), OTHER)], out)
    assert _answered(out) == [(0x22, 5, OTHER)]
    assert ports[0].station.phase == 1 and ports[0].station.counters.foreign_source == 1
    assert ports[1].station.counters.status_queries == 1 and ports[1].responses == 1
    assert bus.unaddressed == 1
