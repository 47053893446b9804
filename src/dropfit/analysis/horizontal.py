"""Oblique bounces: the horizontal motion of a 2-D recording, after the vertical analysis.

Each flight's horizontal position x(t) is fitted on the samples the vertical fit gave that flight (the
flights table's time windows): a line, or with a quadratic drag k shared by all flights when the
Bayesian information criterion prefers it (:func:`dropfit.physics.horizontal_position`, the drag
model of the vertical flights along x). At every impact the tangential velocities before (at
touchdown) and after (at lift-off) follow, with the angles of the velocity above the floor and the
seed's check of a smooth floor, tan θ′ = e tan θ (the tangential velocity kept, the normal one
reversed with e).

e stays the vertical analysis' alone: this module reads the impacts table (touchdown and lift-off
times, the normal speeds ``v_in_m_s`` and ``v_out_m_s``) and adds columns to it, so a horizontal
drift never moves e.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from ..numerics import jacobian, propagate, robust_sigma
from ..physics import horizontal_position, horizontal_velocity
from ..restitution import estimate
from .flights import MIN_SAMPLES_PER_FLIGHT, bic, fit_covariance
from .tables import add_with_interval
from .uncertainty import correlated_noise_factor

#: A sample whose horizontal residual exceeds this many robust standard deviations is left out
#: (a tracker jump in x); the same threshold as the vertical fit's outliers.
HORIZONTAL_OUTLIER_SIGMAS = 5.0
#: A horizontal velocity below this many standard errors is no horizontal motion: the angle check is
#: not made (a vertical drop filmed by a video has x, but no tangential velocity to keep or lose).
MOTION_IN_SE = 3.0
#: The angle check calls the tangential velocity changed beyond this many standard errors of
#: tan θ′ − e tan θ (0.3 % false alarms per impact on a smooth floor).
ANGLE_CHECK_IN_SE = 3.0

#: The columns added to the impacts table (each number with ``_se`` and a 95 % interval), in order.
HORIZONTAL_COLUMNS = ["vx_in_m_s", "vx_out_m_s", "delta_vx_m_s", "tangential_ratio", "theta_in_deg",
                      "theta_out_deg", "tan_theta_out", "e_tan_theta_in"]


@dataclass
class HorizontalFit:
    """The joint fit of every flight's x(t): θ = (x_ref_0, u_ref_0, …, [k]), each flight's position (m) and
    velocity (m/s) at its reference time ``t_ref`` (s, the mean time of its samples) and, with
    ``with_drag``, the shared drag parameter k (1/m); ``covariance`` of θ; ``n_samples`` per flight
    (0 for a flight without enough x samples, whose values are NaN); ``bic`` of the line and drag models
    tried; ``noise_m``, the residuals' robust standard deviation."""

    t_ref: np.ndarray
    theta: np.ndarray
    covariance: np.ndarray
    with_drag: bool
    n_samples: np.ndarray
    bic: dict
    noise_m: float

    def drag_k(self, theta):
        """k (1/m) of ``theta``: fitted, or 0 for lines."""
        return float(theta[-1]) if self.with_drag else 0.0

    def velocity(self, theta, flight, t):
        """Horizontal velocity (m/s) of ``flight`` at time ``t`` (s)."""
        return horizontal_velocity(t, self.t_ref[flight], theta[2 * flight], theta[2 * flight + 1],
                                   self.drag_k(theta))

    def position(self, theta, flight, t):
        """Horizontal position (m) of ``flight`` at times ``t`` (s)."""
        return horizontal_position(t, self.t_ref[flight], theta[2 * flight], theta[2 * flight + 1],
                                   self.drag_k(theta))


def fit_horizontal(time_s, x_m, bounds, drag="auto", noise_correlation=0.0):
    """Fit every flight's horizontal position jointly: lines, or with a shared quadratic drag.

    Parameters
    ----------
    time_s, x_m : numpy.ndarray
        Sample times (s) and horizontal positions (m, NaN where not measured).
    bounds : list of (float, float)
        Each flight's time window (s, open), as the vertical fit assigned its samples.
    drag : {"auto", "off", "on"}
        The analysis' drag option: k fitted when the BIC prefers it, never, or always.
    noise_correlation : float
        Lag-1 autocorrelation of successive samples' errors (a video's tracked centre); the covariance
        is widened by (1 + ρ)/(1 − ρ) as the vertical fit's is.

    Returns
    -------
    HorizontalFit or None
        None when no flight has :data:`MIN_SAMPLES_PER_FLIGHT` samples with x.
    """
    time_s, x_m = np.asarray(time_s, dtype=float), np.asarray(x_m, dtype=float)
    pieces = []
    for start, end in bounds:
        inside = (time_s > start) & (time_s < end) & np.isfinite(x_m)
        pieces.append((time_s[inside], x_m[inside]))
    usable = np.array([t.size >= MIN_SAMPLES_PER_FLIGHT for t, _ in pieces])
    if not usable.any():
        return None
    t_ref = np.array([t.mean() if ok else np.nan for (t, _), ok in zip(pieces, usable)])
    kept = [np.ones(t.size, dtype=bool) for t, _ in pieces]
    for attempt in range(3):  # fit, leave out the outliers (tracker jumps in x), fit again
        fits = {False: _joint_fit(pieces, kept, usable, t_ref, False)}
        if drag != "off":
            fits[True] = _joint_fit(pieces, kept, usable, t_ref, True)
        with_drag = drag == "on" or (drag == "auto" and bic(fits[True][0]) < bic(fits[False][0]))
        result, theta = fits[with_drag]
        noise = robust_sigma(result.fun)
        outliers = np.abs(result.fun) > HORIZONTAL_OUTLIER_SIGMAS * max(noise, 1e-12)
        if not outliers.any() or attempt == 2:
            break
        start = 0
        for flight in np.flatnonzero(usable):
            used = np.flatnonzero(kept[flight])
            kept[flight][used[outliers[start: start + used.size]]] = False
            start += used.size
    free = np.isfinite(theta)
    covariance = np.zeros((theta.size, theta.size))
    covariance[np.ix_(free, free)] = correlated_noise_factor(noise_correlation) * fit_covariance(result)
    counts = np.array([np.count_nonzero(k) if ok else 0 for k, ok in zip(kept, usable)])
    return HorizontalFit(t_ref, theta, covariance, with_drag, counts,
                         {name: bic(fit[0]) for name, fit in zip(("line", "quadratic drag"), fits.values())},
                         float(robust_sigma(result.fun)))


def _joint_fit(pieces, kept, usable, t_ref, with_drag):
    """Least-squares fit of the usable flights' kept samples: scipy's result (over the free parameters)
    and the full θ (NaN for the flights without samples)."""
    flights = np.flatnonzero(usable)
    starts = []
    for flight in range(len(pieces)):
        t, x = (part[kept[flight]] for part in pieces[flight])
        if flight in flights:
            slope, intercept = np.polyfit(t - t_ref[flight], x, 1)
            starts.extend([intercept, slope])
        else:
            starts.extend([np.nan, np.nan])
    theta0 = np.array(starts + ([1e-3] if with_drag else []))
    free = np.isfinite(theta0)

    def residuals(values):
        theta = theta0.copy()
        theta[free] = values
        k = theta[-1] if with_drag else 0.0
        return np.concatenate([horizontal_position(pieces[f][0][kept[f]], t_ref[f], theta[2 * f], theta[2 * f + 1], k)
                               - pieces[f][1][kept[f]] for f in flights])

    lower = np.full(np.count_nonzero(free), -np.inf)
    if with_drag:
        lower[-1] = 0.0
    result = least_squares(residuals, theta0[free], bounds=(lower, np.inf), x_scale="jac", xtol=1e-12, ftol=1e-12)
    full = theta0.copy()
    full[free] = result.x
    return result, full


def horizontal_velocities(fit, touchdown_s, liftoff_s, touchdown_se_s, liftoff_se_s):
    """Each impact's horizontal velocity before (at touchdown, flight n − 1) and after (at lift-off,
    flight n), m/s, and their covariance: the x fit's, plus the touchdown and lift-off times' standard
    errors (s; from the vertical fit, independent of x) times the drag's deceleration.

    Returns
    -------
    (numpy.ndarray, numpy.ndarray)
        (vx_in_1, vx_out_1, vx_in_2, …), shape (2n,), and its covariance, shape (2n, 2n).
    """
    n = len(touchdown_s)

    def velocities(free_theta):
        theta = fit.theta.copy()
        theta[np.isfinite(fit.theta)] = free_theta
        return np.ravel([[fit.velocity(theta, i, touchdown_s[i]), fit.velocity(theta, i + 1, liftoff_s[i])]
                         for i in range(n)])

    free = np.isfinite(fit.theta)
    values = velocities(fit.theta[free])
    lower = np.full(np.count_nonzero(free), -np.inf)
    if fit.with_drag:
        lower[-1] = 0.0
    covariance = propagate(jacobian(velocities, fit.theta[free], lower), fit.covariance[np.ix_(free, free)])
    k = fit.drag_k(fit.theta)
    times_se = np.ravel(np.column_stack([touchdown_se_s, liftoff_se_s]))
    # dvx/dt = −k vx|vx|: a touchdown known to ±1 ms moves vx by k vx² × 1 ms
    covariance += np.diag((k * values * np.abs(values) * times_se) ** 2)
    return values, covariance


def impact_angles(v_in, v_out, v_in_se, v_out_se, vx_pair, vx_covariance):
    """One impact's oblique quantities and their standard errors, from its normal speeds (m/s, > 0, from
    the vertical fit) and its horizontal velocities before and after (m/s, with their 2 × 2 covariance).

    Angles are of the velocity above the floor, as in the seed (tan θ = v_n / |v_t|), so a smooth floor
    gives tan θ′ = e tan θ = v_out / |vx_in|.

    Returns
    -------
    (dict, float)
        Value and se of every column of :data:`HORIZONTAL_COLUMNS`, and the standard error of
        tan θ′ − e tan θ (their covariance taken into account).
    """
    def quantities(p):
        speed_in, speed_out, vx_in, vx_out = p
        tan_out, e_tan_in = speed_out / abs(vx_out), speed_out / abs(vx_in)
        return np.array([vx_in, vx_out, vx_out - vx_in, vx_out / vx_in,
                         np.degrees(np.arctan2(speed_in, abs(vx_in))), np.degrees(np.arctan2(speed_out, abs(vx_out))),
                         tan_out, e_tan_in, tan_out - e_tan_in])

    p = np.array([v_in, v_out, *vx_pair])
    covariance = np.zeros((4, 4))
    covariance[0, 0], covariance[1, 1] = v_in_se**2, v_out_se**2
    covariance[2:, 2:] = vx_covariance
    with np.errstate(divide="ignore", invalid="ignore"):
        values = quantities(p)
        se = np.sqrt(np.clip(np.diag(propagate(jacobian(quantities, p), covariance)), 0.0, None))
    return dict(zip(HORIZONTAL_COLUMNS, zip(values[:-1], se[:-1]))), float(se[-1])


def angle_verdict(vx_in, vx_in_se, tan_out, e_tan_in, difference_se):
    """The seed's check of one impact in words: tan θ′ against e tan θ.

    "not tested" when the ball had no horizontal motion to speak of (|vx_in| below
    :data:`MOTION_IN_SE` standard errors); "consistent: tangential velocity kept" when tan θ′ − e tan θ
    lies within :data:`ANGLE_CHECK_IN_SE` standard errors of 0; else the share of the tangential
    velocity lost (friction or spin) or gained (spin).
    """
    if not abs(vx_in) > MOTION_IN_SE * vx_in_se:
        return f"not tested: no horizontal motion resolved (vx_in = {vx_in:.3g} ± {vx_in_se:.2g} m/s)"
    difference = tan_out - e_tan_in
    if not abs(difference) > ANGLE_CHECK_IN_SE * difference_se:
        return "consistent: tangential velocity kept"
    change = e_tan_in / tan_out - 1.0  # = |vx_out| / |vx_in| − 1
    if change < 0:
        return f"tangential velocity lost {-100 * change:.1f} %: friction or spin"
    return f"tangential velocity gained {100 * change:.1f} %: spin"


def add_horizontal(analysis, time_s, x_m, drag="auto", noise_correlation=0.0):
    """The analysis with the oblique columns added to its impacts table and a ``horizontal`` record in its
    summary.

    Parameters
    ----------
    analysis : dropfit.analysis.BounceAnalysis
        The vertical analysis (tables' times in s on the trajectory's clock).
    time_s, x_m : numpy.ndarray
        The trajectory's time (s) and horizontal position (m).
    drag, noise_correlation
        As :func:`fit_horizontal`.

    Returns
    -------
    dropfit.analysis.BounceAnalysis
        With every column of :data:`HORIZONTAL_COLUMNS` (with ``_se`` and the 95 % interval) and
        ``angle_check`` (words) in the impacts table, and the summary's ``horizontal``
        (:func:`horizontal_record`); unchanged when x has too few samples.
    """
    impacts, flights, summary = analysis.impacts, analysis.flights, analysis.summary
    bounds = list(zip(flights["t_start_s"], flights["t_end_s"]))
    fit = fit_horizontal(time_s, x_m, bounds, drag, noise_correlation)
    if fit is None:
        return analysis
    vx, vx_covariance = horizontal_velocities(fit, impacts["t_touchdown_s"].to_numpy(), impacts["t_liftoff_s"].to_numpy(),
                                              impacts["t_touchdown_se_s"].to_numpy(),
                                              impacts["t_liftoff_se_s"].to_numpy())
    columns = {name: ([], []) for name in HORIZONTAL_COLUMNS}
    verdicts = []
    for i, row in enumerate(impacts.itertuples(index=False)):
        pair = slice(2 * i, 2 * i + 2)
        values, difference_se = impact_angles(row.v_in_m_s, row.v_out_m_s, row.v_in_se_m_s, row.v_out_se_m_s,
                                              vx[pair], vx_covariance[pair, pair])
        for name, (value, se) in values.items():
            columns[name][0].append(value)
            columns[name][1].append(se)
        verdicts.append(angle_verdict(*values["vx_in_m_s"], values["tan_theta_out"][0],
                                      values["e_tan_theta_in"][0], difference_se))
    impacts = impacts.copy()
    for name, (value, se) in columns.items():
        add_with_interval(impacts, name, np.array(value), np.array(se))
    impacts["angle_check"] = verdicts
    return dataclasses.replace(analysis, impacts=impacts,
                               summary={**summary, "horizontal": horizontal_record(fit, summary, time_s, x_m)})


def horizontal_record(fit, summary, time_s, x_m):
    """The summary's ``horizontal`` record: the drag model of x, the release's horizontal speed u (m/s, flight
    0 at its apex) with its se, and the distance (m) from the release to where the ball is when it comes
    to rest (the samples interpolated; NaN if it never does)."""
    free = np.isfinite(fit.theta)
    apex = float(summary["drop_apex_time_s"])

    def release_speed(values):
        theta = fit.theta.copy()
        theta[free] = values
        return np.array([fit.velocity(theta, 0, apex)])

    u = float(release_speed(fit.theta[free])[0])
    u_se = float(np.sqrt(propagate(jacobian(release_speed, fit.theta[free]), fit.covariance[np.ix_(free, free)])[0, 0]))
    finite = np.isfinite(x_m)
    rest = summary.get("rest_time_s", np.nan)
    x_release = float(fit.position(fit.theta, 0, apex)) if fit.n_samples[0] else np.nan
    x_rest = float(np.interp(rest, time_s[finite], x_m[finite])) if np.isfinite(rest) else np.nan
    return {"drag_model": "quadratic" if fit.with_drag else "none",
            "drag_k_per_m": estimate(fit.drag_k(fit.theta), np.sqrt(fit.covariance[-1, -1]) if fit.with_drag else 0.0,
                                     "1/m"),
            "bic": fit.bic, "release_speed_m_s": u, "release_speed_se_m_s": u_se,
            "distance_to_rest_m": x_rest - x_release, "noise_m": fit.noise_m,
            "n_samples": fit.n_samples.tolist()}


def distance_check(record, total_bouncing_time):
    """The seed's distance travelled while bouncing, u t∞, against the measured one (``fit.json``'s
    ``theory.horizontal_distance``).

    Parameters
    ----------
    record : dict
        The summary's ``horizontal`` record (:func:`horizontal_record`; read back from JSON, a missing
        number is None).
    total_bouncing_time : dict
        The theory check of t∞ (:func:`dropfit.restitution.theory_checks`): ``predicted`` t∞ (s) with
        its se.

    Returns
    -------
    dict
        ``predicted``: u t∞ (m) with its se (those of u and t∞, independent: one from x, the other
        from y); ``release_speed``: u (m/s); ``measured_m``: the distance from the release to where the
        ball comes to rest (m, NaN if it does not); and a note.
    """
    def number(value):
        return float("nan") if value is None else float(value)

    u, u_se = number(record["release_speed_m_s"]), number(record["release_speed_se_m_s"])
    t_inf, t_inf_se = total_bouncing_time["predicted"]["value"], total_bouncing_time["predicted"]["se"]
    return {"predicted": estimate(u * t_inf, np.hypot(u_se * t_inf, u * t_inf_se), "m"),
            "release_speed": estimate(u, u_se, "m/s"),
            "measured_m": number(record["distance_to_rest_m"]),
            "note": "u t_inf: the release's horizontal speed times the predicted total bouncing time (constant e, "
                    "no drag, smooth floor); the measured distance ends where the measured bouncing time does"}
