"""Four ways to estimate the coefficient of restitution e of every impact from one height log.

Each estimator is a pure function of the same trajectory (time in s, centre height in m, up; NaN
where the sensor dropped out) and returns one row per detected impact. The three simple ones share
the smallest segmentation that works: dropfit's own noise estimate, release and bounce detectors
(:mod:`dropfit.analysis`), which give the lowest sample of each bounce; what each does beyond that
is its own cost.

* :func:`peak_heights` — e_n = √(h_n / h_{n−1}) from the highest sample of each flight (no fit).
* :func:`flight_time_ratio` — e_n = T_n / T_{n−1} from the times between impacts (no length scale).
* :func:`parabola_fit` — a known-g parabola per flight; e = v_out / v_in at the contact height.
* :func:`drag_fit` — dropfit's default analysis (:func:`dropfit.analysis.analyse_bounces`): all
  flights fitted jointly, quadratic drag added when the BIC asks for it.

Without drag, apex heights and flight times measure e exactly; with drag, both √(h_n/h_{n−1}) and
T_n/T_{n−1} are smaller than v_out/v_in, because the flight itself loses energy.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from .analysis import MIN_SAMPLES_PER_FLIGHT, analyse_bounces, segment
from .analysis.flights import known_g_parabola
from .analysis.impacts import meeting_height
from .analysis.segmentation import last_flight_end
from .errors import InputError
from .numerics import jacobian
from .physics import STANDARD_GRAVITY_M_S2

def _bounce_samples(time_s, height_m, source, gravity_m_s2=STANDARD_GRAVITY_M_S2):
    """The samples dropfit's segmentation keeps (:func:`dropfit.analysis.segment`), its release and
    bounces and the noise."""
    found = segment(np.asarray(time_s, dtype=float), np.asarray(height_m, dtype=float), source, gravity_m_s2)
    return found.time, found.height, found.release, found.impacts, found.noise


def _flight_slices(y, release, minima, noise):
    """Sample slices of flight 0 (from the release) up to the flight after the last bounce.

    The lowest sample of each bounce belongs to neither neighbouring flight: it may lie on either
    side of the impact.
    """
    edges = np.concatenate([[release - 1], minima, [last_flight_end(y, minima[-1], noise)]])
    return [slice(start + 1, stop) for start, stop in zip(edges[:-1], edges[1:])]


def _table(t_impact_s, e, e_se):
    """The per-impact table every estimator returns."""
    return pd.DataFrame({"impact": np.arange(1, len(e) + 1), "t_impact_s": t_impact_s, "e": e, "e_se": e_se})


def peak_heights(time_s, height_m, contact_height_m, source="trajectory"):
    """e_n = √(h_n / h_{n−1}) from the highest sample of each flight: the ITF way, no fit.

    h_n is the highest sample of the flight after impact n minus the contact height; h_0 is the
    highest sample from the release to the first impact. A sampled apex is low by up to
    g (Δt/2)² / 2 (the sample nearest the apex is at most Δt/2 from it; 1.4 mm at 30 Hz), and the
    maximum of noisy samples near the apex is high by about one to two noise standard deviations.

    Parameters
    ----------
    time_s, height_m, source
        As for :func:`peak_heights`.
    contact_height_m : float
        Centre height in m at which the ball touches the floor (floor + radius), in the frame of
        ``height_m``. The method has no way to find it from the maxima: a rig measures it.
    source : str
        Name of the recording, used in error messages.

    Returns
    -------
    pandas.DataFrame
        ``impact`` (1 = first detected), ``t_impact_s`` (time of the lowest sample, s), ``e`` and
        ``e_se`` (NaN: a sample maximum is biased, not scattered about the apex, so the method has
        no honest standard error).
    """
    t, y, release, minima, noise = _bounce_samples(time_s, height_m, source)
    apex = np.array([np.max(y[flight]) for flight in _flight_slices(y, release, minima, noise)])
    rise = apex - float(contact_height_m)
    with np.errstate(invalid="ignore"):
        e = np.sqrt(rise[1:] / rise[:-1])
    return _table(t[minima], e, np.full(e.size, np.nan))


def _impact_time(t, y, lowest):
    """Where the line through the two samples before the lowest meets the line through the two after.

    With an instantaneous impact the lowest sample is within one interval of the impact, so the
    samples two and one before it are falling and those one and two after it are rising; the
    curvature of the flight over those samples lifts each line at the impact by g a b / 2 (a, b the
    samples' distances from it, so at most 3 g Δt²), which shifts the meeting by at most
    3 g Δt² / (v_in + v_out − 3 g Δt) in time.
    """
    t0, t1, t2, t3 = t[lowest - 2], t[lowest - 1], t[lowest + 1], t[lowest + 2]
    y0, y1, y2, y3 = y[lowest - 2], y[lowest - 1], y[lowest + 1], y[lowest + 2]
    falling = (y1 - y0) / (t1 - t0)
    rising = (y3 - y2) / (t3 - t2)
    return t1 + (y2 - y1 - rising * (t2 - t1)) / (falling - rising)


def flight_time_ratio(time_s, height_m, source="trajectory"):
    """e_n = T_n / T_{n−1} from the times between impacts: the acoustic way, free of any length scale.

    Each impact time is where straight lines through the two samples either side of the bounce's
    lowest sample meet; T_n is the time from impact n to impact n+1. Without drag the flight time is
    2 v_out / g, so the ratio of successive flight times is e; with drag it is smaller.

    Parameters
    ----------
    time_s : array_like
        Sample times in s, increasing.
    height_m : array_like
        Centre height of the ball in any length unit (up), NaN where the sensor dropped out.
    source : str
        Name of the recording, used in error messages.

    Returns
    -------
    pandas.DataFrame
        ``impact``, ``t_impact_s`` (s), ``e`` and ``e_se``. The first impact has no e (the drop
        before it is half a flight from an unknown release) and neither has the last (no impact ends
        its flight). ``e_se`` is NaN: each impact time rests on four samples, not on a fit with a
        covariance.
    """
    t, y, _, minima, _ = _bounce_samples(time_s, height_m, source)
    minima = minima[(minima >= 2) & (minima + 2 < t.size)]
    impact_times = np.array([_impact_time(t, y, lowest) for lowest in minima])
    flight_times = np.diff(impact_times)
    e = np.full(impact_times.size, np.nan)
    e[1:-1] = flight_times[1:] / flight_times[:-1]
    return _table(impact_times, e, np.full(e.size, np.nan))


def parabola_fit(time_s, height_m, gravity_m_s2=STANDARD_GRAVITY_M_S2, contact_height_m=None,
                 source="trajectory"):
    """e = v_out / v_in at the contact height from a least-squares parabola of known g per flight.

    Every flight is fitted on its own (linear least squares of y + g t²/2 = a₀ + a₁ t, so apex
    height y_a and time); without drag v = √(2 g (y_a − c)) at the contact height c, so
    e_n = √((y_a,n − c) / (y_a,n−1 − c)). Flights are used up to the first with fewer than
    ``MIN_SAMPLES_PER_FLIGHT`` samples. Drag is ignored: the method is biased where drag matters.

    Parameters
    ----------
    time_s, height_m, source
        As for :func:`peak_heights`.
    gravity_m_s2 : float
        Local gravitational acceleration in m/s².
    contact_height_m : float, optional
        Centre height in m at which the ball touches the floor, in the frame of ``height_m``. If
        omitted, each impact's own: the height where its two fitted parabolas meet.

    Returns
    -------
    pandas.DataFrame
        ``impact``, ``t_impact_s`` (where the fitted falling branch reaches the contact height, s),
        ``e`` and ``e_se`` (delta method on the two flights' fit covariances, taken independent).
    """
    g = float(gravity_m_s2)
    t, y, release, minima, noise = _bounce_samples(time_s, height_m, source, g)
    apexes, covariances = [], []
    for flight in _flight_slices(y, release, minima, noise):
        tf, yf = t[flight], y[flight]
        if tf.size < MIN_SAMPLES_PER_FLIGHT:
            break
        y_apex, t_apex, covariance = known_g_parabola(tf, yf, g)
        covariances.append(covariance)
        apexes.append((y_apex, t_apex))
    if len(apexes) < 2:
        raise InputError(f"{source}: no bounce with at least {MIN_SAMPLES_PER_FLIGHT} samples in the flights "
                         f"before and after it")

    def impact(theta):
        """(touchdown time in s, e) of one impact from θ = (y_apex, t_apex) before and after it."""
        y_before, t_before, y_after, t_after = theta
        contact = (meeting_height(y_before, t_before, y_after, t_after, 0.0, g)
                   if contact_height_m is None else float(contact_height_m))
        with np.errstate(invalid="ignore"):
            return np.array([t_before + np.sqrt(2.0 * (y_before - contact) / g),
                             np.sqrt((y_after - contact) / (y_before - contact))])

    touchdown, e, e_se = [], [], []
    for (before, cov_before), (after, cov_after) in zip(zip(apexes, covariances), zip(apexes[1:], covariances[1:])):
        theta = np.array([*before, *after])
        covariance = np.zeros((4, 4))
        covariance[:2, :2], covariance[2:, 2:] = cov_before, cov_after
        value = impact(theta)
        gradient = jacobian(lambda th: impact(th)[1:], theta)[0]
        touchdown.append(value[0])
        e.append(value[1])
        e_se.append(float(np.sqrt(gradient @ covariance @ gradient)))
    return _table(np.array(touchdown), np.array(e), np.array(e_se))


def drag_fit(time_s, height_m, gravity_m_s2=STANDARD_GRAVITY_M_S2, contact_height_m=None, source="trajectory"):
    """e = v_out / v_in from dropfit's default analysis: all flights fitted jointly, drag by BIC.

    See :func:`dropfit.analysis.analyse_bounces` (``drag="auto"``). The contact height is shared by
    all impacts; samples are reassigned to flights by the fitted touchdown and lift-off times.

    Parameters
    ----------
    time_s, height_m, gravity_m_s2, contact_height_m, source
        As for :func:`parabola_fit`.

    Returns
    -------
    pandas.DataFrame
        ``impact``, ``t_impact_s`` (fitted touchdown, s), ``e`` and ``e_se`` (delta method on the
        joint fit).
    """
    impacts = analyse_bounces(time_s, height_m, gravity_m_s2, drag="auto", contact_height_m=contact_height_m,
                              source=source).impacts
    return _table(impacts["t_touchdown_s"].to_numpy(), impacts["e"].to_numpy(), impacts["e_se"].to_numpy())
