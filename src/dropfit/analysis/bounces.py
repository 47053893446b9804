"""From a height-against-time trajectory to flights and impacts, with standard errors.

:func:`analyse_bounces` applies the defaults and runs the pure steps in the order of the data:
segmentation (:mod:`.segment`), the joint flight fit and its refinement (:mod:`.flights`), the
impact quantities (:mod:`.impacts`) and their covariance (:mod:`.uncertainty`).

Every flight is fitted with the closed-form vertical flight of :mod:`dropfit.physics` (known g, two
parameters per flight: apex time and apex height), and a quadratic-drag parameter k shared by all
flights is fitted only when the Bayesian information criterion says the data support it. Otherwise k
is held: when the ball's size and mass are known, at that of a smooth sphere (relative se
:data:`NOMINAL_DRAG_RELATIVE_SE`) combined with what the flights say about k; else at 0. The
uncertainty of a held k is carried into every impact quantity as a systematic error: drag too weak
to show in the flight shapes still biases e by more than its statistical error. The contact height
(the centre height at which the ball touches the floor) is either given or found where the fitted
flights before and after each impact meet.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from ..errors import InputError
from ..physics import STANDARD_GRAVITY_M_S2, time_from_apex
from .flights import (MIN_SAMPLES_PER_FLIGHT, bic, combine_with_prior, first_misfit_flight, first_spurious_impact,
                      fit_flights, parabola_start)
from .impacts import (IMPACT_COLUMNS, ImpactQuantities, contact_resolvable, quantity_index, rest_time,
                      unpack_quantities)
from .segment import IMPACT_DEPTH_IN_NOISE, check_free_fall, detect_bounces, flight_bounds
from .tables import add_with_interval
from .uncertainty import quantity_covariance

#: Number of passes of "assign samples to flights, fit, locate the contacts".
REFINEMENT_PASSES = 3
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

    bounds = flight_bounds(t, y, release, minima, noise, contact_height_m)
    # keep impacts while both neighbouring flights are sampled well enough
    counts = [np.count_nonzero((t > lo) & (t < hi)) for lo, hi in bounds]
    n_flights = next((i for i, c in enumerate(counts) if c < MIN_SAMPLES_PER_FLIGHT), len(bounds))
    if n_flights < 2:
        raise InputError(f"{source}: no bounce with at least {MIN_SAMPLES_PER_FLIGHT} samples in the flights "
                         f"before and after it")
    bounds = bounds[: check_free_fall(t, y, bounds[:n_flights], g, source)]
    if len(bounds) < 2:
        raise InputError(f"{source}: the flight after the first bounce falls with far less than g: it hides a "
                         f"bounce too shallow to detect, and no impact is left to analyse")
    starts = []
    for lo, hi in bounds:
        inside = (t > lo) & (t < hi)
        starts.extend(parabola_start(t[inside], y[inside], g))
    theta_no_drag = np.asarray(starts)

    with_drag = drag != "off"
    theta0 = np.append(theta_no_drag, 1e-3) if with_drag else theta_no_drag
    guard_s = float(contact_guard_s)
    held_k = float(nominal_drag_k_per_m or 0.0)
    held_k_se = NOMINAL_DRAG_RELATIVE_SE * held_k
    fit = refine(t, y, bounds, with_drag, g, theta0, contact_height_m, noise, guard_s, held_k)
    if fit is None:
        raise InputError(f"{source}: the flights could not be fitted (too few samples between bounces)")
    bics = {with_drag: bic(fit[1])}
    if drag == "auto":
        # compare the two models on the same samples: those the larger model kept
        model, result, _, _, final_bounds = fit
        rival = fit_flights(t, y, final_bounds, False, g, result.x[:-1], held_k)
        bics[False] = bic(rival[1])
        if bics[False] <= bics[True]:
            if held_k > 0:
                held_k, held_k_se = combine_with_prior(result, held_k, held_k_se)
            fit = refine(t, y, final_bounds, False, g, rival[1].x, contact_height_m, noise, guard_s, held_k) or fit
    return _assemble(fit, bics, t_all, y_all, noise, g, float(t[release]), source, held_k_se, scale_rel_se,
                     contact_height_se_m, noise_correlation)


def refine(t, y, bounds, with_drag, g, theta0, contact_height_m, noise, guard_s, fixed_k=0.0):
    """Alternate fitting and re-assigning samples by the fitted touchdown and lift-off times.

    A flight keeps the samples more than ``guard_s`` (s) after the lift-off before it and before
    the touchdown after it. A noise dip that split one flight in two is joined again; a flight whose
    residuals hide an impact too shallow to detect ends the sequence before it.

    Returns
    -------
    (FlightModel, OptimizeResult, numpy.ndarray, ImpactQuantities, list) or None
        The model, its fit, the samples per flight, the impact quantities and the flights' bounds.
    """
    fitted = fit_flights(t, y, bounds, with_drag, g, theta0, fixed_k)
    if fitted is None:
        return None
    spurious = first_spurious_impact(*fitted[:2])
    if spurious is not None:
        i = spurious
        merged = bounds[:i] + [(bounds[i][0], bounds[i + 1][1])] + bounds[i + 2:]
        theta = np.delete(fitted[1].x, [2 * i + 2, 2 * i + 3])
        return refine(t, y, merged, with_drag, g, theta, contact_height_m, noise, guard_s, fixed_k)
    for _ in range(REFINEMENT_PASSES):
        model, result, counts = fitted
        quantities = ImpactQuantities(model, contact_height_m)
        quantities.set_weights(result)
        values = unpack_quantities(quantities(result.x), quantities.n_impacts)
        y_apex, t_apex, k = model.unpack(result.x)
        starts = np.concatenate([[t_apex[0] - 1e-9], values["t_liftoff_s"] + guard_s])
        last_end = t_apex[-1] + time_from_apex(y_apex[-1] - values["contact_height_m"], k, g)
        ends = np.append(values["t_touchdown_s"] - guard_s, last_end - guard_s)
        new_bounds = list(zip(starts, ends))
        refitted = fit_flights(t, y, new_bounds, with_drag, g, result.x, fixed_k)
        if refitted is None:
            break
        fitted, bounds = refitted, new_bounds
    model, result, counts = fitted
    misfit = first_misfit_flight(model, result, noise)
    if misfit is not None and misfit >= 2:
        theta = np.concatenate([result.x[: 2 * misfit], result.x[2 * model.n_flights:]])
        return refine(t, y, bounds[:misfit], with_drag, g, theta, contact_height_m, noise, guard_s, fixed_k)
    quantities = ImpactQuantities(model, contact_height_m)
    quantities.set_weights(result)
    return model, result, counts, quantities, bounds


def _assemble(fit, bics, t_all, y_all, noise, g, release_time, source, held_k_se, scale_rel_se, contact_height_se_m,
              noise_correlation):
    """The flights and impacts tables, covariances and summary of the final fit."""
    model, result, counts, quantities, bounds = fit
    theta = result.x
    parts = quantity_covariance(model, result, quantities, held_k_se, scale_rel_se, contact_height_se_m,
                                noise_correlation)
    cov, cov_theta = parts["covariance"], parts["theta_covariance"]
    vector = quantities(theta)
    se = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    n = quantities.n_impacts
    values = unpack_quantities(vector, n)
    errors = unpack_quantities(se, n)
    scale_errors = unpack_quantities(np.abs(parts["scale_part"]), n)
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
    add_with_interval(flights, "apex_height_m", values["apex_height_m"], errors["apex_height_m"])
    impacts = pd.DataFrame({"impact": np.arange(1, n + 1)})
    for name in IMPACT_COLUMNS[:-1]:
        add_with_interval(impacts, name, values[name], errors[name])
    add_with_interval(impacts, "h_before_m", values["apex_height_m"][:-1], errors["apex_height_m"][:-1])
    add_with_interval(impacts, "h_after_m", values["apex_height_m"][1:], errors["apex_height_m"][1:])
    impacts["h_before_scale_se_m"] = scale_errors["apex_height_m"][:-1]
    impacts["h_after_scale_se_m"] = scale_errors["apex_height_m"][1:]
    contact_ms, contact_se_ms = 1e3 * values["t_contact_s"], 1e3 * errors["t_contact_s"]
    if quantities.given_contact_height is not None and np.any(contact_ms < -3 * contact_se_ms - 1e-6):
        raise InputError(f"{source}: the flights meet above the given contact height (floor + radius): "
                         f"the floor is lower than that; check floor_m and the ball radius")
    add_with_interval(impacts, "t_contact_ms", contact_ms, contact_se_ms)
    sample_interval = float(np.median(np.diff(t_all)))
    impacts["contact_resolvable"] = contact_resolvable(contact_ms, contact_se_ms, sample_interval,
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
        "drag_k_se_per_m": float(np.sqrt(parts["k_variance"])),
        "bic_no_drag": bics.get(False, np.nan),
        "bic_quadratic_drag": bics.get(True, np.nan),
        "noise_m": float(noise),
        "residual_rms_m": float(np.sqrt(np.mean(result.fun**2))),
        "sample_interval_s": sample_interval,
        "release_time_s": release_time,
        "drop_apex_time_s": float(t_apex[0]),
        "drop_height_m": float(values["apex_height_m"][0]),
        "drop_height_se_m": float(errors["apex_height_m"][0]),
        "drop_height_scale_se_m": float(scale_errors["apex_height_m"][0]),
        "rest_time_s": rest_time(t_all, y_all, contact, noise, IMPACT_DEPTH_IN_NOISE,
                                 after=float(values["t_liftoff_s"][-1])),
        "gravity_m_s2": g,
        "n_impacts": n,
        "scale_rel_se": float(scale_rel_se),
        "noise_correlation": float(noise_correlation),
    }
    e_rows = quantity_index("e", n)
    contact_rows = quantity_index("t_contact_s", n)
    pair = np.r_[e_rows, contact_rows]
    return BounceAnalysis(flights=flights, impacts=impacts, e_covariance=cov[e_rows, e_rows],
                          e_contact_covariance=cov[np.ix_(pair, pair)],
                          e_drag_covariance=parts["drag_covariance"][e_rows], summary=summary)
