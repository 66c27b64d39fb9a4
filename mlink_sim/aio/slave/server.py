"""The slave side over UDP: one datagram endpoint per hosted station, feeding the sans-I/O card cores.

The server only moves bytes and keeps time: ``datagram -> station.receive(data, addr, now) -> sendto``, then
``station.finish()`` (what the command left for after its answer: docs/timing.md, "When each command is answered"). Each
station's socket is read in batches; a backlog beyond eight commands per source is superseded
(``SlaveServer._port``, :mod:`mlink_sim.aio.slave.bus`). A 1 ms housekeeping tick calls ``station.poll(now)`` for
stations whose deadline has come (silence detection, drive). EEPROM images the cards hand over (``take_eeprom``)
are written atomically in a worker thread, and once an image is written, fsync'd and renamed the card is told
(``station.eeprom_durable``): a CONFIG to EEPROM answers CMDRDY = 0 until then (docs/cards.md, "EEPROM").
Temporary files a killed process left are removed at start.

What a slave's control endpoint answers (:mod:`mlink_sim.aio.control.slave`: ``stats``, ``cpu``, ``status``, the
parameters, the drive faults) it reads here: :meth:`SlaveServer.stats` (every station's snapshot and counters, the
process's CPU time and host stalls), :meth:`SlaveServer.stats_text` (the same, built one station at a time, the loop
answering the cyclic commands in between), :meth:`SlaveServer.cpu`.

Touches: the stations' UDP sockets, the card cores, the EEPROM image files (a worker thread writes them).
"""

from __future__ import annotations

import asyncio
import json
import os
import resource
import time
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path
from typing import Any


from ..._log import get_logger
from ...capture.text import card_note
from ...drive.monitors import ref_to_hz
from ...jsonable import to_jsonable
from ...metrics.stalls import WORKER_STALL_NS, StallLog
from ...faults.plant import PlantFaults
from .allow import AllowList
from .bus import Bus, Port, due
from .state import atomic_write, eeprom_path, remove_stale_temps
from ..transport.tapped import tap
from ..transport.udp import BatchEndpoint, open_batch_endpoint
from ..timing.realtime import background_thread, yield_after_send
from ..timing.slack import Slack, Step

__all__ = ["HostedStation", "SlaveServer"]

log = get_logger("mlink_sim.slave")

_POLL_INTERVAL_S = 0.001
_POLL_INTERVAL_NS = 1_000_000
_KEEP_BEHIND = 8  # datagrams per source processed from one read; older ones are superseded (see _port)
_POLL_MAX_KEYS = ("period_ns", "lead_ns")  #: of the arrival polls' counters, those not summed but the largest taken
_MIN_CYCLE_NS = 250_000  # the shortest transmission cycle (SI-ET3 Table 14): sizes the backlog "absorb" keeps
_BURST = 64  # datagrams read per wake-up of a station's socket at most (a shared socket: this many per station)
# Receive buffer of a station's socket; a shared socket asks for this much per station, so that a backlog lasts
# as long as on a socket of its own (the kernel caps the request at net.core.rmem_max).
_RCVBUF = 1 << 20
_STALLS_REPORTED = 256  # recent stalls in each stats reply (the session keeps them by time)
_COMPACT = (",", ":")  # json.dumps separators of the control replies
_STATS_PACE_S = 0.001  #: the longest wait for a slack between two stations of a stats reply (SlaveServer.stats_text)
#: … for this long at most: the rest without a pause, so that the reply stays well inside the 1 s a query waits
#: (``query_control``) on a loaded host too (docs/performance.md, "A worker's stats reply")
_STATS_PACED_S = 0.3
#: after a read's answers are sent (and the cards settled), the worker's loop is free this long for the work beside
#: the commands (a stats reply's steps): half the shortest transmission cycle (SI-ET3 Table 28, 250 µs)
_SLACK_NS = _MIN_CYCLE_NS // 2


def _cpu_seconds() -> float:
    ru = resource.getrusage(resource.RUSAGE_SELF)
    return ru.ru_utime + ru.ru_stime


@dataclass
class HostedStation:
    """A card core and where it listens."""

    station: Any  #: a mlink_sim.cards Station
    host: str
    port: int
    endpoint: BatchEndpoint | None = None
    eeprom: Path | None = None
    bus_port: Any = field(default=None, repr=False, compare=False)  #: the aio.slave.bus.Port that serves it (it counts)

    @property
    def responses(self) -> int:
        """The answers sent for this station (counted by its :class:`~mlink_sim.aio.slave.bus.Port`)."""
        return 0 if self.bus_port is None else int(self.bus_port.responses)


class SlaveServer:
    """Serves one or more stations; ``await start()`` binds, ``await close()`` stops."""

    def __init__(
        self,
        stations: list[HostedStation],
        *,
        state_dir: str | Path | None = None,
        absorb_ns: int = 0,
        capture: Any = None,
        shared: bool = False,
        arrival_poll: tuple[int, int | None] | None = None,
        batched: bool = True,
        allow: AllowList | None = None,
    ) -> None:
        """*capture*: a :class:`~mlink_sim.capture.CaptureWriter`: every station socket is tapped, and each
        station's phase changes (seen by the 1 ms tick) become notes.

        *shared*: the stations of one link that listen on the same host and port (port 0 included) share one
        socket, as stations share a bus: the station address of each datagram (byte 3, docs/wire-format.md) picks
        its station, and the answers to one read go back in one burst (``mmsg.BurstSocket.send_burst``: one
        offloaded packet per burst where the kernel can). A datagram for no station hosted there is counted in
        :attr:`unaddressed`, as a station on a bus ignores frames for others.

        *arrival_poll*: :func:`~mlink_sim.config.units.parse_arrival_poll`'s setting (None: off). Each shared socket,
        or the worker's only socket, is then read in a short busy-poll around the time its next burst of commands is
        due (:class:`~mlink_sim.aio.timing.arrival.ArrivalPoll`). The sockets of a worker hosting several stations each
        on its own port are not: their polls would hold each other up.

        *allow*: the sources that may change a station (:mod:`mlink_sim.aio.slave.allow`; None: any). The kernel
        drops every other source's datagrams at each station socket (:meth:`_refuse_others`); each read is screened
        once more (:meth:`AllowList.screen <mlink_sim.aio.slave.allow.AllowList.screen>`, one look-up per datagram)
        and the datagrams of a source that may not change a station go to the cards' ``receive_untrusted``. Host
        names are resolved in a worker thread at the start and again, once a second at most, while one is
        unresolved or an unknown source shows (a rise in the sockets' drops, :meth:`_watch_allow`).

        *batched*: the batched calls (``sendmmsg``/``recvmmsg``, UDP segmentation offload) where the kernel has them;
        False keeps the per-datagram calls on every socket (the tests compare both paths that way)."""
        self.stations = stations
        self.shared = shared
        self.arrival_poll = arrival_poll
        self._buses: list[Bus] = []  #: one per shared socket (its ``unaddressed`` count)
        self._ports: dict[int, Port] = {}  #: each station's Port, by ``id(hs)`` (Port.forget)
        #: host-stall policy (docs/timing.md): 0 = strict, else the stall bound. With "absorb" a backlog that a
        #: stall of this worker of up to the bound left on a socket is answered in full (late, not superseded).
        self.absorb_ns = absorb_ns
        self._keep_behind = max(_KEEP_BEHIND, absorb_ns // _MIN_CYCLE_NS + 2)
        self.stalls = StallLog("absorb" if absorb_ns else "strict", absorb_ns)
        self.batched = batched
        self.allow = allow
        self._resolving: asyncio.Future[None] | None = None
        self._resolved_at = 0.0
        self._unresolved: list[str] = []  #: the names last logged as unresolved
        self._refusing: tuple[list[str | None], int] = ([], 0)  #: how each socket refuses others, as last logged
        self._drops_checked = 0.0
        self._drops_seen = 0
        self._tick_due = 0
        self.state_dir = Path(state_dir) if state_dir else None
        self._tick: asyncio.TimerHandle | None = None
        self._pending_writes: dict[Path, tuple[HostedStation, int, bytes]] = {}
        self._writer: asyncio.Task[None] | None = None
        #: the thread that writes the EEPROM images, in the background (realtime.background_thread): at the loop's
        #: real-time priority it would hold the worker's CPU while the commands of the cycle wait
        self._writes: ThreadPoolExecutor | None = None
        self._write_wakeup = asyncio.Event()
        self._started_wall = time.monotonic()
        self._started_cpu = _cpu_seconds()
        self.write_errors = 0
        self._closing = False
        self._capture = capture
        self._phases = {id(hs): hs.station.phase for hs in stations}
        self._cores = [hs.station for hs in stations]  #: the card cores, for the tick's scan (``bus.due``)
        self.plants = PlantFaults()  #: drive faults in force (a slave's ``fault`` operation)
        #: the time after a read's answers went, where a stats reply's steps run (:mod:`mlink_sim.aio.timing.slack`)
        self.slack = Slack(max_wait_s=_STATS_PACE_S)
        self._stats_step = Step()
        for hs in stations:
            if self.state_dir is not None and hs.eeprom is None:
                hs.eeprom = eeprom_path(self.state_dir, hs.station.card, hs.station.address)
            # a CONFIG to EEPROM completes once its image is durable (nothing to wait for without a file)
            hs.station.persist_eeprom(hs.eeprom is not None)

    # -- lifecycle --------------------------------------------------------------------------------------------

    async def start(self) -> None:
        loop = asyncio.get_running_loop()
        for hs in self.stations:
            if hs.eeprom is not None and (n := remove_stale_temps(hs.eeprom)):
                log.info("eeprom_stale_temps_removed", path=str(hs.eeprom), count=n)
        try:
            wrap = None if self._capture is None else partial(tap, self._capture, batched=self.batched)
            groups = self._port_groups()
            for group in groups:
                first = group[0]
                if len(group) == 1:
                    endpoint = await open_batch_endpoint(self._receiver(first), first.host, first.port, wrap=wrap,
                                                         rcvbuf=_RCVBUF, batched=self.batched)
                else:
                    endpoint = await open_batch_endpoint(self._bus_receiver(group), first.host, first.port,
                                                         wrap=wrap, burst=_BURST * len(group),
                                                         rcvbuf=_RCVBUF * len(group), batched=self.batched)
                    endpoint.enable_gro()  # the master sends each cycle's commands to this port as one burst
                for hs in group:
                    hs.endpoint, hs.port = endpoint, endpoint.local_address[1]
                if len(group) > 1 or len(groups) == 1:
                    endpoint.poll_arrivals(self.arrival_poll)
        except OSError:
            await self.close()
            raise
        self._note_cards()
        self._writer = loop.create_task(self._write_loop())
        self._refuse_others()
        self._resolve_allow()
        self._tick_due = time.monotonic_ns() + _POLL_INTERVAL_NS
        self._tick = loop.call_later(_POLL_INTERVAL_S, self._on_tick)
        self._started_wall = time.monotonic()
        self._started_cpu = _cpu_seconds()

    async def close(self) -> None:
        self._closing = True
        if self._tick is not None:
            self._tick.cancel()
            self._tick = None
        for hs in self.stations:
            self._collect_eeprom(hs)
            if hs.endpoint is not None:
                hs.endpoint.close()
        if self._resolving is not None:  # a name being resolved in a worker thread: its answer lands on this loop
            await asyncio.wait([self._resolving], timeout=2.0)
        if self._writer is not None:
            self._write_wakeup.set()
            await self._writer
            self._writer = None

    def ready_info(self) -> dict[str, Any]:
        """What the ``ready`` line reports: where every station listens (the caller adds the control port)."""
        return {
            "event": "ready",
            "pid": os.getpid(),
            "stations": [
                {
                    "address": hs.station.address,
                    "card": hs.station.card,
                    "host": hs.host,
                    "port": hs.port,
                    "link": hs.station.link.name,
                    "frame_size": hs.station.data_size,
                }
                for hs in self.stations
            ],
        }

    # -- datagrams --------------------------------------------------------------------------------------------

    def _port(self, hs: HostedStation) -> Port:
        """*hs* as its socket's reads see it (:class:`~mlink_sim.aio.slave.bus.Port`). More than ``_keep_behind``
        datagrams from one source waiting means the worker fell that many cycles behind: the oldest are counted as
        ``SUPERSEDED`` drops and only the newest ``_keep_behind`` are answered (with the host-stall policy "absorb",
        as many as a stall of the bound leaves at the shortest cycle: a stall of this process within the bound
        costs no command). On a bus their slots have passed; answering every one would queue latency up (a 1 MiB
        receive buffer holds about a second of commands) and keep an overloaded worker behind for good. A hiccup of
        up to ``_KEEP_BEHIND`` cycles is still answered in full (late, not lost): a worker on a busy machine is held
        up for a few cycles now and then, and a command lost to such a hiccup is a reception failure at the card,
        two in a row an alarm and a bUS trip (docs/performance.md, "A worker's backlog")."""
        port = self._ports[id(hs)] = Port(hs.station, hs, self._keep_behind, self._collect_eeprom, time.monotonic_ns)
        return port

    def _forget(self, hs: HostedStation | None = None) -> None:
        """Something other than a read is about to reach *hs*'s card (every card's, with None): drop its answer
        made ahead (:meth:`Port.forget <mlink_sim.aio.slave.bus.Port.forget>`)."""
        if hs is not None:
            one = self._ports.get(id(hs))
            if one is not None:
                one.forget()
            return
        for port in self._ports.values():
            port.forget()

    def _receiver(self, hs: HostedStation) -> Callable[[list[tuple[bytes, Any]]], None]:
        """The batch handler of one station's own socket: the answers go back on it (one ``sendto``, or a burst
        after a backlog)."""
        port = self._port(hs)
        serve, after_send, allow, slack = port.serve, port.after_send, self.allow, self.slack

        def on_batch(batch: list[tuple[bytes, Any]]) -> None:
            out: list[tuple[bytes, Any]] = []
            if allow is not None:
                batch, others = allow.screen(batch)
                if others:
                    now = time.monotonic_ns()
                    for data, addr in others:
                        port.serve_untrusted(data, addr, now, out)
            if batch:
                serve(batch, out)
            endpoint = hs.endpoint
            try:
                if endpoint is not None and out:
                    if len(out) == 1:  # the common case: one command, one answer
                        endpoint.sendto(*out[0])
                    else:
                        endpoint.send_burst(out)
            finally:
                after_send()  # what the commands left for after their answers (Station.finish)
                slack.open(time.monotonic_ns() + _SLACK_NS)

        return on_batch

    def _port_groups(self) -> list[list[HostedStation]]:
        """The stations that share a socket: with *shared*, those of one link on one host and port; else one each."""
        if not self.shared:
            return [[hs] for hs in self.stations]
        groups: dict[tuple[str, int, Any], list[HostedStation]] = {}
        for hs in self.stations:
            groups.setdefault((hs.host, hs.port, hs.station.link), []).append(hs)
        return list(groups.values())

    def _bus_receiver(self, group: list[HostedStation]) -> Callable[[list[tuple[bytes, Any]]], None]:
        """The batch handler of a shared socket (:class:`~mlink_sim.aio.slave.bus.Bus`): each datagram to the station
        its address byte names, through that station's :class:`~mlink_sim.aio.slave.bus.Port` (the same backlog rule
        per station and source), and the answers of the read back in one burst; then the cards take the commands
        their predictions answered (:meth:`Bus.settle <mlink_sim.aio.slave.bus.Bus.settle>`)."""
        bus = Bus([self._port(hs) for hs in group], time.monotonic_ns)
        self._buses.append(bus)
        serve, settle, allow, slack = bus.serve, bus.settle, self.allow, self.slack
        first = group[0]  # its endpoint is the group's (set once the socket is bound)

        pause = yield_after_send()  # the master reads its answers before the settle (realtime.yield_after_send)

        def on_batch(batch: list[tuple[bytes, Any]]) -> None:
            others: list[tuple[bytes, Any]] = []
            if allow is not None:
                batch, others = allow.screen(batch)
            out = serve(batch) if batch else []
            if others:
                bus.serve_untrusted(others, out)
            ep = first.endpoint
            try:
                if out and ep is not None:
                    ep.send_burst(out)
                    if pause is not None:
                        pause()
            finally:
                settle()
                slack.open(time.monotonic_ns() + _SLACK_NS)

        return on_batch

    @property
    def unaddressed(self) -> int:
        """Datagrams on a shared port for a station not hosted there (or shorter than 4 bytes)."""
        return sum(bus.unaddressed for bus in self._buses)

    def _on_tick(self) -> None:
        now = time.monotonic_ns()
        lag = now - self._tick_due
        if lag >= WORKER_STALL_NS:  # this process was held up (metrics/stalls.py): the report names it
            self.stalls.record("self", self._tick_due, lag, 0, lag <= self.absorb_ns)
        stations = self.stations
        for i in due(self._cores, now):  # compiled (mlink_sim.aio.slave.bus): the scan of every station, once a tick
            hs = stations[i]
            st = hs.station
            if hs.endpoint is not None and st.silence_due(now):
                # After a hold-up of this worker the loop runs its timers before it reads the sockets: the
                # commands that arrived meanwhile are read first, or they would count as the master's silence
                # (2 cycles = bUS on an SI-T/V7; seen in tests/testbed/test_netns.py).
                hs.endpoint.read_pending()
            self._forget(hs)
            st.poll(now)
            st.finish()  # what the poll found (a reception failure, bUS) is logged now
            self._collect_eeprom(hs)
        if self._capture is not None:
            self._note_phases(now)
        if self.allow is not None:
            self._watch_allow()
        if not self._closing:
            self._tick_due = time.monotonic_ns() + _POLL_INTERVAL_NS
            self._tick = asyncio.get_running_loop().call_later(_POLL_INTERVAL_S, self._on_tick)

    def _endpoints(self) -> list[BatchEndpoint]:
        """Each socket of this process once (the stations of a shared port have one)."""
        return list({id(ep): ep for hs in self.stations if (ep := hs.endpoint) is not None}.values())

    def _refuse_others(self) -> None:
        """Have the kernel drop, at every station socket, the datagrams of every source the allow list does not name
        (:meth:`AllowList.sources <mlink_sim.aio.slave.allow.AllowList.sources>`): connected to the one master where
        the list is one literal ``HOST:PORT``, else a socket filter, replaced whenever the names resolve anew. Where
        the kernel cannot, the allow list's own check in :meth:`_receiver` keeps the stations (and a warning says so)."""
        allow = self.allow
        if allow is None:
            return
        sources, how = allow.sources(), []
        for endpoint in self._endpoints():
            try:
                how.append(endpoint.refuse_others(sources, connect=not allow.named))
            except (OSError, ValueError) as exc:
                log.warning("allow_master_kernel_refused", port=endpoint.local_address[1], error=str(exc))
                how.append(None)
        if (how, len(sources)) != self._refusing:
            self._refusing = (how, len(sources))
            log.info("allow_master_in_kernel", sockets=how, sources=len(sources))
            if None in how:
                log.warning("allow_master_kernel_refused", sockets=how,
                            error="the kernel refuses no source at these sockets: the slave's own check only")

    def _watch_allow(self) -> None:
        """Once a second at most, while the list names a host: a datagram the kernel refused may come from a name
        whose address changed (the slave never sees it), so a rise in the sockets' drops makes the list stale; a
        stale list is resolved again (:meth:`_resolve_allow`)."""
        allow = self.allow
        assert allow is not None
        if allow.named and not allow.stale and time.monotonic() - self._drops_checked >= 1.0:
            self._drops_checked = time.monotonic()
            drops = self.socket_drops()
            if drops is not None and drops > self._drops_seen:
                allow.stale = True
            self._drops_seen = drops or 0
        if allow.stale:
            self._resolve_allow()

    def socket_drops(self) -> int | None:
        """The datagrams the kernel dropped at this process's station sockets: refused by their filter, or the
        receive buffer full (:meth:`BatchEndpoint.socket_drops <mlink_sim.aio.transport.udp.BatchEndpoint.
        socket_drops>`); None where the kernel does not say. A connected socket's refusals are not among them: they
        find no socket (docs/cards.md, "The allow list")."""
        counts = [ep.socket_drops() for ep in self._endpoints()]
        return None if not counts or None in counts else sum(c for c in counts if c is not None)

    def _resolve_allow(self) -> None:
        """Resolve the allow list's host names in a worker thread (one at a time, once a second at most)."""
        allow = self.allow
        if allow is None or not allow.stale or self._resolving is not None or self._closing:
            return
        if time.monotonic() - self._resolved_at < 1.0 and self._resolved_at:
            return
        self._resolved_at = time.monotonic()
        fut = self._resolving = asyncio.get_running_loop().run_in_executor(None, allow.resolve)

        def done(f: asyncio.Future[None]) -> None:
            self._resolving = None
            if not f.cancelled() and f.exception() is not None:
                log.warning("allow_master_unresolved", error=str(f.exception()))
            elif allow.unresolved != self._unresolved:
                if allow.unresolved:
                    log.warning("allow_master_unresolved", names=allow.unresolved)
                else:
                    log.info("allow_master_resolved", rules=allow.rules)
            self._unresolved = list(allow.unresolved)
            self._refuse_others()  # the kernel's filter follows the names

        fut.add_done_callback(done)

    def _note_cards(self) -> None:
        """Tell a capture which card each station is (``station 21H: card SI-T3 (MECHATROLINK-II, 32-byte), speed in
        0.01 Hz counts``), as the master does: ``mlink-sim decode`` and the dissector name a MECHATROLINK-II
        station's parameters by it, and give INV_CTL's speed in Hz by the drive's units (o1-03 / n035) at power-up."""
        if self._capture is None:
            return
        now = time.monotonic_ns()
        for hs in self.stations:
            st = hs.station
            self._capture.note(now, card_note(st.address, st.label, f"({st.link.label}, {st.data_size}-byte)",
                                              ref_to_hz(st.drive.settings, 1)))

    def _note_phases(self, now: int) -> None:
        for hs in self.stations:
            phase, old = hs.station.phase, self._phases[id(hs)]
            if old != phase:
                self._capture.note(now, f"station {hs.station.address:02X}H: phase {old} -> {phase}")
                self._phases[id(hs)] = phase

    # -- EEPROM -----------------------------------------------------------------------------------------------

    def _collect_eeprom(self, hs: HostedStation) -> None:
        image = hs.station.take_eeprom()
        if image is None or hs.eeprom is None:
            return
        self._pending_writes[hs.eeprom] = (hs, hs.station.eeprom_generation, image)  # a newer image supersedes a queued one
        self._write_wakeup.set()

    async def _write_loop(self) -> None:
        loop = asyncio.get_running_loop()
        while True:
            await self._write_wakeup.wait()
            self._write_wakeup.clear()
            while self._pending_writes:
                path, (hs, generation, data) = self._pending_writes.popitem()
                if self._writes is None:
                    self._writes = ThreadPoolExecutor(1, "eeprom", initializer=background_thread)
                try:
                    await loop.run_in_executor(self._writes, atomic_write, path, data)
                except OSError as exc:
                    self.write_errors += 1
                    log.error("eeprom_write_failed", path=str(path), error=str(exc))
                    ok = False
                else:
                    log.info("eeprom_saved", path=str(path), bytes=len(data), generation=generation)
                    ok = True
                self._forget(hs)
                hs.station.eeprom_durable(generation, ok=ok)  # written, fsync'd, renamed: the CONFIG may complete
            if self._closing:
                if self._writes is not None:
                    self._writes.shutdown(wait=False)
                return

    # -- control ----------------------------------------------------------------------------------------------

    def cpu(self) -> dict[str, Any]:
        """This process's CPU use since start, its arrival polls' counters, and the answers its shared ports made
        ahead and any of those that the card then contradicted (``Bus.ahead``, ``Bus.mispredicted``) (``{"op":
        "cpu"}``: small at any station count; ``stats`` has all of it too)."""
        wall = time.monotonic() - self._started_wall
        cpu = _cpu_seconds() - self._started_cpu
        return {"ok": True, "pid": os.getpid(), "wall_s": wall, "cpu_s": cpu,
                "cpu_pct": 100.0 * cpu / wall if wall > 0 else 0.0, "arrival_poll": self._poll_stats(),
                "answered_ahead": sum(bus.ahead for bus in self._buses),
                "mispredicted": sum(bus.mispredicted for bus in self._buses)}

    def stats(self, since: int = 0) -> dict[str, Any]:
        """Snapshot of every hosted station plus this process's CPU use and its stalls since *since* (monotonic
        ns): the most recent events and the totals. Reading changes nothing."""
        return {**self._stats_head(since), "stations": dict(map(self._station_stats, self.stations))}

    def _stats_head(self, since: int) -> dict[str, Any]:
        return {**self.cpu(), "unaddressed": self.unaddressed, "socket_drops": self.socket_drops(),
                "stalls": self.stalls.events("self", last=_STALLS_REPORTED, since=since),
                "stall_totals": self.stalls.totals("self", since)}

    @staticmethod
    def _station_stats(hs: HostedStation) -> tuple[str, Any]:
        return f"{hs.station.address:#04x}", to_jsonable(hs.station.snapshot())

    async def stats_text(self, since: int = 0, **extra: Any) -> str:
        """:meth:`stats` (and *extra* fields) as the JSON text of a reply (``"ok": true`` first), built one station
        at a time, each in the slack after a read's answers went (:attr:`slack`; at most :data:`_STATS_PACE_S`
        later where no commands come), for :data:`_STATS_PACED_S` at most: built at once, the stats of many
        stations would hold the worker's loop for milliseconds and make answers late (docs/performance.md, "A
        slave's stats"). Each station's figures are its own at one instant; the stations' instants lie up to that
        long apart."""
        head = json.dumps({"ok": True, **self._stats_head(since), **extra}, separators=_COMPACT)
        parts = []
        paced_until = time.monotonic() + _STATS_PACED_S
        step = self._stats_step
        for hs in list(self.stations):
            if time.monotonic() < paced_until:
                await self.slack.wait(step.need_ns)
            else:
                await asyncio.sleep(0)
            with step:
                key, snap = self._station_stats(hs)
                parts.append(f'"{key}":{json.dumps(snap, separators=_COMPACT)}')
        return f'{head[:-1]},"stations":{{{",".join(parts)}}}}}'

    def _poll_stats(self) -> dict[str, int]:
        """The arrival polls' counters, summed over the sockets (:meth:`ArrivalPoll.stats
        <mlink_sim.aio.timing.arrival.ArrivalPoll.stats>`; the largest learned cycle and lead); empty without a poll."""
        polls = list({id(ep): ep.poll for hs in self.stations
                      if (ep := hs.endpoint) is not None and ep.poll is not None}.values())
        total: dict[str, int] = {}
        for poll in polls:
            for key, value in poll.stats().items():
                total[key] = max(total.get(key, 0), value) if key in _POLL_MAX_KEYS else total.get(key, 0) + value
        return total

    def hosted(self, address: int) -> HostedStation | None:
        """The station *address* of this process, or None."""
        return next((hs for hs in self.stations if hs.station.address == address), None)

    def cores(self) -> dict[int, Any]:
        """This process's card cores, by station address."""
        return {hs.station.address: hs.station for hs in self.stations}

    def changed(self, hs: HostedStation) -> None:
        """*hs* was changed from outside its commands (a drive fault, a parameter set by its keypad): answers made
        ahead are dropped, a new EEPROM image is written."""
        self._forget(hs)
        self._collect_eeprom(hs)
