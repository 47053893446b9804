"""Segmentation: from the samples of a trajectory to the release and the bounces that split it into flights.

The first step of every estimator (:mod:`dropfit.estimators` starts from it too): the noise of the
heights, the release sample and the lowest sample of each bounce, and from those the time interval
of each flight before the fits refine it.
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from ..numerics import robust_sigma
from .flights import MIN_SAMPLES_PER_FLIGHT, shared_acceleration

#: A dip must fall and rise by this many noise standard deviations to count as an impact.
IMPACT_DEPTH_IN_NOISE = 5.0
#: Noise floor in the height's own unit, so that noise-free data still segment.
NOISE_FLOOR_FRACTION = 1e-6
#: The flights' own curvature may differ from g by this fraction (drag changes it by a few %).
FREE_FALL_TOLERANCE = 0.15
#: A flight whose own curvature is below this fraction of g, by more than HIDDEN_IMPACT_SIGMAS
#: standard errors, holds two flights: the detector missed the impact between them (strong drag
#: lowers a table-tennis ball's drop to 0.84 g; two flights fitted as one fall with far less).
HIDDEN_IMPACT_ACCELERATION_FRACTION = 0.5
HIDDEN_IMPACT_SIGMAS = 5.0


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
    return robust_sigma(np.diff(y, 3)) / np.sqrt(20.0)


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
    noise = max(estimate_noise(y), NOISE_FLOOR_FRACTION * float(np.ptp(y)))
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


def check_free_fall(t, y, bounds, g, source):
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
