"""The coefficient of restitution of a recording, the theory checks of the bounce sequence, and the
ITF verdict. Pure functions on the outputs of :func:`dropfit.analysis.analyse_bounces`.
"""

from __future__ import annotations

import math

import numpy as np

from .numerics import chi2_tail, jacobian, normal_quantile, propagate
from .physics import (apex_rise, bounce_heights, speed_below_apex, time_after_first_touchdown,
                      total_bouncing_time, touchdown_time)

Z95 = float(normal_quantile(0.975))

#: ITF Rules of Tennis, Appendix I: dropped from 254 cm onto a rigid surface, the ball must rebound
#: more than 135 cm and less than 147 cm.
ITF_DROP_HEIGHT_M = 2.54
ITF_REBOUND_MIN_M = 1.35
ITF_REBOUND_MAX_M = 1.47


def estimate(value, se, unit):
    """A parameter as reported: value, standard error, 95 % interval (normal) and unit."""
    value, se = float(value), float(se)
    return {"value": value, "se": se, "ci95": [value - Z95 * se, value + Z95 * se], "unit": unit}


def weighted_fit(design, target, covariance):
    """Linear fit of correlated per-impact values, the one estimator behind every e law.

    Parameters are estimated by least squares weighted with the inverse variances (the diagonal of
    ``covariance``) and their covariance propagates the full covariance through that linear
    estimator (adjacent impacts share a flight and all share the contact height, so their values are
    correlated). Full generalised least squares would weight by the inverse of the estimated,
    strongly correlated covariance; in seeded coverage trials its 95 % intervals covered the truth
    only about 90 % of the time, the diagonal weights about 95 % (``benchmarks/coverage.py``). The
    goodness of fit, for tests and model choice, is the generalised χ² at its minimum, where it
    follows its χ² law.

    Parameters
    ----------
    design : numpy.ndarray
        Design matrix X, shape (n, p): ``target`` ≈ X θ.
    target : numpy.ndarray
        Values, shape (n,).
    covariance : numpy.ndarray
        Their covariance, shape (n, n).

    Returns
    -------
    dict
        ``theta`` (p,), ``covariance`` (p, p), ``estimator`` (p, n: θ = estimator @ target, for
        propagating other covariances), ``chi2`` (generalised, at its minimum), ``dof`` (n − p) and
        ``singular`` (whether the covariance needed a pseudo-inverse).
    """
    design = np.asarray(design, dtype=float)
    target = np.asarray(target, dtype=float)
    covariance = np.asarray(covariance, dtype=float)
    weighted = design / np.diag(covariance)[:, None]
    estimator = np.linalg.pinv(design.T @ weighted) @ weighted.T
    theta = estimator @ target
    precision, singular = _precision(covariance)
    generalised = np.linalg.pinv(design.T @ precision @ design) @ design.T @ precision
    residual = target - design @ (generalised @ target)
    return {
        "theta": theta,
        "covariance": estimator @ covariance @ estimator.T,
        "estimator": estimator,
        "chi2": float(residual @ precision @ residual),
        "dof": int(target.size - design.shape[1]),
        "singular": singular,
    }


def _precision(covariance):
    """Inverse of the covariance, or its pseudo-inverse when it is singular; and whether it was."""
    if np.linalg.matrix_rank(covariance) < covariance.shape[0]:
        return np.linalg.pinv(covariance), True
    return np.linalg.inv(covariance), False


def constant_restitution(e, covariance):
    """Constant-e estimate from correlated per-impact values, with its standard error.

    The estimate and its standard error come from :func:`weighted_fit` with one parameter.

    Parameters
    ----------
    e : numpy.ndarray
        Per-impact e (dimensionless).
    covariance : numpy.ndarray
        Their covariance matrix.

    Returns
    -------
    dict
        ``e`` (estimate dict), ``weights`` (list: e = weights · per-impact e), ``chi2`` and ``dof`` of
        the constant model under the full covariance (at its generalised-least-squares minimum), its
        ``p_value`` (a small one says e is not the same at every impact), and ``n_impacts``.
    """
    e = np.asarray(e, dtype=float)
    fitted = weighted_fit(np.ones((e.size, 1)), e, covariance)
    dof = fitted["dof"]
    return {
        "e": estimate(fitted["theta"][0], np.sqrt(fitted["covariance"][0, 0]), "1"),
        "weights": fitted["estimator"][0].tolist(),
        "chi2": fitted["chi2"],
        "dof": dof,
        "p_value": float(chi2_tail(fitted["chi2"], dof)) if dof > 0 else float("nan"),
        "n_impacts": int(e.size),
    }


def theory_checks(e, e_se, drop_height_m, fall_time_s, measured_heights_m, measured_heights_se_m,
                  measured_bouncing_time_s, impacts_counted=None, first_flight_s=None, contact_time_s=(0.0, 0.0)):
    """Compare the measured bounce sequence with the seed's constant-e, no-drag predictions.

    Parameters
    ----------
    e, e_se : float
        Fitted constant e and its standard error.
    drop_height_m : float
        Drop height h₀ in m (rise of the centre above the contact height at release).
    fall_time_s : float
        t₀: time from release to the first touchdown, in s.
    measured_heights_m, measured_heights_se_m : numpy.ndarray
        Apex heights h_n (m) after impacts 1, 2, … and their standard errors.
    measured_bouncing_time_s : float
        Time from release until the ball rests, in s (NaN if the log ends first); with
        ``impacts_counted``, until the last of them.
    impacts_counted : int, optional
        The measured time ends at this touchdown (the last impact heard in a sound): it is checked
        against the partial sum to that touchdown, not against t∞, which counts every later one.
    first_flight_s : float, optional
        With ``impacts_counted``, given when the release is not known: the first flight's time (lift-off to
        touchdown), s; the measured time then runs from the first touchdown and is checked against T₁ Σ eᵏ
        plus the contact times.
    contact_time_s : (float, float)
        With ``impacts_counted``: the time the ball spends on the floor at the impacts before the last
        counted one, and its standard error, s (touchdowns are a contact and a flight apart).

    Returns
    -------
    dict
        ``heights`` (one entry per bounce: measured and predicted e^{2n}h₀ in m) and
        ``total_bouncing_time`` (t∞ = t₀(1+e)/(1−e) in s against the measured time; with
        ``impacts_counted`` also ``predicted_to_last_impact``, t₀(1 + 2Σeᵏ) in s, which the measured time
        is checked against, and ``impacts_counted``; from the first touchdown, ``from_first_impact``,
        T₁ Σ eᵏ and ``predicted_after_first_impact``, T₁/(1 − e)).
    """
    n = len(measured_heights_m)
    predicted = bounce_heights(e, drop_height_m, n)
    exponent = 2 * np.arange(1, n + 1)
    predicted_se = np.abs(exponent * predicted / e) * e_se
    t_inf = total_bouncing_time(e, fall_time_s)
    t_inf_se = fall_time_s * 2.0 / (1.0 - e) ** 2 * e_se
    total = {"predicted": estimate(t_inf, t_inf_se, "s"), "measured_s": float(measured_bouncing_time_s),
             "fall_time_s": float(fall_time_s),
             "note": "the measured time ends when the ball stays within 5 noise standard deviations of the floor; "
                     "bounces lower than that are not seen, and drag shortens every flight"}
    if impacts_counted:
        from_first = first_flight_s is not None
        t_last, slope = (time_after_first_touchdown(e, first_flight_s, impacts_counted) if from_first
                         else touchdown_time(e, fall_time_s, impacts_counted))
        on_floor, on_floor_se = contact_time_s
        total.update(predicted_to_last_impact=estimate(t_last + on_floor, math.hypot(slope * e_se, on_floor_se), "s"),
                     impacts_counted=int(impacts_counted))
        if from_first:
            t_all, slope_all = time_after_first_touchdown(e, first_flight_s, np.inf)
            total.update(from_first_impact=True, predicted_after_first_impact=estimate(t_all, slope_all * e_se, "s"))
    return {
        "heights": [
            {"bounce": i + 1, "measured_m": float(h), "measured_se_m": float(s), "predicted_m": float(p),
             "predicted_se_m": float(ps)}
            for i, (h, s, p, ps) in enumerate(zip(measured_heights_m, measured_heights_se_m, predicted, predicted_se))
        ],
        "total_bouncing_time": total,
    }


def itf_rebound(drop_height_m, drop_height_se_m, first_rebound_m, first_rebound_se_m, e, e_se, drag_k_per_m,
                gravity_m_s2, drop_height_tolerance_m=0.02, itf_drop_height_m=ITF_DROP_HEIGHT_M,
                e_source="the fitted constant e", drag_k_se_per_m=0.0, e_drag_covariance=0.0):
    """Rebound height in m of a drop from the ITF height, measured or predicted.

    From a drop within ``drop_height_tolerance_m`` of the ITF height, the measured first rebound is
    used, scaled by the ratio of the drop heights. From any other height it is predicted with the
    given e (described by ``e_source``) and drag: v_in at the end of the ITF fall, v_out = e v_in, rise
    of v_out. Its standard error propagates those of e and of the drag parameter k (1/m) and their
    covariance ``e_drag_covariance`` (1/m).

    Returns
    -------
    dict
        ``value``, ``se``, ``ci95`` (m), and ``method`` saying which of the two it is.
    """
    if abs(drop_height_m - itf_drop_height_m) <= drop_height_tolerance_m:
        ratio = itf_drop_height_m / drop_height_m
        value = first_rebound_m * ratio
        se = np.hypot(first_rebound_se_m * ratio, value * drop_height_se_m / drop_height_m)
        result = estimate(value, se, "m")
        result["method"] = f"measured first rebound from a {100 * drop_height_m:.1f} cm drop, scaled to " \
                           f"{100 * itf_drop_height_m:.0f} cm"
        return result
    def rebound(e_value, k):
        return float(apex_rise(e_value * speed_below_apex(itf_drop_height_m, k, gravity_m_s2), k, gravity_m_s2))

    value = rebound(e, drag_k_per_m)
    gradient = jacobian(lambda x: np.array([rebound(x[0], x[1])]), np.array([e, drag_k_per_m]), lower=[0.0, 0.0],
                        absolute_step=1e-7)
    covariance = np.array([[e_se**2, e_drag_covariance], [e_drag_covariance, drag_k_se_per_m**2]])
    result = estimate(value, np.sqrt(max(propagate(gradient, covariance)[0, 0], 0.0)), "m")
    measured = f"measured drop {100 * drop_height_m:.1f} cm" if np.isfinite(drop_height_m) else "no drop measured"
    result["method"] = f"predicted for a {100 * itf_drop_height_m:.0f} cm drop ({measured}) with e = {e:.4f} " \
                       f"from {e_source} and drag k = {drag_k_per_m:.4g} 1/m"
    return result


def itf_verdict(rebound, rebound_min_m=ITF_REBOUND_MIN_M, rebound_max_m=ITF_REBOUND_MAX_M):
    """Guard-banded ITF decision on a rebound estimate (dict with ``ci95`` in m).

    ``pass`` when the whole 95 % interval lies inside (min, max), ``fail`` when it lies wholly
    outside, ``indeterminate`` when it straddles a limit.
    """
    low, high = rebound["ci95"]
    if low > rebound_min_m and high < rebound_max_m:
        return "pass"
    if high < rebound_min_m or low > rebound_max_m:
        return "fail"
    return "indeterminate"
