"""Impacts: every impact quantity as a function of the fitted flight parameters θ.

Touchdown and lift-off are where the fitted flights cross the contact height (given, or estimated
where the flights before and after each impact meet); speeds, e, heights and times follow from the
closed forms of :mod:`dropfit.physics`. Being functions of θ, their covariance follows from the
fit's by the delta method (:mod:`dropfit.analysis.uncertainty`).
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import brentq

from ..numerics import jacobian, propagate
from ..physics import speed_below_apex, time_from_apex
from .flights import fit_covariance

#: Per-impact quantities, in the order of the vector :class:`ImpactQuantities` returns.
IMPACT_COLUMNS = ["t_touchdown_s", "t_liftoff_s", "v_in_m_s", "v_out_m_s", "e", "e_height", "flight_time_ratio",
                  "flight_time_after_s", "t_contact_s"]


def meeting_height(y_before, t_before, y_after, t_after, k, g):
    """Height in m where the falling branch of one flight meets the rising branch of the next; NaN
    where they do not meet below the lower apex (two fitted flights that overlap in time)."""
    def gap(height):
        touchdown = t_before + time_from_apex(y_before - height, k, g)
        liftoff = t_after - time_from_apex(y_after - height, k, g, rising=True)
        return liftoff - touchdown

    top = min(y_before, y_after)
    if not t_after > t_before or not gap(top) >= 0:
        return float("nan")
    if k == 0.0:
        # both branches are parabolas with the same curvature: their meeting point is closed-form
        meet_t = 0.5 * (t_after + t_before) - (y_after - y_before) / (g * (t_after - t_before))
        return y_before - 0.5 * g * (meet_t - t_before) ** 2
    bottom = top - 1.0
    while gap(bottom) > 0:
        bottom -= 2 * (top - bottom)
    return brentq(gap, bottom, top, xtol=1e-13, rtol=1e-14)


class ImpactQuantities:
    """Impact quantities as functions of θ, for values and for the delta-method covariance."""

    def __init__(self, model, contact_height_m=None):
        self.model = model
        self.n_impacts = model.n_flights - 1
        self.given_contact_height = contact_height_m
        self.weights = np.ones(self.n_impacts)
        self._meetings = {}  # (y_apex, t_apex before, after, k) → meeting height, m

    def meeting_heights(self, theta):
        """Height in m where the flights before and after each impact meet."""
        # remembered per impact: a numerical Jacobian moves one parameter at a time, which changes
        # only the impacts next to its flight (k changes all), so the others need no new root search
        y_apex, t_apex, k = self.model.unpack(theta)
        heights = np.empty(self.n_impacts)
        for i in range(self.n_impacts):
            key = (y_apex[i], t_apex[i], y_apex[i + 1], t_apex[i + 1], k)
            if key not in self._meetings:
                self._meetings[key] = meeting_height(*key, self.model.g)
            heights[i] = self._meetings[key]
        return heights

    def contact_height(self, theta):
        """The given contact height, or the weighted mean of the meeting heights (m)."""
        if self.given_contact_height is not None:
            return float(self.given_contact_height)
        heights = self.meeting_heights(theta)
        met = np.isfinite(heights)  # an impact whose flights do not meet ends the sequence later
        return float(np.sum(self.weights[met] * heights[met]) / np.sum(self.weights[met])) if met.any() else np.nan

    def set_weights(self, result):
        """Weight each impact's meeting height by its inverse variance under the fit ``result``
        (weights then held fixed)."""
        if self.given_contact_height is not None or self.n_impacts == 0:
            return
        jac = jacobian(self.meeting_heights, result.x, self.model.lower_bounds(result.x.size))
        variance = np.diag(propagate(jac, fit_covariance(result)))
        self.weights = np.where(np.isfinite(variance), 1.0 / np.maximum(variance, 1e-30), 0.0)

    def with_contact_height(self, contact_height_m):
        """The same quantities with another given contact height (m) and the same weights."""
        moved = ImpactQuantities(self.model, contact_height_m)
        moved.weights = self.weights
        return moved

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


def unpack_quantities(vector, n_impacts):
    """Name → values of the vector of :class:`ImpactQuantities` (``contact_height_m``, the impact
    columns, ``apex_height_m``)."""
    values = {"contact_height_m": vector[0]}
    for j, name in enumerate(IMPACT_COLUMNS):
        values[name] = vector[1 + j * n_impacts: 1 + (j + 1) * n_impacts]
    values["apex_height_m"] = vector[1 + len(IMPACT_COLUMNS) * n_impacts:]
    return values


def quantity_index(name, n_impacts):
    """Slice of the impact column ``name`` in the vector of :class:`ImpactQuantities`."""
    start = 1 + IMPACT_COLUMNS.index(name) * n_impacts
    return slice(start, start + n_impacts)


def contact_resolvable(contact_ms, contact_se_ms, sample_interval_s, contact_height_given):
    """A contact time means something only if the contact height is known independently of it,
    the sampling resolves it, and it stands well clear of its own uncertainty."""
    if not contact_height_given:
        return np.zeros(contact_ms.size, dtype=bool)
    return (contact_ms > 2e3 * sample_interval_s) & (contact_ms > 5 * contact_se_ms)


def rest_time(t, y, contact_height, noise, depth_in_noise, after):
    """First time after ``after`` (s) from which the ball stays within ``depth_in_noise`` noise σ of the
    contact height, or NaN if it is still bouncing when the log ends."""
    finite = np.isfinite(y)
    t, y = t[finite], y[finite]
    away = np.flatnonzero((np.abs(y - contact_height) > depth_in_noise * noise) | (t <= after))
    if away.size == 0 or away[-1] + 1 >= t.size:
        return float("nan")
    return float(t[away[-1] + 1])
