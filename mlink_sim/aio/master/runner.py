"""The master on a real network: :class:`~mlink_sim.master.MasterCore` driven by a :class:`CycleTimer` over one UDP
socket, with awaitable requests (docs/master.md, "Async API").

The I/O here only moves bytes and timestamps; the core decides everything, and builds every request's body and
result (``core.prm_rd(…) -> Request``: :mod:`mlink_sim.master.operations`): a request method here awaits the core's
:class:`~mlink_sim.master.Request`. The master holds its socket as a
:class:`~mlink_sim.aio.transport.ports.DatagramPort` (its batched calls, a ``BurstPort``, found once when it takes
the socket). The master owns a non-blocking UDP
socket, watched with ``loop.add_reader``: each wake-up reads every datagram waiting (up to a bound), each stamped
with ``time.monotonic_ns()`` as it is read, and it is also read in the clock's spin and before each cycle's commands,
so an answer that arrived in time is never counted missing only because the loop was busy with the clock. Where
:mod:`~mlink_sim.aio.transport.mmsg` is supported the socket is a ``BurstSocket``: the
cycle's burst goes out in one ``sendmmsg`` and a read takes what is waiting with one ``recvmmsg``; a capture's tap
keeps those calls (:mod:`~mlink_sim.aio.transport.tapped`), an impairment and the virtual fabric take the per-datagram
path. Transport errors (``sendto``/``recv`` raising ``OSError``, e.g. ``ConnectionRefusedError`` after an ICMP port
unreachable) are counted in :attr:`Master.transport_errors`, never raised.

Touches: one UDP socket (through the transport layer), the cycle timer, the master core and its fault stage; a
capture, when given.
"""

from __future__ import annotations

import asyncio
import time
from collections import Counter
from collections.abc import Callable, Coroutine
from typing import Any, Protocol, TypeVar


from ..._log import get_logger
from ...master import (
    AlarmCleared,
    AlarmRaised,
    Control,
    Late,
    MasterCore,
    Missing,
    NetworkPlan,
    Recovered,
    Request,
    Rtt,
    RunHeld,
    RunResumed,
    StateChanged,
    StationView,
)
from ...capture.text import card_note
from ...faults import Episode, FaultSpec, FaultStage, MasterFault, StationTraits
from ...faults.stage import is_healthy
from ..transport import mmsg
from ..transport.impaired import ImpairedSocket
from ..transport.ports import BurstPort, DatagramPort, bursts
from ..transport.tapped import tap
from ..timing.slack import AnswersIn
from ..timing.ticker import CycleTimer
from ..transport.udp import bound_socket, close_watched

__all__ = ["Master", "MetricsSink", "NullMetrics", "run"]

T = TypeVar("T")
_mono = time.monotonic_ns


class MetricsSink(Protocol):
    """The hooks the master calls (``mlink_sim.metrics.NetworkMetrics`` implements them)."""

    def record_sent(self, station: int) -> None: ...

    def record_rtt(self, station: int, ns: int) -> None: ...

    def record_late(self, station: int) -> None: ...

    def record_missing(self, station: int) -> None: ...

    def record_cycle_lateness(self, ns: int, skipped: int = 0) -> None: ...

    def record_alarm(self, station: int) -> None: ...


class NullMetrics:
    """A :class:`MetricsSink` that records nothing."""

    def record_sent(self, station: int) -> None:
        pass

    def record_rtt(self, station: int, ns: int) -> None:
        pass

    def record_late(self, station: int) -> None:
        pass

    def record_missing(self, station: int) -> None:
        pass

    def record_cycle_lateness(self, ns: int, skipped: int = 0) -> None:
        pass

    def record_alarm(self, station: int) -> None:
        pass


_NOTED = (StateChanged, AlarmRaised, AlarmCleared, Recovered, RunHeld, RunResumed)  # a capture's comments
_READ_BURST = 512  # datagrams read per wake-up at most, so a flood cannot starve the clock


class Master:
    """A running master. Create with ``await Master.start(...)``; stop with ``await master.close()``."""

    def __init__(self, core: MasterCore, endpoints: dict[int, tuple[str, int]], metrics: MetricsSink,
                 loop: asyncio.AbstractEventLoop) -> None:
        self.core = core
        self.endpoints = dict(endpoints)
        self.metrics = metrics
        core.on_rtt = metrics.record_rtt  # what _pump would do with an Rtt event, without the event
        #: a cycle's burst counted sent in one call (NetworkMetrics.record_sent_burst); a sink of its own, which
        #: need only have record_sent, one command at a time
        self._count_sent: Callable[[list[tuple[int, bytes]]], None] = getattr(
            metrics, "record_sent_burst", self._count_sent_one_by_one)
        self.transport_errors: Counter[str] = Counter()
        self._loop = loop
        #: a socket.socket, or what stands in for it: a BurstSocket (batched calls), a capture's tap, an
        #: ImpairedSocket, a FabricPort (the virtual clock) (aio/transport/ports.py)
        self._sock: DatagramPort | None = None
        self._burst: BurstPort | None = None  #: the socket's batched calls, where it has them (:meth:`_use`)
        self._timer: CycleTimer | None = None
        self._owns_timer = True
        self.record_lateness = True  #: False for the 2nd+ master on a shared clock (counted once)
        self._waiters: list[tuple[Callable[[], bool], asyncio.Future[None]]] = []
        self._pending_missing: dict[int, int] = {}
        self._note: Callable[[int, Any], None] | None = None  #: a capture's note hook (``capture=``)
        #: every alarm each station raised (AlarmRaised), by name: what ``expect = "alarm-seen"`` reads
        self.alarms_seen: dict[int, Counter[str]] = {}
        #: the master-side faults (mlink_sim.faults.stage), made on the first fault: None costs nothing per cycle
        self.faults: FaultStage | None = None
        self._closed = False
        self._log = get_logger(__name__).bind(component="master", link=core.plan.link.name)
        #: tells its hook once a cycle when the cycle's answers are in (the work beside the cycle may run then)
        self.answers_in = AnswersIn()

    @staticmethod
    def _now() -> int:
        """The time requests are stamped with (a virtual master reads its simulated clock)."""
        return _mono()

    # ------------------------------------------------------------------ life cycle
    @classmethod
    async def start(cls, plan: NetworkPlan, endpoints: dict[int, tuple[str, int]], *,
                    local: tuple[str, int] = ("127.0.0.1", 0), metrics: MetricsSink | None = None,
                    loop: asyncio.AbstractEventLoop | None = None, strategy: str = "auto",
                    rcvbuf: int = 1 << 20, clock: CycleTimer | None = None, catch_up_ns: int = 0,
                    capture: Any = None, batched: bool = True) -> Master:
        """Open one UDP socket on *local*, start cycling at ``plan.tcycle_ns``; *endpoints* maps every station
        address of the plan to the ``(host, port)`` of its slave.

        *clock*: a :class:`CycleTimer` shared with other masters of the same network (one per link), whose
        callback calls :meth:`on_cycle` of each; the first master records the cycle lateness. Two spinning
        timers in one loop delay each other, so ``mlink-sim up`` drives every link from one clock.

        *catch_up_ns*: the host-stall policy of its own clock (``CycleTimer``'s ``catch_up_ns``; 0 = strict);
        stalls are recorded through the metrics' ``stall_recorder`` when it has one.

        *capture*: a :class:`~mlink_sim.capture.CaptureWriter`; every datagram on the socket is recorded and the
        core's state, alarm and recovery events become notes in it.

        *batched*: the batched calls (``sendmmsg``/``recvmmsg``, :mod:`~mlink_sim.aio.transport.mmsg`) where the kernel
        has them; False keeps the per-datagram calls (the tests compare both paths that way)."""
        missing = [f"{sp.address:02X}H" for sp in plan.stations if sp.address not in endpoints]
        if missing:
            raise ValueError(f"no UDP endpoint for station(s) {', '.join(missing)}")
        loop = loop or asyncio.get_running_loop()
        self = cls(MasterCore(plan), endpoints, metrics if metrics is not None else NullMetrics(), loop)
        add_stations = getattr(self.metrics, "add_stations", None)
        if callable(add_stations):
            add_stations(self.core.addresses)
        sock = bound_socket(local[0], local[1], rcvbuf)
        if capture is not None:
            self._use(tap(capture, sock, batched=batched))  # the batched calls, tapped
            self._note = capture.note
        else:
            self._use(mmsg.wrap(sock, batched=batched))  # sendmmsg/recvmmsg where supported (docs/performance.md)
        if clock is None:
            recorder = getattr(self.metrics, "stall_recorder", None)
            self._timer = CycleTimer(plan.tcycle_ns, self._on_cycle, loop=loop, strategy=strategy,
                                     idle=self.read_one, catch_up_ns=catch_up_ns,
                                     on_stall=recorder("master") if callable(recorder) else None)
        else:
            self._timer, self._owns_timer = clock, False
        if len(set(self.endpoints.values())) < len(self.endpoints) and self._burst is not None:
            self._burst.enable_gro()  # stations share a port (a packed worker): its answers come as one burst
        self.note_cards()
        loop.add_reader(sock.fileno(), self.read_responses)  # a read on every arrival, stamped as it is read
        if clock is None:
            self._timer.start()
        self._log.info("master_started", local=sock.getsockname(), stations=len(plan.stations),
                       tcycle_ns=plan.tcycle_ns, strategy=self._timer.strategy)
        return self

    def _use(self, sock: DatagramPort) -> None:
        """Send and read through *sock* from now on, with its batched calls where it has them."""
        self._sock, self._burst = sock, bursts(sock)

    def watch(self, fn: Callable[[int, Any], None]) -> None:
        """Call *fn(now_ns, event)* for each event a capture notes (state changes, alarms raised and cleared,
        recoveries, held and resumed runs), beside the capture's own note; *event* may also be a capture's text."""
        note = self._note
        if note is None:
            self._note = fn
            return

        def both(now: int, ev: Any) -> None:
            note(now, ev)
            fn(now, ev)

        self._note = both

    def note_cards(self) -> None:
        """Tell a capture which card each station is (``station 21H: card SI-T3 (MECHATROLINK-II, 32-byte), speed in
        0.01 Hz counts``): ``mlink-sim decode`` names the parameters of a MECHATROLINK-II station by it, and gives
        INV_CTL's speed in Hz by the units the plan knows (o1-03 / n035). Nothing without a capture."""
        note = self._note
        if note is None:
            return
        now = self._now()
        for sp in self.core.plan.stations:
            profile = sp.profile
            if profile is not None:
                note(now, card_note(sp.address, profile.label, f"({sp.link.label}, {sp.data_size}-byte)",
                                    sp.hz_per_count))

    @property
    def local_address(self) -> tuple[str, int]:
        assert self._sock is not None
        return self._sock.getsockname()[:2]

    @property
    def timer(self) -> CycleTimer | None:
        return self._timer

    async def close(self, timeout: float = 1.0) -> None:
        """DISCONNECT every connected station (waiting up to *timeout* s), then stop cycling and close the socket."""
        if self._closed:
            return
        self._closed = True
        core = self.core
        reqs = core.disconnect_all(timeout_ns=_ns(timeout), now=self._now())
        if reqs and self._timer is not None and self._timer.running:
            futs = [self._future(r) for r in reqs]
            await asyncio.wait(futs, timeout=timeout)
            for f in futs:  # a station that did not answer is not an error at shutdown: consume its exception
                f.add_done_callback(_consume)
        if self._timer is not None and self._owns_timer:
            self._timer.stop()
        core.abort_requests("master closed")
        self._pump()
        for station in list(self._pending_missing):
            self.metrics.record_missing(station)
        self._pending_missing.clear()
        for _, fut in self._waiters:
            if not fut.done():
                fut.set_exception(ConnectionAbortedError("master closed"))
        self._waiters.clear()
        sock, self._sock, self._burst = self._sock, None, None
        if sock is not None:
            close_watched(self._loop, sock)
        self._log.info("master_closed", transport_errors=dict(self.transport_errors), drops=len(core.drops))

    async def __aenter__(self) -> Master:
        return self

    async def __aexit__(self, *exc: object) -> None:
        await self.close()

    # ------------------------------------------------------------------ waiting
    async def wait_until(self, predicate: Callable[[], bool], timeout: float) -> None:
        """Wait until *predicate()* holds (checked every cycle); ``TimeoutError`` after *timeout* s."""
        if predicate():
            return
        fut: asyncio.Future[None] = self._loop.create_future()
        entry = (predicate, fut)
        self._waiters.append(entry)
        try:
            await asyncio.wait_for(fut, timeout)
        finally:
            if entry in self._waiters:
                self._waiters.remove(entry)

    async def bring_up(self, timeout: float = 5.0) -> None:
        """Wait until every station is at its target phase (3, or 2 without ``sync``)."""
        try:
            await self.wait_until(self.core.all_at_target, timeout)
        except TimeoutError:
            stuck = {f"{a:02X}H": (v.state.value, v.last_error) for a, v in self.core.views().items()
                     if not v.at_target}
            raise TimeoutError(f"bring-up not complete after {timeout} s: {stuck}") from None

    # ------------------------------------------------------------------ requests (built by the core)
    async def request(self, station: int, body: Any, *, sub: bool | None = None,
                      timeout: float | None = None) -> Any:
        """Send *body* (a wire command body) and return the decoded response body; raises
        :class:`~mlink_sim.master.StationAlarmError` or :class:`~mlink_sim.master.RequestTimeout`."""
        return await self._future(self.core.request(station, body, sub=sub, timeout_ns=_ns(timeout), now=self._now()))

    async def prm_rd(self, station: int, register: int | str, size: int = 2, *, sub: bool | None = None,
                     timeout: float | None = None) -> Any:
        """PRM_RD of a parameter by name or of a MEMOBUS register by number (docs/master.md, "Parameters by name").

        A name (``"C1-01"``, ``"n019"``; the station's card picks the table) returns a
        :class:`~mlink_sim.master.ParamValue`: a float in engineering units (``10.0``) with ``unit``, ``raw`` and
        ``register``. A register number returns the raw value: an unsigned int for ``size=2``, else the *size*
        bytes (LSB first). An unknown name or a bad register or size raises
        :class:`~mlink_sim.master.ParamRequestError` before anything is sent (:meth:`MasterCore.prm_rd
        <mlink_sim.master.MasterCore.prm_rd>`)."""
        return await self._future(self.core.prm_rd(station, register, size, sub=sub, timeout_ns=_ns(timeout),
                                                   now=self._now()))

    async def prm_wr(self, station: int, register: int | str, value: Any, size: int = 2, *,
                     sub: bool | None = None, timeout: float | None = None) -> None:
        """PRM_WR of a parameter by name in engineering units (``prm_wr(0x21, "C1-01", 5.0)``: 50 counts of
        0.1 s), checked against the row's range and resolution; or of a register by number with a raw int
        (written LSB first in *size* bytes, negative as two's complement) or the bytes. A bad name, type or
        value raises :class:`~mlink_sim.master.ParamRequestError` before anything is sent. CONFIG
        (:meth:`config`) makes the written values take effect."""
        await self._future(self.core.prm_wr(station, register, value, size, sub=sub, timeout_ns=_ns(timeout),
                                            now=self._now()))

    async def config(self, station: int, mode: int = 0, *, sub: bool = False, timeout: float | None = None) -> None:
        """CONFIG: 0 = enable written parameters (RAM), 1 = also store to EEPROM (SI-T3 Table 12, SI-ET3 Table 15)."""
        await self._future(self.core.config(station, mode, sub=sub, timeout_ns=_ns(timeout), now=self._now()))

    async def id_rd(self, station: int, code: int, offset: int = 0, size: int = 8, *,
                    timeout: float | None = None) -> bytes:
        """ID_RD: *size* bytes of ID *code* (DEVICE_CODE, SI-T3 Table 10 / ID_CODE, SI-ET3 Table 14) from *offset*."""
        result: bytes = await self._future(self.core.id_rd(station, code, offset, size, timeout_ns=_ns(timeout),
                                                           now=self._now()))
        return result

    async def alm_rd(self, station: int, mode: int = 0, index: int = 0, *, sub: bool = False,
                     timeout: float | None = None) -> Any:
        """ALM_RD: the decoded response body (``alm_data`` per SI-T3 Table 14 / SI-ET3 Tables 16/17)."""
        return await self._future(self.core.alm_rd(station, mode, index, sub=sub, timeout_ns=_ns(timeout),
                                                   now=self._now()))

    async def alm_clr(self, station: int, *, timeout: float | None = None) -> None:
        """ALM_CLR mode 0: clear present faults and alarms (SI-T3 Table 15)."""
        await self._future(self.core.alm_clr(station, timeout_ns=_ns(timeout), now=self._now()))

    async def disconnect(self, station: int, *, timeout: float | None = None) -> None:
        """DISCONNECT and keep the station in phase 1 until :meth:`connect`."""
        await self._future(self.core.disconnect(station, timeout_ns=_ns(timeout), now=self._now()))

    def connect(self, station: int) -> None:
        """Bring a disconnected station up again (use :meth:`bring_up` to wait for it)."""
        self.core.connect(station)

    def set_control(self, station: int, forward: bool = False, reverse: bool = False, speed_ref: int = 0,
                    torque_ref: int = 0, **signals: Any) -> Control:
        """Cyclic INV_CTL contents (see :meth:`MasterCore.set_control`)."""
        return self.core.set_control(station, forward, reverse, speed_ref, torque_ref, **signals)

    def view(self, station: int) -> StationView:
        return self.core.view(station)

    def views(self) -> dict[int, StationView]:
        return self.core.views()

    # ------------------------------------------------------------------ faults (docs/faults.md)
    def fault_stage(self) -> FaultStage:
        """The master-side fault stage of this master's stations, made on first use."""
        if self.faults is None:
            core, metrics = self.core, self.metrics
            self.faults = FaultStage(
                [StationTraits(sp.address, sp.family, sp.subcmd) for sp in core.plan.stations],
                healthy=lambda a, since: is_healthy(core.view(a), since),
                on_recovery=getattr(metrics, "record_recovery", None),
                on_unrecovered=getattr(metrics, "record_unrecovered", None))
        return self.faults

    def inject_fault(self, station: int, fault: MasterFault) -> Episode:
        """Start the master-side *fault* (silence, skip-cycles, freeze-wdt, bad-command) on *station* now."""
        self.core.plan.station(station)  # KeyError for a station of another master
        return self.fault_stage().inject(station, fault, self._now())

    def begin_fault(self, station: int, fault: FaultSpec, end_ns: int | None = None) -> Episode:
        """A fault applied on the slave side (a drive fault) begins now: its recovery is measured after
        :meth:`end_fault` (or *end_ns*, a time on this master's clock)."""
        return self.fault_stage().begin(station, fault, self._now(), end_ns)

    def end_fault(self, episode: Episode) -> None:
        self.fault_stage().end(episode, self._now())

    def now_ns(self) -> int:
        """This master's clock (monotonic ns; a virtual master's simulated time)."""
        return self._now()

    def deliver(self, datagram: bytes, now: int) -> None:
        """One response for the core, through the fault stage when a fault is in force (a silenced station's is
        dropped)."""
        faults = self.faults
        if faults is not None and faults.active:
            kept = faults.from_station(datagram, now)
            if kept is None:
                return
            datagram = kept
        self.core.on_response(datagram, now)

    def _future(self, req: Request) -> asyncio.Future[Any]:
        fut: asyncio.Future[Any] = self._loop.create_future()

        def done(r: Request) -> None:
            if fut.done():
                return
            if r.error is not None:
                fut.set_exception(r.error)
            else:
                fut.set_result(r.result)

        req.add_done_callback(done)
        return fut

    # ------------------------------------------------------------------ hot path
    def _on_cycle(self, cycle: int, deadline_ns: int, now_ns: int, skipped: int) -> None:
        metrics = self.metrics
        if self.record_lateness:
            metrics.record_cycle_lateness(now_ns - deadline_ns, skipped)
        sock = self._sock
        if sock is None:
            return
        self.read_responses()  # answers already here belong to the cycle that just ended
        endpoints = self.endpoints
        out = self.core.on_cycle(cycle, now_ns)
        faults = self.faults
        if faults is not None and faults.active:
            out = [(s, d) for s, d in ((s, faults.to_station(s, d, now_ns)) for s, d in out) if d is not None]
        burst = self._burst
        if burst is not None and len(out) > 1:  # the burst in one sendmmsg (mlink_sim.aio.transport.mmsg)
            for _, exc in burst.send_burst([(datagram, endpoints[station]) for station, datagram in out]):
                self._on_error(exc)  # that datagram is lost, the others went
            self._count_sent(out)
        else:
            sendto = sock.sendto
            for station, datagram in out:
                try:
                    sendto(datagram, endpoints[station])
                except OSError as exc:  # BlockingIOError (send buffer full) included: that datagram is lost
                    self._on_error(exc)
                metrics.record_sent(station)
        self._pump()
        if faults is not None and faults.watching:
            faults.after_cycle(now_ns)
        self.answers_in.expect(len(out))

    on_cycle = _on_cycle  #: the cycle callback, for a shared clock

    def read_responses(self, limit: int = _READ_BURST) -> None:
        """Hand the datagrams waiting on the socket (at most *limit*) to the core, each stamped as it is read:
        the reader callback and the start of each cycle read them all, the clock's spin one at a time. On a
        :class:`~mlink_sim.aio.transport.mmsg.BurstSocket` one ``recvmmsg`` reads them all, and they share its time."""
        sock = self._sock
        if sock is None:
            return
        faults = self.faults
        clean = faults is None or not faults.active
        on_response = self.core.on_response if clean else self.deliver
        burst = self._burst
        n = 0
        if burst is not None:  # recvmmsg: what is waiting in one call, each batch stamped with the time it was read
            on_batch = self.core.on_responses if clean else self._deliver_all
            for batch in mmsg.drain(burst.recv_burst, limit, self._on_error):
                on_batch(batch, _mono())
                n += len(batch)
        else:
            recv = sock.recv
            for _ in range(limit):
                try:
                    data = recv(4096)
                except BlockingIOError:
                    break
                except OSError as exc:
                    self._on_error(exc)
                    continue
                on_response(data, _mono())
                n += 1
        if n:
            self.answers_in.answered(n)

    def _deliver_all(self, datagrams: list[bytes], now: int) -> None:
        """:meth:`deliver` of each of one read's answers (the faults' path of :meth:`read_responses`)."""
        for datagram in datagrams:
            self.deliver(datagram, now)

    def _count_sent_one_by_one(self, out: list[tuple[int, bytes]]) -> None:
        for station, _ in out:
            self.metrics.record_sent(station)

    def impair_with(self, layer: Any) -> None:
        """Route this master's datagrams through the impairment *layer* (``aio/transport/impaired.py``) while it has a
        fault; the socket is unwrapped again once every fault has ended (no cost without impairments)."""
        sock = self._sock
        if sock is None or isinstance(sock, ImpairedSocket) or not layer.active:
            return
        wrapper: ImpairedSocket

        def unwrap() -> None:
            if self._sock is wrapper:  # the wrapper stands in for the socket
                self._use(wrapper.sock)

        wrapper = ImpairedSocket(sock, layer, self._loop, on_ready=self.read_responses, on_error=self._on_error,
                                 on_idle=unwrap)
        self._use(wrapper)

    def read_one(self) -> None:
        """The clock's ``idle`` hook: one datagram at most, so the spin ends close to its deadline."""
        self.read_responses(1)

    def _on_error(self, exc: Exception) -> None:
        name = type(exc).__name__
        self.transport_errors[name] += 1
        n = self.transport_errors[name]
        if n & (n - 1) == 0:  # 1, 2, 4, 8 … : visible, not flooding
            self._log.debug("transport_error", error=name, detail=str(exc), count=n)

    def _pump(self) -> None:
        """Feed the core's events to metrics and the log; wake waiters."""
        events = self.core.events
        if events:
            metrics = self.metrics
            pending = self._pending_missing
            log = self._log
            note = self._note
            ev: Any  # dispatched on its exact type below (`t is Rtt` ...: cheaper than isinstance, not narrowed)
            for ev in self.core.drain_events():
                t = type(ev)
                if note is not None and t in _NOTED:
                    note(self._now(), ev)
                if t is Rtt:
                    metrics.record_rtt(ev.station, ev.ns)
                elif t is Missing:
                    # Counted once given up for good: a late answer may still come until the next Missing.
                    old = pending.get(ev.station)
                    if old is not None:
                        metrics.record_missing(ev.station)
                    pending[ev.station] = ev.cycle
                elif t is Late:
                    if pending.get(ev.station) == ev.cycle:
                        del pending[ev.station]
                        metrics.record_rtt(ev.station, ev.ns)
                        metrics.record_late(ev.station)
                elif t is StateChanged:
                    log.info("station_state", station=f"{ev.station:02X}H", old=ev.old.value, new=ev.new.value)
                elif t is AlarmRaised:
                    record_alarm = getattr(metrics, "record_alarm", None)  # a sink of its own may not count them
                    if record_alarm is not None:
                        record_alarm(ev.station)
                    self.alarms_seen.setdefault(ev.station, Counter())[ev.name or f"{ev.code:02X}H"] += 1
                    log.info("station_alarm", station=f"{ev.station:02X}H", code=ev.code, name=ev.name,
                                source=ev.source)
                elif t is AlarmCleared:
                    log.info("station_alarm_cleared", station=f"{ev.station:02X}H", source=ev.source)
                elif t is Recovered:
                    log.info("station_recovered", station=f"{ev.station:02X}H", reason=ev.reason,
                             after_ms=round(ev.ns / 1e6, 3))
                elif t is RunHeld:
                    log.info("run_held", station=f"{ev.station:02X}H", until=ev.until)
                elif t is RunResumed:
                    log.info("run_resumed", station=f"{ev.station:02X}H", reason=ev.reason)
        if self._waiters:
            for pred, fut in list(self._waiters):
                if not fut.done() and pred():
                    fut.set_result(None)


def _ns(timeout: float | None) -> int | None:
    """A timeout in seconds as the core takes it (ns); None: the plan's."""
    return None if timeout is None else int(timeout * 1e9)


def _consume(fut: asyncio.Future[Any]) -> None:
    if not fut.cancelled():
        fut.exception()


def run(main: Coroutine[Any, Any, T]) -> T:
    """Run *main* on uvloop when installed, else on asyncio's default loop."""
    try:
        import uvloop
    except ImportError:  # pragma: no cover
        return asyncio.run(main)
    return uvloop.run(main)
