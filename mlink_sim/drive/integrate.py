"""The drive's integrator: one sub-step, and the closed form of a steady state.

Bound as methods of :class:`mlink_sim.drive.Drive` (``Drive._substep`` / ``Drive._steady_to``);
kept in their own module to keep the files small.  They read and write the drive's private
state directly: this is the inside of the drive, not an API.

Per sub-step ``h`` (docs/drive-model.md, "Numerics"):

1. soft starter: the output frequency magnitude ``m`` moves toward the target with rate ``q``
   limited to ``E1-04 / C1-0x`` and jerk ``rate / C2-0x`` (S-curve); the landing follows
   ``q = sqrt(2 j e)`` so the end jerk is exact; stall prevention holds ``q = 0``;
2. motor: ``T = K phi^2 (w_s - w)`` (or a held torque value), the synchronous speed ``w_s``
   linear in time across the step;
3. mechanics ``J dw/dt = T - T_c - B w`` integrated exactly (exponential integrator) with the
   load linearised at the start of the step (exact for inertia, constant, friction loads);
4. DC bus energy ``E = C V^2 / 2`` takes ``-(P_out + P_ctrl) h`` above the rectified level;
5. oL1 thermal state, oC / ov / Uv1 checks, stall-prevention flags, steady-state detection.

While a speed search runs (:func:`search_step`) the drive applies no torque (its search voltage is
reduced; the shaft coasts through steps 2-3) and the sweep frequency and the search current replace
step 1; after it, :func:`restart_watch` restarts a search whose current stays above b3-17 (SEr when
b3-19 is exceeded).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

from .faults import Fault
from .settings import OL1_TRIP_LEVEL, StopMethod

if TYPE_CHECKING:
    from .drive import Drive

__all__ = ["restart_watch", "search_step", "steady_to", "substep"]

INF = math.inf
_STOP_W = 1e-4  # rad/s below which a coasting shaft is taken as stopped


def steady_to(self: Drive, end: int) -> None:
    """Steady state: only the oL1 thermal state moves, exactly: th -> i^2 + (th - i^2) e^(-t/tau)."""
    if not self._ol1:
        self._t = end
        return
    dt = (end - self._t) * 1e-9
    i2 = self._I / self._Ir
    i2 *= i2
    th = self._theta
    if i2 > OL1_TRIP_LEVEL > th:
        t_trip = self._tau * math.log((i2 - th) / (i2 - OL1_TRIP_LEVEL))
        if t_trip <= dt:
            self._t += max(1, math.ceil(t_trip * 1e9))
            self._theta = OL1_TRIP_LEVEL
            self._trip_now(Fault.OL1, StopMethod.COAST)
            self._recompute()
            return
    self._theta = i2 + (th - i2) * math.exp(-dt / self._tau)
    self._t = end

def substep(self: Drive, h: float) -> None:  # noqa: C901, PLR0912, PLR0915 - the hot loop, flat on purpose
    if h <= 0.0:
        return
    (K, wph, fb, Tr, IT, I0, R3, J, B, kind, Tl, kf, En, Pc, C, Vn, ov, uv, oc, acc_lvl,
     dec_lvl, dec_raise, ol1, tau, Ir) = self._hot
    mains = self._mains
    w = self._w
    E = self._E
    srch = self._ss
    out = self._out and not srch
    m0 = m1 = self._m
    q = 0.0
    T1 = I1 = pag = 0.0
    limited = False
    if out:
        # ---- soft starter (ramp with S-curve) ------------------------------------------
        q, d, mt = self._q, self._dir, self._mt
        if self._dt != d:
            if m0 == 0.0:
                d = self._dir = self._dt
            else:
                mt = 0.0
        if m0 != mt or q != 0.0:
            if mt > m0:
                if self._hold_acc:
                    q = 0.0
                else:
                    je, js, a = self._Je, self._Js, self._A
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
                if self._hold_dec:
                    q = 0.0
                    if dec_raise:  # L3-04 = 2: no frequency below the rotor's
                        fr = d * w / wph
                        if fr > m1:
                            m1 = fr
                else:
                    je, js, a = self._Jde, self._Jds, self._D
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
        tmode = self._tmode
        if tmode:
            tv = self._tval
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
    x = lam * h
    if x < 1e-6:
        a1 = h * (1.0 - 0.5 * x)
        a2 = h * h * (0.5 - x / 6.0)
        e = 1.0 - x
    else:
        e = math.exp(-x)
        a1 = (1.0 - e) / lam
        a2 = (h - a1) / lam
    w1 = w * e + u0 * a1 + kk * (ws1 - ws0) / (h * J) * a2
    if kind == 1 and (w * w1 < 0.0 or (w == 0.0 and Tc == td)):
        w1 = 0.0  # a passive load stops the shaft and holds it
    if not out and -_STOP_W < w1 < _STOP_W:
        w1 = 0.0
    if srch:
        I1 = search_step(self, h, w1)
    # ---- electrical ---------------------------------------------------------------------
    if out:
        T1 = aT + kk * (ws1 - w1)
        if limited:
            fel = (w1 + T1 / k) / wph
            if tmode == 1:
                m1, q = (fel * d if fel * d > 0.0 else 0.0), 0.0
            self._fout = fel
        else:
            self._fout = d * m1
        pag = 0.5 * (T0 * (w + T0 / k) + T1 * (w1 + T1 / k))
        it = T1 / Tr * IT / phi
        i0 = I0 * phi
        I1 = math.sqrt(i0 * i0 + it * it)
        self._m, self._q = m1, q
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
        E1, V = E, self._V
    # ---- state, protections --------------------------------------------------------------
    self._w, self._T, self._I, self._P, self._E, self._V = w1, T1, I1, P, E1, V
    changed = srch and not self._ss  # a speed search found the motor speed
    if ol1:
        i2 = I1 / Ir
        i2 *= i2
        th = self._theta
        th += (i2 - th) * h / tau
        self._theta = th
        if th >= OL1_TRIP_LEVEL and out:
            self._trip_now(Fault.OL1, StopMethod.COAST)
            changed = True
    if out:
        if I1 >= oc:
            self._trip_now(Fault.OC, StopMethod.COAST)
            changed = True
        if V >= ov:
            self._trip_now(Fault.OV, StopMethod.COAST)
            changed = True
        if not mains and V < uv:
            self._trip_now(Fault.UV1, StopMethod.COAST)
            changed = True
        ha, hd = I1 >= acc_lvl, V >= dec_lvl
        if ha != self._hold_acc or hd != self._hold_dec or limited != self._tlimited:
            self._hold_acc, self._hold_dec, self._tlimited = ha, hd, limited
        if not self._run and m1 == 0.0 and q == 0.0:
            changed = True  # stop completed: baseblock
        if self._ss_hi is not None and not changed:
            changed = restart_watch(self, h, I1)
    dyn = self._dyn
    if dyn or V >= ov or (not mains and V < uv):
        nd = set()
        if V >= ov and not out:
            nd.add(Fault.OV)
        if not mains and V < uv and not out:
            nd.add(Fault.UV)
        if frozenset(nd) != dyn:
            self._dyn = frozenset(nd)
            changed = True
    if changed:
        self._recompute()
        return
    self._status = None
    if not srch and E1 == E and (w1 == w or -1e-9 * (1.0 + abs(w)) <= w1 - w <= 1e-9 * (1.0 + abs(w))):
        if not out or (m1 == m0 and q == 0.0 and self._dt == self._dir):
            self._steady = True
            self.steady_epoch += 1


def search_step(self: Drive, h: float, w: float) -> float:
    """One sub-step of a speed search; returns the output current.  ``w``: shaft speed at the step's end.

    Phase 1 (b3-05 delay, b3-25 wait): output off.  Then Speed Estimation (b3-24 = 1) outputs the rotor's
    own electrical frequency, in its direction.  Current Detection sweeps the output down from the start
    frequency at E1-04 / b3-03 Hz/s with the current held at the b3-02 level; at full V/f voltage the
    motor would draw ``I = phi sqrt(I0^2 + (I_T s / s_r)^2)`` at slip ``s`` (section 4), so the current
    drops below b3-02 where ``s = s_r sqrt((I_b302 / phi)^2 - I0^2) / I_T``: the output resumes there.
    """
    rate, level, _ = self._ss_k
    d = self._dir
    if self._ss == 1:
        self._ss_wait -= h
        self._fout = 0.0
        if self._ss_wait > 1e-12:
            return 0.0
        if self.settings.search.estimation:
            fr = w / self._wph
            if fr:
                d = 1 if fr > 0.0 else -1
            fr = min(abs(fr), self.settings.max_freq_hz)
            _resume(self, fr, d)
            return self._I0 * (self._fb / fr if fr > self._fb else 1.0)
        self._ss = 2
        self._fout = d * self._ss_f
        return level
    f0 = self._ss_f
    f1 = f0 - rate * h
    if f1 < 0.0:
        f1 = 0.0
    fr = d * w / self._wph  # rotor electrical frequency in the search direction
    lim = level / (self._fb / f1) if f1 > self._fb else level
    x = lim * lim - self._I0 * self._I0
    if x > 0.0:
        s_th = self.settings.motor_rated_slip_hz * math.sqrt(x) / self._IT
        if f1 - fr <= s_th:
            _resume(self, min(max(fr + s_th, f1), f0), d)
            return level
    if f1 == 0.0:  # swept to 0 Hz without finding it (e.g. turning the other way): a plain start
        _resume(self, 0.0, d)
        return 0.0
    self._ss_f = f1
    self._fout = d * f1
    return level


def _resume(self: Drive, f: float, d: int) -> None:
    """Output on at ``f`` Hz in direction ``d``; the ramp goes on from there.  Watch b3-17 from now."""
    self._ss = 0
    self._m, self._q, self._dir = f, 0.0, d
    self._fout = d * f
    self._ss_hi = 0.0
    self._event("speed_search", f"found {f:.2f} Hz")


def restart_watch(self: Drive, h: float, i: float) -> bool:
    """After a search: current >= b3-17 for b3-18 restarts it (after the b3-25 wait); more than b3-19
    restarts trip SEr (SI-T3 Table 26, 3BH).  The first step below b3-17 ends the watch and the count."""
    ss = self.settings.search
    if i < self._ss_k[2]:
        self._ss_hi = None
        self._ss_n = 0
        return False
    hi = self._ss_hi = (self._ss_hi or 0.0) + h
    if hi < ss.restart_s - 1e-12:
        return False
    self._ss_n += 1
    if self._ss_n > ss.restarts:
        self._ss_hi = None
        self._trip_now(Fault.SER, StopMethod.COAST)
    else:
        self._begin_search(self._ss_start, ss.wait_s)
    return True
