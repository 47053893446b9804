"""Does the coefficient of restitution depend on impact speed? Generalised least-squares fits of the
restitution laws of :func:`dropfit.physics.restitution` to the per-impact e, and a choice between them
by the Bayesian information criterion. Pure functions, no I/O.
"""

from __future__ import annotations

import numpy as np
from scipy import stats

from .restitution import estimate

#: Exponent of the viscoelastic Hertz law 1 − e = b v^p (fixed, not fitted).
POWER_EXPONENT = 0.2

#: Below this BIC difference between the best model and another, the data cannot tell them apart.
DELTA_BIC_INDISTINGUISHABLE = 2.0

#: Order of preference at equal parameter count when models are indistinguishable (simplest first).
_PREFERENCE = ("constant", "power", "linear")

_UNITS = {"e0": "1", "slope_s_m": "s/m", "coefficient": "(s/m)^(1/5)"}


def _design(kind, v):
    """Design matrix X and offset c such that e = c + X θ, with the parameter names of θ."""
    v = np.asarray(v, dtype=float)
    if kind == "constant":
        return np.ones((v.size, 1)), np.zeros(v.size), ["e0"]
    if kind == "linear":
        return np.column_stack([np.ones(v.size), -v]), np.zeros(v.size), ["e0", "slope_s_m"]
    if kind == "power":
        return -(v ** POWER_EXPONENT)[:, None], np.ones(v.size), ["coefficient"]
    raise ValueError(f"unknown restitution model kind {kind!r}")


def _inverse_covariance(covariance):
    """Inverse of the covariance, or its pseudo-inverse when it is singular; and whether it was."""
    rank = np.linalg.matrix_rank(covariance)
    if rank < covariance.shape[0]:
        return np.linalg.pinv(covariance), True
    try:
        return np.linalg.inv(covariance), False
    except np.linalg.LinAlgError:
        return np.linalg.pinv(covariance), True


def _gls(kind, v, e, weight):
    """One GLS fit of model ``kind``; ``weight`` is the (pseudo-)inverse covariance of e."""
    x, offset, names = _design(kind, v)
    y = e - offset
    normal = x.T @ weight @ x
    parameter_covariance = np.linalg.pinv(normal)
    theta = parameter_covariance @ (x.T @ weight @ y)
    residual = y - x @ theta
    chi2 = float(residual @ weight @ residual)
    n, p = e.size, len(names)
    dof = n - p
    return {
        "kind": kind,
        "parameters": {name: estimate(value, np.sqrt(max(parameter_covariance[i, i], 0.0)), _UNITS[name])
                       for i, (name, value) in enumerate(zip(names, theta))},
        "parameter_covariance": parameter_covariance.tolist(),
        "n_parameters": p,
        "chi2": chi2,
        "dof": dof,
        "p_value": float(stats.chi2.sf(chi2, dof)) if dof > 0 else float("nan"),
        "aic": float(chi2 + 2.0 * p),
        "bic": float(chi2 + p * np.log(n)),
    }


def fit_speed_dependence(speed_m_s, e, covariance):
    """Fit constant, linear and power-law restitution against impact speed and choose one by BIC.

    Each model is fitted by generalised least squares with the full covariance of the per-impact e
    (adjacent impacts share a flight, so their e are correlated); a singular covariance is replaced
    by its pseudo-inverse. The models, as in :func:`dropfit.physics.restitution`, are

    - ``constant``: e = e0 (1 parameter);
    - ``linear``: e = e0 − a v (2 parameters, a in s/m);
    - ``power``: 1 − e = b v^(1/5), viscoelastic Hertz contact (1 parameter, b in (s/m)^(1/5);
      the exponent is fixed).

    AIC = χ² + 2p and BIC = χ² + p ln n are computed from the GLS χ² (the covariance is taken as
    known, so −2 ln L equals χ² up to a constant common to all models). The model with the lowest
    BIC is the best; every model within ΔBIC < 2 of it counts as indistinguishable from it, and the
    simplest of those is chosen (fewest parameters; at equal count the lower BIC).

    Parameters
    ----------
    speed_m_s : array_like
        Impact speed of each impact in m/s (magnitude), shape (n,).
    e : array_like
        Per-impact coefficient of restitution (dimensionless), shape (n,).
    covariance : array_like
        Covariance matrix of ``e``, shape (n, n).

    Returns
    -------
    dict
        JSON-ready: ``models`` maps ``"constant"``, ``"linear"``, ``"power"`` to a dict with
        ``kind``, ``parameters`` (name → :func:`dropfit.restitution.estimate` dict: ``e0`` in 1,
        ``slope_s_m`` in s/m, ``coefficient`` in (s/m)^(1/5)), ``parameter_covariance`` (list of
        lists, same order as ``parameters``), ``n_parameters``, ``chi2``, ``dof``, ``p_value``,
        ``aic``, ``bic`` and ``delta_bic`` (to the best). ``chosen`` is the chosen model's name,
        ``why`` a sentence saying why, ``indistinguishable`` whether another model lies within
        ΔBIC < 2 of the best, and ``covariance_singular`` whether the pseudo-inverse was used.
    """
    v = np.asarray(speed_m_s, dtype=float).ravel()
    e = np.asarray(e, dtype=float).ravel()
    covariance = np.asarray(covariance, dtype=float)
    if v.size != e.size or covariance.shape != (e.size, e.size):
        raise ValueError("speed_m_s, e and covariance must have shapes (n,), (n,) and (n, n)")
    if e.size < 3:
        raise ValueError("need at least 3 impacts to compare the speed-dependence models")
    weight, singular = _inverse_covariance(covariance)

    models = {kind: _gls(kind, v, e, weight) for kind in ("constant", "linear", "power")}
    ranked = sorted(models, key=lambda k: models[k]["bic"])
    best, runner_up = ranked[0], ranked[1]
    for kind in models:
        models[kind]["delta_bic"] = float(models[kind]["bic"] - models[best]["bic"])
    close = [k for k in ranked if models[k]["delta_bic"] < DELTA_BIC_INDISTINGUISHABLE]
    indistinguishable = len(close) > 1
    if indistinguishable:
        chosen = min(close, key=lambda k: (models[k]["n_parameters"], models[k]["bic"], _PREFERENCE.index(k)))
        others = [k for k in close if k != best]
        names = " and ".join([f"'{best}'"] + [f"'{k}'" for k in others])
        why = (f"The data cannot tell {names} apart (ΔBIC = "
               + ", ".join(f"{models[k]['delta_bic']:.2f} for '{k}'" for k in others)
               + f" < {DELTA_BIC_INDISTINGUISHABLE:g}); the simplest, '{chosen}' "
               f"({models[chosen]['n_parameters']} parameter{'s' if models[chosen]['n_parameters'] > 1 else ''}),"
               " is chosen.")
    else:
        chosen = best
        why = (f"'{best}' has the lowest BIC ({models[best]['bic']:.2f}); the runner-up '{runner_up}' is "
               f"worse by ΔBIC = {models[runner_up]['delta_bic']:.2f} ≥ {DELTA_BIC_INDISTINGUISHABLE:g}.")
    return {
        "models": models,
        "chosen": chosen,
        "why": why,
        "indistinguishable": bool(indistinguishable),
        "covariance_singular": bool(singular),
    }


def predict_e(model_result, speed_m_s):
    """e predicted by a fitted model at the given speeds, with its standard error (delta method).

    Parameters
    ----------
    model_result : dict
        One entry of ``fit_speed_dependence(...)["models"]``.
    speed_m_s : float or array_like
        Impact speed in m/s.

    Returns
    -------
    e : numpy.ndarray
        Predicted e (dimensionless), same shape as ``speed_m_s`` (not clipped to [0, 1]).
    se : numpy.ndarray
        Its standard error from the parameter covariance (dimensionless), same shape.
    """
    v = np.asarray(speed_m_s, dtype=float)
    x, offset, names = _design(model_result["kind"], v.ravel())
    theta = np.array([model_result["parameters"][name]["value"] for name in names])
    parameter_covariance = np.asarray(model_result["parameter_covariance"], dtype=float)
    e = offset + x @ theta
    variance = np.einsum("ij,jk,ik->i", x, parameter_covariance, x)
    return e.reshape(v.shape), np.sqrt(np.clip(variance, 0.0, None)).reshape(v.shape)
