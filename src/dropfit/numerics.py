"""The numerical helpers every estimator shares: a robust standard deviation, the covariance of a
least-squares fit from its Jacobian, numerical derivatives, and the normal, t and χ² quantiles and tails.
Each formula lives here once.

The distributions come from :mod:`scipy.special` (exact, and cheap to import), not :mod:`scipy.stats`,
whose import alone costs most of a second of each command's start-up.
"""

from __future__ import annotations

import numpy as np
from scipy.special import chdtrc, ndtri, stdtrit

#: σ = MAD_SCALE × median absolute deviation for Gaussian data.
MAD_SCALE = 1.4826


#: Up to this many values, :func:`fast_median` sorts them instead of calling :func:`numpy.median` (a sort
#: of 1 000 float32 takes 8 µs, NumPy's median 23 µs).
FEW_VALUES = 1000


def fast_median(values):
    """``numpy.median(values, axis=0)``, the same numbers; up to ``FEW_VALUES`` values by one sort: NumPy's
    median has 20 µs of overhead a call, most of its cost on the few hundred values a tracker takes the
    median of in every frame.

    Parameters
    ----------
    values : numpy.ndarray
        Integers or floats (float32 stays float32, as in NumPy's median), shape (n, ...).

    Returns
    -------
    numpy.ndarray or numpy.floating
        The median along the first axis (of integers, float64), in ``values``' unit.
    """
    if not 0 < len(values) <= FEW_VALUES or values.dtype == np.float16:
        return np.median(values, axis=0)
    ordered = np.sort(values, axis=0)
    if not np.issubdtype(ordered.dtype, np.inexact):
        ordered = ordered.astype(float)
    elif np.isnan(ordered[-1]).any():
        return np.median(values, axis=0)  # NaN (sorted last): NumPy's own answer
    middle = ordered.shape[0] // 2
    # + 0.0: NumPy's mean of the middle values starts its sum at 0, so a median of -0.0 is 0.0
    return (ordered[middle] if ordered.shape[0] % 2 else (ordered[middle - 1] + ordered[middle]) / 2) + 0.0


def robust_sigma(values, centre=None):
    """Standard deviation estimated from the median absolute deviation, immune to a few outliers.

    Parameters
    ----------
    values : array_like
        Samples (any unit); NaNs are ignored.
    centre : float, optional
        The value deviations are taken from; default their median.

    Returns
    -------
    float
        σ in the unit of ``values`` (0 for no finite value).
    """
    values = np.asarray(values, dtype=float)
    values = values[np.isfinite(values)]
    if values.size == 0:
        return 0.0
    centre = float(fast_median(values)) if centre is None else float(centre)
    return MAD_SCALE * float(fast_median(np.abs(values - centre)))


def least_squares_covariance(jacobian, residuals, n_parameters=None, sigma_floor=0.0):
    """Parameter covariance σ² (JᵀJ)⁻¹ of a least-squares fit, σ² from its residuals (at least ``sigma_floor``²).

    Parameters
    ----------
    jacobian : numpy.ndarray or scipy.sparse array
        J, shape (n, p): derivative of the residuals with respect to the parameters.
    residuals : numpy.ndarray
        Residuals at the minimum, shape (n,) (any unit).
    n_parameters : int, optional
        Parameters fitted, for the degrees of freedom n − p; default p, the columns of J.
    sigma_floor : float
        Least σ (the residuals' unit): a few residuals can lie closer to the fit than the noise.

    Returns
    -------
    numpy.ndarray
        Covariance, shape (p, p), in the parameters' units (a pseudo-inverse where JᵀJ is singular).
    """
    residuals = np.asarray(residuals, dtype=float)
    p = jacobian.shape[1] if n_parameters is None else n_parameters
    dof = max(residuals.size - p, 1)
    sigma2 = max(float(residuals @ residuals) / dof, sigma_floor**2)
    # columns scaled to unit norm first: parameters of very different size (a drag k of 1e-5 1/px beside
    # an acceleration of 1e4 px/s²) would otherwise lose a direction to the pseudo-inverse's cut-off
    if hasattr(jacobian, "toarray"):  # sparse (a long log's flights): the p × p product, never an n × p copy
        gram = (jacobian.T @ jacobian).toarray()
        norms = np.sqrt(np.diag(gram))
        norms[norms == 0] = 1.0
        return sigma2 * np.linalg.pinv(gram / np.outer(norms, norms)) / np.outer(norms, norms)
    jacobian = np.asarray(jacobian, dtype=float)
    norms = np.linalg.norm(jacobian, axis=0)
    norms[norms == 0] = 1.0
    scaled = jacobian / norms
    return sigma2 * np.linalg.pinv(scaled.T @ scaled) / np.outer(norms, norms)


def linear_fit(design, target):
    """Ordinary least squares target ≈ design @ coef, with the coefficients' covariance.

    Returns
    -------
    (numpy.ndarray, numpy.ndarray)
        The coefficients, shape (p,), and their covariance σ² (XᵀX)⁻¹ with σ² from the residuals.
    """
    design = np.asarray(design, dtype=float)
    target = np.asarray(target, dtype=float)
    coef, *_ = np.linalg.lstsq(design, target, rcond=None)
    return coef, least_squares_covariance(design, target - design @ coef)


def propagate(jacobian, covariance):
    """Covariance J C Jᵀ of a function of parameters with covariance C (delta method)."""
    jacobian = np.atleast_2d(np.asarray(jacobian, dtype=float))
    return jacobian @ np.asarray(covariance, dtype=float) @ jacobian.T


def jacobian(function, theta, lower=None, relative_step=1e-6, absolute_step=1e-6):
    """Central-difference Jacobian of a vector function, one-sided where a step down would cross a bound.

    Parameters
    ----------
    function : callable
        θ ↦ vector (numpy.ndarray, shape (m,)).
    theta : numpy.ndarray
        Parameters, shape (p,).
    lower : numpy.ndarray, optional
        Lower bound of each parameter (−inf where there is none).
    relative_step, absolute_step : float
        The step of parameter j is max(absolute_step, relative_step × |θ_j|), in θ_j's unit.

    Returns
    -------
    numpy.ndarray
        Shape (m, p).
    """
    theta = np.asarray(theta, dtype=float)
    lower = np.full(theta.size, -np.inf) if lower is None else np.asarray(lower, dtype=float)
    base = np.asarray(function(theta), dtype=float)
    jac = np.empty((base.size, theta.size))
    for j in range(theta.size):
        step = max(absolute_step, relative_step * abs(theta[j]))
        up, down = theta.copy(), theta.copy()
        up[j] += step
        down[j] = max(theta[j] - step, lower[j])
        jac[:, j] = (np.asarray(function(up), dtype=float) - np.asarray(function(down), dtype=float)) / (up[j] - down[j])
    return jac


def derivative(function, x, step):
    """Central-difference derivative of a (vector) function of one scalar ``x``, with the given step."""
    return (np.asarray(function(x + step), dtype=float) - np.asarray(function(x - step), dtype=float)) / (2.0 * step)


def running_min(values, half_width):
    """The smallest of ``values[i - half_width : i + half_width + 1]`` for every i (the window cut at the ends).

    Linear in the length whatever the window (van Herk / Gil–Werman: minima running forward and
    backward within blocks of the window's width), where comparing each sample with its 2w neighbours
    costs n × w.

    Parameters
    ----------
    values : numpy.ndarray
        Shape (n,), finite (any unit).
    half_width : int
        w ≥ 0, samples on each side.

    Returns
    -------
    numpy.ndarray
        Shape (n,), in the unit of ``values``.
    """
    values = np.asarray(values, dtype=float)
    width = 2 * half_width + 1
    blocks_needed = -(-(values.size + 2 * half_width) // width)
    padded = np.full(blocks_needed * width, np.inf)
    padded[half_width: half_width + values.size] = values
    blocks = padded.reshape(-1, width)
    forward = np.minimum.accumulate(blocks, axis=1).ravel()
    backward = np.minimum.accumulate(blocks[:, ::-1], axis=1)[:, ::-1].ravel()
    # the window starting at i covers the end of i's block (backward) and the start of the next (forward)
    return np.minimum(backward[: values.size], forward[width - 1: width - 1 + values.size])


def normal_quantile(probability):
    """The standard normal distribution's quantile: z with P(Z ≤ z) = ``probability`` (array or float)."""
    return ndtri(probability)


def t_quantile(probability, dof):
    """Student's t quantile: t with P(T ≤ t) = ``probability`` for ``dof`` degrees of freedom (> 0)."""
    return stdtrit(dof, probability)


def chi2_tail(chi2, dof):
    """The p-value of a χ² statistic: P(X ≥ ``chi2``) for ``dof`` degrees of freedom (any real > 0)."""
    return chdtrc(dof, chi2)
