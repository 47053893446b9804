"""Ball drop dynamics integrated numerically through flights *and* contacts.

The ball (mass m in kg, radius R in m) moves in a vertical plane: centre
height y (m, up) and horizontal coordinate x (m), velocities v and u (m/s),
spin w (rad/s, counter-clockwise positive).  Internally the height is the
centre's height above the contact height, z = y - (floor + R) in m, so that
the penetration is delta = -z without cancellation.

Flight
    m a = -m g e_y - 1/2 rho C_d A |V| V        (A = pi R^2, V = (u, v))
    i.e. a = -g e_y - k |V| V with k = rho C_d A / (2 m) in 1/m.
Contact (delta > 0)
    m dv/dt = -m g - m k |V| v + F_n,  F_n = max(0, law(delta, delta_dot)),
    and, with a Coulomb friction coefficient mu > 0, a tangential force
    -mu F_n sign(slip) while the contact point slips (slip = u + w R), the
    ball rolling (slip locked at 0) once the slip has vanished.

Everything is integrated with :func:`scipy.integrate.solve_ivp` (DOP853,
rtol 1e-10, atol 1e-12 by default), event by event: touchdown (z = 0
downward), force zero (the law's force returns to 0 while delta > 0),
separation (z = 0 upward), apex (v = 0 downward), maximum penetration, slip
stop, and rest (see :func:`simulate`).  No closed-form flight and no
instantaneous impact is used anywhere.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from types import SimpleNamespace

import numpy as np
import pandas as pd
from scipy.integrate import solve_ivp
from scipy.optimize import minimize_scalar

from .contact import ContactLaw, HertzDamped, HuntCrossley, LinearSpringDamper
from .hand import Catch, HandPhase

__all__ = ["Ball", "PRESETS", "preset", "simulate", "impact_response", "Truth", "G_DEFAULT"]

G_DEFAULT = 9.81  # m/s^2; deliberately not 9.80665 so that tests pass g explicitly


@dataclass(frozen=True)
class Ball:
    """A ball and its contact with the floor.

    Parameters
    ----------
    name : str
        Label.
    mass_kg : float
        Mass m in kg.
    radius_m : float
        Radius R in m.
    contact : ContactLaw
        Normal contact law (see :mod:`refsim.contact`).
    drag_coefficient : float
        C_d (dimensionless), constant.  0 disables drag.
    air_density_kg_m3 : float
        Air density rho in kg/m^3.
    friction_coefficient : float
        Coulomb friction mu with the floor (dimensionless); 0: frictionless.
    inertia_factor : float
        I = inertia_factor m R^2 (0.4 solid sphere, 2/3 thin shell).
    """

    name: str
    mass_kg: float
    radius_m: float
    contact: ContactLaw
    drag_coefficient: float = 0.5
    air_density_kg_m3: float = 1.2
    friction_coefficient: float = 0.0
    inertia_factor: float = 0.4

    @property
    def area_m2(self) -> float:
        """Cross-section pi R^2 in m^2."""
        return math.pi * self.radius_m**2

    @property
    def drag_k_1_m(self) -> float:
        """Quadratic-drag parameter k = rho C_d A / (2 m) in 1/m."""
        return self.air_density_kg_m3 * self.drag_coefficient * self.area_m2 / (2.0 * self.mass_kg)

    def without_drag(self) -> "Ball":
        """A copy with C_d = 0."""
        return replace(self, drag_coefficient=0.0)

    def undamped(self) -> "Ball":
        """A copy with the contact damping set to zero (e -> 1)."""
        return replace(self, contact=self.contact.undamped())

    def with_contact(self, law: ContactLaw) -> "Ball":
        """A copy with another contact law."""
        return replace(self, contact=law)


# ---------------------------------------------------------------------------------------
# Presets.  K, C / alpha / c calibrated with refsim.calibrate (see README for e(v), T(v)).
# ---------------------------------------------------------------------------------------
PRESETS: dict[str, Ball] = {
    # ITF-like tennis ball: e(7.06 m/s) = 0.75, contact 4.5 ms at 7.06 m/s
    "tennis": Ball("tennis", 0.057, 0.0335, HertzDamped(K=3.201e5, C=113.1),
                   drag_coefficient=0.55, friction_coefficient=0.6, inertia_factor=0.55),
    # steel ball bearing on a hard (stone) floor: e(3 m/s) = 0.90, contact 0.15 ms at 3 m/s
    "steel": Ball("steel", 0.0642, 0.0125, HertzDamped(K=2.570e9, C=1.099e4),
                  drag_coefficient=0.47, friction_coefficient=0.2, inertia_factor=0.4),
    # solid rubber ("bouncy") ball: e(4 m/s) ~ 0.85, contact ~ 1 ms
    "rubber": Ball("rubber", 0.055, 0.0225, HuntCrossley(K=1.694e7, alpha=0.0439),
                   drag_coefficient=0.47, friction_coefficient=0.8, inertia_factor=0.4),
    # table-tennis ball (thin shell, near-linear): e = 0.89, contact 1.0 ms, strong drag
    "table_tennis": Ball("table_tennis", 0.0027, 0.02, LinearSpringDamper(k=2.673e4, c=0.6435),
                         drag_coefficient=0.5, friction_coefficient=0.3, inertia_factor=2.0 / 3.0),
    # glass marble on a stack of paper: e(1.4 m/s) ~ 0.70 -> 0.51 at 3 m/s, contact ~ 1 ms at 2 m/s
    "marble_paper": Ball("marble_paper", 0.0054, 0.008, HuntCrossley(K=2.671e6, alpha=0.3001),
                         drag_coefficient=0.47, friction_coefficient=0.4, inertia_factor=0.4),
}


def preset(name: str) -> Ball:
    """Return the preset ball ``name`` (one of :data:`PRESETS`)."""
    try:
        return PRESETS[name]
    except KeyError:
        raise KeyError(f"unknown preset {name!r}; choose from {sorted(PRESETS)}") from None


def _event(fn, terminal: bool, direction: float):
    fn.terminal = terminal
    fn.direction = direction
    return fn


class _Dynamics:
    """Right-hand sides and event functions for one ball, g and rest threshold."""

    def __init__(self, ball: Ball, g: float, h_rest: float, rtol: float, atol: float):
        self.ball = ball
        self.g = g
        self.h_rest = h_rest
        self.rtol = rtol
        self.atol = atol
        self.m = m = ball.mass_kg
        self.R = R = ball.radius_m
        self.k = k = ball.drag_k_1_m
        self.mu = mu = ball.friction_coefficient
        self.I = I = ball.inertia_factor * m * R * R
        law = ball.contact
        self.law = law
        # integrate the first contact phase in q = sqrt(t - t_touchdown) for laws with
        # fractional powers of delta (not for the linear law, analytic in t)
        self.sqrt_start = not isinstance(law, LinearSpringDamper)
        f = law.scalar_force()
        hsign = law.sign_expr()
        hypot = math.hypot
        arr = np.array

        def rhs_free(t, s):
            u = s[2]
            v = s[3]
            sp = hypot(u, v)
            return arr([u, v, -k * sp * u, -g - k * sp * v, 0.0])

        self.rhs_free = rhs_free

        def make_contact_rhs(mode):
            # mode: 0 no friction, +1/-1 sliding with slip sign, 2 rolling (slip locked)
            def rhs(t, s):
                u = s[2]
                v = s[3]
                sp = hypot(u, v)
                ax = -k * sp * u
                ay = -g - k * sp * v
                wdot = 0.0
                d = -s[1]
                if d > 0.0:
                    # unclipped: this RHS is only used until the force-zero event, and its smooth
                    # continuation past the event keeps the steps that straddle it accurate
                    F = f(d, -v)
                    ay += F / m
                    if mode == 1 or mode == -1:
                        Ft = -mu * F * mode
                        ax += Ft / m
                        wdot = R * Ft / I
                if mode == 2:
                    # rolling: tangential force keeps u + w R = 0 against the drag
                    Dx = m * ax
                    Ft = -Dx / (1.0 + m * R * R / I)
                    ax = (Dx + Ft) / m
                    wdot = R * Ft / I
                return arr([u, v, ax, ay, wdot])

            return rhs

        self.rhs_contact = {mode: make_contact_rhs(mode) for mode in (0, 1, -1, 2)}

        def make_settle_rhs():
            def rhs(t, s):
                u = s[2]
                v = s[3]
                sp = hypot(u, v)
                ay = -g - k * sp * v
                d = -s[1]
                if d > 0.0:
                    F = f(d, -v)
                    if F > 0.0:
                        ay += F / m
                return arr([u, v, -k * sp * u, ay, 0.0])

            return rhs

        self.rhs_settle = make_settle_rhs()

        # -- events ------------------------------------------------------------------
        self.ev_touchdown = lambda: _event(lambda t, s: s[1], True, -1.0)
        self.ev_separation = lambda: _event(lambda t, s: s[1], True, 1.0)
        self.ev_apex = lambda terminal=False: _event(lambda t, s: s[3], terminal, -1.0)
        self.ev_vmin = lambda: _event(lambda t, s: s[3], False, 1.0)
        self.ev_force_zero = lambda: _event(lambda t, s: hsign(-s[1], -s[3]), True, -1.0)
        self.ev_force_on = lambda: _event(lambda t, s: hsign(-s[1], -s[3]), True, 1.0)
        self.ev_slip = lambda: _event(lambda t, s: s[2] + s[4] * R, True, 0.0)
        U = law.elastic_energy
        mg = m * g

        def energy_height(s):
            """Energy bound above the contact height, as a height in m."""
            d = -s[1]
            e = 0.5 * s[3] * s[3] / g + s[1]
            if d > 0.0:
                e += float(U(d)) / mg
            return e

        self.energy_height = energy_height
        self.ev_rest = lambda: _event(lambda t, s: energy_height(s) - h_rest, True, -1.0)

    def solve(self, rhs, t0, t1, s0, events, max_step=np.inf):
        return solve_ivp(rhs, (t0, t1), s0, method="DOP853", rtol=self.rtol, atol=self.atol,
                         events=events, dense_output=True, max_step=max_step)

    def solve_from_touchdown(self, rhs, t0, t1, s0, events):
        """Integrate from a touchdown in the variable q = sqrt(t - t0).

        Near a touchdown delta ~ v (t - t0), so delta^(1/2) (and delta^(3/2))
        are not smooth in t but are analytic in q; DOP853 then needs fewer
        steps and is more accurate.  Returns an object like solve_ivp's with
        times converted back to t and a dense output callable in t.
        """

        def rhs_q(q, s):
            return (2.0 * q) * rhs(t0 + q * q, s)

        sol = solve_ivp(rhs_q, (0.0, math.sqrt(t1 - t0)), s0, method="DOP853", rtol=self.rtol, atol=self.atol,
                        events=events, dense_output=True)
        qsol = sol.sol

        def dense(t):
            return qsol(np.sqrt(np.maximum(np.asarray(t, dtype=float) - t0, 0.0)))

        t_events = None
        if sol.t_events is not None:
            t_events = [t0 + np.asarray(te) ** 2 for te in sol.t_events]
        t = t0 + sol.t**2
        t[-1] = t1 if sol.status == 0 else t[-1]
        return SimpleNamespace(t=t, y=sol.y, sol=dense, t_events=t_events, y_events=sol.y_events,
                               status=sol.status, message=sol.message, nfev=sol.nfev)

    def force_of(self, states):
        """Clipped normal force in N for states of shape (5, n)."""
        d = -states[1]
        F = self.law.force(d, -states[3])
        return np.where(d > 0.0, np.maximum(F, 0.0), 0.0)

    def friction_mode(self, s) -> int:
        if self.mu <= 0.0:
            return 0
        slip = s[2] + s[4] * self.R
        if abs(slip) <= 1e-9 * max(1.0, abs(s[2])):
            return 2
        return 1 if slip > 0 else -1


def _fired(sol, index) -> bool:
    te = sol.t_events[index]
    return len(te) > 0 and te[-1] == sol.t[-1]


@dataclass
class _ContactResult:
    status: str  # "separated", "rest", "stopped"
    t_end: float
    s_end: np.ndarray
    segments: list
    t_force_zero: float
    v_force_zero: float
    max_pen: float
    t_max_pen: float
    peak_force: float
    t_peak_force: float


def _integrate_contact(dyn: _Dynamics, t0: float, s0: np.ndarray, t_stop: float, use_rest: bool) -> _ContactResult:
    """Integrate one contact from touchdown (z = 0, v < 0) to separation, rest or t_stop."""
    segments = []
    t, s = t0, np.array(s0, dtype=float)
    regime = "force"
    first = True
    forced_mode = None  # set to 2 (rolling) once a slip-stop event has fired
    t_fz = math.nan
    v_fz = math.nan
    max_pen, t_max_pen = 0.0, t0
    peak_F, t_peak_F = 0.0, t0
    status = None
    if use_rest and dyn.energy_height(s) < dyn.h_rest:
        return _ContactResult("rest", t0, s, [], math.nan, math.nan, 0.0, t0, 0.0, t0)
    for _ in range(10000):
        if regime == "force":
            mode = forced_mode if forced_mode is not None else dyn.friction_mode(s)
            events = [dyn.ev_force_zero(), dyn.ev_separation(), dyn.ev_vmin()]
            if use_rest:
                events.append(dyn.ev_rest())
            if mode in (1, -1):
                events.append(dyn.ev_slip())
            if mode == 2:
                s = s.copy()
                s[4] = -s[2] / dyn.R
            if first and dyn.sqrt_start:
                sol = dyn.solve_from_touchdown(dyn.rhs_contact[mode], t, t_stop, s, events)
            else:
                sol = dyn.solve(dyn.rhs_contact[mode], t, t_stop, s, events)
            first = False
        else:
            events = [dyn.ev_force_on(), dyn.ev_separation()]
            if use_rest:
                events.append(dyn.ev_rest())
            sol = dyn.solve(dyn.rhs_free, t, t_stop, s, events)
        t1 = float(sol.t[-1])
        segments.append((t, t1, sol.sol, "contact" if regime == "force" else "contact_free"))
        s_end = sol.y[:, -1].copy()
        if regime == "force":
            for te, ye in zip(sol.t_events[2], sol.y_events[2]):
                if -ye[1] > max_pen:
                    max_pen, t_max_pen = -ye[1], float(te)
            # peak force on this sub-segment: dense sampling then a bounded refinement
            if t1 > t:
                tg = np.linspace(t, t1, 129)
                Fg = dyn.force_of(sol.sol(tg))
                i = int(np.argmax(Fg))
                lo, hi = tg[max(i - 1, 0)], tg[min(i + 1, tg.size - 1)]
                if hi > lo:
                    r = minimize_scalar(lambda tt: -dyn.force_of(sol.sol(tt).reshape(5, 1))[0],
                                        bounds=(lo, hi), method="bounded",
                                        options={"xatol": 1e-14 * max(1.0, abs(t1))})
                    Fi, ti = -float(r.fun), float(r.x)
                    if Fg[i] > Fi:
                        Fi, ti = float(Fg[i]), float(tg[i])
                else:
                    Fi, ti = float(Fg[i]), float(tg[i])
                if Fi > peak_F:
                    peak_F, t_peak_F = Fi, ti
        if sol.status == 0:  # reached t_stop
            status = "stopped"
            t, s = t1, s_end
            break
        if sol.status < 0:
            raise RuntimeError(f"solve_ivp failed in contact at t={t}: {sol.message}")
        if regime == "force":
            if _fired(sol, 1):  # separation while the force is still on (undamped laws)
                t_fz, v_fz = t1, float(s_end[3])
                status = "separated"
            elif _fired(sol, 0):
                t_fz, v_fz = t1, float(s_end[3])
                regime = "free"
                if s_end[1] > -1e-15 and s_end[3] > 0.0:
                    # the force vanished at delta = 0 itself (undamped laws): separation now
                    status = "separated"
            elif use_rest and _fired(sol, 3):
                status = "rest"
            else:  # slip stopped -> stay in the force regime, rolling from now on
                forced_mode = 2
        else:
            if _fired(sol, 1):
                status = "separated"
            elif _fired(sol, 0):
                regime = "force"
                forced_mode = None
            elif use_rest and _fired(sol, 2):
                status = "rest"
        t, s = t1, s_end
        if status is not None:
            break
    else:  # pragma: no cover
        raise RuntimeError("too many contact sub-phases")
    if status == "separated":
        s = s.copy()
        s[1] = 0.0
    return _ContactResult(status, t, s, segments, t_fz, v_fz, max_pen, t_max_pen, peak_F, t_peak_F)


def impact_response(ball: Ball, v_in_m_s: float, *, g_m_s2: float = G_DEFAULT, u_in_m_s: float = 0.0,
                    spin_in_rad_s: float = 0.0, rtol: float = 1e-10, atol: float = 1e-12,
                    t_max_s: float = 0.1) -> dict:
    """Integrate a single contact starting at touchdown with normal speed ``v_in_m_s``.

    Parameters
    ----------
    ball : Ball
        The ball (its drag acts during the contact too).
    v_in_m_s : float
        Normal (downward) speed at touchdown in m/s (> 0).
    g_m_s2 : float
        Gravity in m/s^2 (0 for the pure impact problem).
    u_in_m_s, spin_in_rad_s : float
        Tangential velocity (m/s) and spin (rad/s) at touchdown.
    rtol, atol : float
        solve_ivp tolerances.
    t_max_s : float
        Give up (NaN results) if the ball has not separated after this time (s).

    Returns
    -------
    dict
        ``e`` (v_out/v_in at z = 0 crossings), ``v_out_m_s``,
        ``contact_time_s`` (delta = 0 down to delta = 0 up),
        ``contact_time_force_s`` (touchdown to force zero), ``v_force_zero_m_s``,
        ``peak_force_N``, ``max_penetration_m``, ``u_out_m_s``,
        ``spin_out_rad_s``.  NaN values if the ball does not separate within
        ``t_max_s`` (at very low speed gravity can keep it on the floor).
    """
    dyn = _Dynamics(ball, g_m_s2, 0.0, rtol, atol)
    s0 = np.array([0.0, 0.0, u_in_m_s, -abs(v_in_m_s), spin_in_rad_s])
    r = _integrate_contact(dyn, 0.0, s0, t_max_s, use_rest=False)
    ok = r.status == "separated"
    nan = math.nan
    return {
        "v_in_m_s": abs(v_in_m_s),
        "v_out_m_s": float(r.s_end[3]) if ok else nan,
        "e": float(r.s_end[3]) / abs(v_in_m_s) if ok else nan,
        "contact_time_s": r.t_end if ok else nan,
        "contact_time_force_s": r.t_force_zero if ok else nan,
        "v_force_zero_m_s": r.v_force_zero if ok else nan,
        "peak_force_N": r.peak_force,
        "max_penetration_m": r.max_pen,
        "u_out_m_s": float(r.s_end[2]) if ok else nan,
        "spin_out_rad_s": float(r.s_end[4]) if ok else nan,
    }


# ---------------------------------------------------------------------------------------
# The ground truth
# ---------------------------------------------------------------------------------------
class Truth:
    """Ground truth of one simulated drop, evaluable at any time.

    Attributes (all times in s on this truth's clock, see :meth:`shifted`)
    ----------
    ball : Ball
    g_m_s2 : float
        Gravity used, m/s^2.
    drag_k_1_m : float
        k = rho C_d A / (2 m), 1/m.
    floor_m : float
        Floor height, m.
    radius_m, mass_kg : float
    contact_height_m : float
        floor + R, m: the centre's height at touchdown / separation.
    t_release_s : float
        Release time (s).
    y_release_centre_m : float
        Centre height at the release (m, absolute).
    release_bottom_height_m : float
        Bottom of the ball above the floor at release (m) -- the drop height.
    v_release_m_s, u_release_m_s : float
        Vertical / horizontal velocity at the release (m/s); non-zero when
        released from a moving hand.
    h_drop_apex_m : float
        Highest rise of the centre above the contact height in the first
        flight (m); equals the release height unless released moving up.
    impacts : pandas.DataFrame
        One row per completed impact (touchdown to separation), columns:
        ``impact`` (1-based), ``t_touchdown_s`` (delta = 0 downward),
        ``t_force_zero_s`` (the contact force returns to zero: the lift-off
        *by force*; the ball may still be pressed in), ``t_liftoff_s``
        (delta = 0 upward: geometric separation), ``contact_time_s`` =
        t_liftoff - t_touchdown, ``contact_time_force_s`` = t_force_zero -
        t_touchdown, ``v_in_m_s`` (normal speed at touchdown, > 0),
        ``v_force_zero_m_s`` (vertical velocity at force zero),
        ``v_out_m_s`` (vertical velocity at delta = 0 upward), ``e`` =
        v_out/v_in, ``u_in_m_s``, ``u_out_m_s`` (horizontal velocities),
        ``spin_in_rad_s``, ``spin_out_rad_s``, ``x_touchdown_m``,
        ``t_apex_before_s``, ``h_before_m``, ``t_apex_after_s``,
        ``h_after_m`` (centre's highest rise above the contact height in the
        flights before / after, m), ``peak_force_N``, ``t_peak_force_s``,
        ``max_penetration_m``, ``t_max_penetration_s``.
    flights : pandas.DataFrame
        One row per flight (flight 0 starts at the release, flight n at the
        separation of impact n): ``flight``, ``t_start_s``, ``t_end_s``,
        ``end`` ("touchdown", "catch", "t_end"), ``t_apex_s``, ``h_apex_m``
        (centre above contact height), ``y_apex_centre_m``, ``x_apex_m``,
        ``apex_is_turning_point`` (False when the flight never rises, e.g. a
        release at rest: the highest point is then the start).
    rest_time_s : float
        The time the ball's mechanical energy bound (kinetic + potential
        above the contact height + elastic energy stored) falls below
        m g h_rest: after it the centre never rises more than ``h_rest_m``
        above the contact height.  NaN if the ball did not come to rest.
    t_final_touchdown_s : float
        Touchdown of the contact during which the ball comes to rest.
    t_settled_s : float
        From this time on the ball is held exactly at static equilibrium
        (the integration of the settling converged there to < settle_tol_m,
        1e-8 m by default, or lasted settle_periods / settle_max_s; the jump
        at the snap is ``settle_residual_m``).
    y_rest_centre_m, delta_static_m : float
        Equilibrium centre height and static penetration (m).
    t_catch_s : float
        Time a hand caught the ball (NaN if none).
    t_end_s : float
        The simulation's end; evaluating later raises unless the ball rests
        or was caught.
    time_offset_s : float
        Offset added to the simulation clock for every reported time.

    Notes
    -----
    Heights of the logged points: ``top`` = centre + R; ``bottom`` =
    max(floor, centre - R), i.e. during contact the (deformed) bottom lies
    on the floor.
    """

    def __init__(self, **kw):
        self.__dict__.update(kw)

    # -- time base -----------------------------------------------------------------------
    def shifted(self, offset_s: float) -> "Truth":
        """A copy whose reported times (tables, scalars, evaluation) are shifted by ``offset_s`` (s)."""
        new = Truth(**self.__dict__)
        new.time_offset_s = self.time_offset_s + offset_s
        new.impacts = self.impacts.copy()
        new.flights = self.flights.copy()
        for df in (new.impacts, new.flights):
            for c in df.columns:
                if c.startswith("t_") and c.endswith("_s"):
                    df[c] = df[c] + offset_s
        for c in list(new.__dict__):
            if c.startswith("t_") and c.endswith("_s"):
                setattr(new, c, getattr(self, c) + offset_s)
        new.rest_time_s = self.rest_time_s + offset_s
        return new

    def _local(self, t):
        return np.atleast_1d(np.asarray(t, dtype=float)) - self.time_offset_s

    # -- evaluation ----------------------------------------------------------------------
    def _state_local(self, tl: np.ndarray):
        """State (x, z, u, v, w) at local times, and the phase label index."""
        out = np.empty((5, tl.size))
        starts = self._seg_starts
        idx = np.searchsorted(starts, tl, side="right") - 1
        idx = np.clip(idx, 0, len(self._segments) - 1)
        phase = np.empty(tl.size, dtype=object)
        for j in np.unique(idx):
            sel = idx == j
            t0, t1, fn, label = self._segments[j]
            if label == "beyond_end":
                bad = tl[sel]
                raise ValueError(f"times up to {bad.max() + self.time_offset_s:.6g} s lie after the simulation "
                                 f"end t_end_s={self.t_end_s:.6g} s (ball not at rest)")
            out[:, sel] = fn(tl[sel])
            phase[sel] = label
        return out, phase

    def sample(self, t) -> pd.DataFrame:
        """Everything at times ``t`` (s): DataFrame with ``t_s``, ``x_m``,
        ``y_centre_m``, ``y_bottom_m``, ``y_top_m``, ``u_m_s``, ``v_m_s``,
        ``spin_rad_s``, ``force_N`` (normal contact force), ``phase``."""
        tl = self._local(t)
        st, phase = self._state_local(tl)
        yc = st[1] + self.contact_height_m
        F = np.where(np.isin(phase, ["contact", "contact_free", "settle", "rest"]), self._dyn.force_of(st), 0.0)
        F = np.where(phase == "rest", self.mass_kg * self.g_m_s2, F)
        return pd.DataFrame({
            "t_s": tl + self.time_offset_s,
            "x_m": st[0],
            "y_centre_m": yc,
            "y_bottom_m": self.floor_m + np.maximum(st[1], 0.0),
            "y_top_m": yc + self.radius_m,
            "u_m_s": st[2],
            "v_m_s": st[3],
            "spin_rad_s": st[4],
            "force_N": F,
            "phase": phase,
        })

    def y_centre(self, t) -> np.ndarray:
        """Centre height (m, absolute) at times ``t`` (s)."""
        st, _ = self._state_local(self._local(t))
        return st[1] + self.contact_height_m

    def y_bottom(self, t) -> np.ndarray:
        """Lowest point of the ball (m): max(floor, centre - R)."""
        st, _ = self._state_local(self._local(t))
        return self.floor_m + np.maximum(st[1], 0.0)

    def y_top(self, t) -> np.ndarray:
        """Top of the ball (m): centre + R."""
        return self.y_centre(t) + self.radius_m

    def y_point(self, t, point: str = "centre") -> np.ndarray:
        """Height (m) of ``point`` in {"bottom", "centre", "top"} at times ``t`` (s)."""
        if point in ("centre", "center"):
            return self.y_centre(t)
        if point == "bottom":
            return self.y_bottom(t)
        if point == "top":
            return self.y_top(t)
        raise ValueError(f"point must be bottom, centre or top, got {point!r}")

    def x(self, t) -> np.ndarray:
        """Horizontal position of the centre (m) at times ``t`` (s)."""
        st, _ = self._state_local(self._local(t))
        return st[0]

    def v(self, t) -> np.ndarray:
        """Vertical velocity (m/s) at times ``t`` (s)."""
        st, _ = self._state_local(self._local(t))
        return st[3]

    def summary(self) -> dict:
        """Scalar ground truth as a dict (units in the keys)."""
        keys = ["t_release_s", "y_release_centre_m", "release_bottom_height_m", "v_release_m_s", "u_release_m_s",
                "h_drop_apex_m", "g_m_s2", "drag_k_1_m", "floor_m", "radius_m", "mass_kg", "contact_height_m",
                "rest_time_s", "t_final_touchdown_s", "t_settled_s", "y_rest_centre_m", "delta_static_m",
                "t_catch_s", "t_end_s", "h_rest_m", "settle_residual_m", "time_offset_s", "n_impacts", "status"]
        d = {k: getattr(self, k) for k in keys if k != "n_impacts"}
        d["n_impacts"] = len(self.impacts)
        return d

    def __repr__(self):
        return (f"Truth(ball={self.ball.name!r}, impacts={len(self.impacts)}, status={self.status!r}, "
                f"rest_time_s={self.rest_time_s:.6g})")


_IMPACT_COLUMNS = [
    "impact", "t_touchdown_s", "t_force_zero_s", "t_liftoff_s", "contact_time_s", "contact_time_force_s",
    "v_in_m_s", "v_force_zero_m_s", "v_out_m_s", "e", "u_in_m_s", "u_out_m_s", "spin_in_rad_s",
    "spin_out_rad_s", "x_touchdown_m", "t_apex_before_s", "h_before_m", "t_apex_after_s", "h_after_m",
    "peak_force_N", "t_peak_force_s", "max_penetration_m", "t_max_penetration_s",
]
_FLIGHT_COLUMNS = ["flight", "t_start_s", "t_end_s", "end", "t_apex_s", "h_apex_m", "y_apex_centre_m",
                   "x_apex_m", "apex_is_turning_point"]


def simulate(ball: Ball | str, drop_height_m: float = 1.0, *, g_m_s2: float = G_DEFAULT, floor_m: float = 0.0,
             t_release_s: float = 0.0, v0_m_s: float | None = None, x0_m: float = 0.0, u0_m_s: float = 0.0,
             spin0_rad_s: float = 0.0, hand: HandPhase | None = None, catch: Catch | None = None,
             t_end_s: float = 10.0, h_rest_m: float = 1e-5, rtol: float = 1e-10, atol: float = 1e-12,
             max_impacts: int = 1000, settle_max_s: float = 1.0, settle_periods: float = 30.0,
             settle_tol_m: float = 1e-8) -> Truth:
    """Simulate a drop by integrating flights and contacts with solve_ivp.

    Parameters
    ----------
    ball : Ball or str
        The ball, or a preset name.
    drop_height_m : float
        Height of the ball's bottom above the floor at the release (m).
    g_m_s2 : float
        Gravity (m/s^2), default 9.81.
    floor_m : float
        Floor height (m).
    t_release_s : float
        Release time on the simulation clock (s).
    v0_m_s : float or None
        Vertical velocity at the release (m/s).  Default: the hand's velocity
        at the release if ``hand`` is given, else 0.
    x0_m, u0_m_s : float
        Horizontal position (m) and velocity (m/s) at the release.
    spin0_rad_s : float
        Spin at release (rad/s, counter-clockwise positive).
    hand : HandPhase or None
        Hand phase before the release (track before ``t_release_s``); the
        ball leaves with the hand's velocity.  Without a hand the ball is
        shown held still before the release (give a hand for a release with
        velocity that is consistent before and after).
    catch : Catch or None
        A hand catching the ball; the simulation stops there and the track
        follows the hand afterwards.
    t_end_s : float
        Simulation end (s) if the ball has not come to rest.
    h_rest_m : float
        Rest threshold (m): once the energy bound of the ball corresponds to
        a rise below this, the ball is "at rest"; its remaining tiny motion
        is integrated (settling, same equations, no event bookkeeping) and it
        is then held at static equilibrium.
    rtol, atol : float
        solve_ivp tolerances (DOP853).
    max_impacts : int
        Safety cap on the number of impacts.
    settle_max_s : float
        Longest settling integration (s) before snapping to equilibrium.
    settle_periods : float
        ... or after this many periods 2 pi / omega_eq of the small
        oscillation about the equilibrium (omega_eq^2 = F'(delta_static)/m).
    settle_tol_m : float
        The settling stops (and the ball is held at the static equilibrium)
        once |z - z_eq| + |v| / omega_eq < settle_tol_m (m); the track jumps
        by less than that.

    Returns
    -------
    Truth
    """
    if isinstance(ball, str):
        ball = preset(ball)
    if drop_height_m <= 0:
        raise ValueError("drop_height_m must be > 0 (ball above the floor)")
    if hand is not None and v0_m_s is None:
        v0 = hand.release_velocity()
    else:
        v0 = 0.0 if v0_m_s is None else float(v0_m_s)
    dyn = _Dynamics(ball, g_m_s2, h_rest_m, rtol, atol)
    R, m = ball.radius_m, ball.mass_kg
    contact_h = floor_m + R
    t_rel = float(t_release_s)
    s0 = np.array([x0_m, drop_height_m, u0_m_s, v0, spin0_rad_s])
    use_rest = g_m_s2 > 0 and h_rest_m > 0
    catch_flight = None
    t_stop = t_end_s
    if catch is not None:
        if catch.after_impact is not None:
            catch_flight = int(catch.after_impact)
        else:
            t_stop = min(t_end_s, float(catch.t_s))

    segments: list = []
    flights: list[dict] = []
    impacts: list[dict] = []
    t, s = t_rel, s0
    status = "t_end"
    t_rest = math.nan
    t_final_td = math.nan
    s_rest = None
    t_catch = math.nan
    fl_index = 0
    while True:
        apex_terminal = catch_flight is not None and fl_index == catch_flight
        events = [dyn.ev_touchdown(), dyn.ev_apex(apex_terminal)]
        sol = dyn.solve(dyn.rhs_free, t, t_stop, s, events)
        if sol.status < 0:
            raise RuntimeError(f"solve_ivp failed in flight at t={t}: {sol.message}")
        t1 = float(sol.t[-1])
        segments.append((t, t1, sol.sol, "flight"))
        s1 = sol.y[:, -1].copy()
        fl = {"flight": fl_index, "t_start_s": t, "t_end_s": t1}
        if len(sol.t_events[1]):
            ta, ya = float(sol.t_events[1][0]), sol.y_events[1][0]
            fl.update(t_apex_s=ta, h_apex_m=float(ya[1]), x_apex_m=float(ya[0]), apex_is_turning_point=True)
        elif s[3] <= 0.0:
            fl.update(t_apex_s=t, h_apex_m=float(s[1]), x_apex_m=float(s[0]), apex_is_turning_point=False)
        else:
            fl.update(t_apex_s=math.nan, h_apex_m=math.nan, x_apex_m=math.nan, apex_is_turning_point=False)
        if sol.status == 0:
            fl["end"] = "catch" if (catch is not None and t1 >= t_stop and t_stop < t_end_s) else "t_end"
            flights.append(fl)
            status = fl["end"]
            if status == "catch":
                t_catch = t1
            t, s = t1, s1
            break
        if apex_terminal and _fired(sol, 1):
            fl["end"] = "catch"
            flights.append(fl)
            status = "catch"
            t_catch = t1
            t, s = t1, s1
            break
        # touchdown
        fl["end"] = "touchdown"
        flights.append(fl)
        s1[1] = 0.0
        if len(impacts) >= max_impacts:
            status = "max_impacts"
            t, s = t1, s1
            break
        c = _integrate_contact(dyn, t1, s1, t_stop, use_rest)
        segments.extend(c.segments)
        if c.status == "separated":
            impacts.append({
                "impact": len(impacts) + 1,
                "t_touchdown_s": t1,
                "t_force_zero_s": c.t_force_zero,
                "t_liftoff_s": c.t_end,
                "contact_time_s": c.t_end - t1,
                "contact_time_force_s": c.t_force_zero - t1,
                "v_in_m_s": -float(s1[3]),
                "v_force_zero_m_s": c.v_force_zero,
                "v_out_m_s": float(c.s_end[3]),
                "e": float(c.s_end[3]) / -float(s1[3]),
                "u_in_m_s": float(s1[2]),
                "u_out_m_s": float(c.s_end[2]),
                "spin_in_rad_s": float(s1[4]),
                "spin_out_rad_s": float(c.s_end[4]),
                "x_touchdown_m": float(s1[0]),
                "peak_force_N": c.peak_force,
                "t_peak_force_s": c.t_peak_force,
                "max_penetration_m": c.max_pen,
                "t_max_penetration_s": c.t_max_pen,
            })
            t, s = c.t_end, c.s_end
            fl_index += 1
            continue
        if c.status == "rest":
            status = "rest"
            t_rest = c.t_end
            t_final_td = t1
            s_rest = c.s_end
            t, s = c.t_end, c.s_end
            break
        # stopped at t_stop inside a contact
        status = "catch" if (catch is not None and t_stop < t_end_s) else "t_end"
        if status == "catch":
            t_catch = c.t_end
        t, s = c.t_end, c.s_end
        break

    # -- settling and rest -----------------------------------------------------------------
    delta_static = ball.contact.static_penetration(m * g_m_s2) if g_m_s2 > 0 else 0.0
    z_eq = -delta_static
    t_settled = math.nan
    settle_residual = math.nan
    final_segment = None
    if status == "rest":
        kt = ball.contact.tangent_stiffness(max(delta_static, 1e-12))
        w_eq = math.sqrt(max(kt, 1e-300) / m)
        period = 2.0 * math.pi / w_eq
        chunk = 10.0 * period
        t_s, s_s = t_rest, np.array(s_rest, dtype=float)
        t_lim = min(t_end_s, t_rest + settle_max_s, t_rest + settle_periods * period)
        while True:
            t_to = min(t_s + chunk, t_lim)
            if t_to <= t_s:
                break
            sol = solve_ivp(dyn.rhs_settle, (t_s, t_to), s_s, method="DOP853", rtol=max(rtol, 1e-9),
                            atol=atol, dense_output=True)
            segments.append((t_s, t_to, sol.sol, "settle"))
            t_s, s_s = t_to, sol.y[:, -1].copy()
            amp = abs(s_s[1] - z_eq) + abs(s_s[3]) / w_eq
            if amp < settle_tol_m or t_s >= t_lim:
                break
        settle_residual = abs(s_s[1] - z_eq)
        t_settled = t_s
        x_r, u_r, w_r = float(s_s[0]), float(s_s[2]), float(s_s[4])

        def rest_fn(tt, x_r=x_r, u_r=u_r, w_r=w_r, t0=t_settled):
            n = np.size(tt)
            return np.vstack([x_r + u_r * (tt - t0), np.full(n, z_eq), np.full(n, u_r), np.zeros(n), np.full(n, w_r)])

        final_segment = (t_settled, np.inf, rest_fn, "rest")
        t_end_eff = t_settled
    elif status == "catch":
        s_c = np.array(s, dtype=float)

        def catch_fn(tt, s_c=s_c, t0=t):
            dx, dy, uu, vv = catch.relative(tt - t0, float(s_c[3]), float(s_c[2]))
            return np.vstack([s_c[0] + dx, s_c[1] + dy, uu, vv, np.full(np.size(tt), s_c[4])])

        final_segment = (t, np.inf, catch_fn, "caught")
        t_end_eff = t
    else:
        t_end_eff = t
        final_segment = (float(np.nextafter(t, np.inf)), np.inf, None, "beyond_end")

    # -- before the release: the hand (or the ball held still) ----------------------------------
    if hand is not None:
        def hand_fn(tt, hand=hand, x0=x0_m, z0=drop_height_m, u0=u0_m_s, w0=spin0_rad_s):
            tau = tt - t_rel
            dy, vy = hand.relative(tau)
            tau_c = np.maximum(tau, -hand.duration_s)
            return np.vstack([x0 + u0 * tau_c, z0 + dy, np.where(tau < -hand.duration_s, 0.0, u0 + 0 * tau), vy,
                              np.full(np.size(tt), w0)])
        label = "hand"
    else:
        def hand_fn(tt, x0=x0_m, z0=drop_height_m):
            n = np.size(tt)
            return np.vstack([np.full(n, x0), np.full(n, z0), np.zeros(n), np.zeros(n), np.zeros(n)])
        label = "held"
    all_segments = [(-np.inf, t_rel, hand_fn, label)] + segments + [final_segment]

    # -- tables --------------------------------------------------------------------------
    fl_df = pd.DataFrame(flights, columns=_FLIGHT_COLUMNS)
    fl_df["y_apex_centre_m"] = fl_df["h_apex_m"] + contact_h
    fl_df["apex_is_turning_point"] = fl_df["apex_is_turning_point"].astype(bool)
    for r in impacts:
        n = r["impact"]
        before = flights[n - 1]
        r["t_apex_before_s"], r["h_before_m"] = before["t_apex_s"], before["h_apex_m"]
        if n < len(flights):
            after = flights[n]
            r["t_apex_after_s"], r["h_after_m"] = after["t_apex_s"], after["h_apex_m"]
        else:
            r["t_apex_after_s"], r["h_after_m"] = math.nan, math.nan
    imp_df = pd.DataFrame(impacts, columns=_IMPACT_COLUMNS)
    imp_df["impact"] = imp_df["impact"].astype(int)
    fl_df["flight"] = fl_df["flight"].astype(int)

    first = flights[0]
    truth = Truth(
        ball=ball, g_m_s2=g_m_s2, drag_k_1_m=ball.drag_k_1_m, floor_m=floor_m, radius_m=R, mass_kg=m,
        contact_height_m=contact_h, t_release_s=t_rel, y_release_centre_m=contact_h + drop_height_m,
        release_bottom_height_m=drop_height_m, v_release_m_s=v0, u_release_m_s=u0_m_s,
        h_drop_apex_m=max(float(first["h_apex_m"]), drop_height_m) if not math.isnan(first["h_apex_m"]) else math.nan,
        impacts=imp_df, flights=fl_df, rest_time_s=t_rest, t_final_touchdown_s=t_final_td, t_settled_s=t_settled,
        y_rest_centre_m=contact_h + z_eq, delta_static_m=delta_static, t_catch_s=t_catch,
        t_end_s=t_end_eff, h_rest_m=h_rest_m, settle_residual_m=settle_residual, time_offset_s=0.0, status=status, hand=hand, catch=catch,
        recording=None, _dyn=dyn, _segments=all_segments,
        _seg_starts=np.array([sgm[0] for sgm in all_segments]),
    )
    return truth
