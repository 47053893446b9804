"""Segmentation: from the samples of a trajectory to the release and the bounces that split it into flights.

The first step of every estimator (:mod:`dropfit.estimators` and the gravity calibration of a px log
start from it too), in the order of the data:

1. the noise of the heights (:func:`estimate_noise`);
2. tracking jumps: runs of a few samples displaced from the track (:func:`find_outliers`), left out;
3. the dips that may be bounces (:func:`find_impacts`), and among them the first real impact: the
   one the ball reaches fastest (:func:`first_impact`). A hand holding, lifting, lowering or shaking
   the ball before the release makes dips too, but slow ones;
4. the release (:func:`find_release`): going back from the first impact, the earliest sample from
   which the ball moves in free fall. Samples before it are the hand's and are left out.

It needs no length scale: the downward acceleration of the flights is given (g, for heights in m) or
measured from the bounces' own curvature (a px log before its calibration).
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

from ..errors import InputError, NotFreeFallError
from ..numerics import least_squares_covariance, robust_sigma, running_min
from .flights import MIN_SAMPLES_PER_FLIGHT, shared_acceleration

#: A dip must fall and rise by this many noise standard deviations to count as an impact.
IMPACT_DEPTH_IN_NOISE = 5.0
#: Noise floor in the height's own unit, as a fraction of the height range, so that noise-free data
#: still segment.
NOISE_FLOOR_FRACTION = 1e-6
#: The flights' own curvature may differ from g by this fraction (drag changes it by a few %).
FREE_FALL_TOLERANCE = 0.15
#: A flight whose own curvature is below this fraction of g, by more than HIDDEN_IMPACT_SIGMAS
#: standard errors, holds two flights: the detector missed the impact between them (strong drag
#: lowers a table-tennis ball's drop to 0.84 g; two flights fitted as one fall with far less).
HIDDEN_IMPACT_ACCELERATION_FRACTION = 0.5
HIDDEN_IMPACT_SIGMAS = 5.0
#: A tracking jump displaces at most this many consecutive samples (a tracker that stays on another
#: object longer is not a jump, and its samples fail the flight fits instead).
MAX_OUTLIER_RUN = 12
#: Samples on each side whose median velocity a jump's velocity spike is compared with.
SPIKE_WINDOW = 3
#: A velocity spike must stand this many noise standard deviations clear of both sides' medians.
SPIKE_SIGMAS = 6.0
#: The two ends of a jump displace the track by opposite amounts that agree within this fraction.
JUMP_MATCH_TOLERANCE = 0.35
#: Time in s before a dip whose samples may already be in contact (a tennis ball's contact lasts
#: about 4.4 ms and the dip's sample lies within it); the approach speed and the fall are read earlier.
CONTACT_CLEARANCE_S = 0.006
#: Samples of the line whose slope is the speed at which the ball approaches a dip.
APPROACH_SAMPLES = 5
#: Fastest sampling at which dips are searched, Hz (:func:`impact_dips`): an approach speed read over
#: APPROACH_SAMPLES samples 0.5 ms apart at 1 mm noise is uncertain by about 0.3 m/s, far below an
#: impact speed; 0.05 ms apart by 3 m/s, as much as the speed itself.
MAX_DIP_SEARCH_RATE_HZ = 2000.0
#: The first impact is the first dip approached at least this fraction of the fastest approach: the
#: drop's impact is the fastest of all, a hand moves the ball far more slowly than its fall.
FIRST_IMPACT_SPEED_FRACTION = 0.5
#: A sample fits the free fall when it lies within this many standard deviations (noise and the
#: fall's extrapolation) of the fall fitted to the samples after it.
RELEASE_SIGMAS = 4.0
#: Heights seen but not measured cleanly scatter far more than the clean ones (phonesim's white MOV at 30 Hz:
#: blurred frames a few px off, one in ten 20-40 px low near the floor), so where there are such heights, tracking
#: jumps are judged against this many times the noise of the two together. On six of the white MOV's seeds, at 1
#: the lowest frame of a bounce and the clean frames beside it were taken for a jump on four, at 3 on two, at 4 on
#: none. Applied to the clean steps alone, the noise itself took runs of 12-16 clean frames of phonesim's
#: yellow_green_tape (30 Hz, 19 % of its frames merged with the shadow or hand) for jumps, and the capture rate
#: inferred from the flights came out 90 fps.
SEEN_JUMP_NOISE_FACTOR = 4.0


@dataclass
class Segmentation:
    """Result of :func:`segment`: the samples kept and where the bounces split them.

    Attributes
    ----------
    time, height : numpy.ndarray
        The samples kept: valid, not a tracking jump (s; length unit L of the input, up).
    noise : float
        Noise standard deviation in L.
    release : int
        Index (into ``time``) of the first sample of the free fall.
    impacts : numpy.ndarray
        Index (into ``time``) of the lowest sample of each bounce after the release.
    acceleration : float
        Downward acceleration of the flights in L/s² (given, or measured from their curvature).
    outliers : numpy.ndarray
        Index (into the input samples) of each sample left out as a tracking jump.
    notes : list of str
        What was left out and why, in words.
    clean : numpy.ndarray or None
        Which samples kept were measured cleanly, when the segmentation ran on the heights seen, clean or not
        (``seen_height`` of :func:`segment`); None: every one.
    clean_noise : float or None
        Noise standard deviation of the clean samples in L (None: ``noise``).
    """

    time: np.ndarray
    height: np.ndarray
    noise: float
    release: int
    impacts: np.ndarray
    acceleration: float
    outliers: np.ndarray
    notes: list = field(default_factory=list)
    clean: np.ndarray | None = None
    clean_noise: float | None = None

    def fit_samples(self):
        """The samples to fit (times in s, heights in L) and their noise (L): the clean ones."""
        if self.clean is None:
            return self.time, self.height, self.noise
        return self.time[self.clean], self.height[self.clean], self.clean_noise


def estimate_noise(y):
    """Robust standard deviation of the measurement noise of uniformly sampled heights.

    The third difference of a parabola sampled at a constant interval is zero, so the third
    differences of a free flight are pure noise with variance 20 σ²; the median absolute deviation
    ignores the few that straddle an impact or a jump.

    Parameters
    ----------
    y : numpy.ndarray
        Heights (any length unit) without NaNs, in time order.

    Returns
    -------
    float
        σ in the unit of ``y``.

    Notes
    -----
    A ball held still before its release or at rest after its last bounce for much of a recording is
    measured with far less noise than in flight (no motion blur): those quiet ends
    (:func:`moving_span`) are left out, or their third differences, near zero, pull the median down and
    a flight's own noise reads as tracking jumps (a clip 45 % at rest lost 64 samples to them).

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> t = np.arange(400) / 100.0
    >>> y = np.where(t < 2.0, 1.0 - 0.5 * 9.81 * (t % 0.4) ** 2, 0.0) + rng.normal(0, 1e-3, t.size) * (t < 2.0)
    >>> round(float(estimate_noise(y)) * 1e3, 1)
    1.0
    """
    y = np.asarray(y, dtype=float)
    return robust_sigma(np.diff(y[moving_span(y)], 3)) / np.sqrt(20.0)


#: An end of a recording is quiet where its heights stay within this fraction of their whole range of the
#: value at that end (:func:`moving_span`).
QUIET_END_FRACTION = 0.01
#: Fewest samples the quiet ends leave for the noise (:func:`moving_span`), else none is left out.
MIN_MOVING_SAMPLES = 10


def moving_span(y):
    """The samples of ``y`` between its quiet ends: the longest runs at the start and at the end that stay
    within ``QUIET_END_FRACTION`` of the heights' range of the first (last) height, where they hold at least
    ``MIN_SAMPLES_PER_FLIGHT`` samples (the few before a sparsely filmed fall are its release, not a rest);
    all of them where fewer than ``MIN_MOVING_SAMPLES`` would be left.

    Parameters
    ----------
    y : numpy.ndarray
        Heights (any length unit), no NaNs, in time order.

    Returns
    -------
    slice
        From a first to a last index, both given.
    """
    if y.size < MIN_MOVING_SAMPLES:
        return slice(0, y.size)
    band = QUIET_END_FRACTION * float(np.ptp(y))
    start = int(np.argmax(np.abs(y - y[0]) > band))
    tail = int(np.argmax(np.abs(y[::-1] - y[-1]) > band))
    start = start if start >= MIN_SAMPLES_PER_FLIGHT else 0
    end = y.size - (tail if tail >= MIN_SAMPLES_PER_FLIGHT else 0)
    return slice(start, end) if end - start >= MIN_MOVING_SAMPLES else slice(0, y.size)


def _side_medians(values, window):
    """Median of the ``window`` values before and of the ``window`` after each value (NaN-padded ends)."""
    padded = np.concatenate([np.full(window, np.nan), values, np.full(window, np.nan)])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # the all-NaN windows at the ends
        medians = np.nanmedian(sliding_window_view(padded, window), axis=1)
    return medians[: values.size], medians[window + 1: window + 1 + values.size]


def find_outliers(t, y, noise):
    """Samples displaced from the track by a tracking jump: runs of 1 to ``MAX_OUTLIER_RUN`` samples.

    A jump shows in the velocity between samples as two spikes: one where the track leaves, one where
    it returns, displacing the positions by opposite, nearly equal amounts. A spike stands out from
    the median velocity of the samples before it and of those after it, on the same side of both; an
    impact does not, since there the velocity steps from falling to rising and the sample that
    straddles it lies between the two sides, nor does the steady change of velocity by gravity.

    Parameters
    ----------
    t : numpy.ndarray
        Sample times in s, increasing.
    y : numpy.ndarray
        Heights (any length unit L), no NaNs.
    noise : float
        Noise standard deviation in L.

    Returns
    -------
    numpy.ndarray
        Boolean mask, True for a sample inside a jump.
    """
    outlier = np.zeros(y.size, dtype=bool)
    if y.size < 2 * SPIKE_WINDOW + 3:
        return outlier
    dt = np.diff(t)
    velocity = np.diff(y) / dt
    change = np.diff(velocity)
    # gravity changes the velocity between a value and the sides' medians by about two steps (in flight: a
    # ball at rest for most of a clip makes most changes zero)
    span = moving_span(y)
    moving = change[span.start:span.stop - 2]
    trend = 2.0 * max(robust_sigma(moving), abs(float(np.median(moving))))
    left, right = _side_medians(velocity, SPIKE_WINDOW)
    from_left, from_right = velocity - left, velocity - right
    threshold = SPIKE_SIGMAS * noise * np.sqrt(2.0) / dt + trend
    same_side = np.sign(from_left) == np.sign(from_right)
    size = np.minimum(np.abs(from_left), np.abs(from_right))
    spikes = np.flatnonzero(same_side & (size > threshold))
    jump = np.where(from_left > 0, 1.0, -1.0) * size * dt  # displacement each spike makes, in L
    used = set()
    for a_position, a in enumerate(spikes):
        if a in used:
            continue
        for b in spikes[a_position + 1:]:
            if b - a > MAX_OUTLIER_RUN:
                break
            if b in used or np.sign(jump[b]) == np.sign(jump[a]):
                continue
            if abs(jump[a] + jump[b]) <= JUMP_MATCH_TOLERANCE * max(abs(jump[a]), abs(jump[b])):
                outlier[a + 1: b + 1] = True  # velocity a is between samples a and a + 1
                used.update((a, b))
                break
    return outlier


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
        lowest = y[idx] <= running_min(y, lag)[idx]
        rise = np.minimum(y[idx - lag], y[idx + lag]) - y[idx]
        # the lag-2 test also accepts a rise over three samples, for slow, low bounces
        if lag == 2 and y.size > 3:
            wider = np.full(idx.size, -np.inf)
            ok = (idx >= 3) & (idx + 3 < y.size)
            wider[ok] = np.minimum(y[idx[ok] - 3], y[idx[ok] + 3]) - y[idx[ok]]
            rise = np.maximum(rise, wider)
        candidates = idx[lowest & (rise > depth)]
        if found.size and candidates.size:
            # the nearest found dip is one of the two that the candidate falls between
            after = np.searchsorted(found, candidates)
            before = found[np.maximum(after - 1, 0)]
            distance = np.minimum(np.abs(candidates - before), np.abs(found[np.minimum(after, found.size - 1)] - candidates))
            candidates = candidates[distance > lag]
        found = np.union1d(found, candidates)
    return found


def _clearance_samples(t):
    """Samples in CONTACT_CLEARANCE_S at the median sample interval (at least 1)."""
    return max(1, int(round(CONTACT_CLEARANCE_S / float(np.median(np.diff(t))))))


def approach_speed(t, y, dips):
    """Downward speed (L/s) at which the ball approaches each dip, read before its contact.

    The slope of a line through the APPROACH_SAMPLES samples that end ``m`` samples before the dip, m
    the samples in CONTACT_CLEARANCE_S (NaN where the log starts too late).
    """
    m = _clearance_samples(t)
    speed = np.full(dips.size, np.nan)
    for i, dip in enumerate(dips):
        window = slice(dip - m - APPROACH_SAMPLES + 1, dip - m + 1)
        if window.start >= 0:
            tau = t[window] - t[window].mean()
            speed[i] = -float(tau @ (y[window] - y[window].mean()) / (tau @ tau))
    return speed


def first_impact(t, y, dips):
    """Position in ``dips`` of the first real impact: the first dip the ball approaches at least
    FIRST_IMPACT_SPEED_FRACTION of the fastest approach.

    Every bounce loses speed, so the impact that ends the drop is the fastest of all, give or take the
    noise of the speeds; a hand holding, lifting, lowering or shaking the ball before the release
    makes dips that it approaches slowly.
    """
    speed = approach_speed(t, y, dips)
    if not np.any(np.isfinite(speed)) or np.nanmax(speed) <= 0:  # no dip approached from above: keep them all
        return 0
    return int(np.flatnonzero(speed >= FIRST_IMPACT_SPEED_FRACTION * np.nanmax(speed))[0])


def flight_acceleration_estimate(t, y, dips, fall_end):
    """Downward acceleration (L/s²) of the flights between the dips, measured from their curvature; with
    no whole flight between them, from the last samples of the fall (index < ``fall_end``)."""
    m = _clearance_samples(t)
    pieces = [(t[a + m: b - m + 1], y[a + m: b - m + 1]) for a, b in zip(dips[:-1], dips[1:])
              if b - a - 2 * m + 1 >= MIN_SAMPLES_PER_FLIGHT]
    if not pieces:
        start = max(0, fall_end - 4 * MIN_SAMPLES_PER_FLIGHT)
        pieces = [(t[start:fall_end], y[start:fall_end])]
        if fall_end - start < 3:  # the log starts at its first dip: no curvature to measure
            return math.nan
    # the median of the flights' own curvatures: a hand that catches the ball at the end does not count
    return float(np.median([shared_acceleration([piece])[0] for piece in pieces]))


def find_release(t, y, noise, dip, acceleration):
    """Index of the first sample of the free fall that ends at the first impact's ``dip``.

    The fall is fitted with a parabola to its last samples, then extended back one stretch at a time
    while every earlier sample lies within RELEASE_SIGMAS of the fitted fall (noise and the
    extrapolation's own uncertainty); the first one that does not is the hand's. The parabola's
    curvature is the downward ``acceleration`` (L/s²) within FREE_FALL_TOLERANCE: firm while the
    stretch is short, free enough over a long fall for the drag to bend it. Returns None when no fall
    of at least MIN_SAMPLES_PER_FLIGHT samples precedes the dip.
    """
    end = dip - _clearance_samples(t) + 1  # one past the last sample read
    if end < MIN_SAMPLES_PER_FLIGHT:
        return None
    start = end - MIN_SAMPLES_PER_FLIGHT
    tau = t - t[dip]
    # the curvature's prior as one more observation, weighted like a sample of the noise
    prior_weight = noise / (0.5 * FREE_FALL_TOLERANCE * acceleration)
    prior_row, prior_target = prior_weight * np.array([0.0, 0.0, 1.0]), -0.5 * acceleration * prior_weight
    previous = None
    while True:
        design = np.vstack([np.column_stack([np.ones(end - start), tau[start:end], tau[start:end] ** 2]), prior_row])
        target = np.append(y[start:end], prior_target)
        coef, *_ = np.linalg.lstsq(design, target, rcond=None)
        # a parabola misses a long fall with drag (by 0.3 mm over 254 cm): judge by what it misses so far
        scale = max(noise, robust_sigma(y[start:end] - design[:-1] @ coef))
        # σ from a few residuals of a short stretch lying close to its parabola is too small, and the
        # extrapolation then fails samples of the fall (a clip's release was read 0.4 s late): σ ≥ scale
        covariance = least_squares_covariance(design, target - design @ coef, sigma_floor=scale)
        curvature_se = 2.0 * math.sqrt(covariance[2, 2])
        off_g = abs(-2.0 * coef[2] - acceleration) - RELEASE_SIGMAS * curvature_se
        if previous is not None and off_g > FREE_FALL_TOLERANCE * acceleration:
            # the stretch took the hand's samples: those just before the release lie within the noise of the
            # fall's apex, so the last sample failing is a few samples early, and fitted with them the fall no
            # longer curves with g (a 5 cm drop at 100 Hz: 9.2, then 7.9 m/s², widening the scatter that let in
            # more of the hold, down to 1.8 m/s² and 'check the units'); the stretch before is the fall
            return previous
        # (only a stretch seen to fall with g is one to go back to: a log in slipped units or slow motion never is,
        # and its free-fall check names the cause)
        falls_with_g = abs(-2.0 * coef[2] / acceleration - 1.0) <= FREE_FALL_TOLERANCE \
            and curvature_se <= FREE_FALL_TOLERANCE * acceleration
        previous = start if falls_with_g else previous
        earlier = np.column_stack([np.ones(start), tau[:start], tau[:start] ** 2])
        predicted_variance = np.einsum("ij,jk,ik->i", earlier, covariance, earlier)
        misfit = np.abs(y[:start] - earlier @ coef) > RELEASE_SIGMAS * np.sqrt(scale**2 + predicted_variance)
        failing = np.flatnonzero(misfit)
        new_start = int(failing[-1]) + 1 if failing.size else 0
        if new_start == start:
            return start
        # extend by at most a quarter of the stretch: a far extrapolation is too uncertain to tell the hand
        start = max(new_start, start - max((end - start) // 4, MIN_SAMPLES_PER_FLIGHT))


def noise_level(y):
    """The heights' noise for the dip search: :func:`estimate_noise`, at least ``NOISE_FLOOR_FRACTION`` of
    their range (a noise-free log still needs a depth to compare with)."""
    return max(estimate_noise(y), NOISE_FLOOR_FRACTION * float(np.ptp(y)))


def impact_dips(t, y, noise):
    """Indices of the impacts (:func:`find_impacts`) from the first real one (:func:`first_impact`) on.

    A log sampled faster than ``MAX_DIP_SEARCH_RATE_HZ`` is searched block-averaged down to that rate,
    and each dip found is the lowest sample of its block and the blocks beside it: among 10⁵ samples a
    second, noise makes dips that look deep over a few samples, and an approach speed read over five
    samples 50 µs apart is noise too (a 20 kHz log's first impact was missed, its drop height halved).

    Parameters
    ----------
    t, y : numpy.ndarray
        Sample times (s, increasing) and heights (any length unit, no NaN).
    noise : float
        The heights' noise standard deviation (their unit).
    """
    interval = float(np.median(np.diff(t)))
    block = int(1.0 / (interval * MAX_DIP_SEARCH_RATE_HZ))
    # a short burst (a high-speed clip's 15 frames in 0.5 ms) has too few blocks to average: search it whole
    if block < 2 or y.size // block < 3 * MIN_SAMPLES_PER_FLIGHT:
        # lags up to ~10 ms: dense sampling through a contact that lasts a few milliseconds
        dips = find_impacts(y, noise, max_lag=max(3, int(round(0.01 / interval))))
        return dips[first_impact(t, y, dips):] if dips.size else dips
    count = y.size // block
    blocks_t, blocks_y = (a[:count * block].reshape(count, block).mean(axis=1) for a in (t, y))
    dips = impact_dips(blocks_t, blocks_y, noise_level(blocks_y))
    lowest = [start + int(np.argmin(y[start:(dip + 2) * block]))
              for dip in dips for start in [max(dip - 1, 0) * block]]
    return np.unique(np.asarray(lowest, dtype=int))


#: What heights that point down are, and what to do (a log's distance from a sensor above, read as heights).
HEIGHTS_POINT_DOWN = ("the heights point down (a distance from above); name the column a distance with --columns "
                      "distance=COL[m] (or give --sensor-height-m), or give heights up")


#: Shortest fall over a log's whole span (s) that :func:`_undersampled` judges: 64 ms is 2 cm at g, beyond the
#: span of a held ball's noise (a 1 mm-noise log spans about 6 mm), which falls in fewer than 5 intervals at 100 Hz.
MIN_UNDERSAMPLED_FALL_S = 0.064


def _undersampled(t, y, acceleration=None):
    """Why a log sampled too slowly for its fall shows no bounce, in words, or None: with ``acceleration`` (L/s²,
    the heights' unit known), a fall over the whole span of the heights lasting fewer than
    ``MIN_SAMPLES_PER_FLIGHT`` sample intervals (and at least :data:`MIN_UNDERSAMPLED_FALL_S`)."""
    interval = float(np.median(np.diff(t))) if t.size > 1 else 0.0
    if acceleration is None or not acceleration > 0 or not interval > 0:
        return None
    fall_s = math.sqrt(2.0 * float(np.ptp(y)) / acceleration)
    if fall_s >= MIN_SAMPLES_PER_FLIGHT * interval or fall_s < MIN_UNDERSAMPLED_FALL_S:
        return None
    return (f"a fall over the whole span of its heights lasts {fall_s / interval:.1f} sample intervals at "
            f"{1.0 / interval:.3g} samples/s, fewer than the {MIN_SAMPLES_PER_FLIGHT} a flight needs: record at "
            f"{math.ceil(MIN_SAMPLES_PER_FLIGHT / fall_s):g} samples/s or faster (the bounces, lower, need more)")


def _no_bounce_cause(t, y, noise):
    """Why no dip was found in a log sampled densely enough, in words: heights that point down (the dips are
    peaks), else no dip deep enough in the noise."""
    if impact_dips(t, -y, noise).size:
        return f"it peaks sharply where a bounce dips: {HEIGHTS_POINT_DOWN}"
    tail = y[-max(y.size // 10, 3):]
    if np.median(tail) - np.min(y) < IMPACT_DEPTH_IN_NOISE * noise < float(np.ptp(y)) / 4.0:
        # a fall that ends at rest at its lowest: the rebound, if any, is lost in the noise
        return (f"the ball falls and comes to rest: no rebound rises more than {IMPACT_DEPTH_IN_NOISE:g} noise standard "
                f"deviations ({IMPACT_DEPTH_IN_NOISE * noise:.2g} in the heights' unit); a rebound that small needs a "
                f"log with less noise, or the ball does not bounce")
    return f"no dip deeper than {IMPACT_DEPTH_IN_NOISE:g} noise standard deviations"


def segment(time_s, height, source="trajectory", acceleration=None, seen_height=None):
    """Noise, tracking jumps, release and bounces of a trajectory: the segmentation every estimator uses.

    Parameters
    ----------
    time_s : numpy.ndarray
        Sample times in s, increasing.
    height : numpy.ndarray
        Heights (any length unit L, up), NaN where the sensor dropped out.
    source : str
        Name of the recording, used in error messages.
    acceleration : float, optional
        Downward acceleration of a free flight in L/s² (g for heights in m); default: measured from
        the bounces' curvature.
    seen_height : numpy.ndarray, optional
        Heights (L) wherever the ball was seen, measured cleanly or not (a video's blurred, shaded or merged
        frames, off by a few px), NaN elsewhere; ``height`` then holds the clean ones alone. The bounces are
        found on the two together, where a clip's fast flights near the floor, blurred, show them; the
        clean samples are marked for the fits (``Segmentation.clean``). Where some heights are seen but not
        clean, tracking jumps are judged against ``SEEN_JUMP_NOISE_FACTOR`` times the noise of the two together.

    Returns
    -------
    Segmentation
    """
    time_s = np.asarray(time_s, dtype=float)
    height = np.asarray(height, dtype=float)
    clean_noise = clean = None
    if seen_height is not None:
        clean_all = np.isfinite(height)
        clean_noise = noise_level(height[clean_all]) if clean_all.any() else 0.0
        height = np.where(clean_all, height, np.asarray(seen_height, dtype=float))
    valid = np.flatnonzero(np.isfinite(height))
    t, y = time_s[valid], height[valid]
    if y.size < 3 * MIN_SAMPLES_PER_FLIGHT:
        slow = _undersampled(t, y, acceleration) if y.size > 1 else None
        raise InputError(f"{source}: only {y.size} valid samples, too few to find a bounce{f' ({slow})' if slow else ''}")
    noise = noise_level(y)
    clean = None if seen_height is None else clean_all[valid]
    jumps = find_outliers(t, y, noise if clean is None or clean.all() else SEEN_JUMP_NOISE_FACTOR * noise)
    if clean is not None:
        clean = clean[~jumps]
    outliers = valid[jumps]
    t, y = t[~jumps], y[~jumps]
    dips = impact_dips(t, y, noise)
    if dips.size == 0:
        # sampled too slowly, the motion itself reads as noise: the sampling is named before a ball that never falls
        slow = _undersampled(t, y, acceleration)
        if slow:
            raise InputError(f"{source}: no bounce found ({slow})")
        if np.ptp(y) <= 2 * IMPACT_DEPTH_IN_NOISE * noise:
            raise InputError(f"{source}: the ball never falls (height stays within noise of its start)")
        raise InputError(f"{source}: no bounce found ({_no_bounce_cause(t, y, noise)})")
    if acceleration is None:
        acceleration = flight_acceleration_estimate(t, y, dips, dips[0] - _clearance_samples(t) + 1)
        if not acceleration > 0:
            raise InputError(f"{source}: the flights between the bounces do not curve downwards: this does not "
                             f"look like a ball bouncing on a floor (check the sign of the height axis)")
    release = find_release(t, y, noise, dips[0], acceleration)
    if release is None:
        raise InputError(f"{source}: the log starts less than {MIN_SAMPLES_PER_FLIGHT} samples before the first "
                         f"impact: no fall to analyse")
    notes = []
    if outliers.size:
        notes.append(f"{outliers.size} samples left out as tracking jumps (runs of up to {MAX_OUTLIER_RUN} samples "
                     f"displaced from the track and back)")
    if release > 0:
        notes.append(f"the ball was held or moved by hand before the release: the {release} samples before the "
                     f"free fall are left out")
    return Segmentation(time=t, height=y, noise=noise, release=release, impacts=dips, acceleration=float(acceleration),
                        outliers=outliers, notes=notes, clean=clean, clean_noise=clean_noise)


#: :func:`check_free_fall` widens :data:`FREE_FALL_TOLERANCE` by this many standard errors of the flights' median
#: curvature.
FREE_FALL_SIGMAS = 3.0
#: :func:`vertical_sign` takes the sign of the flights' median curvature where it is at least this many of its
#: standard errors from 0.
FLIGHT_CURVATURE_SIGMAS = 3.0
#: Standard error of a median over that of a mean, for Gaussian values: √(π/2).
MEDIAN_SE_FACTOR = 1.2533


def vertical_sign(time_s, height, seen_height=None):
    """+1 if the height axis points up, −1 if it points down (image rows).

    The second differences (over about 10 ms) of the samples that move are mostly the flights' own: g times
    the step squared, downwards. Their median's sign decides where it is at least
    ``FLIGHT_CURVATURE_SIGMAS`` standard errors from 0: tracking jumps (a hand taken for the ball while it
    held it, lone positions seen in a gap) move a few differences by hundreds of px and do not move a median
    (their sum outweighed seven impacts of a phone clip, and the clip was read upside down). The clean
    ``height`` is judged first, then with ``seen_height`` filling its gaps: a ball held at the frame's edge and
    rolling after its bounces, seen but not measured cleanly, scattered the median of a clip whose 40 clean flight
    samples curve down by 12-14 px a step, and a hand's jumps read it upside down. Else every second
    difference that is not free flight lies above the flights' curvature on an axis pointing up, and below it on
    one pointing down: an impact (the velocity reverses upwards) far above, a ball at rest (no curvature) above
    by g times the step squared; the sign of the large ones' sum decides (a tracking jump makes large
    differences of both signs that cancel). Without any large one (no impact in view, no rest), a dropped
    ball starts above its median position.
    """
    candidates = [np.asarray(height, dtype=float)]
    if seen_height is not None:
        candidates.append(np.where(np.isfinite(candidates[0]), candidates[0], seen_height))
    for heights in candidates:
        decided, y, curvature, spread = _median_curvature_sign(time_s, heights)
        if decided:
            return decided
    if curvature is not None:
        large = curvature[np.abs(curvature) > 10 * spread]
        if large.size and large.sum() != 0:
            return float(np.sign(large.sum()))
    return -1.0 if y[0] < np.median(y) else 1.0


def _median_curvature_sign(time_s, height):
    """(−sign of the moving samples' median second difference or 0.0 when it is within
    ``FLIGHT_CURVATURE_SIGMAS`` standard errors of 0, the valid heights, their second differences about that
    median (None for too few samples) and the differences' robust spread): :func:`vertical_sign`."""
    valid = np.isfinite(height)
    t, y = time_s[valid], height[valid]
    lag = max(1, int(round(0.01 / float(np.median(np.diff(t)))))) if t.size > 1 else 1
    if y.size <= 2 * lag:
        return 0.0, y, None, 0.0
    floor = 1e-12 * float(np.ptp(y))
    curvature = y[2 * lag:] - 2 * y[lag:-lag] + y[: -2 * lag]
    # a clean 30 Hz log's flights curve by 11 mm a step, which stood out from a 0.2 mm noise as if every
    # sample were an impact; a ball held for seconds made the median a rest's 0
    moving = np.abs(y[2 * lag:] - y[: -2 * lag]) > 5 * max(robust_sigma(curvature), floor)
    flights = curvature[moving] if np.count_nonzero(moving) >= 3 else curvature
    centre = float(np.median(flights))
    spread = max(robust_sigma(flights, centre=centre), floor)
    decided = abs(centre) >= FLIGHT_CURVATURE_SIGMAS * MEDIAN_SE_FACTOR * spread / np.sqrt(flights.size)
    return (-float(np.sign(centre)) if decided else 0.0), y, curvature - centre, spread


def up_direction(time_s, x, y):
    """The direction opposite the flights' acceleration in the plane of ``x`` and ``y`` (one length unit),
    as an angle in rad counter-clockwise from the +x axis, and its standard error in rad.

    As in :func:`vertical_sign`, the second differences (over about 10 ms, between samples equally spaced
    in time) of the samples that move are mostly the flights' own, g times the step squared: their
    component-wise median points along g, undisturbed by the few impacts and tracking jumps. The standard
    error is that of the medians across the direction, over their length; π where no direction shows.
    """
    x, y, time_s = (np.asarray(values, float) for values in (x, y, time_s))
    valid = np.isfinite(x) & np.isfinite(y) & np.isfinite(time_s)
    t, x, y = time_s[valid], x[valid], y[valid]
    if t.size < 5:
        return math.pi / 2, math.pi
    lag = max(1, int(round(0.01 / float(np.median(np.diff(t))))))
    if t.size <= 2 * lag + 2:
        return math.pi / 2, math.pi
    first, second = t[lag:-lag] - t[: -2 * lag], t[2 * lag:] - t[lag:-lag]
    even = np.abs(first - second) <= 1e-3 * np.maximum(first, second)  # a skipped frame bends the differences
    ax = (x[2 * lag:] - 2 * x[lag:-lag] + x[: -2 * lag])[even]
    ay = (y[2 * lag:] - 2 * y[lag:-lag] + y[: -2 * lag])[even]
    moved = np.hypot(x[2 * lag:] - x[: -2 * lag], y[2 * lag:] - y[: -2 * lag])[even]
    if ax.size < 3:
        return math.pi / 2, math.pi
    floor = 1e-12 * max(float(np.ptp(x)), float(np.ptp(y)), 1e-300)
    moving = moved > 5 * max(float(np.hypot(robust_sigma(ax), robust_sigma(ay))), floor)
    if np.count_nonzero(moving) >= 3:
        ax, ay = ax[moving], ay[moving]
    centre = np.array([np.median(ax), np.median(ay)])
    length = float(np.hypot(*centre))
    if length == 0:
        return math.pi / 2, math.pi
    spread = max(robust_sigma(ax, centre=centre[0]), robust_sigma(ay, centre=centre[1]), floor)
    se = MEDIAN_SE_FACTOR * spread / math.sqrt(ax.size) / length
    refined = _flights_acceleration(t, x, y, lag, centre, spread)
    if refined is not None and refined[1] < se:
        (acceleration_x, acceleration_y), se = refined
        return float(math.atan2(-acceleration_y, -acceleration_x)), float(min(se, math.pi))
    return float(math.atan2(-centre[1], -centre[0])), float(min(se, math.pi))


def _flights_acceleration(t, x, y, lag, centre, spread):
    """The flights' acceleration (x, y) in length unit per step² of ``lag`` samples and the standard error of
    its direction (rad), from a parabola in x and one in y fitted to each run of samples whose second
    differences all lie within 5 ``spread`` of the median ``centre`` (a flight clear of impacts); None with
    no run of 5 samples. Far more precise than the median of the differences alone."""
    n = t.size
    ax = x[2 * lag:] - 2 * x[lag:-lag] + x[: -2 * lag]
    ay = y[2 * lag:] - 2 * y[lag:-lag] + y[: -2 * lag]
    inside = np.hypot(ax - centre[0], ay - centre[1]) <= 5 * spread
    bad = np.zeros(n, bool)
    for offset in range(3):
        bad[offset * lag: n - (2 - offset) * lag] |= ~inside
    flight = ~bad  # a sample is in a flight while every triple through it is
    edges = np.flatnonzero(np.diff(np.concatenate([[0], flight.astype(int), [0]])))
    step = float(np.median(np.diff(t))) * lag
    values, weights = [], []
    for start, stop in zip(edges[::2], edges[1::2]):
        if stop - start < 5:
            continue
        tau = (t[start:stop] - t[start]) / step
        fits = [np.polyfit(tau, values_[start:stop], 2, cov=True) for values_ in (x, y)]
        values.append([2 * fit[0][0] for fit in fits])
        weights.append([1 / max(4 * fit[1][0, 0], 1e-300) for fit in fits])
    if not values:
        return None
    values, weights = np.array(values), np.array(weights)
    mean = (values * weights).sum(axis=0) / weights.sum(axis=0)
    length = float(np.hypot(*mean))
    if len(values) < 2 or length == 0:
        return None
    se = float(np.hypot(*(1 / np.sqrt(weights.sum(axis=0))))) / length
    return mean, se


def last_flight_end(y, after, noise):
    """Index one past the last sample of the flight that starts at the impact sample ``after``."""
    level = y[after] + IMPACT_DEPTH_IN_NOISE * noise
    below = np.flatnonzero(y[after + 1:] <= level)
    # the first samples after the impact may still be below the level: skip them
    above = np.flatnonzero(y[after + 1:] > level)
    if above.size == 0:
        return after + 1
    later_below = below[below > above[0]]
    return after + 1 + (int(later_below[0]) if later_below.size else y.size - after - 1)


def flight_bounds(t, y, release, minima, noise, contact_height=None):
    """First guess of each flight's time interval: cut at the lowest samples, leaving them out.

    With a known contact height, the samples pressed below it are left out too.

    Returns
    -------
    list of (float, float)
        (start, end) in s of each flight, open intervals; flight 0 starts at the release sample.
    """
    end_of_last = last_flight_end(y, minima[-1], noise)
    edges = np.concatenate([[release], minima, [end_of_last]])
    bounds = []
    for start, stop in zip(edges[:-1], edges[1:]):
        if contact_height is not None and start != release:
            while start + 1 < stop and y[start + 1] < contact_height:
                start += 1
        if contact_height is not None and stop < t.size:
            while stop - 1 > start and y[stop - 1] < contact_height:
                stop -= 1
        lo = t[start] - (1e-9 if start == release else -1e-9)  # the release sample is the first of flight 0
        hi = t[stop] - 1e-9 if stop < t.size else t[-1] + 1.0
        bounds.append((lo, hi))
    return bounds


def free_flights(pieces, acceleration):
    """How many of the first ``pieces`` are free flights: the sequence ends at the first whose own
    curvature lies outside HIDDEN_IMPACT_ACCELERATION_FRACTION … 1/HIDDEN_IMPACT_ACCELERATION_FRACTION
    of ``acceleration`` by more than HIDDEN_IMPACT_SIGMAS standard errors. A piece that curves far less
    holds a bounce the detector missed, or the ball rolling and hopping below the resolution at the end;
    one that curves far more is not in free flight (a hand).

    Each piece's standard error is taken at the median scatter of the pieces about their own parabolas, not
    at its own: a piece that holds a missed bounce misfits, and its own scatter widened its standard error
    enough to hide it (two bounces of a 30 frames/s clip fitted as one: 120 ± 284 px/s² beside four flights
    of 3965–4023 ± 2–5 px/s², their scatter 0.07–0.15 px, its own 12.6 px).

    Parameters
    ----------
    pieces : list of (numpy.ndarray, numpy.ndarray)
        Times (s) and heights (length unit L, up) of each flight, in order.
    acceleration : float
        Downward acceleration of a free flight (L/s²).
    """
    low, high = HIDDEN_IMPACT_ACCELERATION_FRACTION * acceleration, acceleration / HIDDEN_IMPACT_ACCELERATION_FRACTION
    fits = [_own_curvature(*piece) for piece in pieces]
    scatter = float(np.median([fit[2] for fit in fits])) if fits else 0.0
    for i, (own, own_se, own_scatter) in enumerate(fits):
        se = own_se * scatter / own_scatter if own_scatter > 0 else own_se
        if (low - own > HIDDEN_IMPACT_SIGMAS * se) or (own - high > HIDDEN_IMPACT_SIGMAS * se):
            return i
    return len(pieces)


def _own_curvature(time, height):
    """One piece's downward acceleration by its own parabola (L/s²), its standard error at its own scatter
    and that scatter (L, the residuals' RMS over n − 3): :func:`shared_acceleration` of the one piece."""
    tau = time - time[0]
    design = np.column_stack([np.ones_like(tau), tau, -0.5 * tau**2])
    coef, *_ = np.linalg.lstsq(design, height, rcond=None)
    residual = height - design @ coef
    covariance = least_squares_covariance(design, residual)
    scatter = float(np.sqrt(residual @ residual / max(tau.size - 3, 1)))
    return float(coef[-1]), float(np.sqrt(covariance[-1, -1])), scatter


def check_free_fall(t, y, bounds, g, source):
    """Raise InputError unless the flights, fitted with a free curvature, fall with about g.

    Wrong units (time in ms under a ``time_s`` header, heights in cm under ``y_m``) change the
    apparent acceleration of every flight by orders of magnitude; catching it here names the cause.
    A flight that hides an impact the detector missed falls with far less than g on its own: the
    units are judged on the flights before the first such flight, and the bounce sequence stops
    there, by the median of their own curvatures: one flight that took a sample of its neighbour (a bounce
    found a frame late in a 30 Hz clip's blurred frames: 7.55 ± 0.53 m/s² beside six of 9.9-11.3) does not
    make wrong units of the rest.

    Returns
    -------
    int
        The number of first flights before the first one that hides an impact (all of them if none).
    """
    inside = [(t > lo) & (t < hi) for lo, hi in bounds]
    pieces = [(t[mask], y[mask]) for mask in inside]
    kept = free_flights(pieces, g)
    own = [_own_curvature(*piece) for piece in pieces[: max(kept, 1)] if piece[0].size > 3]
    if not own:
        own = [(shared_acceleration([piece])[0], 0.0, 0.0) for piece in pieces[: max(kept, 1)]]
    acceleration = float(np.median([value for value, _, _ in own]))
    # a noisy or sparse log's flights (a px table at 24 frames/s, its scale from these same flights) curve
    # with g only within their own errors: the tolerance widens by three standard errors of their median
    # (the flights' typical se, their median: a 7-sample sliver beside a contact, se 100 m/s², would widen it to all)
    median_se = MEDIAN_SE_FACTOR * float(np.median([se for _, se, _ in own])) / np.sqrt(len(own))
    tolerance = FREE_FALL_TOLERANCE + FREE_FALL_SIGMAS * median_se / g
    if abs(acceleration / g + 1.0) < tolerance:  # g, upwards: heights measured down
        raise NotFreeFallError(f"{source}: the flights fall with {acceleration:.4g} m/s², g upwards: "
                               f"{HEIGHTS_POINT_DOWN}", acceleration)
    if not abs(acceleration / g - 1.0) < tolerance:
        raise NotFreeFallError(f"{source}: the flights fall with {acceleration:.4g} m/s², not g = {g:g} m/s²: check "
                               f"the units of time and height in the column names (or the scale of a px log)",
                               acceleration)
    return kept
