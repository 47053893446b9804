"""Does the coefficient of restitution depend on impact speed? Weighted least-squares fits of the
restitution laws of :func:`dropfit.physics.restitution` to the per-impact e, and a choice between them
by the Bayesian information criterion. Pure functions, no I/O.
"""

from __future__ import annotations

import numpy as np
from scipy import stats

from .restitution import estimate, weighted_fit

#: Exponent of the viscoelastic Hertz law 1 − e = b v^p (fixed, not fitted).
POWER_EXPONENT = 0.2

#: Below this BIC difference between the best model and another, the data cannot tell them apart:
#: "strong" evidence on the scale of Kass & Raftery (1995). With ΔBIC < 2 a constant e was kept in
#: only 94 % of seeded constant-e sequences; with 6, in 99 %, while a slope or a power law ten times
#: its standard error is still chosen every time (tests/test_speed_dependence.py).
DELTA_BIC_INDISTINGUISHABLE = 6.0

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


def _fit(kind, v, e, covariance):
    """Fit of model ``kind`` by the estimator shared with the constant e (:func:`weighted_fit`)."""
    x, offset, names = _design(kind, v)
    fitted = weighted_fit(x, e - offset, covariance)
    chi2, dof = fitted["chi2"], fitted["dof"]
    n, p = e.size, len(names)
    parameter_covariance = fitted["covariance"]
    return {
        "kind": kind,
        "parameters": {name: estimate(value, np.sqrt(max(parameter_covariance[i, i], 0.0)), _UNITS[name])
                       for i, (name, value) in enumerate(zip(names, fitted["theta"]))},
        "parameter_covariance": parameter_covariance.tolist(),
        "estimator": fitted["estimator"].tolist(),
        "n_parameters": p,
        "chi2": chi2,
        "dof": dof,
        "p_value": float(stats.chi2.sf(chi2, dof)) if dof > 0 else float("nan"),
        "aic": float(chi2 + 2.0 * p),
        "bic": float(chi2 + p * np.log(n)),
        "covariance_singular": fitted["singular"],
    }


def fit_speed_dependence(speed_m_s, e, covariance):
    """Fit constant, linear and power-law restitution against impact speed and choose one by BIC.

    Each model is fitted by :func:`dropfit.restitution.weighted_fit`, the estimator of the constant e
    too: inverse-variance weights, parameter covariance from the full covariance of the per-impact e
    (adjacent impacts share a flight, so their e are correlated), generalised χ² for the model
    choice (a singular covariance is replaced by its pseudo-inverse). The models, as in :func:`dropfit.physics.restitution`, are

    - ``constant``: e = e0 (1 parameter);
    - ``linear``: e = e0 − a v (2 parameters, a in s/m);
    - ``power``: 1 − e = b v^(1/5), viscoelastic Hertz contact (1 parameter, b in (s/m)^(1/5);
      the exponent is fixed).

    AIC = χ² + 2p and BIC = χ² + p ln n are computed from the GLS χ² (the covariance is taken as
    known, so −2 ln L equals χ² up to a constant common to all models). The model with the lowest
    BIC is the best; every model within ΔBIC < 6 of it counts as indistinguishable from it, and the
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
        lists, same order as ``parameters``), ``estimator`` (list of lists, parameters = estimator
        @ (e − offset), to propagate other covariances of e), ``n_parameters``, ``chi2``, ``dof``, ``p_value``,
        ``aic``, ``bic`` and ``delta_bic`` (to the best). ``chosen`` is the chosen model's name,
        ``why`` a sentence saying why, ``indistinguishable`` whether another model lies within
        ΔBIC < 6 of the best, and ``covariance_singular`` whether the pseudo-inverse was used.
    """
    v = np.asarray(speed_m_s, dtype=float).ravel()
    e = np.asarray(e, dtype=float).ravel()
    covariance = np.asarray(covariance, dtype=float)
    if v.size != e.size or covariance.shape != (e.size, e.size):
        raise ValueError("speed_m_s, e and covariance must have shapes (n,), (n,) and (n, n)")
    if e.size < 3:
        raise ValueError("need at least 3 impacts to compare the speed-dependence models")
    models = {kind: _fit(kind, v, e, covariance) for kind in ("constant", "linear", "power")}
    singular = models["constant"].pop("covariance_singular")
    for kind in ("linear", "power"):
        models[kind].pop("covariance_singular")
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


def prediction_covariance(model_result, speed_m_s, e_cross_covariance):
    """Covariance of the e predicted at ``speed_m_s`` (m/s, scalar) with another quantity, from the
    covariance of the per-impact e with it (``e_cross_covariance``, shape (n,), in its units)."""
    x, _, _ = _design(model_result["kind"], np.atleast_1d(float(speed_m_s)))
    return float(x[0] @ np.asarray(model_result["estimator"]) @ np.asarray(e_cross_covariance, dtype=float))
