"""From a height-against-time trajectory to flights and impacts, with standard errors.

The trajectory is split into flights at the impacts; every flight is fitted with the closed-form
vertical flight of :mod:`dropfit.physics` (known g, two parameters per flight: apex time and apex
height), and a quadratic-drag parameter k shared by all flights is fitted only when the Bayesian
information criterion says the data support it. Otherwise k is held: when the ball's size and mass are
known, at that of a smooth sphere (relative se :data:`NOMINAL_DRAG_RELATIVE_SE`) combined with what
the flights say about k; else at 0. The uncertainty of a held k is carried into every impact
quantity as a systematic error: drag too weak to show in the flight shapes still biases e by more
than its statistical error. The contact height (the centre height at which
the ball touches the floor) is either given or found where the fitted flights before and after
each impact meet. Every impact quantity is a function of the fitted parameters, so its standard
error, and the covariance between impacts, follow by propagating the fit covariance through that
function (delta method).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd
from scipy import stats
from scipy.optimize import brentq, least_squares

from .errors import InputError
from .physics import STANDARD_GRAVITY_M_S2, flight_height, flight_velocity, speed_below_apex, time_from_apex
from .restitution import Z95

#: An impact needs both of its flights sampled at least this often to be analysed.
MIN_SAMPLES_PER_FLIGHT = 5
#: A dip must fall and rise by this many noise standard deviations to count as an impact.
IMPACT_DEPTH_IN_NOISE = 5.0
#: A flight whose residuals are this improbable under the noise hides an undetected impact.
MISFIT_P_VALUE = 1e-4
#: Noise floor in the height's own unit, so that noise-free data still segment.
_NOISE_FLOOR_FRACTION = 1e-6
#: Number of passes of "assign samples to flights, fit, locate the contacts".
_REFINEMENT_PASSES = 3
#: Relative standard error of a nominal drag parameter (smooth-sphere C_d = 0.5 against the
#: 0.4–0.6 of real balls at drop-test Reynolds numbers), carried as a systematic error.
NOMINAL_DRAG_RELATIVE_SE = 0.25


@dataclass
class BounceAnalysis:
    """Result of :func:`analyse_bounces`.

    Attributes
    ----------
    flights : pandas.DataFrame
        One row per flight (flight 0 is the drop), SI units in the column names.
    impacts : pandas.DataFrame
        One row per impact (impact n ends flight n−1 and starts flight n).
    e_covariance : numpy.ndarray
        Covariance of the per-impact e (dimensionless²), impacts in table order.
    e_contact_covariance : numpy.ndarray
        Covariance of (e_1 … e_n, contact time_1 … contact time_n in s), shape (2n, 2n): e and contact
        time share the flights they are computed from.
    e_drag_covariance : numpy.ndarray
        Covariance of each impact's e with the drag parameter k (1/m), shape (n,); zero without drag.
    summary : dict
        Contact height, drag model and its evidence, noise, release and rest times (SI units).
    """

    flights: pd.DataFrame
    impacts: pd.DataFrame
    e_covariance: np.ndarray
    e_contact_covariance: np.ndarray
    e_drag_covariance: np.ndarray
    summary: dict = field(default_factory=dict)


def estimate_noise(y):
    """Robust standard deviation of the measurement noise of uniformly sampled heights.

    The third difference of a parabola sampled at a constant interval is zero, so the third
    differences of a free flight are pure noise with variance 20 σ²; the median absolute deviation
    ignores the few that straddle an impact.

    Parameters
    ----------
    y : numpy.ndarray
        Heights (any length unit) without NaNs, in time order.

    Returns
    -------
    float
        σ in the unit of ``y``.
    """
    d3 = np.diff(y, 3)
    if d3.size == 0:
        return 0.0
    mad = np.median(np.abs(d3 - np.median(d3)))
    return 1.4826 * mad / np.sqrt(20.0)


def find_release(y, noise):
    """Index of the last sample before the ball starts to fall from the hand (0 if already falling)."""
    start_level = np.median(y[: min(3, y.size)])
    falling = np.flatnonzero(y < start_level - IMPACT_DEPTH_IN_NOISE * noise)
    if falling.size == 0:
        return None
    return max(int(falling[0]) - 1, 0)


def find_impacts(y, noise, start=0, max_lag=3):
    """Indices of the lowest sample of each bounce after ``start``.

    A bounce is a sample that is the lowest within ``lag`` samples on either side and lies at least
    ``IMPACT_DEPTH_IN_NOISE`` noise standard deviations below the samples ``lag`` steps before and
    after it, for some lag from 2 to ``max_lag``. Short lags catch the short flights of low bounces;
    long lags catch impacts sampled so densely that the ball's rounded path through the contact
    rises slowly from sample to sample. Lags are tried from short to long and a longer lag adds
    only dips farther than that lag from those already found.
    """
    depth = IMPACT_DEPTH_IN_NOISE * noise
    lags = [2]
    while lags[-1] < max_lag:
        lags.append(min(max_lag, max(lags[-1] + 1, int(lags[-1] * 1.5))))
    found = np.array([], dtype=int)
    for lag in lags:
        idx = np.arange(max(start, lag), y.size - lag)
        if idx.size == 0:
            break
        lowest = np.ones(idx.size, dtype=bool)
        for shift in range(1, lag + 1):
            lowest &= (y[idx] <= y[idx - shift]) & (y[idx] <= y[idx + shift])
        rise = np.minimum(y[idx - lag], y[idx + lag]) - y[idx]
        # the lag-2 test also accepts a rise over three samples, for slow, low bounces
        if lag == 2 and y.size > 3:
            wider = np.full(idx.size, -np.inf)
            ok = (idx >= 3) & (idx + 3 < y.size)
            wider[ok] = np.minimum(y[idx[ok] - 3], y[idx[ok] + 3]) - y[idx[ok]]
            rise = np.maximum(rise, wider)
        candidates = idx[lowest & (rise > depth)]
        if found.size:
            distance = np.min(np.abs(candidates[:, None] - found[None, :]), axis=1) if candidates.size else []
            candidates = candidates[np.asarray(distance) > lag] if candidates.size else candidates
        found = np.union1d(found, candidates)
    return found


def _last_flight_end(y, after, noise):
    """Index one past the last sample of the flight that starts at the impact sample ``after``."""
    level = y[after] + IMPACT_DEPTH_IN_NOISE * noise
    below = np.flatnonzero(y[after + 1:] <= level)
    # the first samples after the impact may still be below the level: skip them
    above = np.flatnonzero(y[after + 1:] > level)
    if above.size == 0:
        return after + 1
    later_below = below[below > above[0]]
    return after + 1 + (int(later_below[0]) if later_below.size else y.size - after - 1)


class _FlightModel:
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
        y_apex = theta[0: 2 * self.n_flights: 2]
        t_apex = theta[1: 2 * self.n_flights: 2]
        k = float(theta[-1]) if self.with_drag else self.fixed_k
        return y_apex, t_apex, k

    def residuals(self, theta):
        y_apex, t_apex, k = self.unpack(theta)
        model = flight_height(self.t, t_apex[self.flight], y_apex[self.flight], k, self.g)
        return np.nan_to_num(model - self.y, nan=1e6, neginf=-1e6, posinf=1e6)

    def jacobian(self, theta):
        y_apex, t_apex, k = self.unpack(theta)
        rows = np.arange(self.t.size)
        jac = np.zeros((self.t.size, theta.size))
        jac[rows, 2 * self.flight] = 1.0
        jac[rows, 2 * self.flight + 1] = -flight_velocity(self.t, t_apex[self.flight], 0.0, k, self.g)
        if self.with_drag:
            step = 1e-7 + 1e-6 * k
            plus = flight_height(self.t, t_apex[self.flight], y_apex[self.flight], k + step, self.g)
            minus = flight_height(self.t, t_apex[self.flight], y_apex[self.flight], max(k - step, 0.0), self.g)
            jac[:, -1] = (plus - minus) / (k + step - max(k - step, 0.0))
        return np.nan_to_num(jac)

    def lower_bounds(self, n_parameters):
        """Lower bound of every parameter: none, but k ≥ 0."""
        lower = np.full(n_parameters, -np.inf)
        if self.with_drag:
            lower[-1] = 0.0
        return lower

    def fit(self, theta0):
        if self.with_drag:
            result = least_squares(self.residuals, theta0, jac=self.jacobian, bounds=(self.lower_bounds(theta0.size), np.inf),
                                   method="trf", x_scale="jac", xtol=1e-12, ftol=1e-12)
        else:
            result = least_squares(self.residuals, theta0, jac=self.jacobian, method="lm",
                                   xtol=1e-12, ftol=1e-12)
        return result


def _parabola_start(t, y, g):
    """Closed-form known-g parabola fit y + g t²/2 = a0 + a1 t; returns (y_apex, t_apex)."""
    design = np.column_stack([np.ones_like(t), t])
    (a0, a1), *_ = np.linalg.lstsq(design, y + 0.5 * g * t**2, rcond=None)
    t_apex = a1 / g
    return a0 + 0.5 * g * t_apex**2, t_apex


def _numerical_jacobian(func, theta, lower):
    """Central-difference Jacobian of the vector function ``func`` at ``theta``, one-sided where a
    step down would cross the lower bound ``lower`` of a parameter."""
    base = func(theta)
    jac = np.empty((base.size, theta.size))
    for j in range(theta.size):
        step = 1e-6 * max(1.0, abs(theta[j]))
        up, down = theta.copy(), theta.copy()
        up[j] += step
        down[j] = max(theta[j] - step, lower[j])
        jac[:, j] = (func(up) - func(down)) / (up[j] - down[j])
    return jac


def _meeting_height(y_before, t_before, y_after, t_after, k, g):
    """Height in m where the falling branch of one flight meets the rising branch of the next."""
    def gap(height):
        touchdown = t_before + time_from_apex(y_before - height, k, g)
        liftoff = t_after - time_from_apex(y_after - height, k, g, rising=True)
        return liftoff - touchdown

    top = min(y_before, y_after)
    if k == 0.0:
        # both branches are parabolas with the same curvature: their meeting point is closed-form
        meet_t = 0.5 * (t_after + t_before) - (y_after - y_before) / (g * (t_after - t_before))
        return y_before - 0.5 * g * (meet_t - t_before) ** 2
    bottom = top - 1.0
    while gap(bottom) > 0:
        bottom -= 2 * (top - bottom)
    return brentq(gap, bottom, top, xtol=1e-13, rtol=1e-14)


class _ImpactQuantities:
    """Impact quantities as functions of θ, for values and for the delta-method covariance."""

    def __init__(self, model, contact_height_m=None):
        self.model = model
        self.n_impacts = model.n_flights - 1
        self.given_contact_height = contact_height_m
        self.weights = np.ones(self.n_impacts)
        self._meetings = {}  # (y_apex, t_apex before, after, k) → meeting height, m

    def meeting_heights(self, theta):
        # remembered per impact: a numerical Jacobian moves one parameter at a time, which changes
        # only the impacts next to its flight (k changes all), so the others need no new root search
        y_apex, t_apex, k = self.model.unpack(theta)
        heights = np.empty(self.n_impacts)
        for i in range(self.n_impacts):
            key = (y_apex[i], t_apex[i], y_apex[i + 1], t_apex[i + 1], k)
            if key not in self._meetings:
                self._meetings[key] = _meeting_height(*key, self.model.g)
            heights[i] = self._meetings[key]
        return heights

    def contact_height(self, theta):
        if self.given_contact_height is not None:
            return float(self.given_contact_height)
        return float(np.sum(self.weights * self.meeting_heights(theta)) / np.sum(self.weights))

    def __call__(self, theta):
        """Vector: contact height, then per impact (t_td, t_lo, v_in, v_out, e, e_h, ftr, flight time,
        contact time), apex heights."""
        g = self.model.g
        y_apex, t_apex, k = self.model.unpack(theta)
        contact = self.contact_height(theta)
        height_above = y_apex - contact
        before, after = height_above[:-1], height_above[1:]
        touchdown = t_apex[:-1] + time_from_apex(before, k, g)
        liftoff = t_apex[1:] - time_from_apex(after, k, g, rising=True)
        v_in = speed_below_apex(before, k, g)
        v_out = speed_below_apex(after, k, g, rising=True)
        # flight n lasts from lift-off at impact n to touchdown at impact n+1 (predicted for the last)
        end_of_last = t_apex[-1] + time_from_apex(height_above[-1], k, g)
        flight_time = np.append(touchdown[1:], end_of_last) - liftoff
        time_ratio = np.concatenate([[np.nan], flight_time[1:] / flight_time[:-1]])
        columns = [touchdown, liftoff, v_in, v_out, v_out / v_in, np.sqrt(after / before), time_ratio, flight_time,
                   liftoff - touchdown]
        return np.concatenate([[contact], np.concatenate(columns), height_above])


_IMPACT_COLUMNS = ["t_touchdown_s", "t_liftoff_s", "v_in_m_s", "v_out_m_s", "e", "e_height", "flight_time_ratio",
                   "flight_time_after_s", "t_contact_s"]


def _assign_samples(t, flights_bounds):
    """Flight index of every sample (−1 = not in any flight) for half-open time intervals."""
    flight = np.full(t.size, -1)
    for i, (start, end) in enumerate(flights_bounds):
        flight[(t > start) & (t < end)] = i
    return flight


def _fit_flights(t, y, bounds, with_drag, g, theta0, fixed_k=0.0):
    """Assign samples to the flights in ``bounds`` (list of (start, end) in s) and fit them jointly
    (k fitted, or held at ``fixed_k`` in 1/m)."""
    flight = _assign_samples(t, bounds)
    counts = np.bincount(flight[flight >= 0], minlength=len(bounds))
    if np.any(counts < MIN_SAMPLES_PER_FLIGHT):
        return None
    used = flight >= 0
    model = _FlightModel(t[used], y[used], flight[used], len(bounds), with_drag, g, fixed_k)
    return model, model.fit(theta0), counts


def detect_bounces(t, y, source="trajectory"):
    """Noise, release and the lowest sample of every bounce: the segmentation every estimator starts from.

    Parameters
    ----------
    t : numpy.ndarray
        Sample times in s, increasing, without the samples whose height is missing.
    y : numpy.ndarray
        Heights (any length unit, up) at ``t``, no NaNs.
    source : str
        Name of the recording, used in error messages.

    Returns
    -------
    (float, int, numpy.ndarray)
        Noise standard deviation (unit of ``y``), index of the release sample and indices of the
        lowest sample of each bounce.
    """
    if y.size < 3 * MIN_SAMPLES_PER_FLIGHT:
        raise InputError(f"{source}: only {y.size} valid samples, too few to find a bounce")
    noise = max(estimate_noise(y), _NOISE_FLOOR_FRACTION * float(np.ptp(y)))
    release = find_release(y, noise)
    if release is None:
        raise InputError(f"{source}: the ball never falls (height stays within noise of its start)")
    # lags up to ~10 ms: dense sampling through a contact that lasts a few milliseconds
    sample_interval = float(np.median(np.diff(t)))
    minima = find_impacts(y, noise, start=release + 1, max_lag=max(3, int(round(0.01 / sample_interval))))
    if minima.size == 0:
        raise InputError(f"{source}: no bounce found (no dip deeper than {IMPACT_DEPTH_IN_NOISE:g} noise "
                         f"standard deviations after the release)")
    return noise, release, minima


def analyse_bounces(time_s, height_m, gravity_m_s2=STANDARD_GRAVITY_M_S2, drag="auto", contact_height_m=None,
                    source="trajectory", scale_rel_se=0.0, contact_height_se_m=0.0, contact_guard_s=0.0,
                    nominal_drag_k_per_m=0.0, noise_correlation=0.0):
    """Segment a drop-test trajectory into flights, fit them and measure every impact.

    Parameters
    ----------
    time_s : array_like
        Sample times in s, increasing.
    height_m : array_like
        Height of the ball's centre in m (up), NaN where the sensor dropped out. Its zero need not
        be the floor: heights are reported above the contact height.
    gravity_m_s2 : float
        Local gravitational acceleration in m/s².
    drag : {"auto", "off", "on"}
        Quadratic air drag parameter k: fitted when BIC says the data support it, never fitted, or
        always fitted. When not fitted it is held at ``nominal_drag_k_per_m``.
    contact_height_m : float, optional
        Centre height in m at which the ball touches the floor (floor + radius), in the frame of
        ``height_m``. If omitted it is estimated where the flights before and after each impact meet,
        which assumes contact times short against the sample interval.
    source : str
        Name of the recording, used in error messages.
    scale_rel_se : float
        Relative standard error (dimensionless) of the length scale that brought the heights to m
        (a video's px → m). Its effect on every quantity (heights scaled about the zero of
        ``height_m``, the fit's linearised response, a given contact height scaled with them) is added
        to the covariance as a rank-one term, fully correlated between quantities. Not only heights
        take it up: with g known, part of a scale error is absorbed by the drag parameter, which
        moves e, √(h_n/h_{n−1}), flight times and their ratios too (a +0.5 % scale moves a tennis
        ball's first e by about −0.005). The heights' share of their standard error is also
        reported (``h_after_scale_se_m``, ``drop_height_scale_se_m``).
    contact_height_se_m : float
        Standard error in m of a given ``contact_height_m`` (e.g. of a floor found in a video); it
        enters the standard errors of the touchdown, lift-off and contact times, speeds and e.
    contact_guard_s : float
        Samples closer than this (s) to a fitted touchdown or lift-off are left out of the flights.
        0 for instantaneous samples; half the frame interval for video frames, which are exposed for
        up to a frame interval around their time and may show the ball already flattened.
    nominal_drag_k_per_m : float
        Prior value of the drag parameter in 1/m, e.g. that of a smooth sphere of the ball's size and
        mass (:func:`dropfit.physics.drag_parameter`), with relative standard error
        :data:`NOMINAL_DRAG_RELATIVE_SE`. When BIC keeps k from being fitted freely, k is held at this
        prior combined with the free fit's k (inverse-variance weights), and its standard error is
        propagated into every impact quantity. 0 = no drag.
    noise_correlation : float
        Lag-1 autocorrelation (dimensionless, 0 ≤ ρ < 1) of the height errors of successive samples,
        e.g. :data:`dropfit.tracking.TRACKED_CENTRE_CORRELATION` for a video. The fit's covariance,
        which assumes independent errors, is multiplied by (1 + ρ)/(1 − ρ), the variance factor of
        an average over AR(1) errors. 0 for a sensor's white noise.

    Returns
    -------
    BounceAnalysis
    """
    g = float(gravity_m_s2)
    t_all = np.asarray(time_s, dtype=float)
    y_all = np.asarray(height_m, dtype=float)
    valid = np.isfinite(y_all)
    t, y = t_all[valid], y_all[valid]
    noise, release, minima = detect_bounces(t, y, source)

    # first pass: cut at the lowest samples, leaving them out (and, with a known contact height,
    # the samples pressed below it)
    end_of_last = _last_flight_end(y, minima[-1], noise)
    edges = np.concatenate([[release], minima, [end_of_last]])
    bounds = []
    for start, stop in zip(edges[:-1], edges[1:]):
        if contact_height_m is not None and start != release:
            while start + 1 < stop and y[start + 1] < contact_height_m:
                start += 1
        if contact_height_m is not None and stop < t.size:
            while stop - 1 > start and y[stop - 1] < contact_height_m:
                stop -= 1
        lo = t[start] - (1e-9 if start == release else -1e-9)  # the release sample is the first of flight 0
        hi = t[stop] - 1e-9 if stop < t.size else t[-1] + 1.0
        bounds.append((lo, hi))
    # keep impacts while both neighbouring flights are sampled well enough
    counts = [np.count_nonzero((t > lo) & (t < hi)) for lo, hi in bounds]
    n_flights = next((i for i, c in enumerate(counts) if c < MIN_SAMPLES_PER_FLIGHT), len(bounds))
    if n_flights < 2:
        raise InputError(f"{source}: no bounce with at least {MIN_SAMPLES_PER_FLIGHT} samples in the flights "
                         f"before and after it")
    bounds = bounds[: _check_free_fall(t, y, bounds[:n_flights], g, source)]
    if len(bounds) < 2:
        raise InputError(f"{source}: the flight after the first bounce falls with far less than g: it hides a "
                         f"bounce too shallow to detect, and no impact is left to analyse")
    starts = []
    for lo, hi in bounds:
        inside = (t > lo) & (t < hi)
        starts.extend(_parabola_start(t[inside], y[inside], g))
    theta_no_drag = np.asarray(starts)

    with_drag = drag != "off"
    theta0 = np.append(theta_no_drag, 1e-3) if with_drag else theta_no_drag
    guard_s = float(contact_guard_s)
    held_k = float(nominal_drag_k_per_m or 0.0)
    held_k_se = NOMINAL_DRAG_RELATIVE_SE * held_k
    fit = _refine(t, y, bounds, with_drag, g, theta0, contact_height_m, noise, guard_s, held_k)
    if fit is None:
        raise InputError(f"{source}: the flights could not be fitted (too few samples between bounces)")
    bic = {with_drag: _bic(fit[1])}
    if drag == "auto":
        # compare the two models on the same samples: those the larger model kept
        model, result, _, _, final_bounds = fit
        rival = _fit_flights(t, y, final_bounds, False, g, result.x[:-1], held_k)
        bic[False] = _bic(rival[1])
        if bic[False] <= bic[True]:
            if held_k > 0:
                held_k, held_k_se = _combine_with_prior(result, held_k, held_k_se)
            fit = _refine(t, y, final_bounds, False, g, rival[1].x, contact_height_m, noise, guard_s, held_k) or fit
    return _report(fit, bic, t_all, y_all, noise, g, float(t[release]), source, held_k_se, scale_rel_se,
                   contact_height_se_m, noise_correlation)


def _combine_with_prior(result, prior_k, prior_se):
    """k (1/m) and its se from the free-k fit ``result`` combined with the prior ``prior_k`` ± ``prior_se``
    by inverse-variance weighting: flights that cannot pin k down on their own still narrow it."""
    data_se = float(np.sqrt(max(_covariance(result)[-1, -1], 0.0)))
    if not data_se > 0:
        return prior_k, prior_se
    weights = np.array([1.0 / data_se**2, 1.0 / prior_se**2])
    value = float(weights @ [result.x[-1], prior_k] / weights.sum())
    return value, float(1.0 / np.sqrt(weights.sum()))


#: The flights' own curvature may differ from g by this fraction (drag changes it by a few %).
FREE_FALL_TOLERANCE = 0.15
#: A flight whose own curvature is below this fraction of g, by more than HIDDEN_IMPACT_SIGMAS
#: standard errors, holds two flights: the detector missed the impact between them (strong drag
#: lowers a table-tennis ball's drop to 0.84 g; two flights fitted as one fall with far less).
HIDDEN_IMPACT_ACCELERATION_FRACTION = 0.5
HIDDEN_IMPACT_SIGMAS = 5.0


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
    rows, targets = [], []
    for j, (time, height) in enumerate(pieces):
        tau = time - time[0]
        block = np.zeros((tau.size, 2 * len(pieces) + 1))
        block[:, 2 * j], block[:, 2 * j + 1], block[:, -1] = 1.0, tau, -0.5 * tau**2
        rows.append(block)
        targets.append(height)
    design, target = np.vstack(rows), np.concatenate(targets)
    coef, *_ = np.linalg.lstsq(design, target, rcond=None)
    residual = target - design @ coef
    dof = max(target.size - coef.size, 1)
    covariance = (residual @ residual / dof) * np.linalg.pinv(design.T @ design)
    return float(coef[-1]), float(np.sqrt(covariance[-1, -1]))


@dataclass
class SharedAcceleration:
    """Result of :func:`shared_acceleration_with_drag`, in the length unit L of the data.

    Attributes
    ----------
    acceleration, acceleration_se : float
        Downward acceleration without drag (L/s²) and its standard error.
    drag_k, drag_k_se : float
        Quadratic-drag parameter (1/L) and its standard error; 0 for the model without drag.
    drag_model : str
        ``"quadratic"`` or ``"none"``, chosen by the Bayesian information criterion.
    """

    acceleration: float
    acceleration_se: float
    drag_k: float
    drag_k_se: float
    drag_model: str


def shared_acceleration_with_drag(pieces):
    """Free-fall acceleration shared by several flights, with a shared quadratic drag if the data ask.

    Each flight is the closed form of :func:`dropfit.physics.flight_height` (its own apex time and
    height) with a shared acceleration A and drag parameter k ≥ 0: ÿ = −A − k ẏ|ẏ|. Without drag
    the curvature of a fall underestimates A by a fraction of order k v² / A (about 0.4 % for a
    tennis ball from 254 cm). The drag term is kept only when the Bayesian information criterion
    prefers it. k in 1/L does not depend on the time unit, so A scales as (time unit)⁻² alone.

    Parameters
    ----------
    pieces : list of (numpy.ndarray, numpy.ndarray)
        Times (s) and heights (any length unit L, up) of each flight.

    Returns
    -------
    SharedAcceleration
    """
    start, start_se = shared_acceleration(pieces)
    if not start > 0:  # the flights curve upwards (e.g. a few ms of a close-up): no fall to refine
        return SharedAcceleration(start, start_se, 0.0, 0.0, "none")
    theta0 = []
    for time, height in pieces:
        theta0.extend(_parabola_start(time, height, start))
    n = len(pieces)

    def residuals(theta):
        k = theta[2 * n + 1] if theta.size > 2 * n + 1 else 0.0
        return np.concatenate([flight_height(time, theta[2 * j + 1], theta[2 * j], k, theta[2 * n]) - height
                               for j, (time, height) in enumerate(pieces)])

    fits = {}
    for model, extra in (("none", [start]), ("quadratic", [start, 0.0])):
        theta = np.array(theta0 + extra)
        lower = np.full(theta.size, -np.inf)
        lower[2 * n] = 0.0  # the acceleration points down
        if model == "quadratic":
            lower[-1] = 0.0
        fits[model] = least_squares(residuals, theta, bounds=(lower, np.inf), x_scale="jac", xtol=1e-12,
                                    ftol=1e-12)
    model = "quadratic" if _bic(fits["quadratic"]) < _bic(fits["none"]) else "none"
    result = fits[model]
    se = np.sqrt(np.clip(np.diag(_covariance(result)), 0.0, None))
    drag = model == "quadratic"
    return SharedAcceleration(float(result.x[2 * n]), float(se[2 * n]), float(result.x[-1]) if drag else 0.0,
                              float(se[-1]) if drag else 0.0, model)


def _check_free_fall(t, y, bounds, g, source):
    """Raise InputError unless the flights, fitted with a free curvature, fall with about g.

    Wrong units (time in ms under a ``time_s`` header, heights in cm under ``y_m``) change the
    apparent acceleration of every flight by orders of magnitude; catching it here names the cause.
    A flight that hides an impact the detector missed falls with far less than g on its own: the
    units are judged on the flights before the first such flight, and the bounce sequence stops
    there.

    Returns
    -------
    int
        The number of first flights before the first one that hides an impact (all of them if none).
    """
    inside = [(t > lo) & (t < hi) for lo, hi in bounds]
    pieces = [(t[mask], y[mask]) for mask in inside]
    kept = len(pieces)
    for i, piece in enumerate(pieces):
        own, own_se = shared_acceleration([piece])
        if own < HIDDEN_IMPACT_ACCELERATION_FRACTION * g and g - own > HIDDEN_IMPACT_SIGMAS * own_se:
            kept = i
            break
    acceleration, _ = shared_acceleration(pieces[: max(kept, 1)])
    if not abs(acceleration / g - 1.0) < FREE_FALL_TOLERANCE:
        raise InputError(f"{source}: the flights fall with {acceleration:.4g} m/s², not g = {g:g} m/s²: check the "
                         f"units of time and height in the column names (or the scale of a px log)")
    return kept


def _refine(t, y, bounds, with_drag, g, theta0, contact_height_m, noise, guard_s, fixed_k=0.0):
    """Alternate fitting and re-assigning samples by the fitted touchdown and lift-off times.

    A flight keeps the samples more than ``guard_s`` (s) after the lift-off before it and before
    the touchdown after it.
    """
    fitted = _fit_flights(t, y, bounds, with_drag, g, theta0, fixed_k)
    if fitted is None:
        return None
    spurious = _first_spurious_impact(*fitted[:2])
    if spurious is not None:
        # a noise dip split one flight in two: join them again
        i = spurious
        merged = bounds[:i] + [(bounds[i][0], bounds[i + 1][1])] + bounds[i + 2:]
        theta = np.delete(fitted[1].x, [2 * i + 2, 2 * i + 3])
        return _refine(t, y, merged, with_drag, g, theta, contact_height_m, noise, guard_s, fixed_k)
    for _ in range(_REFINEMENT_PASSES):
        model, result, counts = fitted
        quantities = _ImpactQuantities(model, contact_height_m)
        _set_weights(quantities, result)
        values = _unpack_quantities(quantities(result.x), quantities.n_impacts)
        y_apex, t_apex, k = model.unpack(result.x)
        starts = np.concatenate([[t_apex[0] - 1e-9], values["t_liftoff_s"] + guard_s])
        last_end = t_apex[-1] + time_from_apex(y_apex[-1] - values["contact_height_m"], k, g)
        ends = np.append(values["t_touchdown_s"] - guard_s, last_end - guard_s)
        new_bounds = list(zip(starts, ends))
        refitted = _fit_flights(t, y, new_bounds, with_drag, g, result.x, fixed_k)
        if refitted is None:
            break
        fitted, bounds = refitted, new_bounds
    model, result, counts = fitted
    misfit = _first_misfit_flight(model, result, noise)
    if misfit is not None and misfit >= 2:
        # an impact too shallow to be detected hides inside this flight: stop the sequence before it
        theta = np.concatenate([result.x[: 2 * misfit], result.x[2 * model.n_flights:]])
        return _refine(t, y, bounds[:misfit], with_drag, g, theta, contact_height_m, noise, guard_s, fixed_k)
    quantities = _ImpactQuantities(model, contact_height_m)
    _set_weights(quantities, result)
    return model, result, counts, quantities, bounds


#: An impact must reverse the velocity by this many standard errors; a noise dip does not reverse it.
VELOCITY_REVERSAL_IN_SE = 3.0


def _first_spurious_impact(model, result):
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
    jac = _numerical_jacobian(velocity_jump, result.x, model.lower_bounds(result.x.size))
    se = np.sqrt(np.clip(np.einsum("ij,jk,ik->i", jac, _covariance(result), jac), 0.0, None))
    spurious = np.flatnonzero(jump < VELOCITY_REVERSAL_IN_SE * se)
    return int(spurious[0]) if spurious.size else None


def _first_misfit_flight(model, result, noise):
    """Index of the first flight whose residuals are too large for the noise (χ² test, p < 1e-4)."""
    for i in range(model.n_flights):
        residual = result.fun[model.flight == i]
        chi2 = float(residual @ residual) / noise**2
        if stats.chi2.sf(chi2, max(residual.size - 2, 1)) < MISFIT_P_VALUE:
            return i
    return None


def _covariance(result):
    """Parameter covariance σ² (JᵀJ)⁻¹ with σ² from the residuals."""
    dof = max(result.fun.size - result.x.size, 1)
    sigma2 = float(result.fun @ result.fun) / dof
    return sigma2 * np.linalg.pinv(result.jac.T @ result.jac)


def _set_weights(quantities, result):
    """Weight each impact's meeting height by its inverse variance (weights then held fixed)."""
    if quantities.given_contact_height is not None or quantities.n_impacts == 0:
        return
    jac = _numerical_jacobian(quantities.meeting_heights, result.x, quantities.model.lower_bounds(result.x.size))
    variance = np.einsum("ij,jk,ik->i", jac, _covariance(result), jac)
    quantities.weights = 1.0 / np.maximum(variance, 1e-30)


def _bic(result):
    """Bayesian information criterion of a least-squares fit with Gaussian noise."""
    n = result.fun.size
    rss = float(result.fun @ result.fun)
    return n * np.log(max(rss, 1e-300) / n) + result.x.size * np.log(n)


def _unpack_quantities(vector, n_impacts):
    values = {"contact_height_m": vector[0]}
    for j, name in enumerate(_IMPACT_COLUMNS):
        values[name] = vector[1 + j * n_impacts: 1 + (j + 1) * n_impacts]
    values["apex_height_m"] = vector[1 + len(_IMPACT_COLUMNS) * n_impacts:]
    return values


def _contact_height_derivative(quantities, theta, step_m=1e-6):
    """Derivative of the impact quantities with respect to a given contact height (central difference)."""
    height = quantities.given_contact_height
    upper = _ImpactQuantities(quantities.model, height + step_m)(theta)
    lower = _ImpactQuantities(quantities.model, height - step_m)(theta)
    return (upper - lower) / (2 * step_m)


def _report(fit, bic, t_all, y_all, noise, g, release_time, source, held_k_se, scale_rel_se, contact_height_se_m,
            noise_correlation):
    model, result, counts, quantities, bounds = fit
    theta = result.x
    # AR(1) errors: the variance of what a fit averages grows by (1 + ρ)/(1 − ρ)
    inflation = (1.0 + noise_correlation) / (1.0 - noise_correlation)
    cov_theta = inflation * _covariance(result)
    vector = quantities(theta)
    jac = _numerical_jacobian(quantities, theta, model.lower_bounds(theta.size))
    cov = jac @ cov_theta @ jac.T
    if model.with_drag:
        k_variance = float(cov_theta[-1, -1])
        drag_covariance = jac @ cov_theta[:, -1]
    else:
        k_variance = held_k_se**2
        sensitivity = _fixed_drag_sensitivity(model, result, quantities, jac) if model.fixed_k > 0 \
            else np.zeros(vector.size)
        cov += k_variance * np.outer(sensitivity, sensitivity)
        drag_covariance = k_variance * sensitivity
    # the length scale's error moves every quantity together: a rank-one term in their covariance
    scale_part = scale_rel_se * np.nan_to_num(_scale_sensitivity(quantities, result)) if scale_rel_se \
        else np.zeros(vector.size)
    cov += np.outer(scale_part, scale_part)
    if quantities.given_contact_height is not None and contact_height_se_m > 0:
        height_derivative = _contact_height_derivative(quantities, theta)
        cov += np.outer(height_derivative, height_derivative) * contact_height_se_m ** 2
    se = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    n = quantities.n_impacts
    values = _unpack_quantities(vector, n)
    errors = _unpack_quantities(se, n)
    scale_errors = _unpack_quantities(np.abs(scale_part), n)
    y_apex, t_apex, k = model.unpack(theta)
    theta_se = np.sqrt(np.clip(np.diag(cov_theta), 0.0, None))

    residual_rms = np.array([np.sqrt(np.mean(result.fun[model.flight == i] ** 2)) for i in range(model.n_flights)])
    flights = pd.DataFrame({
        "flight": np.arange(model.n_flights),
        "t_start_s": [b[0] for b in bounds],
        "t_end_s": [b[1] for b in bounds],
        "t_apex_s": t_apex,
        "t_apex_se_s": theta_se[1: 2 * model.n_flights: 2],
        "y_apex_m": y_apex,
        "y_apex_se_m": theta_se[0: 2 * model.n_flights: 2],
        "n_samples": counts,
        "residual_rms_m": residual_rms,
    })
    _add_with_interval(flights, "apex_height_m", values["apex_height_m"], errors["apex_height_m"])
    e_index = 1 + _IMPACT_COLUMNS.index("e") * n
    impacts = pd.DataFrame({"impact": np.arange(1, n + 1)})
    for name in _IMPACT_COLUMNS[:-1]:
        _add_with_interval(impacts, name, values[name], errors[name])
    _add_with_interval(impacts, "h_before_m", values["apex_height_m"][:-1], errors["apex_height_m"][:-1])
    _add_with_interval(impacts, "h_after_m", values["apex_height_m"][1:], errors["apex_height_m"][1:])
    impacts["h_before_scale_se_m"] = scale_errors["apex_height_m"][:-1]
    impacts["h_after_scale_se_m"] = scale_errors["apex_height_m"][1:]
    contact_ms, contact_se_ms = 1e3 * values["t_contact_s"], 1e3 * errors["t_contact_s"]
    if quantities.given_contact_height is not None and np.any(contact_ms < -3 * contact_se_ms - 1e-6):
        raise InputError(f"{source}: the flights meet above the given contact height (floor + radius): "
                         f"the floor is lower than that; check floor_m and the ball radius")
    _add_with_interval(impacts, "t_contact_ms", contact_ms, contact_se_ms)
    sample_interval = float(np.median(np.diff(t_all)))
    impacts["contact_resolvable"] = _contact_resolvable(contact_ms, contact_se_ms, sample_interval,
                                                        quantities.given_contact_height is not None)
    impacts["n_samples_before"] = counts[:-1]
    impacts["n_samples_after"] = counts[1:]

    contact = values["contact_height_m"]
    summary = {
        "contact_height_m": contact,
        "contact_height_se_m": errors["contact_height_m"],
        "contact_height_source": "given" if quantities.given_contact_height is not None else
        "estimated where the flights before and after each impact meet",
        "drag_model": "quadratic" if model.with_drag else "nominal" if model.fixed_k > 0 else "none",
        "drag_k_per_m": k,
        "drag_k_se_per_m": float(np.sqrt(k_variance)),
        "bic_no_drag": bic.get(False, np.nan),
        "bic_quadratic_drag": bic.get(True, np.nan),
        "noise_m": float(noise),
        "residual_rms_m": float(np.sqrt(np.mean(result.fun**2))),
        "sample_interval_s": sample_interval,
        "release_time_s": release_time,
        "drop_apex_time_s": float(t_apex[0]),
        "drop_height_m": float(values["apex_height_m"][0]),
        "drop_height_se_m": float(errors["apex_height_m"][0]),
        "drop_height_scale_se_m": float(scale_errors["apex_height_m"][0]),
        "rest_time_s": _rest_time(t_all, y_all, contact, noise, after=float(values["t_liftoff_s"][-1])),
        "gravity_m_s2": g,
        "n_impacts": n,
        "scale_rel_se": float(scale_rel_se),
        "noise_correlation": float(noise_correlation),
    }
    contact_index = 1 + _IMPACT_COLUMNS.index("t_contact_s") * n
    pair = np.r_[e_index: e_index + n, contact_index: contact_index + n]
    return BounceAnalysis(flights=flights, impacts=impacts, e_covariance=cov[e_index: e_index + n, e_index: e_index + n],
                          e_contact_covariance=cov[np.ix_(pair, pair)],
                          e_drag_covariance=drag_covariance[e_index: e_index + n], summary=summary)


def _scale_sensitivity(quantities, result, step=1e-6):
    """Derivative of the quantity vector with respect to the relative scale error ε.

    A scale off by ε multiplies every height (about the trajectory's zero) and a given contact height
    by 1 + ε. The fit answers with δθ = ε (JᵀJ)⁻¹Jᵀy (linearised, as in the covariance); with g known
    it does not simply scale the heights, because the flight times also tell them.
    """
    response = np.linalg.lstsq(result.jac, quantities.model.y, rcond=None)[0]
    moved = quantities
    if quantities.given_contact_height is not None:
        moved = _ImpactQuantities(quantities.model, quantities.given_contact_height * (1.0 + step))
    moved.weights = quantities.weights
    return (moved(result.x + step * response) - quantities(result.x)) / step


def _fixed_drag_sensitivity(model, result, quantities, jac):
    """Total derivative of the quantities with respect to a held drag parameter k (per 1/m): the
    direct change at fixed θ plus the change through θ, refitted by least squares to the new k."""
    k = model.fixed_k
    step = 1e-3 * k

    def at(k_value, function):
        model.fixed_k = k_value
        try:
            return function(result.x)
        finally:
            model.fixed_k = k

    residual_slope = (at(k + step, model.residuals) - at(k - step, model.residuals)) / (2 * step)
    direct = (at(k + step, quantities) - at(k - step, quantities)) / (2 * step)
    return direct - jac @ (np.linalg.pinv(result.jac) @ residual_slope)


def _add_with_interval(table, column, value, se):
    """Add a column, its standard error and its normal 95 % interval (``_ci95_low``/``_ci95_high``)."""
    table[column] = value
    table[_se_name(column)] = se
    table[_se_name(column, "ci95_low")] = value - Z95 * se
    table[_se_name(column, "ci95_high")] = value + Z95 * se


def _se_name(column, tag="se"):
    """Name of a column's standard error (or other ``tag``) that keeps the unit suffix last:
    v_in_m_s → v_in_se_m_s, t_contact_ms → t_contact_se_ms."""
    for unit in ("_m_s", "_ms", "_s", "_m"):
        if column.endswith(unit):
            return column[: -len(unit)] + f"_{tag}" + unit
    return column + f"_{tag}"


def _contact_resolvable(contact_ms, contact_se_ms, sample_interval_s, contact_height_given):
    """A contact time means something only if the contact height is known independently of it,
    the sampling resolves it, and it stands well clear of its own uncertainty."""
    if not contact_height_given:
        return np.zeros(contact_ms.size, dtype=bool)
    return (contact_ms > 2e3 * sample_interval_s) & (contact_ms > 5 * contact_se_ms)


def _rest_time(t, y, contact_height, noise, after):
    """First time after ``after`` (s) from which the ball stays within 5 noise σ of the contact height,
    or NaN if it is still bouncing when the log ends."""
    finite = np.isfinite(y)
    t, y = t[finite], y[finite]
    away = np.flatnonzero((np.abs(y - contact_height) > IMPACT_DEPTH_IN_NOISE * noise) | (t <= after))
    if away.size == 0 or away[-1] + 1 >= t.size:
        return float("nan")
    return float(t[away[-1] + 1])
