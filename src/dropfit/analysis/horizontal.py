"""Oblique bounces: the horizontal motion of a 2-D recording, after the vertical analysis.

Each flight's horizontal position x(t) is fitted on the samples the vertical fit gave that flight (the
flights table's time windows), with the vertical analysis' drag: quadratic drag acts on the full
velocity, so u slows by k u √(u² + v²) with v the fitted vertical flight's velocity
(:func:`dropfit.physics.horizontal_flight`); without drag x is a line. The drag parameter k is the
vertical fit's, held, and its standard error is carried into every horizontal quantity. At every
impact the tangential velocities before (at touchdown) and after (at lift-off) follow, with the angles
of the velocity above the floor and the seed's check of a smooth floor, tan θ′ = e tan θ (the
tangential velocity kept, the normal one reversed with e).

e stays the vertical analysis' alone: this module reads the analysis' tables (touchdown and lift-off
times, the normal speeds ``v_in_m_s`` and ``v_out_m_s``, the flights' apexes) and adds columns to the
impacts table, so a horizontal drift never moves e.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ..numerics import jacobian, linear_fit, propagate, robust_sigma
from ..physics import horizontal_flight
from ..restitution import estimate
from .flights import MIN_SAMPLES_PER_FLIGHT
from .tables import add_with_interval
from .uncertainty import correlated_noise_factor

#: A sample whose horizontal residual exceeds this many robust standard deviations is left out
#: (a tracker jump in x); the same threshold as the vertical fit's outliers.
HORIZONTAL_OUTLIER_SIGMAS = 5.0
#: Passes of "fit, recompute the drag's shape of u(t) with the fitted u": the shape depends on u only
#: through the drag, weakly.
SHAPE_PASSES = 2
#: A horizontal velocity below this many standard errors is no horizontal motion: the angle check is
#: not made (a vertical drop filmed by a video has x, but no tangential velocity to keep or lose).
MOTION_IN_SE = 3.0
#: The angle check calls the tangential velocity changed beyond this many standard errors of
#: tan θ′ − e tan θ (0.3 % false alarms per impact on a smooth floor).
ANGLE_CHECK_IN_SE = 3.0

#: The columns added to the impacts table (each number with ``_se`` and a 95 % interval), in order.
HORIZONTAL_COLUMNS = ["vx_in_m_s", "vx_out_m_s", "delta_vx_m_s", "tangential_ratio", "theta_in_deg",
                      "theta_out_deg", "tan_theta_out", "e_tan_theta_in"]


def fit_flight_x(t, x, apex, k, g, noise_correlation=0.0):
    """One flight's horizontal motion: x = x_ref + u_ref d(t), with the drag's shape d(t) (s) of
    :func:`dropfit.physics.horizontal_flight` per unit u_ref, fitted by linear least squares; samples
    more than :data:`HORIZONTAL_OUTLIER_SIGMAS` robust standard deviations off are left out.

    Parameters
    ----------
    t, x : numpy.ndarray
        The flight's sample times (s) and horizontal positions (m).
    apex : (float, float)
        The vertical flight's apex time (s) and height (m).
    k, g : float
        The drag parameter (1/m; 0 for a line) and g (m/s²).
    noise_correlation : float
        Lag-1 autocorrelation of successive samples' errors; the covariance is widened by
        (1 + ρ)/(1 − ρ) as the vertical fit's is.

    Returns
    -------
    dict or None
        ``t_ref`` (s, the samples' mean time), ``u_ref`` (m/s) with ``u_ref_se``, ``x_ref`` (m), the
        ``motion`` function t ↦ (x in m, u in m/s), ``n_samples``, the residuals' ``noise_m`` and their sum
        of squares ``rss_m2``; None when the drag's shape overflows (a speed of thousands of m/s).
    """
    kept = np.ones(t.size, dtype=bool)
    t_ref = float(np.mean(t))
    u = float(np.polyfit(t - t_ref, x, 1)[0])
    for last in [False] * (SHAPE_PASSES + 1) + [True]:
        shape = horizontal_flight(t, t_ref, 1.0 if u == 0 else u, *apex, k, g)[0] / (1.0 if u == 0 else u)
        if not np.all(np.isfinite(shape)):  # a speed no drag law holds (x in the wrong unit): not fitted
            return None
        coefficients, covariance = linear_fit(np.column_stack([np.ones(kept.sum()), shape[kept]]), x[kept])
        residual = x - coefficients[0] - coefficients[1] * shape
        # off the residuals' median: a jump pulls the whole fit, and with it every residual, aside
        centre = np.median(residual[kept])
        outliers = kept & (np.abs(residual - centre) > HORIZONTAL_OUTLIER_SIGMAS
                           * max(robust_sigma(residual[kept], centre), 1e-12))
        converged = abs(coefficients[1] - u) <= 1e-9 * max(abs(u), 1.0)
        u = float(coefficients[1])
        if last or (converged and not outliers.any()):
            break
        if kept.sum() - outliers.sum() >= MIN_SAMPLES_PER_FLIGHT:
            kept &= ~outliers
    x_ref = float(coefficients[0])

    def motion(times):
        displacement, velocity = horizontal_flight(np.atleast_1d(times), t_ref, u, *apex, k, g)
        return x_ref + displacement, velocity

    return {"t_ref": t_ref, "u_ref": u, "x_ref": x_ref, "motion": motion, "n_samples": int(kept.sum()),
            "u_ref_se": float(np.sqrt(correlated_noise_factor(noise_correlation) * covariance[1, 1])),
            "noise_m": robust_sigma(residual[kept]), "rss_m2": float(residual[kept] @ residual[kept])}


def flight_motions(time_s, x_m, flights, k, g, noise_correlation=0.0):
    """:func:`fit_flight_x` for every flight of the flights table (None for a flight with fewer than
    :data:`MIN_SAMPLES_PER_FLIGHT` samples with x), with the drag k (1/m) and g (m/s²)."""
    fits = []
    for row in flights.itertuples(index=False):
        inside = (time_s > row.t_start_s) & (time_s < row.t_end_s) & np.isfinite(x_m)
        fits.append(fit_flight_x(time_s[inside], x_m[inside], (row.t_apex_s, row.y_apex_m), k, g, noise_correlation)
                    if np.count_nonzero(inside) >= MIN_SAMPLES_PER_FLIGHT else None)
    return fits


#: The largest drag parameter the horizontal fit searches (1/m): three times that of any common ball.
MAX_HORIZONTAL_DRAG_K_PER_M = 1.0


def horizontal_drag(time_s, x_m, flights, g, noise_correlation=0.0):
    """The drag parameter k (1/m) that the horizontal motion shows, shared by all flights, and its standard
    error: the flights' summed squared residuals profiled over k (each flight's x_ref and u_ref refitted
    for every k), its minimum in 0 … :data:`MAX_HORIZONTAL_DRAG_K_PER_M`, and the variance 2σ² / RSS''
    from its curvature (σ² = RSS / (samples − parameters), widened as :func:`fit_flight_x` widens).

    The vertical fit's own k would not do: its flights feel drag as k v|v|, but a ball that also moves
    sideways feels k |V| v, so with horizontal motion the vertical fit reads k high (refsim's tennis ball
    thrown at 2 m/s: 0.027 against 0.020 1/m), and u would slow too fast.
    """
    def rss(k):
        fits = [fit for fit in flight_motions(time_s, x_m, flights, k, g) if fit is not None]
        return sum(fit["rss_m2"] for fit in fits), sum(fit["n_samples"] - 2 for fit in fits) - 1

    from scipy.optimize import minimize_scalar

    best = minimize_scalar(lambda k: rss(k)[0], bounds=(0.0, MAX_HORIZONTAL_DRAG_K_PER_M), method="bounded",
                           options={"xatol": 1e-6})
    k = float(best.x) if rss(best.x)[0] < rss(0.0)[0] else 0.0
    minimum, dof = rss(k)
    step = max(0.05 * k, 1e-3)
    low = k - step if k > step else k  # a second difference, one-sided at the bound k = 0
    values = [rss(low + i * step)[0] for i in range(3)]
    curvature = (values[0] - 2 * values[1] + values[2]) / step**2
    variance = correlated_noise_factor(noise_correlation) * 2 * minimum / max(dof, 1) / curvature if curvature > 0 \
        else np.inf
    return k, float(min(np.sqrt(variance), MAX_HORIZONTAL_DRAG_K_PER_M))


def horizontal_velocities(time_s, x_m, flights, times, times_se, flight_of, k, k_se, g, noise_correlation=0.0):
    """Horizontal velocities (m/s) of the flights ``flight_of`` at the times ``times`` (s), and their
    covariance: each flight's fit (u(t) is u_ref times the drag's shape, so its se is u_ref's times that
    shape), the drag k's standard error ``k_se`` (1/m; every flight refitted with k ± k_se, fully
    correlated) and the times' standard errors ``times_se`` (s; from the vertical fit, independent of x)
    times the drag's deceleration.

    Returns
    -------
    (numpy.ndarray, numpy.ndarray, list)
        The velocities, their covariance and the flights' fits (:func:`flight_motions`, with k).
    """
    def velocities(drag_k):
        fits = flight_motions(time_s, x_m, flights, drag_k, g, noise_correlation)
        values, se = np.full(times.size, np.nan), np.full(times.size, np.nan)
        for i, (time, flight) in enumerate(zip(times, flight_of)):
            if fits[flight] is not None:
                values[i] = fits[flight]["motion"](time)[1][0]
                se[i] = abs(values[i] / fits[flight]["u_ref"]) * fits[flight]["u_ref_se"] if fits[flight]["u_ref"] else \
                    fits[flight]["u_ref_se"]
        return values, se, fits

    values, se, fits = velocities(k)
    covariance = np.zeros((times.size, times.size))
    for flight in set(flight_of):  # one flight's two ends share its u_ref
        ends = np.flatnonzero(flight_of == flight)
        covariance[np.ix_(ends, ends)] = np.outer(se[ends], se[ends])
    if k_se > 0:
        drag_part = 0.5 * (velocities(k + k_se)[0] - velocities(max(k - k_se, 0.0))[0])
        covariance += np.outer(drag_part, drag_part)
    # du/dt = −k u |V|: a touchdown known to ±1 ms moves u by k u |V| × 1 ms (|V| ≥ |u|; taken as |u|)
    covariance += np.diag((k * values * np.abs(values) * times_se) ** 2)
    return values, covariance, fits


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
    # a flight without x leaves its velocity NaN: the quantities of the other flight keep their se
    covariance[2:, 2:] = np.nan_to_num(vx_covariance)
    with np.errstate(divide="ignore", invalid="ignore"):
        values = quantities(p)
        # a NaN velocity's column is NaN: zeroed, and its quantities' se NaN as their values are
        se = np.sqrt(np.clip(np.diag(propagate(np.nan_to_num(jacobian(quantities, p)), covariance)), 0.0, None))
        se[~np.isfinite(values)] = np.nan
    return dict(zip(HORIZONTAL_COLUMNS, zip(values[:-1], se[:-1]))), float(se[-1])


def angle_verdict(vx_in, vx_in_se, tan_out, e_tan_in, difference_se):
    """The seed's check of one impact in words: tan θ′ against e tan θ.

    "not tested" when a flight around the impact has too few x samples (NaN), or the ball had no
    horizontal motion to speak of (|vx_in| below :data:`MOTION_IN_SE` standard errors); "consistent:
    tangential velocity kept" when tan θ′ − e tan θ lies within :data:`ANGLE_CHECK_IN_SE` standard errors
    of 0; else the share of the tangential velocity lost (friction or spin) or gained (spin).
    """
    if np.isnan(tan_out) or np.isnan(e_tan_in):
        return "not tested: too few x samples in the flights before and after"
    if not abs(vx_in) > MOTION_IN_SE * vx_in_se:
        return f"not tested: no horizontal motion resolved (vx_in = {vx_in:.3g} ± {vx_in_se:.2g} m/s)"
    difference = tan_out - e_tan_in
    if not abs(difference) > ANGLE_CHECK_IN_SE * difference_se:
        return "consistent: tangential velocity kept"
    change = e_tan_in / tan_out - 1.0  # = |vx_out| / |vx_in| − 1
    if change < 0:
        return f"tangential velocity lost {-100 * change:.1f} %: friction or spin"
    return f"tangential velocity gained {100 * change:.1f} %: spin"


def add_horizontal(analysis, time_s, x_m, noise_correlation=0.0):
    """The analysis with the oblique columns added to its impacts table and a ``horizontal`` record in its
    summary.

    Parameters
    ----------
    analysis : dropfit.analysis.BounceAnalysis
        The vertical analysis (tables' times in s on the trajectory's clock).
    time_s, x_m : numpy.ndarray
        The trajectory's time (s) and horizontal position (m).
    noise_correlation : float
        As :func:`fit_flight_x`.

    Returns
    -------
    dropfit.analysis.BounceAnalysis
        With every column of :data:`HORIZONTAL_COLUMNS` (with ``_se`` and the 95 % interval) and
        ``angle_check`` (words) in the impacts table, and the summary's ``horizontal``
        (:func:`horizontal_record`); unchanged when x has too few samples.
    """
    impacts, flights, summary = analysis.impacts, analysis.flights, analysis.summary
    g = summary["gravity_m_s2"]
    # drag where the vertical analysis has it (the drag option, the ball), its k from the horizontal motion
    k, k_se = horizontal_drag(time_s, x_m, flights, g, noise_correlation) if summary["drag_k_per_m"] > 0 else (0.0, 0.0)
    # each impact's ends (touchdown in flight n − 1, lift-off in flight n), then the release (flight 0's apex)
    n = len(impacts)
    times = np.append(np.ravel(impacts[["t_touchdown_s", "t_liftoff_s"]].to_numpy()), summary["drop_apex_time_s"])
    times_se = np.append(np.ravel(impacts[["t_touchdown_se_s", "t_liftoff_se_s"]].to_numpy()),
                         flights["t_apex_se_s"].iloc[0])
    flight_of = np.append(np.ravel(np.column_stack([np.arange(n), np.arange(1, n + 1)])), 0)
    vx, vx_covariance, fits = horizontal_velocities(time_s, x_m, flights, times, times_se, flight_of, k, k_se, g,
                                                    noise_correlation)
    if np.isnan(vx).all():
        return analysis
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
                               summary={**summary, "horizontal": horizontal_record(
                                   fits, summary, time_s, x_m, (vx[-1], np.sqrt(vx_covariance[-1, -1])), (k, k_se))})


def horizontal_record(fits, summary, time_s, x_m, release_speed, drag):
    """The summary's ``horizontal`` record: the release's horizontal speed u and its se (m/s, flight 0 at its
    apex, :func:`horizontal_velocities`), the distance (m) from the release to where the ball is when it
    comes to rest (the samples interpolated; NaN if it never does), each flight's samples used, the
    residuals' noise (m) and the drag k (1/m) with its se."""
    apex = float(summary["drop_apex_time_s"])
    x_release = float(fits[0]["motion"](apex)[0][0]) if fits[0] is not None else np.nan
    finite = np.isfinite(x_m)
    rest = summary.get("rest_time_s", np.nan)
    x_rest = float(np.interp(rest, time_s[finite], x_m[finite])) if np.isfinite(rest) else np.nan
    return {"release_speed_m_s": float(release_speed[0]), "release_speed_se_m_s": float(release_speed[1]),
            "distance_to_rest_m": x_rest - x_release,
            "noise_m": float(np.nanmedian([fit["noise_m"] for fit in fits if fit is not None])),
            "n_samples": [fit["n_samples"] if fit is not None else 0 for fit in fits],
            "drag_k_per_m": drag[0], "drag_k_se_per_m": drag[1],
            "drag": "quadratic on the full velocity, k from the horizontal motion" if summary["drag_k_per_m"] > 0
            else "none (the vertical analysis has none): lines"}


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
