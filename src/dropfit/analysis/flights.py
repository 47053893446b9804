"""Flight fits: the closed-form vertical flights of :mod:`dropfit.physics` fitted jointly to the samples.

All flights share g and, when it is fitted, the quadratic-drag parameter k; each has its own apex
time and height. Also the checks made on a fit: whether a flight's residuals hide an impact, whether
an impact found between two flights really reverses the velocity, and the Bayesian information
criterion that decides whether drag is fitted.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import least_squares

from ..numerics import chi2_tail, jacobian, least_squares_covariance, linear_fit, propagate, robust_sigma
from ..physics import flight_height, flight_velocity

#: An impact needs both of its flights sampled at least this often to be analysed.
MIN_SAMPLES_PER_FLIGHT = 5
#: A flight whose residuals are this improbable under the noise hides an undetected impact.
MISFIT_P_VALUE = 1e-4
#: An impact must reverse the velocity by this many standard errors; a noise dip does not reverse it.
VELOCITY_REVERSAL_IN_SE = 3.0
#: Samples above which the flights are fitted with a sparse Jacobian (two or three non-zeros a row) and
#: an iterative trust-region step (LSMR): time and memory linear in the samples. The exact dense solver
#: below it computes an SVD of the n × p Jacobian at every step and holds several n × p copies: 10⁶
#: samples of 10 flights took minutes and gigabytes. Ordinary logs (up to 10⁵ samples) stay on it.
LONG_LOG_SAMPLES = 200_000


class FlightModel:
    """Joint least-squares model of all flights: θ = (y_apex_0, t_apex_0, …, [k]); without a fitted k,
    the drag parameter is held at ``fixed_k`` (1/m)."""

    def __init__(self, t, y, flight_of_sample, n_flights, with_drag, g, fixed_k=0.0):
        self.t, self.y = t, y
        self.flight = flight_of_sample
        self.n_flights = n_flights
        self.with_drag = with_drag
        self.g = g
        self.fixed_k = fixed_k

    def unpack(self, theta):
        """(apex heights in m, apex times in s, k in 1/m) from θ."""
        y_apex = theta[0: 2 * self.n_flights: 2]
        t_apex = theta[1: 2 * self.n_flights: 2]
        k = float(theta[-1]) if self.with_drag else self.fixed_k
        return y_apex, t_apex, k

    def residuals(self, theta):
        """Model minus data at every sample, m."""
        y_apex, t_apex, k = self.unpack(theta)
        model = flight_height(self.t, t_apex[self.flight], y_apex[self.flight], k, self.g)
        return np.nan_to_num(model - self.y, nan=1e6, neginf=-1e6, posinf=1e6)

    def speed_patterns(self, theta, error_m):
        """Height errors (m) at every sample that grow with the ball's speed v, ``error_m`` at the fastest: as
        v|v| (falling high, rising low: what the flights' curvature takes for drag) and as v² (high, or low, in
        both: a blurred or coded ball's centre reads off along its path)."""
        _, t_apex, k = self.unpack(theta)
        speed = flight_velocity(self.t, t_apex[self.flight], 0.0, k, self.g)
        squared = float(np.max(speed**2))
        return error_m * speed * np.abs(speed) / squared, error_m * speed**2 / squared

    @property
    def long(self):
        """Whether the fit uses the sparse Jacobian and iterative solver (:data:`LONG_LOG_SAMPLES`)."""
        return self.t.size > LONG_LOG_SAMPLES

    def jacobian(self, theta):
        """Analytic derivatives of the residuals by the apex heights and times; k's column numerically.
        Dense, or a SciPy sparse array for a :attr:`long` log."""
        y_apex, t_apex, k = self.unpack(theta)
        rows = np.arange(self.t.size)
        # only these two columns can be non-finite: cleaning them, not the n × p matrix, keeps a long log cheap
        by_apex_time = np.nan_to_num(-flight_velocity(self.t, t_apex[self.flight], 0.0, k, self.g))
        by_k = np.nan_to_num(jacobian(
            lambda drag: flight_height(self.t, t_apex[self.flight], y_apex[self.flight], drag[0], self.g),
            np.array([k]), lower=[0.0], absolute_step=1e-7)[:, 0]) if self.with_drag else None
        if self.long:
            from scipy.sparse import csr_array

            columns = [2 * self.flight, 2 * self.flight + 1] + [np.full(self.t.size, theta.size - 1)] * self.with_drag
            values = [np.ones(self.t.size), by_apex_time] + [by_k] * self.with_drag
            return csr_array((np.concatenate(values), (np.tile(rows, len(columns)), np.concatenate(columns))),
                             shape=(self.t.size, theta.size))
        jac = np.zeros((self.t.size, theta.size))
        jac[rows, 2 * self.flight] = 1.0
        jac[rows, 2 * self.flight + 1] = by_apex_time
        if self.with_drag:
            jac[:, -1] = by_k
        return jac

    def lower_bounds(self, n_parameters):
        """Lower bound of every parameter: none, but k ≥ 0."""
        lower = np.full(n_parameters, -np.inf)
        if self.with_drag:
            lower[-1] = 0.0
        return lower

    def fit(self, theta0):
        """Least-squares fit from ``theta0`` (scipy's OptimizeResult)."""
        if self.long:
            return least_squares(self.residuals, theta0, jac=self.jacobian, bounds=(self.lower_bounds(theta0.size), np.inf),
                                 method="trf", tr_solver="lsmr", x_scale="jac", xtol=1e-12, ftol=1e-12)
        if self.with_drag:
            return least_squares(self.residuals, theta0, jac=self.jacobian, bounds=(self.lower_bounds(theta0.size), np.inf),
                                 method="trf", x_scale="jac", xtol=1e-12, ftol=1e-12)
        return least_squares(self.residuals, theta0, jac=self.jacobian, method="lm", xtol=1e-12, ftol=1e-12)


def fit_covariance(result):
    """Parameter covariance σ² (JᵀJ)⁻¹ of a least-squares result, σ² from its residuals."""
    return least_squares_covariance(result.jac, result.fun)


def known_g_parabola(t, y, g):
    """Closed-form least-squares parabola of known curvature: y + g τ²/2 = a0 + a1 τ, τ = t − mean(t).

    Parameters
    ----------
    t : numpy.ndarray
        Times in s of one flight's samples.
    y : numpy.ndarray
        Heights (length unit L, up).
    g : float
        Downward acceleration in L/s².

    Returns
    -------
    (float, float, numpy.ndarray)
        Apex height (L), apex time (s) and their covariance (σ² from the residuals).
    """
    centre = float(np.mean(t))
    tau = t - centre
    (a0, a1), covariance = linear_fit(np.column_stack([np.ones_like(tau), tau]), y + 0.5 * g * tau**2)
    t_apex = a1 / g
    # (y_apex, t_apex) is a smooth map of (a0, a1): carry the covariance through it
    to_apex = np.array([[1.0, t_apex], [0.0, 1.0 / g]])
    return a0 + 0.5 * g * t_apex**2, t_apex + centre, propagate(to_apex, covariance)


def parabola_start(t, y, g):
    """(apex height, apex time) of :func:`known_g_parabola`: the starting point of a flight's fit."""
    return known_g_parabola(t, y, g)[:2]


def assign_samples(t, flights_bounds):
    """Flight index of every sample (−1 = not in any flight) for open time intervals."""
    flight = np.full(t.size, -1)
    for i, (start, end) in enumerate(flights_bounds):
        flight[(t > start) & (t < end)] = i
    return flight


def fit_flights(t, y, bounds, with_drag, g, theta0, fixed_k=0.0):
    """Assign samples to the flights in ``bounds`` (list of (start, end) in s) and fit them jointly
    (k fitted, or held at ``fixed_k`` in 1/m); None if a flight has fewer than
    ``MIN_SAMPLES_PER_FLIGHT`` samples.

    Returns
    -------
    (FlightModel, scipy.optimize.OptimizeResult, numpy.ndarray) or None
        The model, the fit and the samples per flight.
    """
    flight = assign_samples(t, bounds)
    counts = np.bincount(flight[flight >= 0], minlength=len(bounds))
    if np.any(counts < MIN_SAMPLES_PER_FLIGHT):
        return None
    used = flight >= 0
    model = FlightModel(t[used], y[used], flight[used], len(bounds), with_drag, g, fixed_k)
    return model, model.fit(theta0), counts


def bic(result):
    """Bayesian information criterion of a least-squares fit with Gaussian noise."""
    n = result.fun.size
    rss = float(result.fun @ result.fun)
    return n * np.log(max(rss, 1e-300) / n) + result.x.size * np.log(n)


def first_spurious_impact(model, result):
    """Index of the first impact across which the fitted velocity does not reverse significantly.

    At a real impact the velocity jumps from falling to rising by (1 + e) v_in; where a noise dip split
    one flight (near its apex, where the ball is slow and densely sampled), the two fitted halves
    have the same velocity at the split.
    """
    last = np.array([model.t[model.flight == i].max() for i in range(model.n_flights - 1)])
    first = np.array([model.t[model.flight == i + 1].min() for i in range(model.n_flights - 1)])
    split = 0.5 * (last + first)

    def velocity_jump(theta):
        y_apex, t_apex, k = model.unpack(theta)
        return (flight_velocity(split, t_apex[1:], 0.0, k, model.g)
                - flight_velocity(split, t_apex[:-1], 0.0, k, model.g))

    jump = velocity_jump(result.x)
    jac = jacobian(velocity_jump, result.x, model.lower_bounds(result.x.size))
    se = np.sqrt(np.clip(np.diag(propagate(jac, fit_covariance(result))), 0.0, None))
    spurious = np.flatnonzero(jump < VELOCITY_REVERSAL_IN_SE * se)
    return int(spurious[0]) if spurious.size else None


def first_misfit_flight(model, result, noise, outlier_sigmas=math.inf, max_outliers=0):
    """Index of the first flight whose residuals are too large for the noise (χ² test, p < 1e-4).

    The noise is the larger of ``noise`` and the robust spread of all the residuals: noise that is
    correlated from sample to sample, or rounded, is larger than its differences say, alike in every
    flight, while a hidden impact stands out in one. Residuals correlated from one sample to the next
    carry fewer independent values than samples: with ρ the lag-1 autocorrelation of all the flights'
    residuals, a flight's χ² and its degrees of freedom are both scaled by (1 − ρ²)/(1 + ρ²), which
    keeps the χ² distribution's mean and variance for AR(1) residuals. A video's tracked centre drifts
    by ~0.1 px over a flight with the ball's turning seam (ρ ≈ 0.8 on the default phone clip); white
    noise (ρ ≈ 0) leaves the test as it was. Residuals beyond ``outlier_sigmas`` times that noise, when
    there are at most ``max_outliers`` of them, are outliers the caller leaves out, not a misfit: they are not
    counted (one sample of a phone clip 5.8 noise standard deviations off had ended the sequence).
    """
    residuals = result.fun
    scale = max(noise, robust_sigma(residuals))
    counted = np.abs(residuals) <= outlier_sigmas * scale
    if np.count_nonzero(~counted) > max_outliers:
        counted[:] = True
    same_flight = (model.flight[1:] == model.flight[:-1]) & counted[1:] & counted[:-1]
    lagged = float(residuals[1:][same_flight] @ residuals[:-1][same_flight])
    rho = lagged / float(residuals[counted] @ residuals[counted]) if lagged > 0 else 0.0
    independent = (1.0 - rho**2) / (1.0 + rho**2)
    for i in range(model.n_flights):
        residual = residuals[(model.flight == i) & counted]
        chi2 = independent * float(residual @ residual) / scale**2
        if chi2_tail(chi2, max(independent * residual.size - 2, 1)) < MISFIT_P_VALUE:
            return i
    return None


def combine_with_prior(result, prior_k, prior_se, systematic_se=0.0):
    """k (1/m) and its se from the free-k fit ``result`` combined with the prior ``prior_k`` ± ``prior_se``
    by inverse-variance weighting: flights that cannot pin k down on their own still narrow it. The free k's
    standard error is its fit's and ``systematic_se`` (1/m), combined.

    Returns
    -------
    (float, float, float)
        k, its se, and the weight of the free fit's k in it (0 … 1): what moves the free k (a held g,
        the length scale) moves the combined k by that fraction.
    """
    data_se = float(np.hypot(np.sqrt(max(fit_covariance(result)[-1, -1], 0.0)), systematic_se))
    if not data_se > 0:
        return prior_k, prior_se, 0.0
    weights = np.array([1.0 / data_se**2, 1.0 / prior_se**2])
    value = float(weights @ [result.x[-1], prior_k] / weights.sum())
    return value, float(1.0 / np.sqrt(weights.sum())), float(weights[0] / weights.sum())


def shared_acceleration(pieces):
    """Downward acceleration shared by several flights, each with its own start height and speed.

    Linear least squares of y = a_j + b_j τ − A τ²/2 over the flights j (τ from each flight's first
    sample), in the units of the data.

    Parameters
    ----------
    pieces : list of (numpy.ndarray, numpy.ndarray)
        Times (s) and heights (any length unit, up) of each flight.

    Returns
    -------
    (float, float)
        A and its standard error, in length units per s².
    """
    if sum(time.size for time, _ in pieces) > LONG_LOG_SAMPLES:
        return _shared_acceleration_by_flight(pieces)
    rows, targets = [], []
    for j, (time, height) in enumerate(pieces):
        tau = time - time[0]
        block = np.zeros((tau.size, 2 * len(pieces) + 1))
        block[:, 2 * j], block[:, 2 * j + 1], block[:, -1] = 1.0, tau, -0.5 * tau**2
        rows.append(block)
        targets.append(height)
    coef, covariance = linear_fit(np.vstack(rows), np.concatenate(targets))
    return float(coef[-1]), float(np.sqrt(covariance[-1, -1]))


def _shared_acceleration_by_flight(pieces):
    """:func:`shared_acceleration` of a long log without its n × (2F + 1) design matrix (600 MB for 10⁶
    samples of 18 flights): each flight's own height and speed are projected out of its heights and of
    −τ²/2 (Frisch–Waugh–Lovell), leaving the same least-squares A and standard error."""
    residuals = []
    for time, height in pieces:
        tau = time - time[0]
        basis, _ = np.linalg.qr(np.column_stack([np.ones_like(tau), tau]))
        curve = -0.5 * tau**2
        residuals.append((curve - basis @ (basis.T @ curve), height - basis @ (basis.T @ height)))
    curve_ss = sum(float(curve @ curve) for curve, _ in residuals)
    acceleration = sum(float(curve @ height) for curve, height in residuals) / curve_ss
    misfit_ss = sum(float((height - acceleration * curve) @ (height - acceleration * curve)) for curve, height in residuals)
    dof = max(sum(time.size for time, _ in pieces) - (2 * len(pieces) + 1), 1)
    return acceleration, float(np.sqrt(misfit_ss / dof / curve_ss))


@dataclass
class SharedAcceleration:
    """Result of :func:`shared_acceleration_with_drag`, in the length unit L of the data.

    Attributes
    ----------
    acceleration, acceleration_se : float
        Downward acceleration without drag (L/s²) and its standard error, averaged over the drag models
        the data allow, weighted by their evidence.
    drag_k, drag_k_se : float
        Quadratic-drag parameter (1/L) and its standard error of the model with most weight.
    drag_model : str
        ``"none"``, ``"quadratic"`` (k fitted) or ``"nominal"`` (k held at the ball's), the model with most
        weight.
    models : dict
        Per model: ``acceleration``, ``acceleration_se``, ``drag_k``, ``bic`` and ``weight``.
    note : str or None
        Why a model was left out (a fitted k that air cannot give).
    largest_fall : float
        The largest fall (L) of a fitted sample below its flight's apex: a height error growing as v² that
        reaches δ there bends every flight like an acceleration off by the fraction δ / ``largest_fall``.
    """

    acceleration: float
    acceleration_se: float
    drag_k: float
    drag_k_se: float
    drag_model: str
    models: dict = field(default_factory=dict)
    note: str | None = None
    largest_fall: float = math.nan


#: A fitted drag k within this factor of the ball's nominal one is air drag; beyond it, something else
#: bends the flights (C_d of real balls spans 0.25–0.6 against the nominal 0.5).
PLAUSIBLE_DRAG_RATIO = 2.5


def shared_acceleration_with_drag(pieces, nominal_k=0.0, nominal_k_se=0.0, max_k=np.inf):
    """Free-fall acceleration shared by several flights, averaged over the drag models the data allow.

    Each flight is the closed form of :func:`dropfit.physics.flight_height` (its own apex time and
    height) with a shared acceleration A and drag parameter k: ÿ = −A − k ẏ|ẏ|. Without drag the
    curvature of a fall underestimates A by a fraction of order k v² / A (about 0.4 % for a tennis ball
    from 254 cm). Three models: no drag; k fitted; and, when the ball is known, k held at its nominal
    value (its standard error carried into A). A fitted k outside ``nominal_k`` × (1/2.5 … 2.5), or
    above ``max_k`` when the ball is not known, is not air drag: that model is left out, and the
    difference it makes is added to A's uncertainty, since something else bends the flights. The
    others are averaged with weights exp(−BIC/2) (Bayesian model averaging: A's variance is the
    weighted variance within plus between the models). k in 1/L does not depend on the time unit,
    so A scales as (time unit)⁻² alone.

    Parameters
    ----------
    pieces : list of (numpy.ndarray, numpy.ndarray)
        Times (s) and heights (any length unit L, up) of each flight.
    nominal_k, nominal_k_se : float
        The ball's drag parameter in 1/L and its standard error (0: not known).
    max_k : float
        The largest plausible k in 1/L when the ball is not known.

    Returns
    -------
    SharedAcceleration
    """
    start, start_se = shared_acceleration(pieces)
    if not start > 0:  # the flights curve upwards (e.g. a few ms of a close-up): no fall to refine
        return SharedAcceleration(start, start_se, 0.0, 0.0, "none")
    theta0 = []
    for time, height in pieces:
        theta0.extend(parabola_start(time - time[0], height, start))
    n = len(pieces)

    def fit(k):
        """Least-squares fit with k free (None) or held; its A, se and BIC, and k (1/L)."""
        extra = [start, 0.0] if k is None else [start]

        def residuals(theta):
            drag = theta[2 * n + 1] if k is None else k
            return np.concatenate([flight_height(time - time[0], theta[2 * j + 1], theta[2 * j], drag, theta[2 * n])
                                   - height for j, (time, height) in enumerate(pieces)])

        theta = np.array(theta0 + extra)
        lower = np.full(theta.size, -np.inf)
        lower[2 * n] = 0.0  # the acceleration points down
        if k is None:
            lower[-1] = 0.0
        result = least_squares(residuals, theta, bounds=(lower, np.inf), x_scale="jac", xtol=1e-12, ftol=1e-12)
        se = np.sqrt(np.clip(np.diag(fit_covariance(result)), 0.0, None))
        return {"acceleration": float(result.x[2 * n]), "acceleration_se": float(se[2 * n]),
                "drag_k": float(result.x[-1]) if k is None else float(k),
                "drag_k_se": float(se[-1]) if k is None else 0.0, "bic": bic(result)}

    models = {"none": fit(0.0), "quadratic": fit(None)}
    if nominal_k > 0:
        models["nominal"] = fit(nominal_k)
        if nominal_k_se > 0:  # the held k's uncertainty moves A: a systematic part of its se
            slope = (fit(nominal_k + nominal_k_se)["acceleration"] - fit(max(nominal_k - nominal_k_se, 0.0))
                     ["acceleration"]) / (nominal_k + nominal_k_se - max(nominal_k - nominal_k_se, 0.0))
            models["nominal"]["acceleration_se"] = float(np.hypot(models["nominal"]["acceleration_se"],
                                                                  slope * nominal_k_se))
            models["nominal"]["drag_k_se"] = nominal_k_se
    k, k_se = models["quadratic"]["drag_k"], models["quadratic"]["drag_k_se"]
    # implausible only when k's own 95 % interval misses the plausible range
    low, high = (nominal_k / PLAUSIBLE_DRAG_RATIO, PLAUSIBLE_DRAG_RATIO * nominal_k) if nominal_k > 0 else (0.0, max_k)
    plausible = k - 2 * k_se <= high and k + 2 * k_se >= low
    implausible = None if plausible else models.pop("quadratic")
    best = min(model["bic"] for model in models.values())
    for model in models.values():
        model["weight"] = float(np.exp(-0.5 * (model["bic"] - best)))
    total = sum(model["weight"] for model in models.values())
    for model in models.values():
        model["weight"] /= total
    mean = sum(model["weight"] * model["acceleration"] for model in models.values())
    variance = sum(model["weight"] * (model["acceleration_se"] ** 2 + (model["acceleration"] - mean) ** 2)
                   for model in models.values())
    note = None
    if implausible is not None:
        variance += (0.5 * (implausible["acceleration"] - mean)) ** 2
        models["quadratic (left out)"] = implausible
        note = (f"a fitted drag of k = {k:.3g} 1/px is "
                + (f"{k / nominal_k:.2g} times the ball's" if nominal_k > 0 else "more than any ball's")
                + ": not air drag; the scale's uncertainty includes half the difference that fit makes")
    chosen = max((name for name in models if "left out" not in name), key=lambda name: models[name]["weight"])
    largest_fall = max(float(parabola_start(time, height, mean)[0] - np.min(height)) for time, height in pieces)
    return SharedAcceleration(float(mean), float(np.sqrt(variance)), models[chosen]["drag_k"],
                              models[chosen]["drag_k_se"], chosen, models, note, largest_fall)
