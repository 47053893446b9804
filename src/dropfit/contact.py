"""Contact models of a ball pressing into a rigid floor, solved exactly or to tight tolerance.

The ball (mass m) touches down at speed v₀; δ is the penetration (m, positive into the floor) and
the contact force F ≥ 0 pushes the ball back, so that m δ̈ = m g − F while δ > 0 (gravity included).

* :class:`LinearContact` — unilateral Kelvin–Voigt as in the seed chapter: F = max(0, kδ + cδ̇).
  Between its events it is a linear oscillator with a closed-form solution; the events (force
  reaching zero, lift-off at δ = 0, re-engagement) are found by root finding on the closed form.
* :class:`HuntCrossleyContact` — F = max(0, K δⁿ (1 + χ δ̇)); n = 3/2 is Hertz stiffness. The damping
  χ (s/m) may come from the Hunt–Crossley, Lankarani–Nikravesh or Flores forms. Solved with an
  event-locating Runge–Kutta integrator (DOP853) at tolerances that give e to ten digits.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import brentq, least_squares

from .numerics import jacobian, propagate
from .physics import STANDARD_GRAVITY_M_S2
from .restitution import weighted_fit

#: Relative tolerance of the nonlinear integrator (e comes out to better than 1e-10).
ODE_RTOL = 1e-12
_MAX_PHASES = 16
_SCAN_POINTS = 128


@dataclass(frozen=True)
class LinearContact:
    """Unilateral spring–damper: F = max(0, kδ + cδ̇) for δ > 0.

    Attributes
    ----------
    stiffness_n_m : float
        k in N/m.
    damping_n_s_m : float
        c in N·s/m.
    """

    stiffness_n_m: float
    damping_n_s_m: float

    def force(self, penetration_m, rate_m_s):
        """Contact force in N at penetration δ (m) and penetration rate δ̇ (m/s)."""
        penetration_m = np.asarray(penetration_m, dtype=float)
        raw = self.stiffness_n_m * penetration_m + self.damping_n_s_m * np.asarray(rate_m_s, dtype=float)
        return np.where(penetration_m > 0, np.maximum(raw, 0.0), 0.0)


#: Damping forms χ(e, v₀) of the Hunt–Crossley family, χ in s/m for an impact speed v₀ in m/s.
DAMPING_FORMS = {
    "hunt-crossley": lambda e, v0: 3.0 * (1.0 - e) / (2.0 * v0),
    "lankarani-nikravesh": lambda e, v0: 3.0 * (1.0 - e**2) / (4.0 * v0),
    "flores": lambda e, v0: 8.0 * (1.0 - e) / (5.0 * e * v0),
}


@dataclass(frozen=True)
class HuntCrossleyContact:
    """Hunt–Crossley family: F = max(0, K δⁿ (1 + χ δ̇)) for δ > 0.

    Attributes
    ----------
    stiffness : float
        K in N/mⁿ.
    exponent : float
        n (1 = linear spring, 3/2 = Hertz).
    damping_s_m : float
        χ in s/m.
    """

    stiffness: float
    exponent: float
    damping_s_m: float

    @classmethod
    def from_restitution(cls, stiffness, exponent, e, impact_speed_m_s, form="hunt-crossley"):
        """Model whose damping χ is given by one of :data:`DAMPING_FORMS` for e at ``impact_speed_m_s``."""
        return cls(stiffness, exponent, DAMPING_FORMS[form](e, impact_speed_m_s))

    def force(self, penetration_m, rate_m_s):
        """Contact force in N at penetration δ (m) and penetration rate δ̇ (m/s)."""
        penetration_m = np.asarray(penetration_m, dtype=float)
        depth = np.maximum(penetration_m, 0.0)
        raw = self.stiffness * depth**self.exponent * (1.0 + self.damping_s_m * np.asarray(rate_m_s, dtype=float))
        return np.where(penetration_m > 0, np.maximum(raw, 0.0), 0.0)


@dataclass
class ContactResult:
    """One impact computed through the contact.

    Attributes
    ----------
    time_s, penetration_m, rate_m_s, force_n : numpy.ndarray
        History from touchdown (t = 0) to lift-off: time (s), δ (m), δ̇ (m/s), F (N).
    e : float
        Coefficient of restitution v_out / v₀ (dimensionless); 0 if the ball does not lift off.
    contact_time_s : float
        Time from touchdown to lift-off in s.
    peak_force_n, peak_force_time_s : float
        Largest contact force (N) and when it occurs (s after touchdown).
    touchdown_force_n : float
        Force just after touchdown in N (c v₀ for the linear model, 0 for Hunt–Crossley).
    kinetic_energy_change_j, contact_work_j : float
        m (v_out² − v₀²)/2 and ∫ F ẏ dt over the contact, both in J; equal, since the weight does
        no net work between touchdown and lift-off at the same height.
    """

    time_s: np.ndarray
    penetration_m: np.ndarray
    rate_m_s: np.ndarray
    force_n: np.ndarray
    e: float
    contact_time_s: float
    peak_force_n: float
    peak_force_time_s: float
    touchdown_force_n: float
    kinetic_energy_change_j: float
    contact_work_j: float


class _LinearPhase:
    """Closed-form motion while the linear contact pushes: δ̈ + (c/m) δ̇ + (k/m) δ = g."""

    def __init__(self, k, c, m, g, delta0, rate0):
        self.k, self.c, self.m, self.g = k, c, m, g
        omega = np.sqrt(k / m)
        zeta = c / (2.0 * np.sqrt(k * m))
        self.static = m * g / k
        offset = delta0 - self.static
        self.critical = abs(zeta - 1.0) < 1e-9
        if self.critical:
            self.lam = -omega
            self.a, self.b = offset, rate0 + omega * offset
        else:
            root = omega * np.sqrt(complex(zeta**2 - 1.0))
            self.l1, self.l2 = -zeta * omega + root, -zeta * omega - root
            self.c1 = (rate0 - self.l2 * offset) / (self.l1 - self.l2)
            self.c2 = offset - self.c1
        # time scale to scan for the force zero: one damped period, or the slow decay if overdamped
        self.scan_s = 2 * np.pi / (omega * np.sqrt(1 - zeta**2)) if zeta < 1 else 20.0 / (zeta * omega)

    def state(self, tau):
        """(δ in m, δ̇ in m/s) at ``tau`` s after the start of the phase."""
        tau = np.asarray(tau, dtype=float)
        if self.critical:
            decay = np.exp(self.lam * tau)
            delta = self.static + (self.a + self.b * tau) * decay
            rate = (self.b + self.lam * (self.a + self.b * tau)) * decay
            return delta, rate
        e1, e2 = np.exp(self.l1 * tau), np.exp(self.l2 * tau)
        delta = self.static + (self.c1 * e1 + self.c2 * e2).real
        rate = (self.c1 * self.l1 * e1 + self.c2 * self.l2 * e2).real
        return delta, rate

    def force(self, tau):
        delta, rate = self.state(tau)
        return self.k * delta + self.c * rate

    def force_zero(self):
        """First time (s) at which kδ + cδ̇ falls to zero, or None if it never does."""
        grid = np.linspace(0.0, self.scan_s, _SCAN_POINTS)
        values = self.force(grid)
        negative = np.flatnonzero(values[1:] <= 0)
        if negative.size == 0:
            return None
        j = negative[0] + 1
        return brentq(self.force, grid[j - 1], grid[j], xtol=1e-15, rtol=4 * np.finfo(float).eps)


def _linear_events(k, c, m, g, v0):
    """The event loop of the linear contact: pushing phases and free phases until lift-off.

    Returns
    -------
    (list, bool, float, float)
        Segments ``("push", start_s, duration_s, _LinearPhase)`` or ``("free", start_s, duration_s,
        (δ m, δ̇ m/s))``; whether the ball lifted off; the time of lift-off (or of the last event)
        in s; and δ̇ then, in m/s.
    """
    t0, delta, rate = 0.0, 0.0, v0
    segments = []
    for _ in range(_MAX_PHASES):
        phase = _LinearPhase(k, c, m, g, delta, rate)
        duration = phase.force_zero()
        if duration is None:  # the contact never lets go: the ball comes to rest on the floor
            segments.append(("push", t0, phase.scan_s, phase))
            return segments, False, t0, 0.0
        segments.append(("push", t0, duration, phase))
        t0 += duration
        delta, rate = (float(x) for x in phase.state(duration))
        # free phase: δ = δ1 + r1 τ + g τ²/2 until lift-off (δ = 0) or re-engagement (kδ + cδ̇ > 0)
        discriminant = rate**2 - 2.0 * g * delta
        # smaller root of δ1 + r1 τ + g τ²/2 = 0, in the form that stays finite for g = 0
        liftoff = 2.0 * delta / (-rate + np.sqrt(discriminant)) if discriminant >= 0 and rate < 0 else np.inf
        slope = k * rate + c * g  # dF/dτ at the start of the free phase, F(τ) = slope τ + k g τ²/2
        if slope >= 0:
            reengage = 0.0
        else:
            reengage = -2.0 * slope / (k * g) if g > 0 else np.inf
        free = min(liftoff, reengage)
        if free > 0:
            segments.append(("free", t0, free, (delta, rate)))
        t0 += free
        delta, rate = delta + rate * free + 0.5 * g * free**2, rate + g * free
        if liftoff <= reengage:
            return segments, True, t0, rate
    return segments, False, t0, 0.0


def linear_restitution(model, mass_kg, impact_speed_m_s, gravity_m_s2=STANDARD_GRAVITY_M_S2):
    """e (dimensionless) and contact time (s) of the linear contact, from its events alone (fast path).

    Parameters are those of :func:`simulate_linear_contact`.
    """
    v0 = float(impact_speed_m_s)
    _, lifted, t_end, rate = _linear_events(model.stiffness_n_m, model.damping_n_s_m, mass_kg, gravity_m_s2, v0)
    return (-rate / v0, t_end) if lifted else (0.0, np.inf)


def simulate_linear_contact(model, mass_kg, impact_speed_m_s, gravity_m_s2=STANDARD_GRAVITY_M_S2, n_points=400):
    """Impact of a ball on the unilateral linear contact, in closed form between events.

    Parameters
    ----------
    model : LinearContact
    mass_kg : float
        Ball mass in kg.
    impact_speed_m_s : float
        Touchdown speed v₀ in m/s (> 0).
    gravity_m_s2 : float
        Gravity in m/s², acting during the contact.
    n_points : int
        Samples of the returned history per phase.

    Returns
    -------
    ContactResult
    """
    k, c, m, g = model.stiffness_n_m, model.damping_n_s_m, mass_kg, gravity_m_s2
    v0 = float(impact_speed_m_s)
    segments, lifted, t_end, rate = _linear_events(k, c, m, g, v0)
    pieces, work = [], 0.0
    for kind, start, duration, payload in segments:
        tau = np.linspace(0.0, duration, n_points)
        if kind == "push":
            pieces.append((start + tau, *payload.state(tau), np.maximum(payload.force(tau), 0.0)))
            work += _integrate(lambda s, phase=payload: -phase.force(s) * phase.state(s)[1], duration)
        else:
            delta, speed = payload
            pieces.append((start + tau, delta + speed * tau + 0.5 * g * tau**2, speed + g * tau, np.zeros_like(tau)))
    time, penetration, velocity, force = (np.concatenate(parts) for parts in zip(*pieces))
    v_out = -rate if lifted else 0.0
    # the peak lies in the pushing phase whose sampled force is largest: refine it on its closed form
    pushing = [(start, duration, phase) for kind, start, duration, phase in segments if kind == "push"]
    start, duration, phase = max(pushing, key=lambda item: np.max(item[2].force(np.linspace(0, item[1], n_points))))
    grid = np.linspace(0.0, duration, n_points)
    peak_time, peak_force = _refine_peak(lambda s: float(phase.force(s)), grid, int(np.argmax(phase.force(grid))))
    return ContactResult(
        time_s=time, penetration_m=penetration, rate_m_s=velocity, force_n=force,
        e=v_out / v0, contact_time_s=t_end if lifted else np.inf, peak_force_n=peak_force,
        peak_force_time_s=start + peak_time, touchdown_force_n=c * v0,
        kinetic_energy_change_j=0.5 * m * (v_out**2 - v0**2), contact_work_j=work,
    )


_GAUSS_NODES, _GAUSS_WEIGHTS = np.polynomial.legendre.leggauss(256)


def _integrate(integrand, duration):
    """∫₀^duration of a smooth vectorised integrand by 256-point Gauss–Legendre quadrature."""
    half = 0.5 * duration
    return float(half * np.sum(_GAUSS_WEIGHTS * integrand(half * (_GAUSS_NODES + 1.0))))


def _refine_peak(force_at, time, index):
    """Refine a sampled maximum of the force by a bounded scalar search around it."""
    from scipy.optimize import minimize_scalar

    low = time[max(index - 1, 0)]
    high = time[min(index + 1, time.size - 1)]
    if high <= low:
        return float(time[index]), float(force_at(time[index]))
    best = minimize_scalar(lambda s: -force_at(s), bounds=(low, high), method="bounded",
                           options={"xatol": 1e-12 * max(high, 1e-9)})
    return float(best.x), float(-best.fun)


def simulate_contact(model, mass_kg, impact_speed_m_s, gravity_m_s2=STANDARD_GRAVITY_M_S2, n_points=400):
    """Impact of a ball on ``model`` (linear: closed form; Hunt–Crossley: DOP853 with event location).

    Parameters and result as in :func:`simulate_linear_contact`.
    """
    if isinstance(model, LinearContact):
        return simulate_linear_contact(model, mass_kg, impact_speed_m_s, gravity_m_s2, n_points)
    return _simulate_nonlinear(model, mass_kg, impact_speed_m_s, gravity_m_s2, n_points)


def _simulate_nonlinear(model, mass_kg, impact_speed_m_s, gravity_m_s2, n_points):
    m, g, v0 = mass_kg, gravity_m_s2, float(impact_speed_m_s)

    def rhs(_, state):
        delta, rate = state
        return [rate, g - float(model.force(delta, rate)) / m]

    def liftoff(_, state):
        return state[0]

    liftoff.terminal, liftoff.direction = True, -1
    # generous time limit: a quarter period of the stiffness at the largest possible penetration
    horizon = 1.0
    solution = solve_ivp(rhs, (0.0, horizon), [0.0, v0], method="DOP853", rtol=ODE_RTOL, atol=1e-16,
                         events=liftoff, dense_output=True)
    lifted = solution.status == 1 and solution.t_events[0].size > 0
    t_end = float(solution.t_events[0][0]) if lifted else float(solution.t[-1])
    v_out = -float(solution.y_events[0][0][1]) if lifted else 0.0
    time = np.linspace(0.0, t_end, n_points)
    penetration, rate = solution.sol(time)
    force = model.force(penetration, rate)

    def force_at(s):
        d, r = solution.sol(s)
        return model.force(d, r)

    work = _integrate(lambda s: -force_at(s) * solution.sol(s)[1], t_end)
    peak_time, peak_force = _refine_peak(lambda s: float(force_at(s)), time, int(np.argmax(force)))
    return ContactResult(
        time_s=time, penetration_m=penetration, rate_m_s=rate, force_n=force, e=v_out / v0,
        contact_time_s=t_end if lifted else np.inf, peak_force_n=peak_force, peak_force_time_s=peak_time,
        touchdown_force_n=float(model.force(1e-300, v0)), kinetic_energy_change_j=0.5 * m * (v_out**2 - v0**2),
        contact_work_j=work,
    )


def linear_vibration_restitution(damping_ratio):
    """e = exp(−ζπ/√(1 − ζ²)) of a spring–damper that may also pull (linear vibration theory)."""
    return float(np.exp(-damping_ratio * np.pi / np.sqrt(1.0 - damping_ratio**2)))


def linear_vibration_damping_ratio(e):
    """ζ of a spring–damper that may also pull, for a coefficient of restitution e (the inverse of
    :func:`linear_vibration_restitution`; dimensionless)."""
    log_e = np.log(e)
    return -log_e / np.sqrt(np.pi**2 + log_e**2)


def damping_ratio(stiffness_n_m, damping_n_s_m, mass_kg):
    """ζ = c / (2 √(k m)) (dimensionless)."""
    return damping_n_s_m / (2.0 * np.sqrt(stiffness_n_m * mass_kg))


def calibrate_damping(mass_kg, stiffness_n_m, impact_speed_m_s, target_e, gravity_m_s2=STANDARD_GRAVITY_M_S2):
    """Damping c (N·s/m) of the linear contact that gives ``target_e`` at ``impact_speed_m_s`` (m/s).

    Root finding (brentq) on the closed-form e(c), to machine precision, bracketed around the
    damping that linear vibration theory gives for ``target_e``.
    """
    def excess(c):
        return linear_restitution(LinearContact(stiffness_n_m, c), mass_kg, impact_speed_m_s, gravity_m_s2)[0] - target_e

    critical = 2.0 * np.sqrt(stiffness_n_m * mass_kg)
    guess = critical * linear_vibration_damping_ratio(target_e)
    low, high = 0.5 * guess, 2.0 * guess
    while excess(low) < 0 and low > 1e-9 * critical:
        low *= 0.5
    while excess(high) > 0:
        high *= 2.0
    return brentq(excess, low, high, xtol=1e-14, rtol=4 * np.finfo(float).eps)


def linear_from_measurements(mass_kg, impact_speed_m_s, e, contact_time_s, gravity_m_s2=STANDARD_GRAVITY_M_S2):
    """k (N/m) and c (N·s/m) of the linear contact that reproduce a measured e and contact time.

    Starts from linear vibration theory (ζ from e, ω from the contact time ≈ π/ω_d) and solves the
    exact unilateral model, gravity included.
    """
    zeta = linear_vibration_damping_ratio(e)
    omega = np.pi / (contact_time_s * np.sqrt(1 - zeta**2))
    k0 = mass_kg * omega**2
    start = np.log([k0, 2 * zeta * np.sqrt(k0 * mass_kg)])

    def mismatch(log_params):
        k, c = np.exp(log_params)
        model_e, model_time = linear_restitution(LinearContact(k, c), mass_kg, impact_speed_m_s, gravity_m_s2)
        return [model_e - e, model_time / contact_time_s - 1.0]

    solution = least_squares(mismatch, start, xtol=1e-15, ftol=1e-15, gtol=1e-15)
    return tuple(float(x) for x in np.exp(solution.x))


def hunt_crossley_from_measurements(mass_kg, impact_speed_m_s, e, contact_time_s, exponent=1.5,
                                    gravity_m_s2=STANDARD_GRAVITY_M_S2):
    """K (N/mⁿ) and χ (s/m) of a Hunt–Crossley contact that reproduce a measured e and contact time.

    The start comes from the Hunt–Crossley damping form and the Hertz contact time of an elastic
    impact, t_c ≈ 3.218 (m²/(K² v₀))^{1/5} for n = 3/2.
    """
    chi0 = DAMPING_FORMS["hunt-crossley"](e, impact_speed_m_s)
    k0 = (3.218 / contact_time_s) ** 2.5 * mass_kg / np.sqrt(impact_speed_m_s)

    def mismatch(log_params):
        stiffness, chi = np.exp(log_params)
        result = _simulate_nonlinear(HuntCrossleyContact(stiffness, exponent, chi), mass_kg, impact_speed_m_s,
                                     gravity_m_s2, n_points=3)
        return [result.e - e, result.contact_time_s / contact_time_s - 1.0]

    solution = least_squares(mismatch, np.log([k0, chi0]), xtol=1e-14, ftol=1e-14, gtol=1e-14)
    return tuple(float(x) for x in np.exp(solution.x))


def fit_linear_contact(mass_kg, impact_speed_m_s, e, contact_time_s, covariance, gravity_m_s2=STANDARD_GRAVITY_M_S2):
    """k and c of the linear contact from measured impacts, with standard errors.

    Each impact's (e, contact time) is inverted exactly (:func:`linear_from_measurements`). The full
    covariance of all e and contact times (they share the flights they are computed from) is
    propagated through the Jacobians of those inversions, and the impacts are combined by
    :func:`dropfit.restitution.weighted_fit` (inverse-variance weights, full-covariance se).

    Parameters
    ----------
    mass_kg : float
        Ball mass in kg.
    impact_speed_m_s, e, contact_time_s : array_like
        Per impact (n of them): touchdown speed (m/s), e (dimensionless), contact time (s).
    covariance : array_like
        Covariance of (e_1 … e_n, contact time_1 … contact time_n in s), shape (2n, 2n), as
        :attr:`dropfit.analysis.BounceAnalysis.e_contact_covariance`.
    gravity_m_s2 : float
        Gravity in m/s².

    Returns
    -------
    dict
        ``stiffness_n_m`` and ``damping_n_s_m`` as (value, se) pairs combined over the impacts, and
        ``per_impact``: a list of dicts with the same per impact.
    """
    e, contact_time_s = np.asarray(e, dtype=float), np.asarray(contact_time_s, dtype=float)
    n = e.size
    params = np.empty((n, 2))
    # Jacobian of (k_1 … k_n, c_1 … c_n) with respect to (e_1 … e_n, contact time_1 … contact time_n)
    jac = np.zeros((2 * n, 2 * n))
    for i, (v0, ei, tc) in enumerate(zip(impact_speed_m_s, e, contact_time_s)):
        params[i] = linear_from_measurements(mass_kg, v0, ei, tc, gravity_m_s2)
        inversion = jacobian(lambda x: np.array(linear_from_measurements(mass_kg, v0, x[0], x[1], gravity_m_s2)),
                             np.array([ei, tc]), absolute_step=1e-9)
        jac[np.ix_([i, n + i], [i, n + i])] = inversion
    parameter_covariance = propagate(jac, covariance)
    se = np.sqrt(np.clip(np.diag(parameter_covariance), 0.0, None))
    combined = {"per_impact": [{"impact_speed_m_s": float(v0), "stiffness_n_m": (float(params[i, 0]), float(se[i])),
                                "damping_n_s_m": (float(params[i, 1]), float(se[n + i]))}
                               for i, v0 in enumerate(impact_speed_m_s)]}
    for j, name in enumerate(("stiffness_n_m", "damping_n_s_m")):
        block = slice(j * n, (j + 1) * n)
        fitted = weighted_fit(np.ones((n, 1)), params[:, j], parameter_covariance[block, block])
        combined[name] = (float(fitted["theta"][0]), float(np.sqrt(fitted["covariance"][0, 0])))
    return combined
