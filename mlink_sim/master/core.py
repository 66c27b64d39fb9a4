"""The MECHATROLINK master, sans-I/O: cycle numbers and nanoseconds in, datagrams and events out.

:meth:`MasterCore.on_cycle` is called once per transmission cycle and returns the command datagrams of the
stations whose communication cycle is due; :meth:`MasterCore.on_response` consumes one response datagram. The core
never waits: a command still unanswered when its station is due again is recorded as :class:`Missing` and the
next command goes out on time. Everything else (state machine, WDT, requests, recovery) is in docs/master.md.
"""

from __future__ import annotations

import struct
from collections import Counter, deque
from collections.abc import Callable
from typing import Any, Final

from ..wire import CmdAlm, CommAlm, DropReason, Frame, Kind, Link, WireError, decode, encode
from ..wire.frame import HEADER_SIZE, cycle_of
from . import answers, drivefault, requests, restart
from .codec import Reply
from .commands import Cmd, Send
from .machine import Ev, expects, next_state
from .operations import Operations
from .plan import NetworkPlan
from .slave import Sent, Slave
from .types import (
    AlarmCleared,
    AlarmRaised,
    Control,
    Dropped,
    Event,
    MasterDrop,
    Missing,
    Recovered,
    Request,
    StateChanged,
    StationState,
    StationView,
)

__all__ = ["MasterCore"]

S = StationState
_U32: Final = 0xFFFFFFFF
# the members the per-cycle paths compare with, each read once (an enum member is an attribute lookup per use)
_PHASE2: Final = S.PHASE2  # with _PHASE3: the states in which requests and INV_CTL are sent
_PHASE3: Final = S.PHASE3
_PHASE1: Final = S.PHASE1
_BRINGING: Final = frozenset((S.CONNECTING, S.SYNCING))  # counted against NetworkPlan.bringup_window
_CYCLIC: Final = Send.CYCLIC


class MasterCore(Operations):
    """Master of one network (see module docstring). Not thread-safe; never reads a clock.

    ``events`` is a bounded deque the I/O layer drains (:meth:`drain_events`); ``drops`` counts rejected datagrams
    by :class:`~mlink_sim.wire.DropReason` or :class:`MasterDrop`. The operator's requests (:meth:`request`,
    :meth:`prm_rd`, … :meth:`disconnect`) are :class:`~.operations.Operations`'."""

    def __init__(self, plan: NetworkPlan, *, max_events: int = 65_536) -> None:
        super().__init__(plan)
        self.events: deque[Event] = deque(maxlen=max_events)
        self.drops: Counter[Any] = Counter()
        self.events_lost = 0
        self.cycles = 0
        #: Steady-state INV_CTL straight from and to bytes (:mod:`.fastpath`); False = general path only (tests).
        self.fast_path = True
        #: Where an answer's round trip goes, ``on_rtt(station, ns)``: None = an :class:`Rtt` event. A driver that
        #: only counts them (``mlink_sim.aio.master.runner.Master``: its metrics' ``record_rtt``) sets it and saves an
        #: event object and its dispatch per exchange. Late answers are ``Late`` events either way.
        self.on_rtt: Callable[[int, int], None] | None = None
        self._cycle = 0
        self._window = plan.answer_window_ns
        self._bringing = 0  #: stations in CONNECTING or SYNCING (NetworkPlan.bringup_window), kept by _fire

    # ------------------------------------------------------------------ cyclic entry points
    def on_cycle(self, cycle: int, now: int) -> list[tuple[int, bytes]]:
        """Datagrams ``(station address, bytes)`` to send in transmission cycle *cycle* at *now* (ns)."""
        self._now = now
        self._cycle = cycle
        self.cycles += 1
        out: list[tuple[int, bytes]] = []
        window = self.plan.bringup_window
        for st in self._stations:
            if st.main_q or st.sub_q or st.disconnect_waiters:
                requests.expire(st, now)
            if (cycle - st.offset) % st.period == 0:
                if self._bringing >= window and st.state is _PHASE1 and st.enabled and cycle >= st.hold_until:
                    self._retire(st, now)  # its CONNECT waits for the bring-up window: no command this slot
                    continue
                out.append((st.address, self._slot(st, cycle, now)))
        return out

    def on_responses(self, datagrams: list[bytes], now: int) -> None:
        """:meth:`on_response` of each of *datagrams* in order, all received at *now*: one batched read of the
        socket (the loop compiled with the core, not run by the interpreter once per answer)."""
        for datagram in datagrams:
            self.on_response(datagram, now)

    def on_response(self, datagram: bytes, now: int) -> None:
        """Consume one response datagram received at *now*. Never raises on bad input (counted in ``drops``)."""
        self._now = now
        if self.fast_path and self._fast_response(datagram, now):
            return
        try:
            frame = decode(datagram, kind=Kind.RESPONSE)
        except WireError as exc:
            self._drop(None, exc.reason)
            return
        except (ValueError, TypeError, KeyError, struct.error):
            self._drop(None, MasterDrop.MALFORMED)
            return
        st = self._by_addr.get(frame.station)
        if st is None:
            self._drop(frame.station, MasterDrop.UNKNOWN_STATION)
            return
        if frame.link is not st.plan.link:
            self._drop(st.address, MasterDrop.WRONG_LINK)
            return
        if frame.data_size != st.plan.data_size:
            self._drop(st.address, DropReason.BAD_SIZE)
            return
        sent = answers.answer_to(st, frame.cycle)
        if sent is None:
            reason = MasterDrop.DUPLICATE if frame.cycle == st.answered else MasterDrop.NOT_EXPECTED
            self._drop(st.address, reason)
            return
        answers.take(st, sent, now, self.on_rtt, self._emit)
        msg = frame.message
        reply = st.codec.reply(msg, sent.code)
        if answers.shows(st, sent.cycle, msg.rwdt):
            st.rwdt = msg.rwdt
            self._observe(st, reply)
        if expects(st.state, Ev.ANSWERED):
            self._fire(st, Ev.ANSWERED)
        self._advance(st, sent, reply, now)

    def _fast_response(self, datagram: bytes, now: int) -> bool:
        """A clean answer to a cyclic INV_CTL, on time or late, straight from the bytes (:mod:`.fastpath`): what
        the general path does for it (:meth:`_observe`, :meth:`_advance`). False: the general path decides."""
        st = self._by_addr.get(datagram[3]) if len(datagram) >= HEADER_SIZE else None
        if st is None:
            return False
        state = st.state  # `is`, not `in` a tuple: compiled, that compares each enum member as an object
        if (state is not _PHASE3 and state is not _PHASE2) or st.alarm or st.fault or st.cmd_alm or st.comm_alm >= 8:
            return False
        cycle = cycle_of(datagram)
        sent = st.outstanding  # the common answer, on time (answers.answer_to's first case)
        if sent is None or sent.cycle != cycle:
            sent = answers.answer_to(st, cycle)
        if sent is None or sent.send is not _CYCLIC or sent.sub_req is not None:
            return False
        frames = st.frames
        rwdt = frames.response(datagram, cycle, st.comm_alm)
        if rwdt < 0:
            return False
        answers.take(st, sent, now, self.on_rtt, self._emit)
        if answers.shows(st, cycle, rwdt):
            st.rwdt = rwdt
            st.status, st.output_freq, st.output_current, st.mon1, st.mon2, st.warning = frames.last
            if st.run_held or st.searching:
                restart.watch(st, self._emit)
        return True

    def drain_events(self) -> list[Event]:
        """All events since the last call, oldest first."""
        out = list(self.events)
        self.events.clear()
        return out

    # ------------------------------------------------------------------ operator API (requests: .operations)
    def set_control(self, station: int, forward: bool = False, reverse: bool = False, speed_ref: int = 0,
                    torque_ref: int = 0, *, fault_reset: bool = False, ef0: bool = False, ext_bb: bool = False,
                    fault_history_clear: bool = False, multi_inputs: int = 0, sel_ref: int = 0, sel_mon: int = 0x41,
                    ref1: int = 0, ref2: int = 0) -> Control:
        """Set the INV_CTL sent every communication cycle in phase 2/3 when no request is pending."""
        st = self._station(station)
        ctl = Control(forward, reverse, speed_ref, torque_ref, fault_reset, ef0, ext_bb, fault_history_clear,
                      multi_inputs, sel_ref, sel_mon, ref1, ref2)
        st.control = ctl
        st.ctl_body = restart.command(st, self._emit) if st.run_held or st.searching else st.codec.inv_ctl(ctl)
        return ctl

    def control(self, station: int) -> Control:
        return self._station(station).control

    def state(self, station: int) -> StationState:
        return self._station(station).state

    def at_target(self, station: int) -> bool:
        st = self._station(station)
        if not st.enabled:
            return st.state in (S.OFFLINE, S.PHASE1)  # disconnected on request
        return st.state is st.target

    def all_at_target(self) -> bool:
        return all(self.at_target(st.address) for st in self._stations)

    @property
    def addresses(self) -> list[int]:
        return [st.address for st in self._stations]

    def view(self, station: int) -> StationView:
        return self._station(station).view(self.at_target(station))

    def views(self) -> dict[int, StationView]:
        return {st.address: self.view(st.address) for st in self._stations}

    # ------------------------------------------------------------------ slot: choose and encode the command
    def _retire(self, st: Slave, now: int) -> None:
        """A new slot of *st*: its previous command is no longer the outstanding one (in flight within the answer
        window, else Missing), and what stayed in flight too long is aged out."""
        prev = st.outstanding
        if prev is not None:
            st.outstanding = None
            if self._window:
                st.inflight[prev.cycle] = prev
            else:
                self._missing(st, prev, now)
        if st.inflight:
            self._age(st, now)

    def _slot(self, st: Slave, cycle: int, now: int) -> bytes:
        self._retire(st, now)
        codec = st.codec
        if (st.state is _PHASE3 and st.enabled and not st.main_q and not st.sub_q and cycle >= st.hold_until
                and self.fast_path):
            # the steady state, what the general lane below gives for it: no event falls due (Slave.due), the
            # cyclic INV_CTL (Slave.choose_main), no sub-command request (Slave.choose_sub)
            send, body, req = _CYCLIC, st.ctl_body, None
            if body is st.ctl_code_of:
                code = st.ctl_code
            else:
                code = st.ctl_code = codec.main_slot.code_of(body)
                st.ctl_code_of = body
            sub_body = sub_req = None
        else:
            due = st.due(cycle)
            if due is not None:
                self._fire(st, due)
            send, body, req = st.choose_main(cycle)
            code = codec.main_slot.code_of(body)
            sub_body = sub_req = None
            if st.plan.has_sub:
                sub_req = st.choose_sub(code)
                sub_body = sub_req.body if sub_req is not None else None
                if sub_req is not None:
                    sub_req.attempts += 1
            if req is not None:
                req.attempts += 1
        # WDT bits 4-7: the station's communication-cycle count (advances by one per communication cycle, also
        # over cycles the timer skipped); bits 0-3: echo of the slave's count, RWDT bits 0-3 (docs/master.md).
        st.wdt = wdt = ((((cycle - st.offset) // st.period) & 0xF) << 4) | (st.rwdt & 0x0F)
        c32 = cycle & _U32
        st.outstanding = Sent(c32, now, send, code, body, req, sub_req)
        st.sent += 1
        if send is _CYCLIC and sub_body is None and self.fast_path:
            return st.frames.command(body, c32, wdt)
        return encode(Frame(st.plan.link, Kind.COMMAND, st.address, c32, self.plan.tcycle_ns,
                            codec.message(body, wdt, sub_body)))

    def _missing(self, st: Slave, prev: Sent, now: int) -> None:
        """*prev* went unanswered: Missing, a round of each request it carried, OFFLINE after ``offline_after``."""
        st.expired = prev
        st.missing += 1
        st.silent += 1
        self._emit(Missing(st.address, prev.cycle))
        requests.unanswered(st, prev, self.plan.request_retries)
        if st.silent >= self.plan.offline_after and expects(st.state, Ev.SILENT):
            self._fault(st, "silent", now)
            self._fire(st, Ev.SILENT)

    def _age(self, st: Slave, now: int) -> None:
        """Commands in flight longer than the answer window (``NetworkPlan.answer_window_ns``) become Missing."""
        inflight = st.inflight
        horizon = now - self._window
        while inflight:
            cycle, sent = next(iter(inflight.items()))
            if sent.at >= horizon:
                return
            del inflight[cycle]
            self._missing(st, sent, now)

    # ------------------------------------------------------------------ response: state machine
    def _advance(self, st: Slave, sent: Sent, reply: Reply, now: int) -> None:
        """What the answer to *sent* means for the station: the event it is, fired when the state takes it
        (a late answer may find the station elsewhere), and the requests it completes."""
        if sent.sub_req is not None:
            requests.complete(st, st.sub_q, sent.sub_req, reply.sub_code, reply.sub_ready, reply.sub_error,
                              reply.sub_body)
        send = sent.send
        if send is Send.PROBE:
            return
        answered = reply.code == sent.code and (reply.ready or reply.error is not None)
        if send is Send.CONNECT:
            if answered and expects(st.state, Ev.CONNECTED):
                self._connected(st, sent, reply)
            return
        if send is Send.RESET:
            if answered:
                st.reset_first = False
            return
        if send is Send.DISCONNECT:
            if answered:
                self._fire(st, Ev.DISCONNECTED)
                for req in st.disconnect_waiters:
                    req._finish(result=None)
                st.disconnect_waiters.clear()
            return
        # Phase-2/3 commands: SYNC | CLEAR | CYCLIC | REQUEST
        if reply.not_connected:
            if sent.req is not None:
                requests.complete(st, st.main_q, sent.req, reply.code, True, reply.error, reply.body)
            self._fault(st, "phase 1", now)
            self._fire(st, Ev.NOT_CONNECTED)
            return
        same = reply.code == sent.code
        if reply.comm_alarm is not None and expects(st.state, Ev.COMM_ALARM):
            self._alarm(st, Ev.COMM_ALARM, reply.comm_alarm, now)
        elif send is Send.SYNC and same:
            if reply.error is not None and expects(st.state, Ev.SYNC_REFUSED):
                self._alarm(st, Ev.SYNC_REFUSED, reply.error, now)  # clear, then try again (escalates)
            elif reply.ready and expects(st.state, Ev.SYNCED):
                self._fire(st, Ev.SYNCED)
                self._reached(st, now)
        elif send is Send.CLEAR and same:
            if reply.error is not None and expects(st.state, Ev.CLEAR_REFUSED):
                self._alarm(st, Ev.CLEAR_REFUSED, reply.error, now)  # counts as a round (escalates)
            elif reply.ready and expects(st.state, Ev.CLEARED):
                self._fire(st, Ev.CLEARED_TO_SYNC if st.target is S.PHASE3 else Ev.CLEARED)
                if st.target is S.PHASE2:
                    self._reached(st, now)
        if send is Send.REQUEST and sent.req is not None:
            if reply.comm_alarm is not None and reply.warning and st.codec.link is not Link.ML3:
                return  # SI-T3 Table 21: the alarm hides whether an A.94/A.95 came with it; ask again once cleared
            requests.complete(st, st.main_q, sent.req, reply.code, reply.ready, reply.error, reply.body)

    def _connected(self, st: Slave, sent: Sent, reply: Reply) -> None:
        """CONNECT answered in CONNECTING: connected, refused for the plan (back off), or not accepted."""
        error = reply.connect_refusal
        if error is not None and reply.plan_refused:
            # The station rejects the plan's VER/COM_MOD/COM_TIM: wait, then try again.
            st.last_error = f"CONNECT refused: {error[1]} ({error[0]:02X}H)"
            st.hold_until = self._cycle + self.plan.connect_backoff * st.period
            self._fire(st, Ev.PLAN_REFUSED)
            return
        if error is not None or reply.body != sent.body:
            # Not in phase 1 (CONNECT ignored or refused): release the old connection first.
            st.last_error = f"CONNECT not accepted ({error[1] if error else 'echo differs'}); DISCONNECT first"
            st.reset_first = True
            self._fire(st, Ev.NOT_ACCEPTED)
            return
        st.last_error = None
        self._fire(st, Ev.CONNECTED)
        if st.target is S.PHASE2:
            self._reached(st, self._now)

    def _alarm(self, st: Slave, event: Ev, alarm: tuple[int, str], now: int) -> None:
        """A communication alarm, or a refused SYNC_SET / ALM_CLR: an ALM_CLR round, or after
        ``clear_attempts`` rounds DISCONNECT + CONNECT."""
        self._fault(st, alarm[1], now)
        st.clear_rounds += 1
        if st.clear_rounds > self.plan.clear_attempts:
            st.clear_rounds = 0
            st.reset_first = True
            st.last_error = f"{alarm[1]} persists after {self.plan.clear_attempts} ALM_CLR; reconnecting"
            self._fire(st, Ev.ESCALATED)
        else:
            self._fire(st, event)

    # ------------------------------------------------------------------ bookkeeping
    def _observe(self, st: Slave, reply: Reply) -> None:
        codec = st.codec
        ml3_link = codec.link is Link.ML3
        if reply.alarm != st.alarm and not ml3_link:  # ML-III: the code of D_ALM is read (_drive_fault)
            st.alarm = reply.alarm
            if reply.alarm:
                st.alarm_name = codec.alarm_name(reply.alarm, reply.status or 0)
                self._emit(AlarmRaised(st.address, reply.alarm, st.alarm_name, "alarm"))
            else:
                st.alarm_name = None
                self._emit(AlarmCleared(st.address, "alarm"))
        if reply.comm_alm != st.comm_alm:
            st.comm_alm = reply.comm_alm
            self._alarm_edge(st, reply.comm_alm, "comm")
        if reply.cmd_alm != st.cmd_alm:
            st.cmd_alm = reply.cmd_alm
            self._alarm_edge(st, reply.cmd_alm, "command")
        if not reply.status_valid:
            return  # SI-T3 "STATUS Field" note: with PRM_RD only CMDRDY is valid
        if ml3_link and reply.fault is not st.fault:
            self._drive_fault(st, reply.fault)
        st.fault = reply.fault
        st.warning = reply.warning
        if reply.kind is Cmd.INV_CTL:
            b = reply.body
            st.status = reply.status or 0
            st.output_freq = b.output_freq
            st.output_current = b.output_current
            st.mon1 = b.mon1
            st.mon2 = b.mon2
            if st.run_held or st.searching:
                restart.watch(st, self._emit)

    def _alarm_edge(self, st: Slave, code: int, source: str) -> None:
        if code:
            table: Any = CommAlm if source == "comm" else CmdAlm
            try:
                name = table(code).name
            except ValueError:
                name = f"{code:X}H"
            self._emit(AlarmRaised(st.address, code, name, source))
        else:
            self._emit(AlarmCleared(st.address, source))

    def _fault(self, st: Slave, reason: str, now: int) -> None:
        if st.was_up and st.fault_since is None:
            st.fault_since = now
            st.fault_reason = reason

    def _reached(self, st: Slave, now: int) -> None:
        st.was_up = True
        st.clear_rounds = 0
        if st.fault_since is None:
            return
        if st.fault and st.codec.link is Link.ML3:  # D_ALM once the connection is back: which fault? (drivefault)
            if st.fault_read is None and not st.alarm:
                self._read_drive_fault(st)
            if st.fault_read is not None:
                st.recovery_pending = True  # decided when U2-01 is known (_drive_fault_read)
                return
            if self._reset_connection_fault(st):
                return
        self._recovered(st, now)

    def _recovered(self, st: Slave, now: int) -> None:
        since = st.fault_since
        st.recoveries += 1
        self._emit(Recovered(st.address, st.fault_reason, now - since if since is not None else 0))
        st.fault_since = None
        st.fault_resets = 0
        restart.begin(st, self._emit)

    # ------------------------------------------------------------------ ML-III drive faults (drivefault)
    def _drive_fault(self, st: Slave, on: bool) -> None:
        """A D_ALM edge: on, read its code (ALM_RD, SI-ET3 Tables 16/17); off, the view's alarm clears."""
        if on:
            if st.fault_read is None:
                self._read_drive_fault(st)
        elif st.alarm:
            st.alarm, st.alarm_name = 0, None
            self._emit(AlarmCleared(st.address, "alarm"))

    def _read_drive_fault(self, st: Slave) -> None:
        req = st.fault_read = drivefault.read_request(st.address, self._deadline(None, None))
        st.main_q.append(req)
        req.add_done_callback(lambda r: self._drive_fault_read(st, r))

    def _drive_fault_read(self, st: Slave, req: Request) -> None:
        """U2-01 is known (or the read failed): the view, then a recovery that waited for it."""
        st.fault_read = None
        code = drivefault.code_of(req)
        if code and st.fault and code != st.alarm:
            st.alarm, st.alarm_name = code, drivefault.name_of(code)
            self._emit(AlarmRaised(st.address, code, st.alarm_name, "alarm"))
        if st.recovery_pending:
            st.recovery_pending = False
            if st.state is st.target and st.fault_since is not None and not self._reset_connection_fault(st):
                self._recovered(st, self._now)

    def _reset_connection_fault(self, st: Slave) -> bool:
        """bUS / E5 left by the connection loss and not reset by ALM_CLR (RUN on): DISCONNECT + CONNECT, as on
        the SI-T3 (drivefault); at most ``clear_attempts`` times per recovery. False: nothing to do here."""
        if (st.alarm not in drivefault.CONNECTION_FAULTS or st.fault_resets >= self.plan.clear_attempts
                or not expects(st.state, Ev.ESCALATED)):
            return False
        st.fault_resets += 1
        st.reset_first = True
        st.last_error = f"drive fault {st.alarm_name} after the connection loss; DISCONNECT resets it"
        self._fire(st, Ev.ESCALATED)
        return True

    def _fire(self, st: Slave, event: Ev) -> None:
        """The one place a station's state changes: by the table (:func:`~.machine.next_state`, which raises
        :class:`~.machine.IllegalTransition` for a pair it does not hold)."""
        old = st.state
        new = next_state(old, event)
        if old is not new:
            st.state = new
            self._bringing += (new in _BRINGING) - (old in _BRINGING)
            self._emit(StateChanged(st.address, old, new))

    def _emit(self, ev: Event) -> None:
        ev_q = self.events
        if ev_q.maxlen is not None and len(ev_q) == ev_q.maxlen:
            self.events_lost += 1
        ev_q.append(ev)

    def _drop(self, station: int | None, reason: Any) -> None:
        self.drops[reason] += 1
        self._emit(Dropped(station, reason))
