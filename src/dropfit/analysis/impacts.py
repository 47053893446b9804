"""Impacts: every impact quantity as a function of the fitted flight parameters θ.

Touchdown and lift-off are where the fitted flights cross the contact height (given, or estimated
where the flights before and after each impact meet); speeds, e, heights and times follow from the
closed forms of :mod:`dropfit.physics`. Being functions of θ, their covariance follows from the
fit's by the delta method (:mod:`dropfit.analysis.uncertainty`).
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import brentq

from ..balls import CONTACT_TIME_EXPONENT, CONTACT_TIME_EXPONENT_SE
from ..numerics import jacobian, propagate
from ..physics import speed_below_apex, time_from_apex
from .flights import fit_covariance

#: Gauss–Newton steps of the contact height and contact time (converges in two or three).
CONTACT_MODEL_ITERATIONS = 6
#: Standard error of γ in τ = τ₁ v^(−β) exp(γ ln² v), held at 0: how far a real contact's times bend
#: from a power law of the speed. The Hunt–Crossley contact (dropfit.contact) gives γ ≈ 0.12 χ over
#: 0.8–7.5 m/s: 0.002–0.008 for its damping χ = 0.02–0.06 s/m (e ≥ 0.75 at 5 m/s, tennis or steel
#: balls), 0.04 at χ = 0.3 s/m. With the floor not known, precise flights pin the contact height
#: only as well as the law's shape is known; without this share a tennis ball's heights logged at
#: 1–2 kHz to 0.1 mm read 65 µm high at 5 standard errors.
CONTACT_TIME_CURVATURE_SE = 0.005

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
    """Impact quantities as functions of θ, for values and for the delta-method covariance.

    The contact height is given (the floor plus the radius) or modelled: every impact's contact lasts
    τ_n = τ₁ (v_in,n / 1 m/s)^(−β) (:mod:`dropfit.balls`), and the contact height c is the height at
    which the fitted flights before and after each impact are that far apart in time. Where the
    flights meet (τ = 0) lies below c by about τ v_in v_out / (v_in + v_out): 13 mm for a tennis ball's
    4.5 ms at 7 m/s. c, τ₁ and β are fitted to all impacts at once (their speeds differ, so they are
    measurable), by weighted least squares with the priors ``contact_time_prior`` on τ₁ and
    ``contact_exponent`` on β.

    Parameters
    ----------
    model : dropfit.analysis.flights.FlightModel
        The flight model (its ``g`` and held ``fixed_k`` are read at every call).
    contact_height_m : float, optional
        Given contact height (m) in the frame of the heights.
    contact_time_prior : (float, float)
        τ₁ (s, at 1 m/s) and its standard error; (0, 0) for instantaneous contacts.
    contact_exponent : (float, float)
        β of τ ∝ v^(−β) and its standard error (0 holds β).
    """

    def __init__(self, model, contact_height_m=None, contact_time_prior=(0.0, 0.0),
                 contact_exponent=(CONTACT_TIME_EXPONENT, CONTACT_TIME_EXPONENT_SE)):
        self.model = model
        self.n_impacts = model.n_flights - 1
        self.given_contact_height = contact_height_m
        self.contact_time_prior = tuple(float(value) for value in contact_time_prior)
        self.contact_exponent = tuple(float(value) for value in contact_exponent)
        self.contact_curvature = (0.0, CONTACT_TIME_CURVATURE_SE)  # γ held, with its se
        self.weights = np.ones(self.n_impacts)
        self._meetings = {}  # (y_apex, t_apex before, after, k, g) → meeting height, m

    def meeting_heights(self, theta):
        """Height in m where the flights before and after each impact meet."""
        # remembered per impact: a numerical Jacobian moves one parameter at a time, which changes
        # only the impacts next to its flight (k changes all), so the others need no new root search
        y_apex, t_apex, k = self.model.unpack(theta)
        heights = np.empty(self.n_impacts)
        for i in range(self.n_impacts):
            key = (y_apex[i], t_apex[i], y_apex[i + 1], t_apex[i + 1], k, self.model.g)
            if key not in self._meetings:
                self._meetings[key] = meeting_height(*key)
            heights[i] = self._meetings[key]
        return heights

    def _start_height(self, theta):
        """Weighted mean of the finite meeting heights (m): where the contacts would be instantaneous."""
        heights = self.meeting_heights(theta)
        met = np.isfinite(heights)  # an impact whose flights do not meet ends the sequence later
        return float(np.sum(self.weights[met] * heights[met]) / np.sum(self.weights[met])) if met.any() else np.nan

    def contact_times(self, theta, contact):
        """Per impact: the time in s between the fitted flights at height ``contact`` (m), its derivative
        by that height (s/m), and the impact speed (m/s)."""
        g = self.model.g
        y_apex, t_apex, k = self.model.unpack(theta)
        with np.errstate(invalid="ignore", divide="ignore"):
            before, after = y_apex[:-1] - contact, y_apex[1:] - contact
            touchdown = t_apex[:-1] + time_from_apex(before, k, g)
            liftoff = t_apex[1:] - time_from_apex(after, k, g, rising=True)
            v_in = speed_below_apex(before, k, g)
            v_out = speed_below_apex(after, k, g, rising=True)
            return liftoff - touchdown, 1.0 / v_in + 1.0 / v_out, v_in

    def modelled_contact(self, theta):
        """Contact height c (m), contact time at 1 m/s τ₁ (s) and exponent β that fit the flights and
        the priors.

        Gauss–Newton on τ_n(c) = τ₁ v_n^(−β) exp(γ ln² v_n) (γ held, ``contact_curvature``): each step linearises the gap between the flights at c and
        the law in β, and solves the weighted least squares for (Δc, τ₁, Δβ) with each prior as one
        more observation (a prior with standard error 0 holds its parameter).
        """
        contact = self._start_height(theta)
        (tau, tau_se), (beta_prior, beta_se) = self.contact_time_prior, self.contact_exponent
        beta = beta_prior
        for _ in range(CONTACT_MODEL_ITERATIONS):
            gap, slope, speed = self.contact_times(theta, contact)
            use = np.isfinite(gap) & np.isfinite(slope) & (speed > 0) & (self.weights > 0)
            if not use.any():
                break
            law = speed[use] ** (-beta) * np.exp(self.contact_curvature[0] * np.log(speed[use]) ** 2)
            # gap + slope Δc − law τ₁ + τ₁ law ln v Δβ = 0 at every impact
            design = np.column_stack([slope[use], -law, tau * law * np.log(speed[use])])
            normal = design.T @ (self.weights[use, None] * design)
            right = design.T @ (self.weights[use] * -gap[use])
            held = []
            for j, (prior, se, value) in ((1, (self.contact_time_prior[0], tau_se, 0.0)),
                                          (2, (beta_prior, beta_se, beta))):
                if se > 0:
                    normal[j, j] += 1.0 / se**2
                    right[j] += (prior - value) / se**2
                else:
                    held.append(j)
            free = [j for j in range(3) if j not in held]
            # a held τ₁ enters the gap as known; a held β needs no column
            if 1 in held:
                right -= normal[:, 1] * self.contact_time_prior[0]
            solution = np.zeros(3)
            solution[1] = self.contact_time_prior[0] if 1 in held else 0.0
            # least squares, not a plain solve: without contact times β has no column (noise-free data)
            solution[free] = np.linalg.lstsq(normal[np.ix_(free, free)], right[free], rcond=None)[0]
            contact += solution[0]
            tau, beta = solution[1], beta + solution[2]
            if abs(solution[0]) < 1e-12:
                break
        return contact, tau, beta

    def contact_height(self, theta):
        """The given contact height, or the modelled one (m)."""
        if self.given_contact_height is not None:
            return float(self.given_contact_height)
        return self.modelled_contact(theta)[0]

    def set_weights(self, result):
        """Weight each impact by the inverse variance of its gap between the flights under the fit
        ``result`` (weights then held fixed)."""
        if self.given_contact_height is not None or self.n_impacts == 0:
            return
        contact = self._start_height(result.x)
        jac = jacobian(lambda theta: self.contact_times(theta, contact)[0], result.x,
                       self.model.lower_bounds(result.x.size))
        variance = np.diag(propagate(jac, fit_covariance(result)))
        self.weights = np.where(np.isfinite(variance), 1.0 / np.maximum(variance, 1e-30), 0.0)

    def with_contact_height(self, contact_height_m):
        """The same quantities with another given contact height (m) and the same weights."""
        moved = ImpactQuantities(self.model, contact_height_m, self.contact_time_prior, self.contact_exponent)
        moved.weights = self.weights
        return moved

    def __call__(self, theta):
        """Vector: contact height, contact time at 1 m/s and its exponent, then per impact (t_td, t_lo, v_in, v_out, e,
        e_h, ftr, flight time, contact time), apex heights."""
        g = self.model.g
        y_apex, t_apex, k = self.model.unpack(theta)
        if self.given_contact_height is not None:
            contact, tau, beta = float(self.given_contact_height), np.nan, np.nan
        else:
            contact, tau, beta = self.modelled_contact(theta)
        height_above = y_apex - contact
        before, after = height_above[:-1], height_above[1:]
        with np.errstate(invalid="ignore", divide="ignore"):
            touchdown = t_apex[:-1] + time_from_apex(before, k, g)
            liftoff = t_apex[1:] - time_from_apex(after, k, g, rising=True)
            v_in = speed_below_apex(before, k, g)
            v_out = speed_below_apex(after, k, g, rising=True)
            # flight n lasts from lift-off at impact n to touchdown at impact n+1 (predicted for the last)
            end_of_last = t_apex[-1] + time_from_apex(height_above[-1], k, g)
            flight_time = np.append(touchdown[1:], end_of_last) - liftoff
            time_ratio = np.concatenate([[np.nan], flight_time[1:] / flight_time[:-1]])
            columns = [touchdown, liftoff, v_in, v_out, v_out / v_in, np.sqrt(after / before), time_ratio,
                       flight_time, liftoff - touchdown]
        return np.concatenate([[contact, tau, beta], np.concatenate(columns), height_above])


#: Quantities of the recording at the start of the vector of :class:`ImpactQuantities`.
RECORDING_QUANTITIES = ["contact_height_m", "contact_time_1m_s_s", "contact_time_exponent"]


def unpack_quantities(vector, n_impacts):
    """Name → values of the vector of :class:`ImpactQuantities` (the recording's quantities, the impact
    columns, ``apex_height_m``)."""
    values = dict(zip(RECORDING_QUANTITIES, vector))
    offset = len(RECORDING_QUANTITIES)
    for j, name in enumerate(IMPACT_COLUMNS):
        values[name] = vector[offset + j * n_impacts: offset + (j + 1) * n_impacts]
    values["apex_height_m"] = vector[offset + len(IMPACT_COLUMNS) * n_impacts:]
    return values


def length_dimension(n_impacts):
    """The power of length in the unit of every element of the quantity vector (m, m/s: 1; s, ratios: 0)."""
    per_impact = {"v_in_m_s": 1.0, "v_out_m_s": 1.0}
    return np.concatenate([[1.0, 0.0, 0.0]] + [np.full(n_impacts, per_impact.get(name, 0.0)) for name in IMPACT_COLUMNS]
                          + [np.ones(n_impacts + 1)])


def quantity_index(name, n_impacts):
    """Slice of the impact column ``name`` in the vector of :class:`ImpactQuantities`."""
    start = len(RECORDING_QUANTITIES) + IMPACT_COLUMNS.index(name) * n_impacts
    return slice(start, start + n_impacts)


def contact_resolvable(contact_ms, contact_se_ms, sample_interval_s, contact_height_given, longest_ms=np.inf):
    """A contact time means something only if the contact height is known independently of it,
    the sampling resolves it, it stands well clear of its own uncertainty, and it is not longer than
    the ball can have (``longest_ms``, per impact)."""
    if not contact_height_given:
        return np.zeros(contact_ms.size, dtype=bool)
    plausible = contact_ms - 2 * contact_se_ms <= longest_ms
    return (contact_ms > 2e3 * sample_interval_s) & (contact_ms > 5 * contact_se_ms) & plausible


def rest_time(t, y, contact_height, noise, depth_in_noise, after):
    """First time after ``after`` (s) from which the ball stays within ``depth_in_noise`` noise σ of the
    contact height, or NaN if it is still bouncing when the log ends."""
    finite = np.isfinite(y)
    t, y = t[finite], y[finite]
    away = np.flatnonzero((np.abs(y - contact_height) > depth_in_noise * noise) | (t <= after))
    if away.size == 0 or away[-1] + 1 >= t.size:
        return float("nan")
    return float(t[away[-1] + 1])
