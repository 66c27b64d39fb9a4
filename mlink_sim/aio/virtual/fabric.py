"""The in-memory network of the virtual clock: the cards' cores and the masters exchange datagrams through a
:class:`Fabric` instead of UDP sockets, each delivered at ``now + latency ± jitter`` of simulated time.

Model (``[network] latency`` / ``jitter``, docs/configuration.md): every datagram, command or response, takes
``latency + u`` ns from sender to receiver, ``u`` drawn uniformly from ``[-jitter, +jitter]`` by a
``random.Random(seed)``; a datagram never overtakes the one sent before it on the same path (a wire keeps order).
A card answers at the instant a command reaches it; its :meth:`poll` runs at exactly its
:meth:`next_deadline` (silence detection, the drive), where a slave process polls on a 1 ms tick. The draws
happen in the order the datagrams are sent, which the cores fix, so a run is a pure function of config and seed.

The master side is a :class:`FabricPort`, a :class:`~mlink_sim.aio.transport.ports.DatagramPort` (``sendto``,
``recv`` and the socket's own calls: what the master's cycle uses), so :class:`~mlink_sim.aio.master.runner.Master` runs its own cycle code, fast path included,
unchanged. Responses reach ``MasterCore.on_response`` at their arrival time: RTTs are the model's.

Every datagram of a virtual run passes through here twice, so the module is compiled with the cores
(``mlink_sim._accel.COMPILED_MODULES``; its classes are native: no attributes beyond those declared).

Touches: no socket: the card cores it delivers to, the state directory's EEPROM images, a capture's sink when given.
"""

from __future__ import annotations

import random
from collections.abc import Callable
from pathlib import Path
from typing import Any

from ..._log import get_logger
from ...impair import Direction, ImpairmentLayer
from ..slave.state import atomic_write, eeprom_path, remove_stale_temps
from .vqueue import VirtualClock

__all__ = ["Fabric", "FabricPort", "VirtualCycle", "virtual_address"]

log = get_logger("mlink_sim.fabric")

_TICK_NS = 1_000_000  # a slave process's housekeeping tick (aio/slave/server.py): the floor between two polls


class _Node:
    """One station on the fabric: its card core (None while "killed"), and when its paths are next free."""

    def __init__(self, address: int, station: Any, factory: Callable[[int, bytes | None], Any]) -> None:
        self.address: int = address
        self.station: Any = station
        self.factory: Callable[[int, bytes | None], Any] = factory
        self.eeprom: bytes | None = None
        self.armed: int | None = None  # time of the earliest poll queued
        self.down_free: int = 0  # master -> station: no delivery before this (order kept)
        self.up_free: int = 0  # station -> master
        self.epoch: int = 0  # bumped when the station is killed: deliveries queued before are void


class FabricPort:
    """The master's end of the fabric, shaped like the non-blocking UDP socket the master uses: ``sendto(data,
    station_address)`` puts a command on the fabric; ``recv`` never has anything (responses are handed to
    ``on_datagram(data, now)`` when they arrive)."""

    def __init__(self, fabric: Fabric, name: str, on_datagram: Callable[[bytes, int], None]) -> None:
        self.fabric: Fabric = fabric
        self.name: str = name
        self.on_datagram: Callable[[bytes, int], None] = on_datagram
        self.closed: bool = False
        self.address: tuple[str, int] = virtual_address(name)  #: what a capture shows for this end

    def sendto(self, data: bytes, address: int) -> int:
        self.fabric.send(self, address, data)
        return len(data)

    def recv(self, bufsize: int) -> bytes:
        raise BlockingIOError

    def getsockname(self) -> tuple[str, int]:
        return (self.name, 0)

    def fileno(self) -> int:
        return -1

    def close(self) -> None:
        self.closed = True


def virtual_address(end: int | str) -> tuple[str, int]:
    """The IPv4 address a capture shows for an end of the fabric (documentation range 192.0.2.0/24, RFC 5737):
    station *n* is 192.0.2.*n*:47001, the master of link ``ML2``/``ML3`` (a port named ``master:ML2``) is
    192.0.2.1:4000x, x the link number (station addresses start at 03H, so .1 is never a station)."""
    if isinstance(end, int):
        return f"192.0.2.{end}", 47001
    number = end.rsplit("ML", 1)[-1]  # "master:ML3" -> "3"
    return "192.0.2.1", 40000 + (int(number) if number.isdigit() else 0)


class Fabric:
    """Stations and master ports on one :class:`VirtualClock` (see the module docstring)."""

    def __init__(self, clock: VirtualClock, *, latency_ns: int, jitter_ns: int, seed: int,
                 state_dir: Path | None = None, capture: Any = None) -> None:
        if not 0 <= jitter_ns <= latency_ns:
            raise ValueError(f"jitter ({jitter_ns} ns) must be between 0 and the latency ({latency_ns} ns)")
        self.clock: VirtualClock = clock
        self.latency_ns: int = latency_ns
        self.jitter_ns: int = jitter_ns
        self.seed: int = seed
        self.state_dir: Path | None = state_dir
        self.nodes: dict[int, _Node] = {}
        self.undeliverable: int = 0  #: datagrams for no station, or for a station that is down
        self._base: int = latency_ns - jitter_ns  # one-way delay: base + int(random() * span), 0 without jitter
        self._span: int = 2 * jitter_ns + 1 if jitter_ns else 0
        self._random: Callable[[], float] = random.Random(seed).random
        #: a CaptureWriter's ``sink``, fed one ``(ts_ns, datagram, src, dst)`` per datagram: the master's view, as
        #: ``up --capture`` records it – commands as they leave, answers as they arrive – on simulated time and the
        #: addresses of :func:`virtual_address` (made once per end: :attr:`FabricPort.address`, :attr:`_addresses`)
        self._sink: Callable[[tuple[int, bytes, tuple[str, int], tuple[str, int]]], Any] | None = \
            None if capture is None else capture.sink
        #: the capture's address of station n, at index n
        self._addresses: list[tuple[str, int]] = [virtual_address(n) for n in range(256)] if capture else []
        #: the impairment layer (docs/faults.md): while it is active, every datagram goes through it after the
        #: network model (its delays add to the model's ordered delivery time, and may reorder)
        self.impair: ImpairmentLayer | None = None

    # ------------------------------------------------------------------ stations
    def add_station(self, address: int, factory: Callable[[int, bytes | None], Any]) -> Any:
        """Power up the station *address* now: ``factory(now, eeprom_image)`` builds its card core. Temporary files
        an interrupted write of its EEPROM image left are removed (as the slave process does)."""
        node = self.nodes[address] = _Node(address, factory(self.clock.now, None), factory)
        if self.state_dir is not None:
            remove_stale_temps(eeprom_path(self.state_dir, node.station.card, node.station.address))
        self._arm(node)
        return node.station

    def station(self, address: int) -> Any:
        """The card core of *address* (None while it is down after :meth:`kill`)."""
        return self.nodes[address].station

    def kill(self, address: int, restart_after_ns: int | None) -> bool:
        """Take the station off the fabric (as a killed slave process: no answer, datagrams lost); power it up
        again from its EEPROM image after *restart_after_ns* (None: never). False if already down."""
        node = self.nodes[address]
        if node.station is None:
            return False
        node.station = None
        node.epoch += 1
        node.armed = None
        if restart_after_ns is not None:
            self.clock.at(self.clock.now + restart_after_ns, self._restart, (node, node.epoch))
        return True

    def _restart(self, arg: tuple[_Node, int]) -> None:
        node, epoch = arg
        if node.epoch != epoch or node.station is not None:
            return
        node.station = node.factory(self.clock.now, node.eeprom)
        log.info("station_restarted", station=f"{node.address:02X}H")
        self._arm(node)

    # ------------------------------------------------------------------ datagrams
    def send(self, port: FabricPort, address: int, data: bytes) -> None:
        """A command from *port* to station *address*, leaving now."""
        clock = self.clock
        now = clock.now
        if self._sink is not None:
            self._sink((now, data, port.address, self._addresses[address]))
        node = self.nodes.get(address)
        if node is None or node.station is None:
            self.undeliverable += 1
            return
        t = now + self._base
        if self._span:
            t += int(self._random() * self._span)
        if t < node.down_free:
            t = node.down_free
        node.down_free = t
        impair = self.impair
        if impair is not None and impair.active:
            for extra, out in impair.process(data, Direction.TO_STATION, address, now):
                clock.at(t + extra, self._to_station, (node, node.epoch, port, out))
            return
        clock.at(t, self._to_station, (node, node.epoch, port, data))

    def _to_station(self, arg: tuple[_Node, int, FabricPort, bytes]) -> None:
        node, epoch, port, data = arg
        station = node.station
        if station is None or epoch != node.epoch:
            self.undeliverable += 1
            return
        clock = self.clock
        now = clock.now
        response = station.receive(data, port.name, now)
        station.finish()  # what the command left for after its answer (no other work waits on simulated time)
        if station.eeprom_pending:
            self._save(node, station)
        armed = node.armed
        if armed is None or armed > now:  # (a poll due now is queued already)
            self._arm(node)
        if response is not None:
            t = now + self._base
            if self._span:
                t += int(self._random() * self._span)
            if t < node.up_free:
                t = node.up_free
            node.up_free = t
            impair = self.impair
            if impair is not None and impair.active:
                for extra, out in impair.process(response, Direction.TO_MASTER, node.address, now):
                    clock.at(t + extra, self._to_master, (port, out, node.address))
                return
            clock.at(t, self._to_master, (port, response, node.address))

    def _to_master(self, arg: tuple[FabricPort, bytes, int]) -> None:
        port, data, station = arg  # the station it came from (its address byte may have been corrupted)
        if port.closed:
            self.undeliverable += 1
            return
        if self._sink is not None:
            self._sink((self.clock.now, data, self._addresses[station], port.address))
        port.on_datagram(data, self.clock.now)

    # ------------------------------------------------------------------ polls
    def rearm(self, address: int) -> None:
        """The station's deadline may be sooner than armed (a drive fault changed its drive): poll it then."""
        node = self.nodes.get(address)
        if node is not None:
            self._arm(node)

    def _arm(self, node: _Node) -> None:
        station = node.station
        if station is None:
            return
        due = station.next_deadline()
        if due is not None and (node.armed is None or due < node.armed):
            node.armed = due
            self.clock.at(due, self._poll, node)

    def _poll(self, node: _Node) -> None:
        station = node.station
        now = self.clock.now
        if station is None or node.armed != now:
            return  # superseded by an earlier poll, or the station is down
        node.armed = None
        due = station.next_deadline()
        if due is not None and due <= now:
            station.poll(now)
            station.finish()
            if station.eeprom_pending:
                self._save(node, station)
            due = station.next_deadline()
            if due is not None and due <= now:  # still due: poll again a slave tick later, as a slave process would
                node.armed = now + _TICK_NS
                self.clock.at(node.armed, self._poll, node)
                return
        if due is not None:  # self._arm(node), spelt out: nothing is armed now
            node.armed = due
            self.clock.at(due, self._poll, node)

    def _save(self, node: _Node, station: Any) -> None:
        image = station.take_eeprom()
        if image is None:
            return
        node.eeprom = image
        if self.state_dir is not None:
            path = eeprom_path(self.state_dir, station.card, station.address)
            atomic_write(path, image)
            log.info("eeprom_saved", path=str(path), bytes=len(image))


class VirtualCycle:
    """The transmission cycle on simulated time: ``on_cycle(cycle, deadline_ns, now_ns, skipped)`` at exactly
    ``start + k·period`` (never late, never skipped), the interface of :class:`~mlink_sim.aio.timing.ticker.CycleTimer`
    that the master uses (``running``, ``stop``, ``strategy``)."""

    strategy = "virtual"

    def __init__(self, clock: VirtualClock, period_ns: int, on_cycle: Callable[[int, int, int, int], None]) -> None:
        self.clock: VirtualClock = clock
        self.period_ns: int = period_ns
        self._on_cycle: Callable[[int, int, int, int], None] = on_cycle
        self.running: bool = False
        self.cycle: int = -1
        self._start: int = 0

    def start(self) -> None:
        """First cycle one period from now."""
        self.running = True
        self._start = self.clock.now + self.period_ns
        self.clock.at(self._start, self._tick, 0)

    def stop(self) -> None:
        self.running = False

    def _tick(self, k: int) -> None:
        if not self.running:
            return
        deadline = self._start + k * self.period_ns
        self.cycle = k
        self._on_cycle(k, deadline, deadline, 0)
        if self.running:
            self.clock.at(deadline + self.period_ns, self._tick, k + 1)
