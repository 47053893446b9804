"""From impact times to flights and impacts: every flight's time, rise and speeds with the drag of the
given ball, each impact's e, and their covariance. Pure: no files.

An impact is heard when the ball touches down; it leaves the floor one contact time later. So flight n
(after impact n) lasts T_n = t_{n+1} − t_n − τ_n, with τ_n the ball kind's contact time at that
flight's speed (:mod:`dropfit.balls`, a prior with its standard error: the sound does not show the
lift-off). A flight of time T with quadratic drag k rises h where the rising and falling times from
:func:`dropfit.physics.time_from_apex` add up to T; it leaves the floor at the rising speed and lands
at the falling speed of :func:`dropfit.physics.speed_below_apex` for that h. Impact n's e is the
speed leaving it over the speed arriving: e_n = v_out,n / v_in,n (v_in,n from flight n − 1). The first
impact's v_in needs the release (the fall is silent): given its time, the fall from rest of t_1 −
t_release gives the drop height and v_in,1. The last impact heard has no flight after it.

Every quantity is a function of the impact times, the contact-time prior (τ₁ and its exponent), the
drag k and g; their covariance propagates all of those through the numerical Jacobian
(:func:`dropfit.numerics.jacobian`): neighbouring impacts share a time, and all share τ₁, k and g.
Without drag the e of two flights is the ratio of their times, the acoustic way.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd

from ..analysis.bounces import BounceAnalysis
from ..analysis.detection import DETECTION_ERROR, detection_reasons, flights_out_of_sequence, spurious_events
from ..analysis.tables import add_with_interval
from ..balls import contact_time_at
from ..numerics import jacobian, propagate
from ..physics import flight_height, speed_below_apex, time_from_apex

#: Bisection steps of the rise of a flight of given time (2⁻⁶⁰ of the bracket: far below any error).
RISE_ITERATIONS = 60


def flight_rise(flight_time_s, k=0.0, g=9.80665):
    """Rise in m of a vertical flight from the floor back to the floor that lasts ``flight_time_s`` (s).

    The rising and falling times to and from the apex (:func:`dropfit.physics.time_from_apex`) add up
    to the flight time; without drag h = g T²/8. Solved by bisection, elementwise.
    """
    flight_time_s = np.asarray(flight_time_s, dtype=float)
    if k == 0.0:
        return g * flight_time_s**2 / 8.0
    low = np.zeros_like(flight_time_s)
    high = g * flight_time_s**2 / 4.0  # drag lengthens the fall less than it shortens the rise: within 2×
    for _ in range(RISE_ITERATIONS):
        middle = 0.5 * (low + high)
        longer = time_from_apex(middle, k, g, rising=True) + time_from_apex(middle, k, g) > flight_time_s
        high = np.where(longer, middle, high)
        low = np.where(longer, low, middle)
    return 0.5 * (low + high)


def impact_quantities(theta, n_impacts, release_time_s=None):
    """Every reported quantity from the parameters ``theta`` = (t_1 … t_N in s, τ₁ in s, β, k in 1/m, g in m/s²).

    Returns
    -------
    numpy.ndarray
        Concatenated, N each: e, v_in (m/s), v_out (m/s), rise after (m), flight time after (s),
        contact time after (s); then the drop height (m). NaN where the sound cannot tell.
    """
    n = n_impacts
    times = theta[:n]
    tau_1, exponent, k, g = theta[n:n + 4]
    gaps = np.diff(times)
    contact = contact_time_at(tau_1, g * gaps / 2.0, exponent)  # the speed scale of each flight
    flight = gaps - contact
    rise = flight_rise(np.clip(flight, 1e-9, None), k, g)
    v_out = np.full(n, np.nan)
    v_in = np.full(n, np.nan)
    v_out[:-1] = speed_below_apex(rise, k, g, rising=True)
    v_in[1:] = speed_below_apex(rise, k, g)
    drop = np.nan
    if release_time_s is not None:
        drop = float(-flight_height(times[0] - release_time_s, 0.0, 0.0, k, g))
        v_in[0] = speed_below_apex(drop, k, g)
    pad = np.full(1, np.nan)
    return np.concatenate([v_out / v_in, v_in, v_out, np.r_[rise, pad], np.r_[flight, pad], np.r_[contact, pad],
                           [drop]])


def analyse_impact_times(times_s, times_se_s, gravity_m_s2, gravity_se_m_s2=0.0, drag_k_per_m=0.0,
                         drag_relative_se=0.0, contact_time_prior_s=(0.0, 0.0), contact_time_exponent=(0.0, 0.0),
                         release_time_s=None, source="recording"):
    """Flights, impacts and their covariances from the times a ball was heard to hit the floor, detection
    errors found and left out (:mod:`dropfit.analysis.detection`).

    A sound within a flight that splits it in two (:func:`~dropfit.analysis.detection.spurious_events`) is
    no impact: the flights are those of the other times, and the event keeps a row of its own in the
    impacts table with its reason and nothing measured. An impact whose e exceeds 1, or whose flight
    outlasts the one before, or next to a flight out of the sequence (an impact missed), keeps its values
    with ``detection_error`` true, ``in_fit`` false and the reason in ``note``. Parameters and returns as
    :func:`analyse_times`.
    """
    times = np.asarray(times_s, dtype=float)
    times_se = np.asarray(times_se_s, dtype=float)
    spurious = spurious_events(times, times_se)
    kept = np.setdiff1d(np.arange(times.size), spurious)
    analysis = analyse_times(times[kept], times_se[kept], gravity_m_s2, gravity_se_m_s2, drag_k_per_m,
                             drag_relative_se, contact_time_prior_s, contact_time_exponent, release_time_s, source)
    impacts = analysis.impacts.copy()
    flight = impacts["flight_time_after_s"].to_numpy(dtype=float)
    flight_se = impacts["flight_time_after_se_s"].to_numpy(dtype=float)
    out = flights_out_of_sequence(flight, flight_se)
    reasons = detection_reasons(impacts["e"].to_numpy(dtype=float), np.r_[np.nan, flight[:-1]], flight,
                                np.r_[False, out[:-1]], out)
    flagged = reasons != ""
    notes = impacts["note"].astype(object).where(impacts["note"].astype(bool), "").tolist()
    impacts["note"] = [reason or note for reason, note in zip(reasons, notes)]
    impacts["in_fit"] = impacts["in_fit"].to_numpy(bool) & ~flagged
    impacts["detection_error"] = flagged
    summary = dict(analysis.summary, detection_errors=int(flagged.sum()) + len(spurious),
                   spurious_events=[float(times[i]) for i in spurious])
    if spurious:
        impacts, matrices = _with_spurious_rows(impacts, analysis, times, times_se, kept, spurious)
        summary["notes"] = summary["notes"] + [
            f"{len(spurious)} sound{'s' if len(spurious) > 1 else ''} within a flight (at "
            f"{', '.join(f'{times[i]:.4g}' for i in spurious)} s) split it in two: not an impact, left out; the "
            f"flight is whole again"]
        analysis = dataclasses.replace(analysis, **matrices)
    return dataclasses.replace(analysis, impacts=impacts, summary=summary)


def _with_spurious_rows(impacts, analysis, times, times_se, kept, spurious):
    """The impacts table with a row for each spurious event (its time, its reason, nothing measured) in
    time order, renumbered, the covariances of e (and contact times) with zero rows for them, and the
    flights numbered as the impacts they follow."""
    rows = []
    for i in spurious:
        before, after = times[i - 1] if i > 0 else np.nan, times[i + 1] if i + 1 < times.size else np.nan
        rows.append({"t_touchdown_s": times[i], "t_touchdown_se_s": times_se[i], "in_fit": False,
                     "detection_error": True, "contact_resolvable": False,
                     "note": f"{DETECTION_ERROR}: a sound {times[i] - before:.3g} s after the impact before it and "
                             f"{after - times[i]:.3g} s before the next, within one flight of the sequence: not "
                             f"an impact; the flight is whole again, and this event is left out of every fit"})
    order = np.argsort(np.r_[kept, spurious], kind="stable")
    table = pd.concat([impacts, pd.DataFrame(rows)], ignore_index=True).iloc[order].reset_index(drop=True)
    table["impact"] = np.arange(1, len(table) + 1)
    table["in_fit"] = table["in_fit"].astype(bool)
    table["detection_error"] = table["detection_error"].astype(bool)
    table["contact_resolvable"] = table["contact_resolvable"].astype(bool)
    n, total = len(impacts), len(table)
    position = np.empty(total, int)
    position[order] = np.arange(total)
    old = position[:n]  # where each analysed impact lands in the table

    def spread(matrix, blocks):
        grown = np.zeros((blocks * total, blocks * total))
        index = np.concatenate([block * total + old for block in range(blocks)])
        grown[np.ix_(index, index)] = matrix
        return grown

    drag = np.zeros(total)
    drag[old] = analysis.e_drag_covariance
    flights = analysis.flights.copy()  # flight n follows impact n: numbered as their impacts now are
    after = flights["flight"].to_numpy(int)
    flights["flight"] = np.where(after > 0, old[np.clip(after - 1, 0, n - 1)] + 1, after)
    return table, {"e_covariance": spread(analysis.e_covariance, 1),
                   "e_contact_covariance": spread(analysis.e_contact_covariance, 2), "e_drag_covariance": drag,
                   "flights": flights}


def analyse_times(times_s, times_se_s, gravity_m_s2, gravity_se_m_s2=0.0, drag_k_per_m=0.0,
                  drag_relative_se=0.0, contact_time_prior_s=(0.0, 0.0), contact_time_exponent=(0.0, 0.0),
                  release_time_s=None, source="recording"):
    """Flights, impacts and their covariances from the times a ball was heard to hit the floor, as they are.

    Parameters
    ----------
    times_s, times_se_s : array_like
        Impact (touchdown) times in s, increasing, and their standard errors in s (independent).
    gravity_m_s2, gravity_se_m_s2 : float
        g at the site and its standard error, m/s².
    drag_k_per_m, drag_relative_se : float
        Quadratic drag parameter k of the ball (1/m) and its relative standard error (1).
    contact_time_prior_s : (float, float)
        Contact time at 1 m/s and its standard error, s.
    contact_time_exponent : (float, float)
        β of τ ∝ v^(−β) and its standard error.
    release_time_s : float, optional
        When the ball was let go at rest (s, same clock); without it the drop height and the first
        impact's e are not known.
    source : str
        Name of the recording for messages.

    Returns
    -------
    dropfit.analysis.BounceAnalysis
        Flights (one per flight heard: ``flight``, ``t_start_s``, ``t_end_s``, ``t_apex_s``,
        ``y_apex_m`` = ``apex_height_m`` above the contact height, ``flight_time_s``), impacts (the
        log analysis' columns where the sound gives them; ``t_contact_ms`` is the prior, not
        measured), the covariances, and the summary the fit reads.
    """
    times = np.asarray(times_s, dtype=float)
    times_se = np.asarray(times_se_s, dtype=float)
    n = times.size
    k_se = abs(drag_k_per_m) * drag_relative_se
    theta = np.r_[times, contact_time_prior_s[0], contact_time_exponent[0], drag_k_per_m, gravity_m_s2]
    variances = np.r_[times_se**2, contact_time_prior_s[1] ** 2, contact_time_exponent[1] ** 2, k_se**2,
                      gravity_se_m_s2**2]

    def quantities(parameters):
        return impact_quantities(parameters, n, release_time_s)

    values = quantities(theta)
    lower = np.r_[np.full(n, -np.inf), 0.0, -np.inf, 0.0, 0.0]
    gradient = jacobian(quantities, theta, lower=lower, relative_step=1e-7, absolute_step=1e-8)
    gradient = np.nan_to_num(gradient)
    covariance = propagate(gradient, np.diag(variances))
    se = np.sqrt(np.clip(np.diag(covariance), 0.0, None))
    se[~np.isfinite(values)] = np.nan

    def part(index):
        return values[index * n:(index + 1) * n], se[index * n:(index + 1) * n]

    (e, e_se), (v_in, v_in_se), (v_out, v_out_se), (rise, rise_se), (flight, flight_se), (contact, contact_se) = \
        (part(i) for i in range(6))
    drop, drop_se = values[-1], se[-1]
    impacts = pd.DataFrame({"impact": np.arange(1, n + 1)})
    add_with_interval(impacts, "t_touchdown_s", times, times_se)
    add_with_interval(impacts, "v_in_m_s", v_in, v_in_se)
    add_with_interval(impacts, "v_out_m_s", v_out, v_out_se)
    add_with_interval(impacts, "e", e, e_se)
    rise_before = np.r_[drop, rise[:-1]]
    rise_before_se = np.r_[drop_se, rise_se[:-1]]
    add_with_interval(impacts, "h_before_m", rise_before, rise_before_se)
    add_with_interval(impacts, "h_after_m", rise, rise_se)
    impacts["h_after_scale_se_m"] = 0.0  # times need no length scale
    impacts["e_height"] = np.sqrt(rise / rise_before)
    add_with_interval(impacts, "flight_time_after_s", flight, flight_se)
    impacts["flight_time_ratio"] = flight / np.r_[np.nan, flight[:-1]]
    add_with_interval(impacts, "t_contact_ms", 1e3 * contact, 1e3 * contact_se)
    impacts["contact_resolvable"] = False
    impacts["in_fit"] = np.isfinite(e)
    notes = np.full(n, "", dtype=object)
    if release_time_s is None:
        notes[0] = "the fall before it is not heard: give release_time_s for its e and the drop height"
    notes[-1] = "the last impact heard: no flight after it"
    impacts["note"] = notes

    e_rows = np.arange(n)
    e_covariance = np.nan_to_num(covariance[np.ix_(e_rows, e_rows)])
    k_column = n + 2
    e_drag = np.nan_to_num(gradient[e_rows] @ (np.eye(theta.size)[k_column] * variances[k_column]))
    contact_rows = 5 * n + e_rows
    pair = np.r_[e_rows, contact_rows]
    e_contact_covariance = np.nan_to_num(covariance[np.ix_(pair, pair)])

    liftoff = times[:-1] + contact[:-1]
    rising = time_from_apex(rise[:-1], drag_k_per_m, gravity_m_s2, rising=True)
    flights = pd.DataFrame({"flight": np.arange(1, n), "t_start_s": liftoff, "t_end_s": times[1:],
                            "t_apex_s": liftoff + rising, "y_apex_m": rise[:-1]})
    add_with_interval(flights, "flight_time_s", flight[:-1], flight_se[:-1])
    add_with_interval(flights, "apex_height_m", rise[:-1], rise_se[:-1])
    if release_time_s is not None:
        drop_flight = pd.DataFrame({"flight": [0], "t_start_s": [release_time_s], "t_end_s": [times[0]],
                                    "t_apex_s": [release_time_s], "y_apex_m": [drop],
                                    "flight_time_s": [times[0] - release_time_s], "flight_time_se_s": [times_se[0]],
                                    "apex_height_m": [drop], "apex_height_se_m": [drop_se]})
        flights = pd.concat([drop_flight, flights], ignore_index=True)

    summary = {
        "contact_height_m": 0.0,
        "contact_height_se_m": 0.0,
        "contact_height_source": "the frame of the heights: the sound gives times, and every height is a rise of "
                                 "the ball's centre above where it touches the floor",
        "contact_time_prior_s": list(contact_time_prior_s),
        "contact_time_1m_s_s": float(contact_time_prior_s[0]),
        "contact_time_1m_s_se_s": float(contact_time_prior_s[1]),
        "contact_time_exponent": float(contact_time_exponent[0]),
        "contact_time_exponent_se": float(contact_time_exponent[1]),
        "contact_time_why": f"the sound marks the touchdowns only: every flight time takes the ball kind's contact "
                            f"time ({1e3 * contact_time_prior_s[0]:.3g} ± {1e3 * contact_time_prior_s[1]:.2g} ms at "
                            f"1 m/s, a prior), never a measured one",
        "bouncing_time_note": "the measured time ends at the last impact heard (fainter ones are not heard), so it "
                              "is checked against the time the series predicts for that impact; drag shortens "
                              "every flight",
        "drag_model": "nominal" if drag_k_per_m > 0 else "none",
        "drag_k_per_m": float(drag_k_per_m),
        "drag_k_se_per_m": float(k_se),
        "drag_why": "held at that of a smooth ball of this kind, size and mass: impact times alone cannot tell "
                    "drag from e" if drag_k_per_m > 0 else "no drag: the ball's size or mass is not given, or "
                                                           "drag is off",
        "bic_no_drag": np.nan,
        "bic_quadratic_drag": np.nan,
        "noise_m": np.nan,
        "release_time_s": release_time_s,
        "drop_apex_time_s": np.nan if release_time_s is None else float(release_time_s),
        "drop_height_m": float(drop),
        "drop_height_se_m": float(drop_se),
        "drop_height_scale_se_m": 0.0,
        # the last impact heard: later ones are too faint to hear, so this is when the bouncing ends as heard
        "rest_time_s": float(times[-1]),
        "impacts_heard": int(times.size),
        "gravity_m_s2": float(gravity_m_s2),
        "gravity_se_m_s2": float(gravity_se_m_s2),
        "gravity_scaled": False,
        "n_impacts": n,
        "scale_rel_se": 0.0,
        "noise_correlation": 0.0,
        "notes": _notes(release_time_s, contact_time_prior_s, flight),
    }
    return BounceAnalysis(flights=flights, impacts=impacts, e_covariance=e_covariance,
                          e_contact_covariance=e_contact_covariance, e_drag_covariance=e_drag, summary=summary)


def _notes(release_time_s, contact_time_prior_s, flight_times):
    notes = [f"flight times are the intervals between the impacts heard less the contact time of this kind of ball "
             f"({1e3 * contact_time_prior_s[0]:.3g} ± {1e3 * contact_time_prior_s[1]:.2g} ms at 1 m/s; the sound "
             f"does not show the lift-off)",
             "the bouncing time measured ends at the last impact heard"]
    if release_time_s is None:
        notes.append("the release is not heard: the drop height, the first impact's e and the total bouncing time "
                     "t∞ are not measured; give release_time_s")
    if np.any(flight_times <= 0):
        notes.append("an interval between impacts is shorter than the contact time: its flight is not resolved")
    return notes
