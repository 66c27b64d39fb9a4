"""The core's mutable record of one slave station, and of the command each slot sent it.

A :class:`Slave` also answers, without changing anything, what its next slot brings: the event that falls due
(:meth:`Slave.due`: CONNECT in PHASE1, SYNC_SET in PHASE2 with target phase 3) and, after the core has fired it,
the command to send (:meth:`Slave.choose_main`, from :data:`~mlink_sim.master.machine.SENDS`, and
:meth:`Slave.choose_sub`). :class:`StationView` (:mod:`.types`) is its public, frozen face.
"""

from __future__ import annotations

from collections import deque
from typing import Any

from . import restart
from .codec import Codec
from .commands import Send
from .fastpath import CyclicFrames
from .machine import MAY_HOLD_CONNECTION, SENDS, Ev
from .plan import StationPlan
from .types import Control, Request, StationState, StationView

__all__ = ["Slave", "Sent"]

S = StationState
_UP = (S.PHASE2, S.PHASE3)  # states in which requests and INV_CTL are sent


class Sent:
    """The command of one slot, kept until its response arrives or the station's next slot."""

    __slots__ = ("cycle", "at", "send", "code", "req", "sub_req", "late_seen", "body")

    def __init__(self, cycle: int, at: int, send: Send, code: int, body: Any, req: Request | None,
                 sub_req: Request | None) -> None:
        self.cycle = cycle
        self.at = at
        self.send = send
        self.code = code
        self.body = body
        self.req = req
        self.sub_req = sub_req
        self.late_seen = False


class Slave:
    """Mutable per-station state of the core: its place in the state machine, its slot, what is in flight,
    queued requests, the restart rule's state and the fields of its :class:`StationView`."""

    def __init__(self, plan: StationPlan, index: int, period: int, spread: bool, tcycle_ns: int) -> None:
        self.plan = plan
        self.address = plan.address
        self.codec = Codec(plan)
        self.frames = CyclicFrames(plan, tcycle_ns, self.codec)
        self.period = period
        self.offset = index % period if spread else 0
        self.state = StationState.OFFLINE
        self.target = StationState.PHASE3 if plan.sync else StationState.PHASE2
        self.enabled = True
        self.was_up = False
        self.wdt = 0
        self.rwdt = 0
        self.outstanding: Sent | None = None
        #: commands past their next slot still within the answer window, by cycle (oldest first)
        self.inflight: dict[int, Sent] = {}
        self.expired: Sent | None = None
        self.answered: int | None = None
        #: the command cycle of the answer the station shows (-1: none yet; answers.shows)
        self.shown = -1
        self.silent = 0
        self.main_q: deque[Request] = deque()
        self.sub_q: deque[Request] = deque()
        self.disconnect_waiters: list[Request] = []
        self.control = Control()
        self.ctl_body = self.codec.inv_ctl(self.control)
        #: the command code of ``ctl_body`` (its object: ``ctl_code_of``), looked up once per control, not per cycle
        self.ctl_code_of: Any = None
        self.ctl_code = 0
        #: after a recovery: the run command is held back (until standstill) or sent with the search input
        self.run_held = False
        self.searching = False
        #: the SEL_MON code of the motor speed on its card (U1-05 = 1: SI-T3 Table 18, SI-ET3 Table 22); -1: none
        self.motor_code = restart.motor_code(plan)
        self.reset_first = False
        self.hold_until = -1
        self.clear_rounds = 0
        self.fault_since: int | None = None
        self.fault_reason = ""
        #: ML-III: the ALM_RD reading U2-01 behind D_ALM (drivefault), a recovery waiting for it, and the
        #: DISCONNECT + CONNECT rounds spent on a bUS / E5 the connection loss left
        self.fault_read: Request | None = None
        self.recovery_pending = False
        self.fault_resets = 0
        self.last_error: str | None = None
        # view
        self.alarm = 0
        self.alarm_name: str | None = None
        self.comm_alm = 0
        self.cmd_alm = 0
        self.fault = False
        self.warning = False
        self.status = 0
        self.output_freq = 0
        self.output_current = 0
        self.mon1 = 0
        self.mon2 = 0
        self.rtt: int | None = None
        self.last_rx: int | None = None
        self.sent = 0
        self.responses = 0
        self.missing = 0
        self.late = 0
        self.recoveries = 0

    # --- a slot: its event, then its command (docs/master.md, "State machine") -----------------------------------
    def due(self, cycle: int) -> Ev | None:
        """The event this slot brings about before its command is chosen: CONNECT or SYNC_SET falls due."""
        if not self.enabled or cycle < self.hold_until:
            return None
        if self.state is S.PHASE1:
            return Ev.CONNECT_DUE
        if self.state is S.PHASE2 and self.target is S.PHASE3:
            return Ev.SYNC_DUE
        return None

    def choose_main(self, cycle: int) -> tuple[Send, Any, Request | None]:
        """The main command of this slot: the state's (:data:`~.machine.SENDS`), refined. Changes nothing."""
        codec = self.codec
        if not self.enabled:
            if self.state in MAY_HOLD_CONNECTION:
                return Send.DISCONNECT, codec.disconnect(), None
            return Send.PROBE, codec.nop(), None
        if cycle < self.hold_until:
            return Send.PROBE, codec.nop(), None
        send = SENDS[self.state]
        if send is Send.CYCLIC:
            if self.main_q:
                req = self.main_q[0]
                busy_sub = self.sub_q[0] if self.sub_q and self.sub_q[0].attempts else None
                if busy_sub is None or not codec.forbids(req.code, busy_sub.code):
                    return Send.REQUEST, req.body, req
            return send, self.ctl_body, None
        if send is Send.PROBE:
            return send, codec.nop(), None
        if send is Send.CONNECT:
            if self.reset_first:
                return Send.RESET, codec.disconnect(), None
            return send, codec.connect(), None
        if send is Send.SYNC:
            return send, codec.sync_set(), None
        return send, codec.alm_clr(), None  # Send.CLEAR

    def choose_sub(self, main_code: int) -> Request | None:
        """The queued sub-command request that may travel with main command *main_code* in this slot, if any."""
        if not self.sub_q or self.state not in _UP or not self.enabled:
            return None
        req = self.sub_q[0]
        return None if self.codec.forbids(main_code, req.code) else req

    def view(self, at_target: bool) -> StationView:
        return StationView(
            self.address, self.plan.label, self.state, self.state.phase, at_target, self.alarm, self.alarm_name,
            self.comm_alm, self.cmd_alm, self.fault, self.warning, self.status, self.output_freq,
            self.output_current, self.mon1, self.mon2, self.rtt, self.last_rx, self.wdt, self.rwdt, self.sent,
            self.responses, self.missing, self.late, self.recoveries, self.last_error, self.plan.link.name,
            self.plan.card, self.plan.hz_per_count,
        )
