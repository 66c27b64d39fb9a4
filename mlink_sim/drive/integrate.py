"""The drive's integrator: its state, one sub-step, and the closed form of a steady state.

:class:`IntegratorState` holds everything that moves between sub-steps (frequencies, shaft speed, bus
energy, thermal state, speed search), the inputs the drive's mode logic sets (target, ramp rates, torque
mode) and the constants of the motor, the load and the bus.  :class:`mlink_sim.drive.Drive` owns one and
calls the plain functions below on it; this module does not know the :class:`Drive`.  What the drive must
act on -- a trip, an event for its log -- the functions put in :attr:`IntegratorState.pending` and say so
in their return value (:data:`CHANGED`); the drive then applies them in order and re-derives its mode.

Per sub-step ``h`` (:func:`substep`; docs/drive-model.md, "Numerics"), one marked section each:

1. soft starter: the output frequency magnitude ``m`` moves toward the target with rate ``q``
   limited to ``E1-04 / C1-0x`` and jerk ``rate / C2-0x`` (S-curve); the landing follows
   ``q = sqrt(2 j e)`` so the end jerk is exact; stall prevention holds ``q = 0``;
2. motor: ``T = K phi^2 (w_s - w)`` (or a held torque value), the synchronous speed ``w_s``
   linear in time across the step; after step 3 the torque, current, power and output frequency
   at the step's end;
3. mechanics ``J dw/dt = T - T_c - B w`` integrated exactly (exponential integrator) with the
   load linearised at the start of the step (exact for inertia, constant, friction loads);
4. DC bus energy ``E = C V^2 / 2`` takes ``-(P_out + P_ctrl) h`` above the rectified level;
5. oL1 thermal state, oC / ov / Uv1 checks, stall-prevention flags, steady-state detection.

While a speed search runs (:func:`search_step`) the drive applies no torque (its search voltage is
reduced; the shaft coasts through steps 2-3) and the sweep frequency and the search current replace
step 1; after it, :func:`restart_watch` restarts a search whose current stays above b3-17 (SEr when
b3-19 is exceeded).

:func:`substep` is the hot loop of every simulated station and stays one function: its constants are
unpacked from one tuple (``IntegratorState.hot``), because five calls, one per step, cost 11-17 % more per
integrated step (``python -m benchmarks.micro.drive``).  The determinism tests
(tests/drive/test_determinism_and_integration.py) and that benchmark guard it.
"""

from __future__ import annotations

import math
from typing import Final

from .faults import Fault
from .motor import LoadSpec, MotorConstants
from .search import SpeedSearch
from .settings import OL1_TRIP_LEVEL, DriveSettings

__all__ = [
    "CHANGED",
    "STEADY",
    "IntegratorState",
    "begin_search",
    "restart_watch",
    "search_step",
    "ol1_trip_ahead",
    "steady_to",
    "substep",
    "NEVER_HELD",
    "note_held",
    "held_since",
]

INF = math.inf
_STOP_W = 1e-4  # rad/s below which a coasting shaft is taken as stopped
_KIND_CODE = {"inertia": 0, "constant": 1, "fan": 2, "friction": 0}

#: :func:`substep` results: the drive must apply :attr:`IntegratorState.pending` and re-derive its mode ...
CHANGED = 1
#: ... or the state came to rest (the drive goes on in closed form, :func:`steady_to`).
STEADY = 2

#: A :attr:`IntegratorState.pending` entry: a fault that trips with a coast stop, or a log event
#: ``(kind, detail)`` ("speed_search", "start" / "restart <n>" / "found <Hz> Hz").
Pending = Fault | tuple[str, str]


class IntegratorState:
    """The drive's continuous state, its mode inputs and its constants (see the module docstring).

    Symbols follow docs/drive-model.md: ``m`` soft-starter magnitude (Hz), ``q`` its rate (Hz/s), ``dir``
    the output direction (+1/-1), ``w`` shaft speed (rad/s), ``T`` torque (N m), ``I`` current (A), ``P``
    output power (W), ``E`` / ``V`` bus energy (J) / voltage (V), ``theta`` the oL1 thermal state."""

    __slots__ = (
        # state
        "m", "q", "dir", "out", "fout", "w", "T", "I", "P", "E", "V", "theta",
        "hold_acc", "hold_dec", "tlimited", "held", "steady", "dyn",
        # inputs, set by the drive: mains on, run allowed, target magnitude and direction, ramp rate and jerk
        # limits (accel A, Js at the start, Je at the end; decel D, Jds, Jde), torque mode 0 speed /
        # 1 limit / 2 control and its value (N m)
        "mains", "run", "mt", "dt", "A", "Js", "Je", "D", "Jds", "Jde", "tmode", "tval",
        # speed search: phase 0 off / 1 output off (b3-05, b3-25) / 2 sweep; sweep frequency, where it
        # started, time left in phase 1, restarts so far, time above b3-17 (None: not watching), (sweep rate
        # Hz/s, found level A, restart level A)
        "ss", "ss_f", "ss_start", "ss_wait", "ss_n", "ss_hi", "ss_k",
        # constants: motor (MotorConstants), load (LoadSpec.resolve), bus, protections, search settings
        "K", "wph", "Tr", "I0", "IT", "Ir", "R3", "fb", "J", "kind", "Tl", "B", "kf",
        "En", "Vn", "C", "Pc", "ov", "uv", "oc", "acc_lvl", "dec_lvl", "dec_raise", "tau", "ol1",
        "fmax", "slip", "search", "i_drive", "hot",
        # for the drive: trips and events, in the order they happened
        "pending",
    )

    def __init__(self, settings: DriveSettings, load: LoadSpec) -> None:
        self.m = self.q = self.w = self.theta = self.fout = 0.0
        self.T = self.I = self.P = 0.0
        self.dir = 1
        self.out = self.hold_acc = self.hold_dec = self.tlimited = self.steady = False
        #: the holds (REGULATION bits of drive.activity) turned on since the drive last took them: a hold goes on
        #: and off every few milliseconds around its level, within one advance
        self.held = 0
        self.dyn: frozenset[Fault] = frozenset()  # Uv / ov minors found by the integrator
        self.mains, self.run = True, False
        self.mt = 0.0
        self.dt = 1
        self.A = self.Js = self.Je = self.D = self.Jds = self.Jde = INF
        self.tmode, self.tval = 0, 0.0
        self.ss = self.ss_n = 0
        self.ss_f = self.ss_start = self.ss_wait = 0.0
        self.ss_hi: float | None = None
        self.ss_k = (0.0, 0.0, INF)
        self.pending: list[Pending] = []
        self.configure(settings, load)
        self.E, self.V = self.En, self.Vn

    def configure(self, s: DriveSettings, load: LoadSpec) -> None:
        """Take the constants of ``s`` and ``load`` (the state is kept)."""
        mc = MotorConstants.from_settings(s)
        self.K, self.wph, self.Tr = mc.stiffness, mc.w_per_hz, mc.rated_torque
        self.I0, self.IT, self.Ir = mc.i0, mc.i_t_rated, mc.i_rated
        self.R3, self.fb = 3.0 * mc.r_phase, mc.base_freq
        ld = load.resolve(s)
        # resolve() fills every None but the fan's rated speed
        assert ld.inertia_kgm2 is not None and ld.torque_nm is not None and ld.viscous_nms is not None
        self.J, self.kind, self.B = ld.inertia_kgm2, _KIND_CODE[ld.kind], ld.viscous_nms
        self.Tl = ld.torque_nm if ld.kind in ("constant", "fan") else 0.0
        w_fan = (ld.rated_speed_rpm * math.pi / 30.0) if ld.rated_speed_rpm else mc.rated_speed
        self.kf = ld.torque_nm / (w_fan * w_fan) if ld.kind == "fan" else 0.0
        self.C, self.Pc = s.bus_capacitance_f, s.control_power_w
        self.Vn = s.nominal_bus_v
        self.En = 0.5 * self.C * self.Vn * self.Vn
        self.ov, self.uv = s.ov_level_v, s.uv_level_v
        i_drive = self.i_drive = s.drive_rated_current_a
        self.oc = s.oc_level_pct * 0.01 * i_drive
        self.acc_lvl = s.stall_accel_level_pct * 0.01 * i_drive if s.stall_accel else INF
        self.dec_lvl = s.stall_decel_level_v if s.stall_decel else INF
        self.dec_raise = s.stall_decel_intelligent
        self.tau, self.ol1 = s.ol1_tau_s, s.ol1_enabled and s.ol1_tau_s > 0
        self.fmax, self.slip, self.search = s.max_freq_hz, s.motor_rated_slip_hz, s.search
        # the constants of the hot loop, unpacked in one go by substep()
        self.hot = (self.K, self.wph, self.fb, self.Tr, self.IT, self.I0, self.R3, self.J, self.B, self.kind,
                    self.Tl, self.kf, self.En, self.Pc, self.C, self.Vn, self.ov, self.uv, self.oc, self.acc_lvl,
                    self.dec_lvl, self.dec_raise, self.ol1, self.tau, self.Ir)

    def output_off(self) -> None:
        """Baseblock: no output frequency, torque or current; no search, no stall or torque limit."""
        self.m = self.q = self.fout = 0.0
        self.T = self.I = 0.0
        self.ss = self.ss_n = 0
        self.ss_hi = None
        self.hold_acc = self.hold_dec = self.tlimited = False


# ---------------------------------------------------------------------------------------------- closed form
def steady_to(x: IntegratorState, span: int) -> int:
    """Cover ``span`` ns of a steady state: only the oL1 thermal state moves, exactly:
    th -> i^2 + (th - i^2) e^(-t/tau).  0 when the whole span is covered; else the ns to the oL1 trip
    (at least 1), which is then in :attr:`~IntegratorState.pending`."""
    if not x.ol1:
        return 0
    dt = span * 1e-9
    i2 = x.I / x.Ir
    i2 *= i2
    th = x.theta
    if i2 > OL1_TRIP_LEVEL > th:
        t_trip = x.tau * math.log((i2 - th) / (i2 - OL1_TRIP_LEVEL))
        if t_trip <= dt:
            x.theta = OL1_TRIP_LEVEL
            x.pending.append(Fault.OL1)
            return max(1, math.ceil(t_trip * 1e9))
    x.theta = i2 + (th - i2) * math.exp(-dt / x.tau)
    return 0


def ol1_trip_ahead(x: IntegratorState) -> bool:
    """In a steady state, the oL1 thermal state is heading for a trip: its current's level ``(I/Ir)^2`` is above
    the trip level (:func:`steady_to` will find the instant). Below it, steady time never trips."""
    if not x.ol1:
        return False
    i2 = x.I / x.Ir
    return i2 * i2 > OL1_TRIP_LEVEL


# ---------------------------------------------------------------------------------------------- sub-step
def substep(x: IntegratorState, h: float) -> int:
    """Integrate ``h`` seconds: steps 1-5 of the module docstring, one marked section each (one function on
    purpose: split into five calls it costs 11-17 % more per integrated step).  0,
    :data:`CHANGED` (apply :attr:`~IntegratorState.pending`, re-derive the mode) or :data:`STEADY` (the state
    came to rest)."""
    if h <= 0.0:
        return 0
    (K, wph, fb, Tr, IT, I0, R3, J, B, kind, Tl, kf, En, Pc, C, Vn, ov, uv, oc, acc_lvl,
     dec_lvl, dec_raise, ol1, tau, Ir) = x.hot
    mains = x.mains
    w = x.w
    E = x.E
    srch = x.ss
    out = x.out and not srch
    m0 = m1 = x.m
    q = 0.0
    T1 = I1 = pag = 0.0
    limited = False
    if out:
        # ---- soft starter (ramp with S-curve) ------------------------------------------
        q, d, mt = x.q, x.dir, x.mt
        if x.dt != d:
            if m0 == 0.0:
                d = x.dir = x.dt
            else:
                mt = 0.0
        if m0 != mt or q != 0.0:
            if mt > m0:
                if x.hold_acc:
                    q = 0.0
                else:
                    je, js, a = x.Je, x.Js, x.A
                    qlim = a if je == INF else min(a, math.sqrt(2.0 * je * (mt - m0)))
                    if js == INF:
                        q = qlim
                        m1 = m0 + q * h
                    else:
                        q1 = min(q + js * h, qlim)
                        m1 = m0 + 0.5 * (q + q1) * h
                        q = q1
                    if m1 >= mt:
                        m1, q = mt, 0.0
            elif mt < m0:
                if x.hold_dec:
                    q = 0.0
                    if dec_raise:  # L3-04 = 2: no frequency below the rotor's
                        fr = d * w / wph
                        if fr > m1:
                            m1 = fr
                else:
                    je, js, a = x.Jde, x.Jds, x.D
                    qd = -q
                    qlim = a if je == INF else min(a, math.sqrt(2.0 * je * (m0 - mt)))
                    if js == INF:
                        qd = qlim
                        m1 = m0 - qd * h
                    else:
                        q1 = min(qd + js * h, qlim)
                        m1 = m0 - 0.5 * (qd + q1) * h
                        qd = q1
                    q = -qd
                    if m1 <= mt:
                        m1, q = mt, 0.0
            else:
                q = 0.0
        # ---- motor torque: T = K phi^2 (w_s - w), or held at the torque value --------------
        ws0 = d * m0 * wph
        ws1 = d * m1 * wph
        phi = fb / m1 if m1 > fb else 1.0
        k = K * phi * phi
        kk, aT = k, 0.0
        tmode = x.tmode
        if tmode:
            tv = x.tval
            if tmode == 2:  # torque control, speed limit = soft-starter output
                wl = ws1 if tv >= 0.0 else -ws1
                ws0 = ws1 = wl
                tf = k * (wl - w)
                if (tv >= 0.0 and tf > tv) or (tv < 0.0 and tf < tv):
                    kk, aT, limited = 0.0, tv, True
            else:
                tf = k * (ws1 - w)
                if tf > tv or tf < -tv:
                    kk, aT, limited = 0.0, (tv if tf > 0 else -tv), True
        T0 = aT + kk * (ws0 - w)
    else:
        m1 = kk = aT = T0 = ws0 = ws1 = 0.0
    # ---- mechanics: J dw/dt = aT + kk (ws(t) - w) - Tc - B w, exact for linear loads -----
    Tc = 0.0
    if kind == 1:  # constant (passive) torque
        if w > 0.0:
            Tc = Tl
        elif w < 0.0:
            Tc = -Tl
        else:
            td = aT + kk * 0.5 * (ws0 + ws1)
            Tc = td if -Tl <= td <= Tl else (Tl if td > 0 else -Tl)
    elif kind == 2:  # fan, linearised around w
        aw = w if w >= 0.0 else -w
        B = B + 2.0 * kf * aw
        Tc = -kf * w * aw
    lam = (kk + B) / J
    u0 = (aT + kk * ws0 - Tc) / J
    y = lam * h
    if y < 1e-6:
        a1 = h * (1.0 - 0.5 * y)
        a2 = h * h * (0.5 - y / 6.0)
        e = 1.0 - y
    else:
        e = math.exp(-y)
        a1 = (1.0 - e) / lam
        a2 = (h - a1) / lam
    w1 = w * e + u0 * a1 + kk * (ws1 - ws0) / (h * J) * a2
    if kind == 1 and (w * w1 < 0.0 or (w == 0.0 and Tc == td)):
        w1 = 0.0  # a passive load stops the shaft and holds it
    if not out and -_STOP_W < w1 < _STOP_W:
        w1 = 0.0
    if srch:
        I1 = search_step(x, h, w1)
    # ---- electrical ---------------------------------------------------------------------
    if out:
        T1 = aT + kk * (ws1 - w1)
        if limited:
            fel = (w1 + T1 / k) / wph
            if tmode == 1:
                m1, q = (fel * d if fel * d > 0.0 else 0.0), 0.0
            x.fout = fel
        else:
            x.fout = d * m1
        pag = 0.5 * (T0 * (w + T0 / k) + T1 * (w1 + T1 / k))
        it = T1 / Tr * IT / phi
        i0 = I0 * phi
        I1 = math.sqrt(i0 * i0 + it * it)
        x.m, x.q = m1, q
    P = pag + R3 * I1 * I1
    # ---- DC bus: C V dV/dt = -P - P_ctrl above the rectified level ------------------------
    if out or E > En or not mains:
        E1 = E - (P + Pc) * h
        if mains and E1 < En:
            E1 = En
        if E1 < 0.0:
            E1 = 0.0
        V = Vn if E1 == En else math.sqrt(2.0 * E1 / C)
    else:
        E1, V = E, x.V
    # ---- state, protections --------------------------------------------------------------
    x.w, x.T, x.I, x.P, x.E, x.V = w1, T1, I1, P, E1, V
    changed = srch != 0 and x.ss == 0  # a speed search found the motor speed
    if ol1:
        i2 = I1 / Ir
        i2 *= i2
        th = x.theta
        th += (i2 - th) * h / tau
        x.theta = th
        if th >= OL1_TRIP_LEVEL and out:
            x.pending.append(Fault.OL1)
            changed = True
    if out:
        if I1 >= oc:
            x.pending.append(Fault.OC)
            changed = True
        if V >= ov:
            x.pending.append(Fault.OV)
            changed = True
        if not mains and V < uv:
            x.pending.append(Fault.UV1)
            changed = True
        ha, hd = I1 >= acc_lvl, V >= dec_lvl
        if ha != x.hold_acc or hd != x.hold_dec or limited != x.tlimited:
            x.hold_acc, x.hold_dec, x.tlimited = ha, hd, limited
            if ha or hd or limited:
                x.held |= (1 if ha else 0) | (2 if hd else 0) | (4 if limited else 0)
        if not x.run and m1 == 0.0 and q == 0.0:
            changed = True  # stop completed: baseblock
        if x.ss_hi is not None and not changed:
            changed = restart_watch(x, h, I1)
    dyn = x.dyn
    if dyn or V >= ov or (not mains and V < uv):
        nd: set[Fault] = set()
        if V >= ov and not out:
            nd.add(Fault.OV)
        if not mains and V < uv and not out:
            nd.add(Fault.UV)
        if frozenset(nd) != dyn:
            x.dyn = frozenset(nd)
            changed = True
    if changed:
        return CHANGED
    if not srch and E1 == E and (w1 == w or -1e-9 * (1.0 + abs(w)) <= w1 - w <= 1e-9 * (1.0 + abs(w))):
        if not out or (m1 == m0 and q == 0.0 and x.dt == x.dir):
            x.steady = True
            return STEADY
    return 0


# ---------------------------------------------------------------------------------------------- speed search
def begin_search(x: IntegratorState, start_hz: float, wait_s: float) -> None:
    """Start (or restart) a speed search: output off for ``wait_s``, then sweep down from ``start_hz``."""
    ss, i_drive = x.search, x.i_drive
    x.ss, x.ss_f, x.ss_start, x.ss_wait = 1, start_hz, start_hz, wait_s
    x.ss_hi = None
    x.ss_k = (x.fmax / ss.decel_s, ss.current_pct * 0.01 * i_drive, ss.restart_pct * 0.01 * i_drive)
    x.m = x.q = x.fout = 0.0
    x.pending.append(("speed_search", f"restart {x.ss_n}" if x.ss_n else "start"))


def search_step(x: IntegratorState, h: float, w: float) -> float:
    """One sub-step of a speed search; returns the output current.  ``w``: shaft speed at the step's end.

    Phase 1 (b3-05 delay, b3-25 wait): output off.  Then Speed Estimation (b3-24 = 1) outputs the rotor's
    own electrical frequency, in its direction.  Current Detection sweeps the output down from the start
    frequency at E1-04 / b3-03 Hz/s with the current held at the b3-02 level; at full V/f voltage the
    motor would draw ``I = phi sqrt(I0^2 + (I_T s / s_r)^2)`` at slip ``s`` (section 4), so the current
    drops below b3-02 where ``s = s_r sqrt((I_b302 / phi)^2 - I0^2) / I_T``: the output resumes there.
    """
    rate, level, _ = x.ss_k
    d = x.dir
    if x.ss == 1:
        x.ss_wait -= h
        x.fout = 0.0
        if x.ss_wait > 1e-12:
            return 0.0
        if x.search.estimation:
            fr = w / x.wph
            if fr:
                d = 1 if fr > 0.0 else -1
            fr = min(abs(fr), x.fmax)
            _resume(x, fr, d)
            return x.I0 * (x.fb / fr if fr > x.fb else 1.0)
        x.ss = 2
        x.fout = d * x.ss_f
        return level
    f0 = x.ss_f
    f1 = f0 - rate * h
    if f1 < 0.0:
        f1 = 0.0
    fr = d * w / x.wph  # rotor electrical frequency in the search direction
    lim = level / (x.fb / f1) if f1 > x.fb else level
    y = lim * lim - x.I0 * x.I0
    if y > 0.0:
        s_th = x.slip * math.sqrt(y) / x.IT
        if f1 - fr <= s_th:
            _resume(x, min(max(fr + s_th, f1), f0), d)
            return level
    if f1 == 0.0:  # swept to 0 Hz without finding it (e.g. turning the other way): a plain start
        _resume(x, 0.0, d)
        return 0.0
    x.ss_f = f1
    x.fout = d * f1
    return level


def _resume(x: IntegratorState, f: float, d: int) -> None:
    """Output on at ``f`` Hz in direction ``d``; the ramp goes on from there.  Watch b3-17 from now."""
    x.ss = 0
    x.m, x.q, x.dir = f, 0.0, d
    x.fout = d * f
    x.ss_hi = 0.0
    x.pending.append(("speed_search", f"found {f:.2f} Hz"))


def restart_watch(x: IntegratorState, h: float, i: float) -> bool:
    """After a search: current >= b3-17 for b3-18 restarts it (after the b3-25 wait); more than b3-19
    restarts trip SEr (SI-T3 Table 26, 3BH).  The first step below b3-17 ends the watch and the count."""
    ss: SpeedSearch = x.search
    if i < x.ss_k[2]:
        x.ss_hi = None
        x.ss_n = 0
        return False
    hi = x.ss_hi = (x.ss_hi or 0.0) + h
    if hi < ss.restart_s - 1e-12:
        return False
    x.ss_n += 1
    if x.ss_n > ss.restarts:
        x.ss_hi = None
        x.pending.append(Fault.SER)
    else:
        begin_search(x, x.ss_start, ss.wait_s)
    return True


# ---------------------------------------------------------------------------------------------- regulation
#: The time a regulation state was last on, for one never on.
NEVER_HELD: Final = -(1 << 62)


def note_held(x: IntegratorState, at: list[int], t: int) -> None:
    """The holds on during the last advance (:attr:`IntegratorState.held`) or on now were on at *t*: *at* is the
    time each of stall-accel, stall-decel, torque-limit (drive.activity.REGULATION) was last on."""
    bits = x.held | (1 if x.hold_acc else 0) | (2 if x.hold_dec else 0) | (4 if x.tlimited else 0)
    x.held = 0
    if bits & 1:
        at[0] = t
    if bits & 2:
        at[1] = t
    if bits & 4:
        at[2] = t


def held_since(x: IntegratorState, at: list[int], since: int) -> int:
    """The REGULATION bits of the holds on at some time from *since* on (*at*: :func:`note_held`'s times): stall
    prevention during acceleration (the current limit) or deceleration (the DC bus regulation), the torque limit;
    one on at the last advance is on still (a steady drive is not advanced)."""
    return ((1 if x.hold_acc or at[0] >= since else 0) | (2 if x.hold_dec or at[1] >= since else 0)
            | (4 if x.tlimited or at[2] >= since else 0))
