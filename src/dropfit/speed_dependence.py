"""The coefficient of restitution of a recording as a model of its impacts: the candidate laws of e
against impact speed and "one e per impact", each fitted by the one estimator of every e law
(:func:`dropfit.restitution.weighted_fit`), each checked against its own residuals, and the headline
model chosen by evidence. Pure functions, no I/O.

The models (``MODELS``, simplest first):

- ``constant``: e = e₀;
- ``power``: 1 − e = b v^(1/5), viscoelastic Hertz contact (exponent fixed);
- ``linear``: e = e₀ − a v;
- ``contact_power``: 1/e − 1 = a vᵖ (v in m/s), a and p fitted. It is linear in
  y = ln(1/e − 1) = ln a + p ln v, so it is fitted there, with the covariance of y from that of e
  by the delta method (dy/de = −1/(e(1 − e))); it is fitted only when every e lies at least
  ``TRANSFORM_MIN_SE`` standard errors inside (0, 1), where that linearisation holds;
- ``per_impact``: each impact's e on its own, no law (χ² = 0, n parameters).

Every law is tested by its generalised χ² (``verdict``: fits, questionable, rejected); a law that
misfits (p < ``P_QUESTIONABLE``) has its parameter covariance widened by the Birge ratio
√(χ²/dof). The headline is the simplest model within ``DELTA_BIC_INDISTINGUISHABLE`` of the lowest
BIC among the models that their own test does not reject (``per_impact`` is never rejected).
"""

from __future__ import annotations

import numpy as np

from .numerics import chi2_tail
from .restitution import Z95, estimate, weighted_fit

#: Exponent of the viscoelastic Hertz law 1 − e = b v^p (fixed, not fitted).
POWER_EXPONENT = 0.2

#: Below this BIC difference between the best model and another, the data cannot tell them apart:
#: "strong" evidence on the scale of Kass & Raftery (1995). With ΔBIC < 2 a constant e was kept in
#: only 94 % of seeded constant-e sequences; with 6, in 99 %, while a slope or a power law ten times
#: its standard error is still chosen every time (tests/test_speed_dependence.py).
DELTA_BIC_INDISTINGUISHABLE = 6.0

#: Below this χ² p-value a law misfits: its uncertainty is widened by the Birge ratio √(χ²/dof). A
#: correct law is widened in 5 % of recordings, mostly by less than 1.5, which costs little coverage;
#: the conventional size of a goodness-of-fit test.
P_QUESTIONABLE = 0.05

#: Below this χ² p-value a law is rejected and never the headline. A correct law is lost in one
#: recording of a thousand, while a law whose impacts scatter about it by up to about 1.9 (6 dof) or
#: 1.4 (30 dof) times their errors survives, widened: extra scatter of that size (spot to spot on
#: the floor, errors a little underestimated) is what the Birge widening is for. Misfits beyond it
#: are structure that no widening makes honest.
P_REJECTED = 1e-3

#: ``contact_power`` is fitted in ln(1/e − 1) by the delta method only when every e is at least this
#: many standard errors inside (0, 1): closer, the logarithm is not linear across the errors.
TRANSFORM_MIN_SE = 3.0

#: The candidate models, simplest first (the order of preference at equal parameter count and BIC).
MODELS = ("constant", "power", "linear", "contact_power", "per_impact")

#: Each model's law as a formula, and in words.
LAWS = {
    "constant": "e = e₀",
    "power": "1 − e = b v^(1/5)",
    "linear": "e = e₀ − a v",
    "contact_power": "1/e − 1 = a vᵖ",
    "per_impact": "one e per impact",
}
DESCRIPTIONS = {
    "constant": "e is the same at every impact",
    "power": "viscoelastic Hertz contact: the loss 1 − e grows as the impact speed v to the power 1/5",
    "linear": "e falls linearly with the impact speed v",
    "contact_power": "contact mechanics: the ratio of lost to kept speed, 1/e − 1, grows as a fitted power p of "
                     "the impact speed v (v in m/s)",
    "per_impact": "no law describes these impacts: each impact has its own e",
}

VERDICT_FITS, VERDICT_QUESTIONABLE, VERDICT_REJECTED = "fits", "questionable", "rejected"
VERDICT_NOT_TESTABLE = "not testable"

_UNITS = {"e0": "1", "slope_s_m": "s/m", "coefficient": "(s/m)^(1/5)", "a": "1", "exponent": "1"}


def _law_design(model, v):
    """Design matrix X (n, p) of law ``model`` in its linear target y = X θ, and the names of θ."""
    v = np.asarray(v, dtype=float)
    if model == "constant":
        return np.ones((v.size, 1)), ["e0"]
    if model == "linear":
        return np.column_stack([np.ones(v.size), -v]), ["e0", "slope_s_m"]
    if model == "power":
        return (v ** POWER_EXPONENT)[:, None], ["coefficient"]
    if model == "contact_power":
        return np.column_stack([np.ones(v.size), np.log(v)]), ["ln_a", "exponent"]
    raise ValueError(f"{model!r} is not a law of impact speed")


def _target(model, e):
    """The target y(e) that law ``model`` is linear in, and dy/de (dimensionless)."""
    e = np.asarray(e, dtype=float)
    if model == "power":
        return 1.0 - e, -np.ones_like(e)
    if model == "contact_power":
        return np.log(1.0 / e - 1.0), -1.0 / (e * (1.0 - e))
    return e, np.ones_like(e)


def _e_from_target(model, y):
    """e(y), the inverse of :func:`_target`, and de/dy."""
    y = np.asarray(y, dtype=float)
    if model == "power":
        return 1.0 - y, -np.ones_like(y)
    if model == "contact_power":
        e = 1.0 / (1.0 + np.exp(y))
        return e, -e * (1.0 - e)
    return y, np.ones_like(y)


def p_value_text(p_value):
    """A χ² p-value as text: two significant figures, "< 1e-15" below that (the χ² tail is then
    astronomically small and its digits mean nothing), "—" when there is no test (NaN, or None from JSON)."""
    if p_value is None or not np.isfinite(p_value):
        return "—"
    return "< 1e-15" if p_value < 1e-15 else f"{p_value:.2g}"


def p_value_phrase(p_value):
    """"p = 0.044" or "p < 1e-15": a p-value in a sentence."""
    text = p_value_text(p_value)
    return f"p {text}" if text.startswith("<") else f"p = {text}"


def verdict(p_value):
    """A model's goodness of fit in words from its χ² p-value: fits, questionable, rejected (or not
    testable without degrees of freedom, p = NaN)."""
    if not np.isfinite(p_value):
        return VERDICT_NOT_TESTABLE
    if p_value < P_REJECTED:
        return VERDICT_REJECTED
    if p_value < P_QUESTIONABLE:
        return VERDICT_QUESTIONABLE
    return VERDICT_FITS


def birge_factor(chi2, dof, p_value):
    """Factor (≥ 1) that widens a misfitting law's standard errors: the Birge ratio √(χ²/dof) when
    p < ``P_QUESTIONABLE``, else 1."""
    if dof > 0 and np.isfinite(p_value) and p_value < P_QUESTIONABLE:
        return float(max(np.sqrt(chi2 / dof), 1.0))
    return 1.0


def _fit_note(model, chi2, dof, p_value, factor):
    """What the model's own χ² test says about it and its uncertainty, in words."""
    if model == "per_impact":
        return "each impact's e with its own standard error: with no law there is no misfit to widen them by"
    if dof == 0:
        return "as many parameters as impacts: no degrees of freedom are left to test it"
    test = f"χ²/dof = {chi2 / dof:.3g}, {p_value_phrase(p_value)}"
    if factor == 1.0:
        return f"the impacts scatter about this law as their errors allow ({test})"
    note = (f"the impacts scatter about this law {factor:.2g} times more than their errors allow ({test}); "
            f"its uncertainty is widened by that factor")
    if verdict(p_value) == VERDICT_REJECTED:
        note += f"; its own test rejects it (p < {P_REJECTED:g}), so it is never the headline"
    return note


def _reported_parameters(names, theta, covariance):
    """Parameters as reported (name → :func:`dropfit.restitution.estimate` dict) from θ and its covariance."""
    se = np.sqrt(np.clip(np.diag(covariance), 0.0, None))
    parameters = {}
    for name, value, value_se in zip(names, theta, se):
        if name == "ln_a":
            # a > 0: its se by the delta method, its interval that of ln a carried over (never below 0)
            parameters["a"] = estimate(np.exp(value), np.exp(value) * value_se, _UNITS["a"])
            parameters["a"]["ci95"] = [float(np.exp(value - Z95 * value_se)), float(np.exp(value + Z95 * value_se))]
        else:
            parameters[name] = estimate(value, value_se, _UNITS.get(name, "1"))
    return parameters


def _model_record(model, names, theta, covariance, jacobian_e, chi2, dof, n):
    """JSON-ready record of a fitted model, its covariance widened by the Birge ratio where it misfits."""
    p_value = float(chi2_tail(chi2, dof)) if dof > 0 else float("nan")
    factor = birge_factor(chi2, dof, p_value)
    covariance = factor**2 * np.asarray(covariance, dtype=float)
    n_parameters = len(names)
    return {
        "model": model,
        "law": LAWS[model],
        "description": DESCRIPTIONS[model],
        "parameters": _reported_parameters(names, theta, covariance),
        "n_parameters": n_parameters,
        "chi2": float(chi2),
        "dof": int(dof),
        "chi2_per_dof": float(chi2 / dof) if dof > 0 else float("nan"),
        "p_value": p_value,
        "verdict": verdict(p_value),
        "birge_factor": factor,
        "note": _fit_note(model, chi2, dof, p_value, factor),
        "aic": float(chi2 + 2.0 * n_parameters),
        "bic": float(chi2 + n_parameters * np.log(n)),
        "theta_names": list(names),
        "theta": [float(x) for x in theta],
        "parameter_covariance": covariance.tolist(),
        "jacobian_e": np.asarray(jacobian_e, dtype=float).tolist(),
    }


def _fit_law(model, v, e, covariance):
    """Fit of law ``model`` in its linear target by :func:`dropfit.restitution.weighted_fit`; the
    target's covariance from that of e by the delta method (exact for the laws linear in e)."""
    design, names = _law_design(model, v)
    target, slope = _target(model, e)
    fitted = weighted_fit(design, target, covariance * np.outer(slope, slope))
    record = _model_record(model, names, fitted["theta"], fitted["covariance"],
                           fitted["estimator"] * slope[None, :], fitted["chi2"], fitted["dof"], e.size)
    return record, fitted["singular"]


def _per_impact(e, covariance, impact_numbers):
    """The no-law model: every impact's e is its own parameter (χ² = 0, n parameters, BIC = n ln n)."""
    names = [f"e_{number}" for number in impact_numbers]
    return _model_record("per_impact", names, e, covariance, np.eye(e.size), 0.0, 0, e.size)


def _unfittable(model, e, e_se, n):
    """Why law ``model`` cannot be fitted to these impacts, or None when it can."""
    n_parameters = len(_law_design(model, np.ones(1))[1])
    if model != "constant" and n <= n_parameters:
        return f"needs at least {n_parameters + 1} impacts to be tested"
    if model == "contact_power":
        inside = np.minimum(e, 1.0 - e) / e_se
        if not np.all(inside >= TRANSFORM_MIN_SE):
            return (f"fitted in ln(1/e − 1), which needs every e at least {TRANSFORM_MIN_SE:g} standard errors "
                    f"inside (0, 1)")
    return None


def fit_restitution_models(speed_m_s, e, covariance, impact_numbers=None):
    """Fit every model of e to the impacts, test each against its own residuals, choose the headline.

    Each law is fitted by :func:`dropfit.restitution.weighted_fit` (the estimator of the constant e
    too): inverse-variance weights, parameter covariance through the full covariance of the
    per-impact e (adjacent impacts share a flight, so their e are correlated), and the generalised χ²
    at its minimum (a singular covariance is replaced by its pseudo-inverse). AIC = χ² + 2k and
    BIC = χ² + k ln n (k parameters; the covariance is taken as known, so −2 ln L is χ² up to a
    constant common to all models); ``per_impact`` has χ² = 0 and k = n.

    The choice: a law whose χ² test rejects it (p < ``P_REJECTED``) is out. Among the others the
    lowest BIC is the best; every model within ΔBIC < ``DELTA_BIC_INDISTINGUISHABLE`` of it counts as
    indistinguishable from it and the simplest of those is chosen (fewest parameters, a law before
    ``per_impact``; at equal count the lower BIC, then the order of ``MODELS``). ``per_impact`` is chosen when every law is rejected
    or worse than it by ΔBIC ≥ 6.

    Parameters
    ----------
    speed_m_s : array_like
        Impact speed of each impact in m/s (magnitude), shape (n,).
    e : array_like
        Per-impact coefficient of restitution (dimensionless), shape (n,).
    covariance : array_like
        Covariance matrix of ``e``, shape (n, n).
    impact_numbers : array_like of int, optional
        The impacts' numbers, naming the ``per_impact`` parameters (``e_1``, …); default 1 … n.

    Returns
    -------
    dict
        JSON-ready:

        - ``models``: name → record with ``model``, ``law`` (formula), ``description`` (words),
          ``parameters`` (reported name → :func:`dropfit.restitution.estimate` dict: ``e0`` (1),
          ``slope_s_m`` (s/m), ``coefficient`` ((s/m)^(1/5)), ``a`` (1; its interval that of ln a)
          and ``exponent`` (1), ``e_<impact>`` (1) for ``per_impact``), ``n_parameters``, ``chi2``,
          ``dof``, ``chi2_per_dof``, ``p_value``, ``verdict``, ``birge_factor``, ``note``, ``aic``,
          ``bic``, ``delta_bic`` (to the best model not rejected), ``e_reference`` (e predicted at
          the first impact's speed, for ``per_impact`` the first impact's own e), and what
          predictions need: ``theta_names``, ``theta`` (the linear parameters: ln a, not a),
          ``parameter_covariance`` (widened) and ``jacobian_e`` (∂θ/∂e, shape (k, n));
        - ``not_fitted``: name → why a law was not fitted;
        - ``chosen`` (name), ``why`` (a sentence), ``indistinguishable`` (another model not rejected
          lies within ΔBIC < 6 of the best), ``covariance_singular``;
        - ``reference``: ``impact`` (number) and ``speed_m_s`` of the first impact, where the
          headline e is given;
        - ``headline``: ``e`` (estimate: the chosen model's ``e_reference``) and ``weights``
          (∂e/∂eᵢ for each impact: for a constant e, e = weights · per-impact e).
    """
    v = np.asarray(speed_m_s, dtype=float).ravel()
    e = np.asarray(e, dtype=float).ravel()
    covariance = np.asarray(covariance, dtype=float)
    if v.size != e.size or covariance.shape != (e.size, e.size):
        raise ValueError("speed_m_s, e and covariance must have shapes (n,), (n,) and (n, n)")
    if e.size == 0:
        raise ValueError("no impact to fit")
    n = e.size
    numbers = np.arange(1, n + 1) if impact_numbers is None else np.asarray(impact_numbers).ravel()
    e_se = np.sqrt(np.diag(covariance))
    models, not_fitted, singular = {}, {}, False
    for model in MODELS[:-1]:
        reason = _unfittable(model, e, e_se, n)
        if reason:
            not_fitted[model] = reason
            continue
        models[model], model_singular = _fit_law(model, v, e, covariance)
        singular = singular or model_singular
    models["per_impact"] = _per_impact(e, covariance, numbers)

    admissible = [name for name in models if models[name]["verdict"] != VERDICT_REJECTED]
    best = min(admissible, key=lambda name: models[name]["bic"])
    for name, record in models.items():
        record["delta_bic"] = float(record["bic"] - models[best]["bic"])
        record["e_reference"] = _e_reference(record, v[0], 0)
    close = [name for name in admissible if models[name]["delta_bic"] < DELTA_BIC_INDISTINGUISHABLE]
    # per_impact is the least simple at any parameter count: with one impact it is the constant e again
    chosen = min(close, key=lambda name: (models[name]["n_parameters"], name == "per_impact", models[name]["bic"],
                                          MODELS.index(name)))
    return {
        "models": models,
        "not_fitted": not_fitted,
        "chosen": chosen,
        "why": _why(models, chosen, best, close),
        "indistinguishable": len(close) > 1,
        "covariance_singular": bool(singular),
        "reference": {"impact": int(numbers[0]), "speed_m_s": float(v[0])},
        "headline": {"e": models[chosen]["e_reference"], "weights": _weights(models[chosen], v[0], 0).tolist()},
    }


def _why(models, chosen, best, close):
    """Why ``chosen`` is the headline, in a few sentences."""
    rejected = [name for name in MODELS if name in models and models[name]["verdict"] == VERDICT_REJECTED]
    parts = []
    if rejected:
        parts.append(_listed(f"'{name}' ({p_value_phrase(models[name]['p_value'])})" for name in rejected)
                     + (" is rejected by its own" if len(rejected) == 1 else " are rejected by their own")
                     + f" χ² test (p < {P_REJECTED:g}).")
    if chosen == "per_impact":
        parts.append(f"No law describes these impacts: every law is rejected or worse than one e per impact by "
                     f"ΔBIC ≥ {DELTA_BIC_INDISTINGUISHABLE:g}; each impact keeps its own e. Either e differs from "
                     f"impact to impact, or the impacts' standard errors understate their errors.")
    elif len(close) > 1:
        others = [name for name in close if name != chosen]
        count = models[chosen]["n_parameters"]
        parts.append("The data cannot tell " + _listed(f"'{name}'" for name in close) + " apart (ΔBIC = "
                     + ", ".join(f"{models[name]['delta_bic']:.2f} for '{name}'" for name in others)
                     + f" < {DELTA_BIC_INDISTINGUISHABLE:g}); the simplest, '{chosen}' ({count} parameter"
                     + ("s" if count > 1 else "") + "), is chosen.")
    else:
        runner_up = min((name for name in models if name not in (best,) and name not in rejected),
                        key=lambda name: models[name]["bic"])
        parts.append(f"'{best}' has the lowest BIC ({models[best]['bic']:.2f}) of the models not rejected; the "
                     f"runner-up '{runner_up}' is worse by ΔBIC = {models[runner_up]['delta_bic']:.2f} ≥ "
                     f"{DELTA_BIC_INDISTINGUISHABLE:g}.")
    return " ".join(parts)


def _listed(items):
    """'a', 'a and b', 'a, b and c'."""
    items = list(items)
    return items[0] if len(items) == 1 else ", ".join(items[:-1]) + " and " + items[-1]


def _weights(record, speed_m_s, index):
    """∂e/∂eᵢ of the model's e at ``speed_m_s`` (a law) or at impact ``index`` (``per_impact``)."""
    jacobian_e = np.asarray(record["jacobian_e"], dtype=float)
    if record["model"] == "per_impact":
        return jacobian_e[index]
    design, _ = _law_design(record["model"], np.atleast_1d(float(speed_m_s)))
    _, slope = _e_from_target(record["model"], design[0] @ np.asarray(record["theta"]))
    return float(slope) * design[0] @ jacobian_e


def _e_reference(record, speed_m_s, index):
    """The model's e at the reference impact (estimate dict): predicted at its speed, or its own e."""
    if record["model"] == "per_impact":
        name = record["theta_names"][index]
        return dict(record["parameters"][name])
    value, se = predict_e(record, speed_m_s)
    return estimate(value, se, "1")


def predict_e(model_record, speed_m_s):
    """e predicted by a fitted law at the given speeds, with its standard error (delta method).

    Parameters
    ----------
    model_record : dict
        One entry of ``fit_restitution_models(...)["models"]`` other than ``per_impact``.
    speed_m_s : float or array_like
        Impact speed in m/s.

    Returns
    -------
    e : numpy.ndarray
        Predicted e (dimensionless), same shape as ``speed_m_s`` (not clipped to [0, 1]).
    se : numpy.ndarray
        Its standard error from the (Birge-widened) parameter covariance, same shape.
    """
    v = np.asarray(speed_m_s, dtype=float)
    design, _ = _law_design(model_record["model"], v.ravel())
    parameter_covariance = np.asarray(model_record["parameter_covariance"], dtype=float)
    target = design @ np.asarray(model_record["theta"], dtype=float)
    variance = np.einsum("ij,jk,ik->i", design, parameter_covariance, design)
    e, slope = _e_from_target(model_record["model"], target)
    se = np.abs(slope) * np.sqrt(np.clip(variance, 0.0, None))
    return e.reshape(v.shape), se.reshape(v.shape)


def prediction_covariance(model_record, speed_m_s, e_cross_covariance):
    """Covariance of the e a law predicts at ``speed_m_s`` (m/s, scalar) with another quantity, from
    the covariance of the fitted impacts' e with it (``e_cross_covariance``, shape (n,), in its units)."""
    return float(_weights(model_record, speed_m_s, 0) @ np.asarray(e_cross_covariance, dtype=float))


def prediction_law(result):
    """The law that predicts e at another speed (e.g. the ITF drop's), and why.

    Parameters
    ----------
    result : dict
        Output of :func:`fit_restitution_models`.

    Returns
    -------
    name : str
        The chosen model when it is a law; when it is ``per_impact``, the law with the lowest BIC
        (its uncertainty widened by its Birge ratio).
    why : str
        The reason, in words.
    """
    chosen = result["chosen"]
    if chosen != "per_impact":
        return chosen, f"the chosen {chosen} law ({LAWS[chosen]})"
    laws = [name for name in result["models"] if name != "per_impact"]
    best = min(laws, key=lambda name: result["models"][name]["bic"])
    record = result["models"][best]
    widened = (f", its uncertainty widened {record['birge_factor']:.2g} times by its misfit"
               if record["birge_factor"] > 1.0 else "")
    return best, (f"the best law by BIC, {best} ({LAWS[best]}){widened}: no law describes these impacts, so "
                  f"no chosen law predicts another speed")
