"""From a height-against-time trajectory to flights and impacts, with standard errors.

:func:`analyse_bounces` applies the defaults and runs the pure steps in the order of the data:
segmentation (:mod:`.segmentation`), the joint flight fit and its refinement (:mod:`.flights`), the
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

from ..balls import ball_kind, contact_time_at
from ..errors import InputError
from ..numerics import robust_sigma
from ..physics import STANDARD_GRAVITY_M_S2, flight_height, time_from_apex
from .flights import (MIN_SAMPLES_PER_FLIGHT, FlightModel, bic, combine_with_prior, first_misfit_flight, first_spurious_impact,
                      fit_flights, parabola_start)
from .detection import detection_reasons
from .impacts import (IMPACT_COLUMNS, ImpactQuantities, contact_resolvable, quantity_index, rest_time,
                      unpack_quantities)
from .segmentation import (CONTACT_CLEARANCE_S, IMPACT_DEPTH_IN_NOISE, RELEASE_SIGMAS, check_free_fall, flight_bounds,
                           segment)
from .tables import add_with_interval, se_column_name
from .uncertainty import quantity_covariance, refit_response, refit_sensitivity

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
                    nominal_drag_k_per_m=0.0, noise_correlation=0.0, gravity_se_m_s2=0.0, gravity_scaled=False,
                    contact_time_prior_s=None, contact_time_exponent=None,
                    nominal_drag_relative_se=NOMINAL_DRAG_RELATIVE_SE, max_contact_time_s=None, ball_radius_m=None,
                    contact_height_found=False, seen_height_m=None, speed_dependent_error_m=0.0):
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
        ``height_m``. If omitted it is modelled with the contact times: every contact lasts
        τ₁ (v_in / 1 m/s)^(−1/5), and the contact height is where the flights before and after each
        impact are that far apart in time (:class:`dropfit.analysis.impacts.ImpactQuantities`).
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
    contact_height_found : bool
        The contact height was found (a floor's edge in a video's image), not given by the user: flights
        that meet above it set it aside (the contact height is then modelled) instead of refusing the
        recording, and the notes name it as found.
    contact_guard_s : float
        Samples closer than this (s) to a fitted touchdown or lift-off are left out of the flights.
        0 for instantaneous samples; half the frame interval for video frames, which are exposed for
        up to a frame interval around their time and may show the ball already flattened.
    nominal_drag_k_per_m : float
        Prior value of the drag parameter in 1/m, e.g. that of a smooth sphere of the ball's size and
        mass (:func:`dropfit.physics.drag_parameter`), with relative standard error
        ``nominal_drag_relative_se``. When BIC keeps k from being fitted freely, k is held at this
        prior combined with the free fit's k (inverse-variance weights), and its standard error is
        propagated into every impact quantity. When k is fitted freely and comes out implausible (see
        :data:`PLAUSIBLE_DRAG_RATIO`), the note says so and the difference from the analysis with k held
        at this value is added to every uncertainty. 0 = no drag known.
    noise_correlation : float
        Lag-1 autocorrelation (dimensionless, 0 ≤ ρ < 1) of the height errors of successive samples,
        e.g. :data:`dropfit.video.quality.TRACKED_CENTRE_CORRELATION` for a video. The fit's covariance,
        which assumes independent errors, is multiplied by (1 + ρ)/(1 − ρ), the variance factor of
        an average over AR(1) errors. 0 for a sensor's white noise.
    gravity_se_m_s2 : float
        Standard error of ``gravity_m_s2`` (m/s²): 0 for a measured local g, about 0.3 %/√3 where the
        site is not known (:data:`dropfit.physics.UNKNOWN_SITE_GRAVITY_SE_M_S2`). Its effect on every
        quantity, with the flights refitted, is added to the covariance.
    gravity_scaled : bool
        The heights came from px through a scale from gravity: an error of g then scales every length
        (heights, speeds) with it and leaves e, times and ratios alone.
    contact_time_prior_s : (float, float), optional
        Contact time at 1 m/s (s) and its standard error, the prior of the modelled contact height
        (:func:`dropfit.balls.ball_kind`); default that of an unknown kind of ball. (0, 0) treats the
        contacts as instantaneous. Not used with a given ``contact_height_m``.
    contact_time_exponent : (float, float), optional
        β of τ ∝ v^(−β) and its standard error, the prior of its fit; default that of an unknown kind.
    nominal_drag_relative_se : float
        Relative standard error of ``nominal_drag_k_per_m`` (the ball kind's C_d se over its C_d).
    max_contact_time_s : float, optional
        The longest contact time at 1 m/s the ball can have (s; it scales as v^(−β) with the prior β);
        default that of an unknown kind. A longer one is noted and never reported as resolvable.
    ball_radius_m : float, optional
        The ball's radius (m): with a given contact height, a log of the ball's bottom or top taken for
        its centre shows as the flights meeting about a radius below or above it, and the note says so.
    seen_height_m : array_like, optional
        Height in m of the ball's centre wherever it was seen, measured cleanly or not (a video's blurred,
        shaded or merged frames, good to a few px), NaN elsewhere; ``height_m`` holds the clean samples alone.
        The flights and impacts are then found on these heights, and only the clean samples are fitted: a
        clip whose fast flights near the floor are blurred still shows where its bounces are, and the
        impacts are numbered from the release even when the first flights have too few clean samples to
        be fitted.
    speed_dependent_error_m : float
        Largest height error (m, at the fastest sample) that may change with the ball's speed, as a video's
        ball centres do (motion blur, the lossy coding of a moving ball): taken as growing with v|v| (falling
        high and rising low) and with v² (off the same way in both), a standard error for each. The flights'
        curvature takes such an error for drag (phonesim's clips: k 20 % high from H.264 at 120 frames/s, 55 %
        low from the blur of a lossless 30 frames/s clip, e 2–5 standard errors off). With ``drag="auto"`` and a
        ``nominal_drag_k_per_m`` known, the flights' k is then not used alone: its standard error is widened by
        the k such an error makes, it is combined with the nominal k (inverse-variance weights), and k is held
        there, its standard error carried as a systematic error (``drag="on"`` fits it freely). Whatever the
        drag option, what the two shapes do to every quantity at the fit's k is carried as two more.

    Returns
    -------
    BounceAnalysis
    """
    g = float(gravity_m_s2)
    time_s = np.asarray(time_s, dtype=float)
    height_m = np.asarray(height_m, dtype=float)
    finite = np.isfinite(height_m)
    # times relative to the first sample: Unix-epoch stamps would leave no digits for a parabola
    origin = float(time_s[finite][0]) if finite.any() else 0.0
    segmentation = segment(time_s - origin, height_m, source, acceleration=g, seen_height=seen_height_m)
    notes = list(segmentation.notes)
    fit_time, fit_height, noise = segmentation.fit_samples()
    unknown = ball_kind(None)
    contact_prior = (tuple(contact_time_prior_s) if contact_time_prior_s is not None
                     else (unknown.contact_time_s, unknown.contact_time_se_s),
                     tuple(contact_time_exponent) if contact_time_exponent is not None
                     else (unknown.contact_time_exponent, unknown.contact_time_exponent_se))
    problem = FitProblem(fit_time, fit_height, g, contact_height_m, noise, float(contact_guard_s),
                         float(segmentation.time[segmentation.release]), contact_prior)
    bounds, cut, passed_over = initial_bounds(problem, segmentation, source)
    held_k = float(nominal_drag_k_per_m or 0.0)
    speed_error = float(speed_dependent_error_m) if drag == "auto" and held_k > 0 else 0.0
    longest = (unknown.max_contact_time_s if max_contact_time_s is None else float(max_contact_time_s),
               contact_prior[1][0])
    keep = np.ones(problem.t.size, dtype=bool)
    while True:
        skipped = passed_over[-1] + 1 if passed_over else 0  # the first fitted flight's number
        kept = problem.subset(keep)
        fit, bics, held_drag = fit_with_drag_choice(kept, bounds, drag, held_k, float(nominal_drag_relative_se),
                                                    source, speed_error)
        earlier_release = release_extension(fit, problem)
        if earlier_release is not None and earlier_release < problem.release_time:
            problem.release_time = earlier_release
            continue
        outliers = residual_outliers(fit, problem.noise)
        if outliers.size and outliers.size <= kept.outliers_allowed:
            left = keep.copy()
            left[np.flatnonzero(keep)[np.isin(problem.t[keep], fit.model.t[outliers])]] = False
            sampled = sampled_enough(problem.t[left], bounds)
            first, end = fittable_run(sampled)
            if first == 0 and end == len(bounds):
                keep = left
                continue
            # the outliers took a flight below what a fit needs: the sequence starts after it or ends before it
            if end - first < 2:
                raise InputError(f"{source}: flight {skipped + sampled.index(False)} has fewer than "
                                 f"{MIN_SAMPLES_PER_FLIGHT} samples once its outliers of the flight fit are left out: no "
                                 f"impact is left to measure")
            if end < len(bounds):
                notes.append(f"flight {skipped + end} has fewer than {MIN_SAMPLES_PER_FLIGHT} samples once its "
                             f"outliers of the flight fit are left out: the bounce sequence ends before it")
            passed_over += [skipped + i for i in range(first) if not sampled[i]]
            bounds = bounds[first:end]
            if first:
                start_after_impact(problem, bounds)
            continue
        unresolved = first_unresolved_impact(fit, problem.noise)
        if unresolved is None:
            floor_note = None if problem.contact_height is None else implausible_contact_height(
                fit, longest, ball_radius_m, contact_time_se(fit, held_drag, contact_height_se_m=contact_height_se_m,
                                                             noise_correlation=noise_correlation),
                contact_height_found, skipped + 1)
            if floor_note is None:
                break
            # a contact height the flights contradict is not a measurement: model it from the flights
            notes.append(floor_note)
            problem.contact_height = None
            bounds, cut, passed_over = initial_bounds(problem, segmentation, source, keep)
            continue
        if unresolved == 0:
            first = f" (impact {skipped + 1})" if skipped else ""
            raise InputError(f"{source}: the first rebound{first} does not rise clearly above the contact height: no "
                             f"impact is resolved (the ball may not bounce, or the floor is set too high)")
        notes.append(f"impact {skipped + unresolved + 1}: its rebound rises less than {HOP_RESOLUTION_IN_NOISE:g} "
                     f"noise standard deviations above the contact height, below the resolution; the bounce sequence "
                     f"ends before it")
        bounds = fit.bounds[: unresolved + 1]
    if fit.quantities.n_impacts == 0:  # every cut together can leave one flight
        cuts = [note for note in notes + cut if "sequence ends before" in note]
        if fit.misfit_cut is not None:
            cuts.append(f"flight {skipped + fit.misfit_cut}: its residuals are far larger than the noise")
        raise InputError(f"{source}: no impact is left to measure: {'; '.join(cuts) or 'one flight only'}")
    # the free fall starts where flight 0 does (at its apex when the ball left the hand at rest); the first flights
    # passed over start at the segmentation's release
    release_time = float(segmentation.time[segmentation.release] if skipped else fit.bounds[0][0]) + origin
    notes = [note for note in notes if not note.startswith("the ball was held")]
    hand = int(np.count_nonzero(problem.t + origin < release_time - 1e-6))
    rising = rising_into_first_apex(fit, problem.subset(keep))
    if skipped:
        sparse = ", ".join(str(flight) for flight in passed_over)
        notes.append(f"{'flight' if len(passed_over) == 1 else 'flights'} {sparse} "
                     f"{'has' if len(passed_over) == 1 else 'have'} fewer than {MIN_SAMPLES_PER_FLIGHT} samples to "
                     f"fit: the fit starts with flight {skipped}, after impact {skipped}; the impacts keep their "
                     f"numbers from the release, and no drop height is measured")
    elif rising >= MIN_SAMPLES_PER_FLIGHT:
        notes.append(f"flight 0 is a bounce, not a drop: {rising} samples before it rise into its apex along its "
                     f"free flight, so an impact before them was not found (too few samples about it): the impacts "
                     f"are numbered from the first one found, and flight 0's apex is no drop height")
    elif hand:
        notes.append(f"the ball was held or moved by hand until {release_time:.4f} s: the {hand} samples before the "
                     f"free fall are left out")
    extra_parts, drag_note = implausible_drag(fit, problem.subset(keep), held_k)
    if drag_note:
        notes.append(drag_note)
    if fit.misfit_cut is None:  # an earlier cut by the misfit test makes the segmentation's moot
        notes.extend(cut)
    else:
        notes.append(f"flight {skipped + fit.misfit_cut}: its residuals are far larger than the noise (a bounce too "
                     f"shallow to detect, or not a free flight); the bounce sequence ends before it")
    left_out = np.count_nonzero(~keep)
    if left_out:
        notes.append(f"{left_out} samples left out as outliers of the flight fit (more than "
                     f"{RESIDUAL_OUTLIER_SIGMAS:g} noise standard deviations off)")
    kinds = {"longest_s": longest[0], "exponent": longest[1], "radius_m": ball_radius_m}
    uncertainty = {**held_drag, "scale_rel_se": scale_rel_se, "contact_height_se_m": contact_height_se_m,
                   "noise_correlation": noise_correlation, "gravity_se_m_s2": float(gravity_se_m_s2),
                   "gravity_scaled": bool(gravity_scaled), "extra_parts": extra_parts,
                   "speed_error_m": float(speed_dependent_error_m)}
    data = {"release_time_s": release_time, "hand_samples": hand, "tracking_jump_samples": int(segmentation.outliers.size),
            "residual_outlier_samples": int(left_out),
            "first_flight_is_a_bounce": bool(skipped) or rising >= MIN_SAMPLES_PER_FLIGHT,
            "first_impact": skipped + 1}
    if speed_error > 0 and not fit.model.with_drag:  # (a held refit that failed leaves the free fit)
        data["drag_why"] = (f"the ball's nominal k ({held_k:.3g} 1/m ± {float(nominal_drag_relative_se):.0%}) combined "
                            f"with the flights' k, whose standard error is widened by what an error of the heights "
                            f"growing with the ball's speed (a video's centres: motion blur, the codec; "
                            f"{1e3 * speed_error:.2g} mm at the fastest sample) makes of it: the flights' curvature "
                            f"takes such an error for drag; k is held there and its standard error carried into every "
                            f"e, height and contact time as a systematic error (the drag option 'on' fits k)")
    elif speed_error > 0:
        data["drag_why"] = (f"the flights' own k: the refit with k held at the ball's nominal k ({held_k:.3g} 1/m) "
                            f"combined with theirs failed, so k is the free fit's, whose standard error leaves out "
                            f"what a centre error growing with the ball's speed makes of it (treat e as less certain "
                            f"than stated)")
    return _assemble(fit, bics, problem.subset(keep), origin, source, uncertainty, data, notes, kinds)


@dataclass
class FitProblem:
    """What every fit of one recording shares: its samples (s, m; the hand's and the tracking jumps'
    left out), g (m/s²), a given contact height (m, or None), the noise (m), the guard around the
    contacts (s), the release time (s), before which flight 0 never starts, and the priors of a
    modelled contact height: the contact time at 1 m/s (s) and its exponent, each with its se; and how many
    more samples may be left out as residual outliers (``MAX_RESIDUAL_OUTLIER_FRACTION`` of the recording's,
    less those left out already)."""

    t: np.ndarray
    y: np.ndarray
    g: float
    contact_height: float | None
    noise: float
    guard_s: float
    release_time: float
    contact_prior: tuple = ((0.0, 0.0), (0.0, 0.0))
    outliers_allowed: int | None = None  # None: the fraction of these samples
    first_flight_after_impact: bool = False  # flight 0 starts at the release time, rising from a bounce

    def __post_init__(self):
        if self.outliers_allowed is None:
            self.outliers_allowed = int(MAX_RESIDUAL_OUTLIER_FRACTION * self.t.size)

    def subset(self, keep):
        """The same problem on the samples ``keep`` (boolean mask over these samples), the outliers allowed less
        the samples it leaves out."""
        left_out = int(np.count_nonzero(~np.asarray(keep)))
        return FitProblem(self.t[keep], self.y[keep], self.g, self.contact_height, self.noise, self.guard_s,
                          self.release_time, self.contact_prior, max(self.outliers_allowed - left_out, 0),
                          self.first_flight_after_impact)

    def impact_quantities(self, model):
        """The impact quantities of a flight model fitted to this problem."""
        return ImpactQuantities(model, self.contact_height, *self.contact_prior)


@dataclass
class FlightFit:
    """A fitted bounce sequence: the flight model, its least-squares result, the samples per flight,
    the impact quantities built on it, the flights' time intervals (s) and where a misfit ended the
    sequence."""

    model: FlightModel
    result: object
    counts: np.ndarray
    quantities: ImpactQuantities
    bounds: list
    misfit_cut: int | None = None  # the flight whose residuals ended the sequence before it, if any


def sampled_enough(t, bounds):
    """Per flight in ``bounds`` (open intervals, s): whether it holds at least ``MIN_SAMPLES_PER_FLIGHT`` of the
    sample times ``t`` (s)."""
    return [np.count_nonzero((t > lo) & (t < hi)) >= MIN_SAMPLES_PER_FLIGHT for lo, hi in bounds]


def fittable_run(sampled):
    """(first, end): the flights to fit, from the first of two in a row ``sampled`` well enough (0 when none are)
    up to the first after it that is not (its index; their number when none is)."""
    first = next((i for i in range(len(sampled) - 1) if sampled[i] and sampled[i + 1]), 0)
    return first, next((i for i in range(first, len(sampled)) if not sampled[i]), len(sampled))


def start_after_impact(problem, bounds):
    """Let flight 0 of ``problem`` be the first of ``bounds``, a flight that follows an impact: it starts
    ``CONTACT_CLEARANCE_S`` after the lowest sample of that impact, where the ball may still touch the floor."""
    problem.release_time = max(problem.release_time, bounds[0][0] + CONTACT_CLEARANCE_S)
    problem.first_flight_after_impact = True


def initial_bounds(problem, segmentation, source, keep=None):
    """Flight intervals (s) from the segmentation, from the first of two flights in a row with enough samples
    to fit up to the first flight after them sampled too sparsely or not curving like a free flight; checks
    that the flights fall with g. Sets where ``problem``'s flight 0 starts (:func:`start_after_impact` when first
    flights are passed over).

    Parameters
    ----------
    keep : numpy.ndarray, optional
        Boolean mask of ``problem``'s samples still in the fit (default: all).

    Returns
    -------
    (list, list of str, list of int)
        The bounds, a note for where the sequence was cut and why, and the numbers of the first flights
        passed over for too few samples (the fit then starts after the last).
    """
    keep = np.ones(problem.t.size, dtype=bool) if keep is None else keep
    t, y = problem.t[keep], problem.y[keep]
    bounds = flight_bounds(segmentation.time, segmentation.height, segmentation.release, segmentation.impacts,
                           segmentation.noise, problem.contact_height)
    sampled = sampled_enough(t, bounds)
    # keep impacts while both neighbouring flights are sampled well enough
    skipped, end = fittable_run(sampled)
    passed_over = [i for i in range(skipped) if not sampled[i]]
    if skipped:  # the sequence starts after the impact that ends the last sparse flight
        bounds = bounds[skipped:]
        start_after_impact(problem, bounds)
    elif problem.first_flight_after_impact:  # set by an earlier call
        problem.release_time, problem.first_flight_after_impact = float(segmentation.time[segmentation.release]), False
    n_flights = end - skipped
    if n_flights < 2:
        raise InputError(f"{source}: no bounce with at least {MIN_SAMPLES_PER_FLIGHT} samples in the flights "
                         f"before and after it")
    kept = check_free_fall(t, y, bounds[:n_flights], problem.g, source)
    if kept < 2:
        raise InputError(f"{source}: the flight after the first bounce does not curve like a free flight (far less "
                         f"or far more than g): it hides a bounce too shallow to detect, and no impact is left")
    notes = []
    if kept < n_flights:
        notes.append(f"flight {skipped + kept} does not curve like a free flight (a bounce too shallow to detect, the "
                     f"ball rolling, a hand): the bounce sequence ends before it")
    elif n_flights < len(bounds):
        notes.append(f"flight {n_flights + skipped} has fewer than {MIN_SAMPLES_PER_FLIGHT} samples: the bounce "
                     f"sequence ends before it")
    return bounds[:kept], notes, passed_over


def fit_with_drag_choice(problem, bounds, drag, held_k, held_k_relative_se, source, speed_error_m=0.0):
    """Fit the flights in ``bounds`` with and (``drag="auto"``) without a free drag parameter; keep
    the one the BIC prefers. Without a free k, k is held at ``held_k`` (1/m, relative se
    ``held_k_relative_se``) combined with what the free fit says about it. With ``speed_error_m`` > 0 (m, see
    :func:`analyse_bounces`' ``speed_dependent_error_m``) k is always held so, the free k's standard error
    widened by :func:`speed_error_drag_se`.

    Returns
    -------
    (FlightFit, dict, dict)
        The chosen fit, the BIC of each model tried (key: whether k was free) and the held k's
        uncertainty (the fit's model holds k itself): ``held_k_se`` (1/m) and ``held_k_slopes``, the
        derivatives of a k combined with the free fit's by g (1/m per m/s²) and by the relative length
        scale (1/m), through the free fit.
    """
    t, y, g = problem.t, problem.y, problem.g
    starts = []
    for lo, hi in bounds:
        inside = (t > lo) & (t < hi)
        starts.extend(parabola_start(t[inside], y[inside], g))
    with_drag = drag != "off"
    theta0 = np.append(starts, 1e-3) if with_drag else np.asarray(starts)
    held_drag = {"held_k_se": held_k_relative_se * held_k, "held_k_slopes": {}}
    fit = refine(problem, bounds, with_drag, theta0, held_k)
    if fit is None:
        raise InputError(f"{source}: the flights could not be fitted (too few samples between bounces)")
    bics = {with_drag: bic(fit.result)}
    if drag == "auto":
        # compare the two models on the same samples: those the larger model kept
        rival = fit_flights(t, y, fit.bounds, False, g, fit.result.x[:-1], held_k)
        bics[False] = bic(rival[1])
        if bics[False] <= bics[True] or speed_error_m > 0:
            if held_k > 0:
                held_k, held_drag["held_k_se"], weight = combine_with_prior(
                    fit.result, held_k, held_drag["held_k_se"], speed_error_drag_se(fit, speed_error_m))
                free = fit.model
                held_drag["held_k_slopes"] = {
                    "gravity": weight * refit_sensitivity(fit.result, free, free, "g", 1e-4)[-1],
                    "scale": weight * refit_response(fit.result, -free.y)[-1]}
            held = refine(problem, fit.bounds, False, rival[1].x, held_k)
            if held is not None:  # the sequence it refits was cut by the first fit: keep saying so
                held.misfit_cut = held.misfit_cut if held.misfit_cut is not None else fit.misfit_cut
                fit = held
    return fit, bics, held_drag


def speed_error_drag_se(fit, error_m):
    """The change of a free fit's k (1/m) that a height error growing with the ball's speed makes: ``error_m``
    (m) at the fastest sample, shaped as v|v| and as v² (:meth:`FlightModel.speed_patterns`), the two in quadrature,
    through the fit's linearised response; 0 without ``error_m``."""
    if not error_m > 0:
        return 0.0
    return float(np.hypot(*(refit_response(fit.result, pattern)[-1]
                            for pattern in fit.model.speed_patterns(fit.result.x, error_m))))


#: A sample whose flight-fit residual exceeds this many noise standard deviations is an outlier.
RESIDUAL_OUTLIER_SIGMAS = 5.0
#: At most this fraction of the samples is left out as residual outliers; beyond it, the model misfits
#: and the misfit test, not outlier rejection, has to say so.
MAX_RESIDUAL_OUTLIER_FRACTION = 0.02
#: A rebound must rise this many noise standard deviations above the contact height to be resolved.
HOP_RESOLUTION_IN_NOISE = 2.0


#: A fitted drag k more than this many times that of a smooth sphere of the ball's size and mass, or
#: less than its inverse, is more (or less) than air can do to a ball (C_d of real balls: 0.25–0.6).
PLAUSIBLE_DRAG_RATIO = 2.5
#: Without the ball's size and mass: the largest k of a common ball (a table-tennis ball: 0.14 1/m).
MAX_PLAUSIBLE_DRAG_K_PER_M = 0.3


def implausible_drag(fit, problem, nominal_k):
    """Whether a freely fitted drag k is implausible, and if so its systematic part and note.

    Returns
    -------
    (dict, str or None)
        ``{"implausible_drag": part}`` — the difference of every quantity from the analysis with k held at
        ``nominal_k`` (1/m), to be added to their covariance — and the note; ``({}, None)`` when k was
        not fitted or is plausible.
    """
    if not fit.model.with_drag:
        return {}, None
    k = float(fit.result.x[-1])
    if nominal_k > 0:
        ratio = k / nominal_k
        if 1.0 / PLAUSIBLE_DRAG_RATIO <= ratio <= PLAUSIBLE_DRAG_RATIO:
            return {}, None
        what = f"{ratio:.2g} times that of a smooth sphere of this size and mass"
    elif k <= MAX_PLAUSIBLE_DRAG_K_PER_M:
        return {}, None
    else:
        what = f"more than that of any common ball ({MAX_PLAUSIBLE_DRAG_K_PER_M:g} 1/m)"
    note = (f"the fitted air drag k = {k:.3g} 1/m is {what}: the flights' curvature changes with speed for "
            f"another reason too (a scale that is not uniform, a tilted camera, a tracking bias)")
    held = refine(problem, fit.bounds, False, fit.result.x[:-1], nominal_k)
    if held is None or held.quantities.n_impacts != fit.quantities.n_impacts:
        return {}, note + "; the analysis with a sphere's drag could not be compared"
    difference = held.quantities(held.result.x) - fit.quantities(fit.result.x)
    return {"implausible_drag": difference}, note + (
        "; the difference from the analysis with a sphere's drag is added to every uncertainty")


#: A given contact height is rejected when the contacts it implies last this many times longer than
#: the ball can have, or longer by more than CONTACT_HEIGHT_REJECTION_SE of their standard errors.
CONTACT_HEIGHT_REJECTION_FACTOR = 1.5
CONTACT_HEIGHT_REJECTION_SE = 2.0
#: Flights that meet above a given contact height by more than this many standard errors of the contact times
#: refuse it (a found one is set aside).
NEGATIVE_CONTACT_SE = 3.0


def contact_time_se(fit, held_drag, **uncertainty):
    """Standard errors (s) of the contact times of ``fit``: its covariance with the held drag's
    uncertainty (``held_drag``, as :func:`fit_with_drag_choice` gives it) and ``uncertainty`` (keyword
    arguments of :func:`dropfit.analysis.uncertainty.quantity_covariance`)."""
    quantities = fit.quantities
    covariance = quantity_covariance(fit.model, fit.result, quantities, **held_drag, **uncertainty)["covariance"]
    rows = quantity_index("t_contact_s", quantities.n_impacts)
    return np.sqrt(np.clip(np.diag(covariance)[rows], 0.0, None))


def implausible_contact_height(fit, longest, radius_m, contact_se_s=0.0, found=False, first_impact=1):
    """A note if the given contact height makes the contacts longer than the ball can have (a log of
    the ball's bottom taken for its centre, a floor set too high, a floor edge seen behind the ball), else
    None: by ``CONTACT_HEIGHT_REJECTION_FACTOR`` times, or by more than ``CONTACT_HEIGHT_REJECTION_SE`` of
    their standard errors ``contact_se_s`` (s). The flights then contradict the floor: e measured at it
    would be off (a phone clip's floor edge 3 px above the ball's contact gave e 3 standard errors low). A
    contact height that was ``found`` (a video's floor edge), not given, is also set aside when the flights
    meet above it (a contact shorter than zero by ``NEGATIVE_CONTACT_SE`` standard errors), where a given
    one is refused (:func:`_assemble`).

    ``longest``: the longest contact time at 1 m/s (s) and its exponent; ``first_impact``: the number of the
    fit's first impact.
    """
    quantities = fit.quantities
    if quantities.given_contact_height is None:
        return None
    values = unpack_quantities(quantities(fit.result.x), quantities.n_impacts)
    limit = contact_time_at(longest[0], values["v_in_m_s"], longest[1])
    contact, contact_se = values["t_contact_s"], np.asarray(contact_se_s)
    too_long = (contact > CONTACT_HEIGHT_REJECTION_FACTOR * limit) | (
        contact - CONTACT_HEIGHT_REJECTION_SE * contact_se > limit)
    floor = "the floor found in the image" if found else "the given floor"
    ending = "; the floor is not used: the contact height is modelled from the flights"
    flights_meet_above = contact < -NEGATIVE_CONTACT_SE * contact_se
    if found and flights_meet_above.any():
        first = int(np.flatnonzero(flights_meet_above)[0])
        return (f"the flights meet above {floor}: impact {first_impact + first}'s contact would last "
                f"{1e3 * contact[first]:.3g} ms (the floor seen lower than where the ball touches){ending}")
    if not too_long.any():
        return None
    first = int(np.flatnonzero(too_long)[0])
    return (f"{floor} makes impact {first_impact + first}'s contact last {1e3 * contact[first]:.3g} ms, "
            f"more than this kind of ball can (at most {1e3 * limit[first]:.2g} ms)"
            + ("" if found else reference_hint(quantities, fit.result.x, radius_m)) + ending)


def reference_hint(quantities, theta, radius_m):
    """Why the flights may not fit a given contact height: a log of the ball's bottom or top taken for
    its centre puts where the flights meet about a radius below or above it ("" when it does not)."""
    if radius_m is None:
        return ""
    modelled = quantities.with_contact_height(None).modelled_contact(theta)[0]
    offset = float(quantities.given_contact_height - modelled)
    for point, sign in (("bottom", 1.0), ("top", -1.0)):
        if abs(sign * offset - radius_m) < 0.3 * radius_m:
            return (f": the flights meet {abs(offset) * 1e3:.0f} mm {'below' if sign > 0 else 'above'} the floor "
                    f"plus the radius, about one radius: the heights look like the ball's {point}, not its "
                    f"centre (set height_reference {point})")
    return f": the floor may be set too {'high' if offset > 0 else 'low'} (check floor_m)"


def release_extension(fit, problem):
    """Time (s) of the earliest sample before flight 0's start from which every sample fits the fitted
    flight 0 within RELEASE_SIGMAS noise standard deviations, back to its apex; None if no earlier sample
    does. The segmentation finds the release on a parabola; the fitted flight, drag and all, follows a
    long fall to its top."""
    y_apex, t_apex, k = fit.model.unpack(fit.result.x)
    start = fit.bounds[0][0]
    before = np.flatnonzero((problem.t <= start) & (problem.t >= t_apex[0]))[::-1]
    if before.size == 0:
        return None
    residual = flight_height(problem.t[before], t_apex[0], y_apex[0], k, problem.g) - problem.y[before]
    misfit = np.flatnonzero(np.abs(residual) > RELEASE_SIGMAS * problem.noise)
    fitting = before[: misfit[0]] if misfit.size else before
    return float(problem.t[fitting[-1]]) if fitting.size else None


#: Flight 0 follows a bounce that was not found when samples before it rise along its free flight from below
#: this fraction of its apex height above the contact height: a ball tossed up from a hand rises from the
#: hand's height, a ball bouncing from the floor.
BOUNCE_RISE_FRACTION = 0.5


def rising_into_first_apex(fit, problem):
    """How many samples before flight 0's start lie on its rising branch, below its apex, when the lowest of
    them is below ``BOUNCE_RISE_FRACTION`` of the apex height (else 0): a ball released from rest at the apex
    has none (a hand holds it still or moves it otherwise), and a tossed one rises from the hand; a flight 0
    that follows a bounce the segmentation did not find (a fall filmed in a few blurred frames) has its rise
    from the floor."""
    y_apex, t_apex, k = fit.model.unpack(fit.result.x)
    before = problem.t < fit.bounds[0][0]
    if not before.any():
        return 0
    t, y = problem.t[before], problem.y[before]
    on_branch = np.abs(flight_height(t, t_apex[0], y_apex[0], k, problem.g) - y) <= RELEASE_SIGMAS * problem.noise
    rising = on_branch & (y < y_apex[0] - RELEASE_SIGMAS * problem.noise) & (t < t_apex[0])
    contact = float(np.atleast_1d(unpack_quantities(fit.quantities(fit.result.x), fit.quantities.n_impacts)
                                  ["contact_height_m"])[0])
    from_floor = rising.any() and y[rising].min() - contact < BOUNCE_RISE_FRACTION * (y_apex[0] - contact)
    return int(np.count_nonzero(rising)) if from_floor else 0


def residual_outliers(fit, noise):
    """Positions (in the fit's samples) of the samples whose residual is an outlier."""
    residual = fit.result.fun
    scale = max(noise, robust_sigma(residual))
    return np.flatnonzero(np.abs(residual) > RESIDUAL_OUTLIER_SIGMAS * scale)


def first_unresolved_impact(fit, noise):
    """Index of the first impact whose rebound does not rise clearly above the contact height (or
    whose e is not a number); None if all are resolved."""
    values = unpack_quantities(fit.quantities(fit.result.x), fit.quantities.n_impacts)
    rise = values["apex_height_m"][1:]
    bad = ~np.isfinite(values["e"]) | ~(rise > HOP_RESOLUTION_IN_NOISE * noise)
    return int(np.flatnonzero(bad)[0]) if bad.any() else None


def refine(problem, bounds, with_drag, theta0, fixed_k=0.0):
    """Alternate fitting and re-assigning samples by the fitted touchdown and lift-off times.

    A flight keeps the samples more than ``problem.guard_s`` after the lift-off before it and before
    the touchdown after it; flight 0 starts at its apex, but never before the release. A noise dip
    that split one flight in two is joined again; a flight whose residuals hide an impact too shallow
    to detect ends the sequence before it. A flight 0 that follows an impact starts at the release time.

    Returns
    -------
    FlightFit or None
    """
    t, y, g, guard_s = problem.t, problem.y, problem.g, problem.guard_s
    fitted = fit_flights(t, y, bounds, with_drag, g, theta0, fixed_k)
    if fitted is None:
        return None
    spurious = first_spurious_impact(*fitted[:2])
    if spurious is not None:
        i = spurious
        merged = bounds[:i] + [(bounds[i][0], bounds[i + 1][1])] + bounds[i + 2:]
        theta = np.delete(fitted[1].x, [2 * i + 2, 2 * i + 3])
        return refine(problem, merged, with_drag, theta, fixed_k)
    for _ in range(REFINEMENT_PASSES):
        model, result, counts = fitted
        quantities = problem.impact_quantities(model)
        quantities.set_weights(result)
        values = unpack_quantities(quantities(result.x), quantities.n_impacts)
        y_apex, t_apex, k = model.unpack(result.x)
        first_start = (problem.release_time if problem.first_flight_after_impact
                       else max(t_apex[0], problem.release_time)) - 1e-9
        starts = np.concatenate([[first_start], values["t_liftoff_s"] + guard_s])
        last_end = t_apex[-1] + time_from_apex(y_apex[-1] - values["contact_height_m"], k, g)
        ends = np.append(values["t_touchdown_s"] - guard_s, last_end - guard_s)
        new_bounds = list(zip(starts, ends))
        refitted = fit_flights(t, y, new_bounds, with_drag, g, result.x, fixed_k)
        if refitted is None:
            break
        fitted, bounds = refitted, new_bounds
    model, result, counts = fitted
    misfit = first_misfit_flight(model, result, problem.noise, RESIDUAL_OUTLIER_SIGMAS, problem.outliers_allowed)
    if misfit is not None and misfit >= 2:
        theta = np.concatenate([result.x[: 2 * misfit], result.x[2 * model.n_flights:]])
        shorter = refine(problem, bounds[:misfit], with_drag, theta, fixed_k)
        if shorter is not None and shorter.misfit_cut is None:
            shorter.misfit_cut = misfit
        return shorter
    quantities = problem.impact_quantities(model)
    quantities.set_weights(result)
    return FlightFit(model, result, counts, quantities, bounds)


#: Columns of the tables that hold a time (s) since the recording's origin; their _ci95 bounds too.
_TIME_COLUMNS = ("t_start_s", "t_end_s", "t_apex_s", "t_touchdown_s", "t_liftoff_s")


def impact_notes(e, flight_after_s=None):
    """Whether each impact enters the fits of e (``in_fit``), where not why (``note``), and whether it is a
    detection error (:func:`dropfit.analysis.detection.detection_reasons`: e > 1, or the flight after it
    outlasting the one before); ``flight_after_s`` is each impact's flight after it, s (NaN after the last).

    The flights of a log or a video are fitted parabolas, each e measured from its own two flights: a ball
    whose e changes fast with speed (a marble on paper: 0.53, 0.69, 0.76) is not out of its sequence, so
    the sequence test of impact times (:func:`dropfit.analysis.detection.flights_out_of_sequence`, for a
    missed or spurious click) is not applied here."""
    e = np.asarray(e, float)
    if flight_after_s is None:
        reasons = detection_reasons(e)
    else:
        after = np.asarray(flight_after_s, float)
        reasons = detection_reasons(e, np.r_[np.nan, after[:-1]], after)
    detected = reasons != ""
    return np.isfinite(e) & ~detected, np.where(detected, reasons, ""), detected


def _assemble(fit, bics, problem, origin, source, uncertainty, data, notes, ball):
    """The flights and impacts tables, covariances and summary of the final fit (times shifted back by
    ``origin``, s); ``uncertainty``: the keyword arguments of :func:`quantity_covariance`; ``data``: the
    release time (s) and the samples left out; ``ball``: the longest contact time at 1 m/s (s), its
    exponent and the ball's radius (m)."""
    model, result, counts, quantities, bounds = fit.model, fit.result, fit.counts, fit.quantities, fit.bounds
    theta = result.x
    parts = quantity_covariance(model, result, quantities, **uncertainty)
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
        "flight": np.arange(model.n_flights) + data["first_impact"] - 1,
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
    impacts = pd.DataFrame({"impact": np.arange(data["first_impact"], data["first_impact"] + n)})
    for name in IMPACT_COLUMNS[:-1]:
        add_with_interval(impacts, name, values[name], errors[name])
    add_with_interval(impacts, "h_before_m", values["apex_height_m"][:-1], errors["apex_height_m"][:-1])
    add_with_interval(impacts, "h_after_m", values["apex_height_m"][1:], errors["apex_height_m"][1:])
    impacts["h_before_scale_se_m"] = scale_errors["apex_height_m"][:-1]
    impacts["h_after_scale_se_m"] = scale_errors["apex_height_m"][1:]
    contact_ms, contact_se_ms = 1e3 * values["t_contact_s"], 1e3 * errors["t_contact_s"]
    if quantities.given_contact_height is not None and np.any(contact_ms < -NEGATIVE_CONTACT_SE * contact_se_ms - 1e-6):
        raise InputError(f"{source}: the flights meet above the given contact height (floor + radius): "
                         f"the floor is lower than that; check floor_m and the ball radius")
    add_with_interval(impacts, "t_contact_ms", contact_ms, contact_se_ms)
    sample_interval = float(np.median(np.diff(problem.t)))
    longest_ms = 1e3 * contact_time_at(ball["longest_s"], values["v_in_m_s"], ball["exponent"])
    given = quantities.given_contact_height is not None
    impacts["contact_resolvable"] = contact_resolvable(contact_ms, contact_se_ms, sample_interval, given, longest_ms)
    too_long = given & (contact_ms - 2 * contact_se_ms > longest_ms)
    if too_long.any():
        first = int(np.flatnonzero(too_long)[0])
        notes.append(f"impact {data['first_impact'] + first}: the contact lasts {contact_ms[first]:.3g} ms, longer than "
                     f"this kind of ball can (at most {longest_ms[first]:.2g} ms at {values['v_in_m_s'][first]:.2g} m/s)"
                     + reference_hint(quantities, theta, ball["radius_m"])
                     + "; the contact times are not reported as resolved")
    impacts["n_samples_before"] = counts[:-1]
    impacts["n_samples_after"] = counts[1:]
    impacts["in_fit"], impacts["note"], impacts["detection_error"] = impact_notes(
        values["e"], values["flight_time_after_s"])
    for table in (flights, impacts):
        for name in _TIME_COLUMNS:
            for column in (name, se_column_name(name, "ci95_low"), se_column_name(name, "ci95_high")):
                if column in table:
                    table[column] = table[column] + origin

    contact = values["contact_height_m"]
    summary = {
        "contact_height_m": contact,
        "contact_height_se_m": errors["contact_height_m"],
        "contact_height_source": "given" if quantities.given_contact_height is not None else
        "modelled: the height at which the flights before and after each impact are one contact time apart",
        "contact_time_1m_s_s": values["contact_time_1m_s_s"],
        "contact_time_1m_s_se_s": errors["contact_time_1m_s_s"],
        "contact_time_prior_s": list(quantities.contact_time_prior),
        "contact_time_exponent": values["contact_time_exponent"],
        "contact_time_exponent_se": errors["contact_time_exponent"],
        "drag_model": "quadratic" if model.with_drag else "nominal" if model.fixed_k > 0 else "none",
        "drag_k_per_m": k,
        "drag_k_se_per_m": float(np.sqrt(parts["k_variance"])),
        "bic_no_drag": bics.get(False, np.nan),
        "bic_quadratic_drag": bics.get(True, np.nan),
        "noise_m": float(problem.noise),
        "residual_rms_m": float(np.sqrt(np.mean(result.fun**2))),
        "sample_interval_s": sample_interval,
        **data,
        "drop_apex_time_s": float(t_apex[0]) + origin,
        # flight 0 after a bounce that was not found has no drop height
        **({"drop_height_m": np.nan, "drop_height_se_m": np.nan, "drop_height_scale_se_m": np.nan}
           if data["first_flight_is_a_bounce"] else
           {"drop_height_m": float(values["apex_height_m"][0]), "drop_height_se_m": float(errors["apex_height_m"][0]),
            "drop_height_scale_se_m": float(scale_errors["apex_height_m"][0])}),
        "rest_time_s": rest_time(problem.t, problem.y, contact, problem.noise, IMPACT_DEPTH_IN_NOISE,
                                 after=float(values["t_liftoff_s"][-1])) + origin,
        "gravity_m_s2": problem.g,
        "gravity_se_m_s2": uncertainty["gravity_se_m_s2"],
        "gravity_scaled": uncertainty["gravity_scaled"],
        "n_impacts": n,
        "scale_rel_se": float(uncertainty["scale_rel_se"]),
        "noise_correlation": float(uncertainty["noise_correlation"]),
        "notes": list(notes),
    }
    e_rows = quantity_index("e", n)
    contact_rows = quantity_index("t_contact_s", n)
    pair = np.r_[e_rows, contact_rows]
    return BounceAnalysis(flights=flights, impacts=impacts, e_covariance=cov[e_rows, e_rows],
                          e_contact_covariance=cov[np.ix_(pair, pair)],
                          e_drag_covariance=parts["drag_covariance"][e_rows], summary=summary)
