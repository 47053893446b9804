"""Uncertainty: the covariance of every impact quantity, from the fit and from what the fit holds fixed.

The statistical part propagates the fit covariance through the impact quantities (delta method). The
systematic parts are rank-one terms, one per input the fit takes as known: a held drag parameter, g,
the length scale of a px recording, a given contact height, or the contact-time prior and exponent
of a modelled one. Each is the total derivative of the
quantities (with the flights refitted, linearised) times that input's standard error.
"""

from __future__ import annotations

import numpy as np

from ..numerics import derivative, jacobian, propagate
from .flights import fit_covariance
from .impacts import length_dimension


def correlated_noise_factor(correlation):
    """Variance factor (1 + ρ)/(1 − ρ) of an average over AR(1) errors of lag-1 correlation ρ."""
    return (1.0 + correlation) / (1.0 - correlation)


def refit_response(result, residual_change):
    """Linearised change of the fitted θ when the residuals change by ``residual_change`` (least squares)."""
    if hasattr(result.jac, "toarray"):  # a long log's sparse Jacobian: the p × p normal equations, columns scaled
        gram = (result.jac.T @ result.jac).toarray()
        norms = np.sqrt(np.diag(gram))
        norms[norms == 0] = 1.0
        return -(np.linalg.pinv(gram / np.outer(norms, norms)) @ (result.jac.T @ residual_change / norms)) / norms
    return -np.linalg.lstsq(result.jac, residual_change, rcond=None)[0]


def held_input_sensitivity(result, quantities, quantity_jacobian, owner, attribute, step):
    """Total derivative of the quantities with respect to an input the fit holds fixed (an attribute of
    the flight model, such as g or a held drag k, or of the impact quantities, such as the contact-time
    prior): the direct change at fixed θ plus the change through θ, refitted by least squares.

    Parameters
    ----------
    result : scipy.optimize.OptimizeResult
        The flight fit.
    quantities : ImpactQuantities
        The quantities (their model is ``quantities.model``).
    quantity_jacobian : numpy.ndarray
        Derivative of the quantities by θ.
    owner : object
        ``quantities.model`` or ``quantities``: the object holding the input.
    attribute : str
        The input's attribute name; a tuple attribute's first element is the input.
    step : float
        Step of the central difference, in the input's unit.
    """
    direct = derivative(lambda moved: _with_input(owner, attribute, moved, quantities, result.x),
                        _input_value(owner, attribute), step)
    return direct + quantity_jacobian @ refit_sensitivity(result, quantities.model, owner, attribute, step)


def refit_sensitivity(result, model, owner, attribute, step):
    """Derivative of the fitted θ with respect to a held input (arguments as
    :func:`held_input_sensitivity`), linearised by least squares."""
    residual_slope = derivative(lambda moved: _with_input(owner, attribute, moved, model.residuals, result.x),
                                _input_value(owner, attribute), step)
    return refit_response(result, residual_slope)


def _input_value(owner, attribute):
    value = getattr(owner, attribute)
    return value[0] if isinstance(value, tuple) else value


def _with_input(owner, attribute, moved, function, theta):
    """``function(theta)`` with the held input moved to ``moved`` (a tuple input: its first element)."""
    value = getattr(owner, attribute)
    setattr(owner, attribute, (moved, *value[1:]) if isinstance(value, tuple) else moved)
    try:
        return function(theta)
    finally:
        setattr(owner, attribute, value)


def scale_sensitivity(quantities, result, step=1e-6):
    """Derivative of the quantity vector with respect to the relative scale error ε.

    A scale off by ε multiplies every height (about the trajectory's zero) and a given contact height
    by 1 + ε. The fit answers with δθ = ε (JᵀJ)⁻¹Jᵀy (linearised, as in the covariance); with g known
    it does not simply scale the heights, because the flight times also tell them.
    """
    # the residuals are model − data: scaling the data by 1 + ε changes them by −ε y
    response = refit_response(result, -quantities.model.y)
    height = quantities.given_contact_height

    def scaled(epsilon):
        moved = quantities if height is None else quantities.with_contact_height(height * (1.0 + epsilon))
        return moved(result.x + epsilon * response)

    return derivative(scaled, 0.0, step)


def contact_height_sensitivity(quantities, theta, step_m=1e-6):
    """Derivative of the impact quantities with respect to a given contact height (per m)."""
    height = quantities.given_contact_height
    return derivative(lambda value: quantities.with_contact_height(value)(theta), height, step_m)


def quantity_covariance(model, result, quantities, held_k_se=0.0, held_k_slopes=None, scale_rel_se=0.0,
                        contact_height_se_m=0.0, noise_correlation=0.0, gravity_se_m_s2=0.0, gravity_scaled=False,
                        extra_parts=None, speed_error_m=0.0):
    """Covariance of the quantity vector of ``quantities`` at the fit ``result``, with its parts.

    Parameters
    ----------
    model, result, quantities
        The flight model, its least-squares fit and the impact quantities built on it.
    held_k_se : float
        Standard error (1/m) of a drag parameter the fit holds (``model.fixed_k``).
    held_k_slopes : dict, optional
        Derivatives of the held k by g (``gravity``, 1/m per m/s²) and by the relative length scale
        (``scale``, 1/m), where the held k took in a free fit's k: g and the scale move the quantities
        through it too.
    scale_rel_se : float
        Relative standard error of the length scale that brought the heights to m.
    contact_height_se_m : float
        Standard error (m) of a given contact height.
    noise_correlation : float
        Lag-1 correlation of the height errors; the fit covariance grows by (1 + ρ)/(1 − ρ).
    gravity_se_m_s2 : float
        Standard error of g (m/s²).
    gravity_scaled : bool
        The heights were brought to m by a scale from gravity: an error of g, and the scale's own error
        (``scale_rel_se``), then scale every length with it and leave times and ratios (e) alone, instead
        of moving the fit.
    extra_parts : dict, optional
        More systematic parts, name → each quantity's signed share (same layout as the vector).
    speed_error_m : float
        Standard error (m) of a height error growing with the ball's speed, at the fastest sample
        (:meth:`FlightModel.speed_patterns`): its two shapes move the quantities, with the flights refitted at
        the fit's k, as two independent systematic parts (what the shapes do to a held k is in ``held_k_se``).

    Returns
    -------
    dict
        ``covariance`` of the quantities, ``theta_covariance`` (inflated fit covariance),
        ``k_variance`` ((1/m)², fitted or held k), ``drag_covariance`` (of each quantity with k),
        ``scale_part`` (each quantity's signed share from the scale, same unit as the quantity) and
        ``systematic_parts`` (name → each quantity's signed share from that held input).
    """
    theta = result.x
    cov_theta = correlated_noise_factor(noise_correlation) * fit_covariance(result)
    vector = quantities(theta)
    jac = jacobian(quantities, theta, model.lower_bounds(theta.size))
    cov = propagate(jac, cov_theta)
    parts = dict(extra_parts or {})
    slopes = held_k_slopes or {}
    if model.with_drag:
        # a fitted k also carries what g and the length scale leave uncertain (k is per metre)
        k_shares = [theta[-1] * scale_rel_se]
        if gravity_se_m_s2 > 0:
            k_shares.append(theta[-1] * gravity_se_m_s2 / model.g if gravity_scaled else
                            gravity_se_m_s2 * refit_sensitivity(result, model, model, "g", 1e-4)[-1])
        k_variance = float(cov_theta[-1, -1] + np.sum(np.square(k_shares)))
        drag_covariance = jac @ cov_theta[:, -1]
        k_sensitivity = np.zeros(vector.size)
    else:
        # a held k that took in a free fit's k moves with g and the scale as that did
        k_variance = held_k_se**2 + (gravity_se_m_s2 * slopes.get("gravity", 0.0))**2 \
            + (scale_rel_se * slopes.get("scale", 0.0))**2
        k_sensitivity = held_input_sensitivity(result, quantities, jac, model, "fixed_k", 1e-3 * model.fixed_k) \
            if model.fixed_k > 0 else np.zeros(vector.size)
        parts["drag"] = held_k_se * k_sensitivity
        drag_covariance = k_variance * k_sensitivity
    if gravity_se_m_s2 > 0:
        parts["gravity"] = (gravity_se_m_s2 / model.g) * vector * length_dimension(quantities.n_impacts) \
            if gravity_scaled else gravity_se_m_s2 * (held_input_sensitivity(result, quantities, jac, model, "g", 1e-4)
                                                      + slopes.get("gravity", 0.0) * k_sensitivity)
    if quantities.given_contact_height is None:
        prior, prior_se = quantities.contact_time_prior
        if prior_se > 0:
            parts["contact_time_prior"] = prior_se * held_input_sensitivity(
                result, quantities, jac, quantities, "contact_time_prior", 1e-2 * prior_se)
        exponent_se = quantities.contact_exponent[1]
        if exponent_se > 0:
            parts["contact_time_exponent"] = exponent_se * held_input_sensitivity(
                result, quantities, jac, quantities, "contact_exponent", 1e-2 * exponent_se)
        curvature_se = quantities.contact_curvature[1]
        if curvature_se > 0:  # the law's shape: a real contact's times are no exact power law
            parts["contact_time_curvature"] = curvature_se * held_input_sensitivity(
                result, quantities, jac, quantities, "contact_curvature", 1e-2 * curvature_se)
    elif contact_height_se_m > 0:
        parts["contact_height"] = contact_height_se_m * contact_height_sensitivity(quantities, theta)
    if speed_error_m > 0:
        for name, pattern in zip(("speed_error_odd", "speed_error_even"), model.speed_patterns(theta, speed_error_m)):
            parts[name] = jac @ refit_response(result, pattern)
    # the length scale's error moves every quantity together: a rank-one term in their covariance. A scale from
    # gravity made the flights fall with g whatever it is off by: its error scales every length (heights,
    # speeds) and leaves times and ratios (e) alone, as an error of g does; another scale's error, with g held,
    # moves the fit
    if not scale_rel_se:
        scale_part = np.zeros(vector.size)
    elif gravity_scaled:
        scale_part = scale_rel_se * vector * length_dimension(quantities.n_impacts)
    else:
        scale_part = scale_rel_se * np.nan_to_num(scale_sensitivity(quantities, result)
                                                  + slopes.get("scale", 0.0) * k_sensitivity)
    for part in [*parts.values(), scale_part]:
        part = np.nan_to_num(part)
        cov += np.outer(part, part)
    return {"covariance": cov, "theta_covariance": cov_theta, "k_variance": k_variance,
            "drag_covariance": drag_covariance, "scale_part": scale_part, "systematic_parts": parts}
