"""The drive model: reference path, motor and load, DC bus, protections, stopping, faults.

Pure and deterministic: no clock, no sockets.  Time comes in as ``now`` (monotonic int ns).
:meth:`Drive.advance` integrates from the last time to ``now`` in equal sub-steps of at most
``substep_ns`` (default 1 ms); once a sub-step leaves the state unchanged (ramp finished, speed
settled, bus at rest) the drive is *steady* and further time is covered in closed form (only the
oL1 thermal state moves; its trip instant is solved exactly), so the cost does not grow with
the step rate.  Equations and limits: docs/drive-model.md.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Final

from .activity import DriveActivity, read_activity
from .faults import Fault, minor_code
from .integrate import (CHANGED, NEVER_HELD, IntegratorState, begin_search, held_since, note_held, ol1_trip_ahead, steady_to,
                        substep)
from .monitors import read_monitor, read_sel_mon
from .motor import LoadSpec, vf_voltage
from .settings import DriveSettings, Family, StopMethod, _ref_to_hz
from .status import DriveStatus

__all__ = ["Drive", "DriveCommand", "QUIET_FOREVER"]

_MAX_EVENTS = 64
INF = math.inf
#: :meth:`Drive.quiet_until` of a steady drive with no timed event ahead (ns, beyond any clock here: 2^61 ns is 73
#: years). Final and below 2^62, so that compiled code keeps it a native int: 1 << 62 was a boxed one, looked up in
#: the module's dict and subtracted as an object once per card and cycle (``cards.prediction.offer``).
QUIET_FOREVER: Final = 1 << 61
_EF_DELAY_NS = 500_000_000  # A1000 "EF": forward and reverse both on for longer than 0.5 s
_ALARMS = (StopMethod.ALARM_ONLY, StopMethod.ALARM_RUN_D1_04, StopMethod.ALARM_RAMP)


@dataclass(frozen=True, slots=True)
class DriveCommand:
    """What the network asks for; set by the card from INV_CTL (SI-T3 Table 16, SI-ET3 Table 20,
    SI-T/V7 Table 3).  ``multi_inputs`` bit k = terminal S(k+3); references in drive raw units:
    ``freq_ref_raw`` in o1-03 / n035 units (sign ignored), torque reference / limit in 0.1 % of
    motor rated torque."""

    forward: bool = False
    reverse: bool = False
    fault_reset: bool = False
    external_fault: bool = False  # EF0
    external_baseblock: bool = False
    multi_inputs: int = 0
    freq_ref_raw: int = 0
    torque_ref_raw: int = 0
    torque_limit_raw: int = 0
    fault_history_clear: bool = False


_IDLE = DriveCommand()


class Drive:
    """One simulated drive.  See the module docstring and docs/drive-model.md."""

    __slots__ = (
        "family", "settings", "load", "_x", "_events", "_remote_override", "_sub", "_t", "_cmd",
        "_fault", "_fault_stop", "_history", "_latched", "_cond", "_ope", "_stop_alarm", "_d104", "_ef_since",
        "_event_at", "_status", "_skey", "_slast", "steady_epoch", "_ref_hz", "_remote", "_net_run", "_net_ref",
        "_aim", "_aim_at", "_aim_from", "_fault_at", "_fast", "_use2", "_held_at",
    )

    def __init__(self, family: Family, settings: DriveSettings, load: LoadSpec, *, now: int = 0,
                 remote: bool | None = None, substep_ns: int = 1_000_000) -> None:
        if settings.family is not family:
            raise ValueError("settings were built for another drive family")
        if substep_ns <= 0:
            raise ValueError("substep_ns must be > 0")
        self.family = family
        self._events: list[tuple[int, str, str]] = []
        self._remote_override = remote
        self._sub = int(substep_ns)
        self._t = int(now)
        self._cmd = _IDLE
        self._fault: Fault | None = None
        self._fault_stop = StopMethod.COAST
        self._history: list[Fault] = []
        self._latched: set[Fault] = set()
        self._cond: frozenset[Fault] = frozenset()
        self._stop_alarm = False
        self._d104 = False
        self._ef_since: int | None = None
        self._event_at: int | None = None
        self._status: DriveStatus | None = None
        self._skey: tuple[bool, ...] = ()
        self._slast: DriveStatus | None = None
        self._ref_hz = 0.0
        # what activity() reads: the soft starter's aim (run, direction, target), since when and from where; when
        # the fault in effect tripped; a fast stop; the second ramp times selected
        self._aim: tuple[bool, int, float] = (False, 1, 0.0)
        self._aim_at = int(now)
        self._aim_from = 0.0
        self._fault_at = 0
        self._fast = False
        self._use2 = False
        #: when each regulation state (activity.REGULATION: stall-accel, stall-decel, torque-limit) was last on
        self._held_at = [NEVER_HELD, NEVER_HELD, NEVER_HELD]
        #: Bumped whenever the drive becomes steady or stops being steady: while it is steady and this number
        #: is unchanged, no output or monitor of the drive changes (only the oL1 thermal state moves).
        self.steady_epoch = 0
        self.load = load
        #: the integrator's state, inputs and constants (integrate.py): the drive's continuous half
        self._x = IntegratorState(settings, load)
        self._apply_settings(settings)
        self._recompute()

    # ------------------------------------------------------------------ configuration
    def _apply_settings(self, s: DriveSettings) -> None:
        self.settings = s
        self._x.configure(s, self.load)
        self._ope = s.check()
        ro = self._remote_override
        self._net_run = s.run_from_network if ro is None else ro
        self._net_ref = s.ref_from_network if ro is None else ro
        self._remote = self._net_run

    def reconfigure(self, settings: DriveSettings, now: int) -> None:
        """CONFIG: take new settings; oPE (and no run) while :meth:`DriveSettings.check` fails."""
        if settings.family is not self.family:
            raise ValueError("settings were built for another drive family")
        self.advance(now)
        self._apply_settings(settings)
        if self._ope is not None:
            self._event("ope", self._ope)
        x = self._x
        x.E = max(x.E, x.En) if x.mains else x.E
        x.V = math.sqrt(2.0 * x.E / x.C)
        self._recompute()

    def set_load(self, load: LoadSpec, now: int) -> None:
        """Change the mechanical load (e.g. a load step); the shaft speed is kept."""
        self.advance(now)
        self.load = load
        self._apply_settings(self.settings)
        self._recompute()

    def set_main_power(self, on: bool, now: int) -> None:
        """Mains on/off.  Off: the bus feeds the load and the control power until the Uv level."""
        self.advance(now)
        x = self._x
        x.mains = bool(on)
        if on and x.E < x.En:
            x.E, x.V = x.En, x.Vn
            x.dyn = frozenset()
        self._recompute()

    # ------------------------------------------------------------------ network inputs
    def command(self, cmd: DriveCommand, now: int) -> None:
        """Advance to ``now``, then apply ``cmd`` (cheap when it equals the previous one)."""
        self.advance(now)
        prev = self._cmd
        if cmd is prev or cmd == prev:
            return
        self._cmd = cmd
        inp = self.settings.inputs
        reset_now = cmd.fault_reset or bool(cmd.multi_inputs & inp.fault_reset)
        reset_before = prev.fault_reset or bool(prev.multi_inputs & inp.fault_reset)
        if cmd.fault_history_clear and not prev.fault_history_clear:
            self.clear_fault_history()
        self._recompute()
        if reset_now and not reset_before:
            self.reset_fault(now)

    def trip(self, fault: Fault, stop: StopMethod, now: int) -> None:
        """Card-detected cause (bUS per F6-01, E5 per F6-25, EF0 per F6-03 ...): fault or minor."""
        self.advance(now)
        stop = StopMethod(stop)
        if stop in _ALARMS:
            self._latched.add(fault)
            if stop is StopMethod.ALARM_RAMP:
                self._stop_alarm = True
            elif stop is StopMethod.ALARM_RUN_D1_04:
                self._d104 = True
        else:
            self._trip_now(fault, stop)
        self._recompute()

    def clear_minor(self, fault: Fault, now: int) -> None:
        """Clear a minor fault raised with :meth:`trip` (e.g. the card's CyC once the cycle is ok)."""
        self.advance(now)
        self._latched.discard(fault)
        if not self._latched:
            self._stop_alarm = self._d104 = False
        self._recompute()

    def reset_fault(self, now: int) -> bool:
        """Fault reset / ALM_CLR.  False, and no change, while RUN is on (SI-T3 section ALM_CLR
        "Drive faults and alarms cannot be reset while the Drive RUN command is ON"), or while the
        cause of an external fault is still input."""
        self.advance(now)
        c = self._cmd
        if c.forward or c.reverse:
            return False
        f = self._fault
        if f is not None and self._cause_present(f):
            return False
        if f is not None:
            self._event("fault_reset", f.display)
        self._fault = None
        self._latched.clear()
        self._stop_alarm = self._d104 = False
        self._recompute()
        return True

    def clear_fault_history(self) -> None:
        """Fault history trace clear (SI-T3 Table 16 bit E, SI-ET3 Table 20 bit 11)."""
        self._history = [self._fault] if self._fault is not None else []
        self.steady_epoch += 1

    def _cause_present(self, f: Fault) -> bool:
        c, s = self._cmd, self.settings
        if f is Fault.EF0:
            return c.external_fault
        for ef in s.inputs.ext_faults:
            if ef.fault is f and (bool(c.multi_inputs & ef.mask) != ef.normally_closed):
                return True
        return False

    def _trip_now(self, fault: Fault, stop: StopMethod) -> None:
        if self._fault is not None:
            if stop is StopMethod.COAST:  # a second, harder cause still cuts the output
                self._fault_stop = StopMethod.COAST
            return
        self._fault, self._fault_stop = fault, stop
        self._fault_at = self._t
        self._history.insert(0, fault)
        del self._history[10:]
        self._event("fault", f"{fault.display} {stop.name}")

    def _event(self, kind: str, detail: str) -> None:
        ev = self._events
        ev.append((self._t, kind, detail))
        if len(ev) > _MAX_EVENTS:
            del ev[0]

    def drain_events(self) -> list[tuple[int, str, str]]:
        """Events since the last call, oldest first: ``(t_ns, kind, detail)`` with kind
        ``"fault"`` (detail ``"<display> <stop>"``), ``"fault_reset"``, ``"ope"``, ``"speed_search"`` (detail
        ``"start"``, ``"restart <n>"``, ``"found <Hz> Hz"``).  At most the
        last 64 are kept; the card logs them with its bound context (the drive does no I/O)."""
        ev, self._events = self._events, []
        return ev

    # ------------------------------------------------------------------ mode evaluation
    def _recompute(self) -> None:
        """Re-derive run request, target, ramp rates and torque mode after any discrete change."""
        s, c, x = self.settings, self._cmd, self._x
        inp, mi = s.inputs, self._cmd.multi_inputs
        x.steady = False
        self.steady_epoch += 1
        self._status = self._slast = None
        run_src = self._net_run
        fwd, rev = (c.forward, c.reverse) if run_src else (False, False)
        cond: set[Fault] = set()
        self._event_at = None
        if fwd and rev:
            if self._ef_since is None:
                self._ef_since = self._t
            if self._t - self._ef_since >= _EF_DELAY_NS:
                cond.add(Fault.EF)
            else:
                self._event_at = self._ef_since + _EF_DELAY_NS
        else:
            self._ef_since = None
        active = x.out or (fwd != rev)
        fast_alarm = False
        if c.external_fault and (not s.ef0_run_only or active):
            if s.ef0_stop in _ALARMS:
                cond.add(Fault.EF0)
            else:
                self._trip_now(Fault.EF0, s.ef0_stop)
        for ef in inp.ext_faults:
            if (bool(mi & ef.mask) != ef.normally_closed) and (not ef.run_only or active):
                if ef.stop in _ALARMS:
                    cond.add(ef.fault)
                    fast_alarm |= ef.stop is StopMethod.ALARM_RAMP
                else:
                    self._trip_now(ef.fault, ef.stop)
        bb = c.external_baseblock or bool(mi & inp.baseblock_no) or bool(
            inp.baseblock_nc and not mi & inp.baseblock_nc)
        if bb:
            cond.add(Fault.BB)
        fast = bool(mi & inp.fast_stop_no) or bool(inp.fast_stop_nc and not mi & inp.fast_stop_nc)
        self._cond = frozenset(cond)
        pon = x.mains or x.V >= x.uv
        can_run = ((fwd != rev) and self._fault is None and self._ope is None and pon and not bb
                   and not fast and not fast_alarm and not self._stop_alarm)
        self._ref_hz = ref = self._select_ref(mi)
        x.run = can_run
        fmax, fast_rate = s.max_freq_hz, INF
        use2 = bool(mi & inp.accel_decel_2)
        acc_s, dec_s = (s.accel2_s, s.decel2_s) if use2 else (s.accel_s, s.decel_s)
        s0, s1, s2, s3 = s.s_curve_s
        out = x.out
        if can_run:
            x.dt = 1 if fwd else -1
            mt = min(ref, fmax)
            x.mt = mt if mt >= s.min_freq_hz else 0.0
            if not out:  # output on: V/f starts at 0 Hz, or at the speed a speed search finds
                x.out, x.m, x.q, x.dir = True, 0.0, 0.0, x.dt
                if s.search.at_start or mi & (inp.search_max | inp.search_ref):
                    from_ref = bool(mi & inp.search_ref) and not mi & inp.search_max
                    begin_search(x, x.mt if from_ref else fmax, s.search.delay_s)
                    self._take_pending()
        else:
            x.dt, x.mt = x.dir, 0.0
            coast = bb or self._ope is not None or not pon
            if self._fault is not None:
                coast |= self._fault_stop is StopMethod.COAST
                if self._fault_stop is StopMethod.FAST:
                    fast = True
            elif fast or fast_alarm:
                fast = True
            elif not self._stop_alarm:
                coast |= s.coast_on_run_off
            if coast or x.ss or (out and x.m == 0.0 and x.q == 0.0):
                x.out = False  # a search cut short by a stop leaves the motor coasting
            if fast and s.fast_stop_s > 0:
                fast_rate = fmax / s.fast_stop_s
            elif fast:
                fast_rate = INF
        if not x.out:
            x.output_off()
        aim = (x.run, x.dt, x.mt)
        if aim != self._aim:
            self._aim, self._aim_at, self._aim_from = aim, self._t, x.m
        self._fast, self._use2 = fast, use2
        x.A = fmax / acc_s if acc_s > 0 else INF
        x.Js = x.A / s0 if s0 > 0 else INF
        x.Je = x.A / s1 if s1 > 0 else INF
        if fast:
            x.D, x.Jds, x.Jde = fast_rate, INF, INF
        else:
            x.D = fmax / dec_s if dec_s > 0 else INF
            x.Jds = x.D / s2 if s2 > 0 else INF
            x.Jde = x.D / s3 if s3 > 0 else INF
        if s.torque_from_network and s.family is Family.A1000:
            if s.torque_control:
                x.tmode, x.tval = 2, c.torque_ref_raw * 0.001 * x.Tr
            else:
                x.tmode, x.tval = 1, abs(c.torque_limit_raw) * 0.001 * x.Tr
        else:
            x.tmode, x.tval = 0, 0.0

    def _take_pending(self) -> None:
        """Apply what the integrator reported, in its order: trips (coast stop) and log events."""
        x = self._x
        for p in x.pending:
            if isinstance(p, Fault):
                self._trip_now(p, StopMethod.COAST)
            else:
                self._event(*p)
        x.pending.clear()

    def _select_ref(self, mi: int) -> float:
        """Selected frequency reference (Hz): d1-04 override, jog, multi-step (F6-07), network."""
        s = self.settings
        if self._d104:
            return s.step_refs_hz[3]
        inp = s.inputs
        if mi & inp.jog:
            return s.jog_hz
        if s.multi_step_enabled:
            ms = inp.multi_step
            idx = ((1 if mi & ms[0] else 0) | (2 if mi & ms[1] else 0)
                   | (4 if mi & ms[2] else 0) | (8 if mi & ms[3] else 0))
            if idx:
                return s.step_refs_hz[idx]
        if self._net_ref:
            return _ref_to_hz(s, self._cmd.freq_ref_raw)
        return s.local_ref_hz

    # ------------------------------------------------------------------ time
    def advance(self, now: int) -> None:
        """Integrate to ``now`` (monotonic ns; earlier times are ignored)."""
        x = self._x
        while self._t < now:
            t = self._t
            ev = self._event_at
            end = now if ev is None or ev > now else ev
            if x.steady:
                took = steady_to(x, end - t)
                if took:  # an oL1 trip after `took` ns; the loop goes on from there
                    self._t = t + took
                    self._take_pending()
                    self._recompute()
                else:
                    self._t = end
            else:
                self._status = None
                dt = end - t
                sub = self._sub
                if dt <= sub:
                    r = substep(x, dt * 1e-9)
                    if r:
                        self._after_substep(r)
                    self._t = end
                else:
                    n = -(-dt // sub)
                    for i in range(n):
                        t_i = t + (dt * (i + 1)) // n
                        r = substep(x, (t_i - self._t) * 1e-9)
                        if r:
                            self._after_substep(r)
                        self._t = t_i
                        if x.steady:
                            break  # the rest in closed form, next turn of the loop
            if ev is not None and self._t == ev and self._event_at == ev:
                self._event_at = None
                self._recompute()
        if x.held or x.hold_acc or x.hold_dec or x.tlimited:
            note_held(x, self._held_at, self._t)

    def regulation(self, since_ns: int) -> int:
        """The regulation states (:data:`~.activity.REGULATION` bits) the drive was in at some time from *since_ns*
        to :attr:`now` (:func:`~.integrate.held_since`). Reading it changes nothing (docs/drive-model.md,
        "Activity")."""
        return held_since(self._x, self._held_at, since_ns)

    def _after_substep(self, result: int) -> None:
        if result == CHANGED:
            self._take_pending()
            self._recompute()
        else:  # STEADY
            self.steady_epoch += 1

    # ------------------------------------------------------------------ outputs
    @property
    def now(self) -> int:
        return self._t

    @property
    def status(self) -> DriveStatus:
        st = self._status
        if st is None:
            st = self._status = self._make_status()
        return st

    def _make_status(self) -> DriveStatus:
        """Build the status; reuse the last object when nothing it shows has changed.

        Discrete inputs (faults, minors, commands, oPE, mains) only change through
        :meth:`_recompute`, which drops the cached object; the integrator only moves the
        continuous signals, compared here as a small key (a frozen dataclass is slow to build)."""
        s, x = self.settings, self._x
        out = x.out
        f = x.fout if out else 0.0
        running = x.run or out
        af = f if f >= 0.0 else -f
        on = out and not x.ss  # no speed agree while a speed search sweeps
        key = (running, f < 0.0 or (f == 0.0 and running and x.dir < 0),
               af < s.min_freq_hz or not out,
               running and on and abs(af - min(self._ref_hz, s.max_freq_hz)) <= s.agree_width_hz,
               running and on and abs(af - s.agree_level_hz) <= s.agree_width_hz,
               x.tlimited, x.hold_acc or x.hold_dec)
        last = self._slast
        if last is not None and key == self._skey:
            return last
        running, reverse, zero, agree, uagree, tlim, stall = key
        minors = frozenset(self._latched | self._cond | x.dyn)
        minor = min(minors, key=lambda x: (minor_code(self.family, x) or 0x1000, x.value)) if minors else None
        pon = x.mains or x.V >= x.uv
        st = DriveStatus(
            running=running, reverse=reverse, zero_speed=zero, speed_agree=agree,
            user_speed_agree=uagree, ready=pon and self._fault is None and self._ope is None,
            faulted=self._fault is not None, minor_fault=bool(minors), baseblock=not out,
            main_power_on=pon, ope=self._ope is not None, fault_reset_input=self._reset_input(),
            remote=self._remote, motor2=bool(self._cmd.multi_inputs & s.inputs.motor2),
            torque_limited=tlim, fault=self._fault, minor=minor, minors=minors,
            ope_code=self._ope, stall_prevention=stall)
        self._skey, self._slast = key, st
        return st

    def _reset_input(self) -> bool:
        c = self._cmd
        return c.fault_reset or bool(c.multi_inputs & self.settings.inputs.fault_reset)

    @property
    def fault_history(self) -> tuple[Fault, ...]:
        """Faults, most recent first (max 10; minor faults are not recorded)."""
        return tuple(self._history)

    @property
    def frequency_reference_hz(self) -> float:
        return self._ref_hz

    @property
    def output_frequency_hz(self) -> float:
        """Signed output frequency (negative in reverse); 0 while baseblocked."""
        x = self._x
        return x.fout if x.out else 0.0

    @property
    def soft_starter_hz(self) -> float:
        x = self._x
        return x.dir * x.m if x.out else 0.0

    @property
    def motor_speed_rad_s(self) -> float:
        return self._x.w

    @property
    def motor_speed_rpm(self) -> float:
        return self._x.w * 30.0 / math.pi

    @property
    def output_current_a(self) -> float:
        return self._x.I

    @property
    def output_voltage_v(self) -> float:
        x = self._x
        return vf_voltage(self.settings, x.fout) if x.out else 0.0

    @property
    def output_power_kw(self) -> float:
        x = self._x
        return x.P * 1e-3 if x.out else 0.0

    @property
    def dc_bus_v(self) -> float:
        return self._x.V

    @property
    def torque_nm(self) -> float:
        return self._x.T

    @property
    def torque_pct(self) -> float:
        x = self._x
        return 100.0 * x.T / x.Tr

    @property
    def motor_thermal(self) -> float:
        """oL1 thermal state theta (per unit of rated-current heating; trips at 1.21)."""
        return self._x.theta

    @property
    def speed_search_active(self) -> bool:
        """True while a speed search runs (b3 / n101, n102): its delay, its sweep, the wait before a restart."""
        return self._x.ss != 0

    @property
    def is_steady(self) -> bool:
        return self._x.steady

    def quiet_until(self) -> int:
        """While the drive is steady: the time (ns) before which :meth:`advance` changes none of its outputs, its
        status or its monitors (its next timed event, or :data:`QUIET_FOREVER`); -1 when it is not steady, has
        something pending, or an oL1 trip lies ahead (:func:`~.integrate.ol1_trip_ahead`). The slave cards'
        answer predictions (:mod:`mlink_sim.cards.prediction`) hold no longer than this."""
        x = self._x
        if not x.steady or x.pending or ol1_trip_ahead(x):
            return -1
        ev = self._event_at
        return QUIET_FOREVER if ev is None else ev

    def activity(self) -> DriveActivity:
        """What the drive is doing and what holds it, as of :attr:`now` (docs/drive-model.md, "Activity"). Reading
        it changes nothing: the drive is not advanced."""
        c, f = self._cmd, self._fault
        return read_activity(
            self.settings, self._x, at_ns=self._t, run_requested=c.forward != c.reverse, net=(self._net_run,
            self._net_ref), reference_hz=self._ref_hz, fault=(f, self._fault_at, self._fault_stop.name),
            minors=self.status.minors, ope=self._ope, baseblock_input=Fault.BB in self._cond, fast=self._fast,
            second=self._use2, aim=(self._aim_at, self._aim_from))

    @property
    def command_in_effect(self) -> DriveCommand:
        """The last command applied."""
        return self._cmd

    def monitor(self, name: str) -> int:
        """U1-xx / U2-xx / U3-xx (A1000) or U-xx (V7) in the drive's raw monitor units (signed;
        unknown names read 0).  See :mod:`mlink_sim.drive.monitors` for the units."""
        return read_monitor(self, name)

    def sel_mon(self, table: str, code: int) -> int:
        """Value of SEL_MON ``code`` in the SEL_MON table *table* ("SI-T3", "SI-ET3", "SI-T/V7": a card profile's
        ``selections``), signed int."""
        return read_sel_mon(self, table, code)
