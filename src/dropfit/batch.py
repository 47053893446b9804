"""Batch quality control: several drops per ball, several balls per batch.

Pure functions on the per-recording summary table (:func:`dropfit.report.batch_rows` with a
``ball_id`` column). A ball's rebound height is the mean over its drops; its standard error comes
from the drop-to-drop scatter (the drops differ more than their measurement errors say: the ball
hits the floor on another spot, warms up) but is never smaller than the measurement errors
propagated to the mean. With the scatter of n drops the 95 % interval uses Student's t with n − 1
degrees of freedom: three drops estimate a spread poorly, and a normal interval (±1.96 se) would cover the
ball's true mean only about 81 % of the time. The batch gets a control chart of the ball means:
centre line their mean, control limits ±3 σ with σ their standard deviation (the ball-to-ball spread,
drop noise included, which is what a ball mean varies by). The limits come from the same balls they
judge (a first, phase-I chart): a few balls with one far off widen them.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from .numerics import t_quantile
from .restitution import ITF_REBOUND_MAX_M, ITF_REBOUND_MIN_M, Z95, itf_verdict

#: Verdicts counted for a batch, in report order.
VERDICTS = ["pass", "fail", "indeterminate", "not applicable", "not analysed"]

#: Columns of the per-ball table (:func:`ball_rows`); heights in m, e dimensionless.
BALL_COLUMNS = ["ball_id", "n_drops", "n_failed", "rebound_m", "rebound_se_m", "rebound_ci95_low_m",
                "rebound_ci95_high_m", "rebound_sd_between_drops_m", "rebound_se_from", "e", "e_se",
                "e_sd_between_drops", "itf_verdict"]

#: Multiple of the ball-to-ball standard deviation between the centre line and a control limit (Shewhart).
CONTROL_LIMIT_SIGMAS = 3.0


def mean_over_drops(values, standard_errors):
    """Mean of one ball's drops with an honest standard error and 95 % interval.

    Parameters
    ----------
    values : array_like
        Per-drop estimates (any unit; NaN = drop without a value, left out).
    standard_errors : array_like
        Their measurement standard errors, same unit.

    Returns
    -------
    dict or None
        ``value``, ``se``, ``ci95`` [low, high], ``n`` (drops used), ``sd_between_drops`` (sample
        standard deviation, NaN for one drop) and ``se_from`` ("drop-to-drop scatter" or
        "measurement"); None if no drop has a value. ``se`` is the larger of sd/√n and
        √(Σ se_i²)/n; the interval is ±t(0.975, n − 1)·se for n ≥ 2, ±1.96·se for one drop.
    """
    values = np.asarray(values, dtype=float)
    standard_errors = np.asarray(standard_errors, dtype=float)
    used = np.isfinite(values)
    values, standard_errors = values[used], standard_errors[used]
    n = values.size
    if n == 0:
        return None
    mean = float(values.mean())
    measurement_se = float(np.sqrt(np.nansum(standard_errors ** 2)) / n)
    if n == 1:
        sd, se, quantile, source = float("nan"), measurement_se, Z95, "measurement"
    else:
        sd = float(values.std(ddof=1))
        scatter_se = sd / np.sqrt(n)
        source = "drop-to-drop scatter" if scatter_se >= measurement_se else "measurement"
        se, quantile = max(scatter_se, measurement_se), float(t_quantile(0.975, n - 1))
    return {"value": mean, "se": se, "ci95": [mean - quantile * se, mean + quantile * se], "n": n,
            "sd_between_drops": sd, "se_from": source}


def ball_rows(recordings, rebound_min_m=ITF_REBOUND_MIN_M, rebound_max_m=ITF_REBOUND_MAX_M):
    """One row per ball: mean rebound height and e over its drops, their spread, the ITF verdict.

    Parameters
    ----------
    recordings : pandas.DataFrame
        One row per recording: ``ball_id``, ``status`` ("ok" or "failed"), ``e`` and ``e_se`` (1),
        ``itf_rebound_m`` and ``itf_rebound_se_m`` (m, the 254 cm rebound; NaN where the ITF test
        does not apply).
    rebound_min_m, rebound_max_m : float
        ITF rebound window in m.

    Returns
    -------
    pandas.DataFrame
        Columns :data:`BALL_COLUMNS`, balls in order of first appearance. The verdict is the
        guard-banded one of :func:`dropfit.restitution.itf_verdict` on the ball's 95 % interval;
        "not applicable" without ITF rebounds (not a tennis ball), "not analysed" if every drop failed.
    """
    rows = []
    for ball_id, drops in recordings.groupby("ball_id", sort=False):
        analysed = drops[drops["status"] != "failed"]
        rebound = mean_over_drops(analysed["itf_rebound_m"], analysed["itf_rebound_se_m"])
        e = mean_over_drops(analysed["e"], analysed["e_se"])
        if analysed.empty:
            verdict = "not analysed"
        elif rebound is None:
            verdict = "not applicable"
        else:
            verdict = itf_verdict(rebound, rebound_min_m, rebound_max_m)
        rebound = rebound or {"ci95": [np.nan, np.nan]}
        e = e or {}
        rows.append({
            "ball_id": ball_id, "n_drops": len(analysed), "n_failed": len(drops) - len(analysed),
            "rebound_m": rebound.get("value", np.nan), "rebound_se_m": rebound.get("se", np.nan),
            "rebound_ci95_low_m": rebound["ci95"][0], "rebound_ci95_high_m": rebound["ci95"][1],
            "rebound_sd_between_drops_m": rebound.get("sd_between_drops", np.nan),
            "rebound_se_from": rebound.get("se_from"),
            "e": e.get("value", np.nan), "e_se": e.get("se", np.nan),
            "e_sd_between_drops": e.get("sd_between_drops", np.nan), "itf_verdict": verdict,
        })
    return pd.DataFrame(rows, columns=BALL_COLUMNS)


def batch_statistics(balls):
    """Batch mean and spread of the ball rebound heights, verdict counts and the control chart.

    Parameters
    ----------
    balls : pandas.DataFrame
        Per-ball table of :func:`ball_rows`.

    Returns
    -------
    dict
        ``n_balls``; ``verdict_counts`` (verdict → number of balls, every one of :data:`VERDICTS`);
        over the balls with a rebound height: ``n_balls_measured``, ``rebound_mean_m`` (mean of the
        ball means, the centre line), ``rebound_sd_between_balls_m`` (their sample standard
        deviation, NaN below two balls), ``rebound_sd_within_balls_m`` (drop-to-drop standard
        deviation pooled over the balls with two or more drops, NaN if there is none), its degrees
        of freedom ``within_balls_dof``, the control limits ``control_low_m`` and ``control_high_m``
        (mean ± 3 ball-to-ball sd, NaN below two balls) and ``out_of_control`` (ids of the balls
        whose mean lies outside them).
    """
    measured = balls[np.isfinite(balls["rebound_m"])]
    dof = int((measured["n_drops"] - 1).clip(lower=0).sum())
    repeated = measured[measured["n_drops"] >= 2]
    pooled_variance = float(((repeated["n_drops"] - 1) * repeated["rebound_sd_between_drops_m"] ** 2).sum() / dof) \
        if dof else np.nan
    counts = balls["itf_verdict"].value_counts()
    centre = float(measured["rebound_m"].mean()) if len(measured) else np.nan
    spread = float(measured["rebound_m"].std(ddof=1)) if len(measured) >= 2 else np.nan
    low, high = centre - CONTROL_LIMIT_SIGMAS * spread, centre + CONTROL_LIMIT_SIGMAS * spread
    outside = measured[(measured["rebound_m"] < low) | (measured["rebound_m"] > high)]
    return {
        "n_balls": len(balls),
        "verdict_counts": {verdict: int(counts.get(verdict, 0)) for verdict in VERDICTS},
        "n_balls_measured": len(measured),
        "rebound_mean_m": centre,
        "rebound_sd_between_balls_m": spread,
        "rebound_sd_within_balls_m": float(np.sqrt(pooled_variance)),
        "within_balls_dof": dof,
        "control_low_m": low,
        "control_high_m": high,
        "out_of_control": outside["ball_id"].tolist(),
    }


def failed_recordings(recordings):
    """The recordings that could not be analysed, with their one-line reasons.

    Parameters
    ----------
    recordings : pandas.DataFrame
        Per-recording table with ``sample_id``, ``ball_id``, ``status`` and ``error``.

    Returns
    -------
    pandas.DataFrame
        ``sample_id``, ``ball_id``, ``reason``.
    """
    failed = recordings[recordings["status"] == "failed"]
    return pd.DataFrame({"sample_id": failed["sample_id"], "ball_id": failed["ball_id"],
                         "reason": failed["error"]}).reset_index(drop=True)
