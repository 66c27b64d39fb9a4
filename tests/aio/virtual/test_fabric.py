"""mlink_sim.aio.virtual.fabric: the virtual clock's in-memory network (latency ± seeded jitter, order kept, polls at
the stations' deadlines, kill and restart) and its cycle."""

from __future__ import annotations

import pytest

from mlink_sim.aio.virtual.fabric import Fabric, FabricPort, VirtualCycle
from mlink_sim.aio.virtual.vclock import VirtualClock

US = 1_000


class EchoStation:
    """A station core that answers every command with b"R" + it, and wants a poll at ``due``."""

    card = "si-t3"
    address = 0x21

    def __init__(self, now: int, eeprom: bytes | None = None) -> None:
        self.powered_at = now
        self.eeprom = eeprom
        self.received: list[tuple[int, bytes, object]] = []
        self.polls: list[int] = []
        self.due: int | None = None
        self.eeprom_pending = False

    def receive(self, data: bytes, source: object, now: int) -> bytes | None:
        self.received.append((now, data, source))
        return b"R" + data

    def next_deadline(self) -> int | None:
        return self.due

    def poll(self, now: int) -> None:
        self.polls.append(now)
        self.due = None

    def finish(self) -> None:
        """Nothing is left for after an answer here."""

    def take_eeprom(self) -> bytes | None:
        self.eeprom_pending = False
        return b"image"


def _net(latency=50 * US, jitter=10 * US, seed=0):
    clock = VirtualClock()
    fabric = Fabric(clock, latency_ns=latency, jitter_ns=jitter, seed=seed)
    station = fabric.add_station(0x21, EchoStation)
    got: list[tuple[int, bytes]] = []
    port = FabricPort(fabric, "master:ML2", lambda data, now: got.append((now, data)))
    return clock, fabric, station, port, got


def test_a_round_trip_takes_two_one_way_delays_without_jitter():
    clock, _, station, port, got = _net(jitter=0)
    port.sendto(b"cmd", 0x21)
    clock.run_until(10**9)
    assert station.received == [(50 * US, b"cmd", "master:ML2")]
    assert got == [(100 * US, b"Rcmd")]


def test_jitter_stays_within_bounds_and_is_a_function_of_the_seed():
    def arrivals(seed):
        clock, _, station, port, _ = _net(seed=seed)
        for k in range(200):
            clock.run_until(k * 1_000 * US)
            port.sendto(bytes([k]), 0x21)
        clock.run_until(10**9)
        return [now - k * 1_000 * US for k, (now, _, _) in enumerate(station.received)]

    delays = arrivals(1)
    assert all(40 * US <= d <= 60 * US for d in delays)
    assert len(set(delays)) > 50  # drawn, not constant
    assert arrivals(1) == delays
    assert arrivals(2) != delays


def test_a_datagram_never_overtakes_the_one_before_it():
    clock, _, station, port, _ = _net(latency=50 * US, jitter=50 * US, seed=3)
    for k in range(500):
        port.sendto(k.to_bytes(2, "big"), 0x21)  # all at t = 0: each later draw may be shorter
    clock.run_until(10**9)
    order = [int.from_bytes(data, "big") for _, data, _ in station.received]
    assert order == list(range(500))
    times = [now for now, _, _ in station.received]
    assert times == sorted(times)


def test_the_station_is_polled_at_its_deadline():
    clock, fabric, station, port, _ = _net()
    station.due = 5_000 * US
    port.sendto(b"x", 0x21)  # a reception re-reads the deadline
    clock.run_until(10**9)
    assert station.polls == [5_000 * US]


def test_a_killed_station_loses_its_datagrams_and_powers_up_again_with_its_eeprom():
    clock, fabric, station, port, got = _net(jitter=0)
    station.eeprom_pending = True
    port.sendto(b"a", 0x21)
    clock.run_until(1_000 * US)
    assert fabric.nodes[0x21].eeprom == b"image"
    port.sendto(b"b", 0x21)  # in flight when the station dies
    assert fabric.kill(0x21, restart_after_ns=500_000 * US)
    assert fabric.kill(0x21, restart_after_ns=None) is False
    port.sendto(b"c", 0x21)
    clock.run_until(400_000 * US)
    assert fabric.station(0x21) is None and fabric.undeliverable == 2
    clock.run_until(600_000 * US)
    reborn = fabric.station(0x21)
    assert reborn is not station and reborn.eeprom == b"image" and reborn.powered_at == 501_000 * US
    assert [d for _, d in got] == [b"Ra"]


def test_jitter_larger_than_the_latency_is_refused():
    with pytest.raises(ValueError, match="jitter"):
        Fabric(VirtualClock(), latency_ns=10, jitter_ns=11, seed=0)


def test_the_cycle_is_on_time_every_period_until_stopped():
    clock = VirtualClock(start_ns=7)
    calls = []
    cycle = VirtualCycle(clock, 1_000_000, lambda k, d, now, skipped: calls.append((k, d, now, skipped)))
    cycle.start()
    clock.run_until(3_500_007)
    assert calls == [(k, 7 + (k + 1) * 1_000_000, 7 + (k + 1) * 1_000_000, 0) for k in range(3)]
    cycle.stop()
    clock.run_until(10**9)
    assert len(calls) == 3 and not cycle.running


def test_stale_eeprom_temporaries_are_removed_when_a_station_powers_up(tmp_path):
    """As the slave process does at start (docs/cards.md, "EEPROM"): an interrupted write's temporary file goes."""
    stale = tmp_path / ".si-t3-21H.eeprom.json.k1ll3d.tmp"
    stale.write_bytes(b"partial")
    fabric = Fabric(VirtualClock(), latency_ns=50 * US, jitter_ns=0, seed=0, state_dir=tmp_path)
    fabric.add_station(0x21, EchoStation)
    assert not stale.exists()


class _Capture:
    """What the fabric takes of a CaptureWriter: its ``sink``."""

    def __init__(self) -> None:
        self.records: list[tuple] = []
        self.sink = self.records.append


def test_a_capture_shows_each_answer_from_the_station_that_sent_it():
    """The master's view on the fabric's addresses (docs/virtual-time.md): a command to station 21H from the ML-II
    master's port, its answer from 21H, whatever its address byte says (the echo's answer b"Rcmd" carries 64H
    there, as a corrupted answer might)."""
    clock, capture = VirtualClock(), _Capture()
    fabric = Fabric(clock, latency_ns=50 * US, jitter_ns=0, seed=0, capture=capture)
    fabric.add_station(0x21, EchoStation)
    port = FabricPort(fabric, "master:ML2", lambda data, now: None)
    port.sendto(b"cmd", 0x21)
    clock.run_until(10**9)
    station, master = ("192.0.2.33", 47001), ("192.0.2.1", 40002)
    assert capture.records == [(0, b"cmd", master, station), (100 * US, b"Rcmd", station, master)]
