"""The fit result of one recording (``fit.json``): from the analysis summary and the impacts table to
the restitution models and the headline e, the drag, contact time and contact model, the theory
checks, the ITF verdict and the provenance. Pure: no files.

:func:`analysis_summary` makes the JSON-ready summary that ``analysis.json`` holds, and
:func:`fit_summary` the fit result from it and the impacts table, whether both come from memory
(:func:`dropfit.pipeline.fit_analysis`) or from the files (``dropfit fit``): the same numbers either
way, since the tables are written to round-trip exactly.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from . import __version__
from .analysis.horizontal import distance_check
from .balls import ball_kind
from .contact import fit_linear_contact
from .errors import InputError
from .physics import speed_below_apex
from .restitution import estimate, itf_rebound, itf_verdict, theory_checks
from .settings import Settings
from .speed_dependence import fit_restitution_models, predict_e, prediction_covariance, prediction_law


def analysis_summary(result, trajectory_attrs):
    """JSON-ready analysis summary (``analysis.json``): the analysis' summary, the covariances and the
    trajectory's attributes.

    Parameters
    ----------
    result : dropfit.analysis.BounceAnalysis
        The analysis (its summary holds the options it ran with, see
        :func:`dropfit.pipeline.analyse_trajectory`).
    trajectory_attrs : mapping
        The attributes of the trajectory analysed.
    """
    summary = dict(result.summary)
    summary["e_covariance"] = result.e_covariance.tolist()
    summary["e_contact_covariance"] = result.e_contact_covariance.tolist()
    summary["e_drag_covariance"] = result.e_drag_covariance.tolist()
    summary["trajectory_attrs"] = {key: plain(value) for key, value in trajectory_attrs.items()}
    return {key: plain(value) for key, value in summary.items()}


def plain(value):
    """A JSON-ready Python value from a numpy scalar or array (nested in dicts, lists and tuples)."""
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, dict):
        return {key: plain(item) for key, item in value.items()}
    if isinstance(value, (list, tuple)):
        return [plain(item) for item in value]
    return value


def fit_summary(summary, impacts, settings=None, ball_type=None):
    """The fit result (JSON-ready dict, the content of ``fit.json``) from an analysis summary
    (:func:`analysis_summary`) and its impacts table.

    Every fit (the restitution models, the ITF prediction, the contact k and c) uses only the impacts
    with ``in_fit`` true (:func:`fit_rows`) and the matching blocks of the covariances; the restitution
    models and the headline are those of :func:`dropfit.speed_dependence.fit_restitution_models`.

    Parameters
    ----------
    summary : dict
        The analysis summary, missing numbers as NaN (as :func:`dropfit.inputs.read_analysis` reads it).
    impacts : pandas.DataFrame
        The impacts table.
    settings : dropfit.settings.Settings, optional
        The ITF window and drop-height tolerance (m); default :class:`~dropfit.settings.Settings`.
    ball_type : str, optional
        Overrides the trajectory's ``ball_type`` (the ITF verdict is for ``tennis``).

    Raises
    ------
    dropfit.errors.InputError
        When no impact is left to fit.
    """
    settings = settings or Settings()
    attrs = summary.get("trajectory_attrs", {})
    ball_type = ball_type or attrs.get("ball_type")
    if ball_type:  # any case, as the options take it; an unknown kind is refused, not silently not tennis
        ball_type = ball_kind(ball_type).name
    mass = attrs.get("ball_mass_kg")
    used = fit_rows(impacts)
    if used.size == 0:
        raise InputError("no impact is left to fit: the analysis marked every impact as not in_fit "
                         "(see the note column of the impacts table)")
    fitted_impacts = impacts.iloc[used]
    models = fit_restitution_models(fitted_impacts["v_in_m_s"].to_numpy(), fitted_impacts["e"].to_numpy(),
                                    np.asarray(summary["e_covariance"])[np.ix_(used, used)],
                                    fitted_impacts["impact"].to_numpy())
    # the seed's theory checks are those of a constant e, whichever model is the headline
    constant = models["models"]["constant"]["parameters"]["e0"]
    touchdowns = impacts["t_touchdown_s"].to_numpy(dtype=float)
    fall_time = touchdowns[0] - summary["drop_apex_time_s"]
    heard = summary.get("impacts_heard")
    # impacts heard without the release: the series is checked from the first of them, as Erickson's is
    from_first = bool(heard) and not np.isfinite(fall_time) and touchdowns.size > 1
    # touchdowns heard are a contact and a flight apart: the contacts before the last (the kind's prior,
    # one systematic error for all)
    on_floor = tuple(1e-3 * float(np.nansum(impacts[column].to_numpy(dtype=float)[:-1]))
                     for column in ("t_contact_ms", "t_contact_se_ms")) if heard else (0.0, 0.0)
    theory = theory_checks(constant["value"], constant["se"], summary["drop_height_m"], fall_time,
                           impacts["h_after_m"].to_numpy(), impacts["h_after_se_m"].to_numpy(),
                           summary["rest_time_s"] - (touchdowns[0] if from_first else summary["drop_apex_time_s"]),
                           heard, impacts["flight_time_after_s"].iloc[0] if from_first else None, on_floor)
    if summary.get("horizontal"):  # a 2-D recording: the distance travelled while bouncing, u t∞
        theory["horizontal_distance"] = distance_check(summary["horizontal"], theory["total_bouncing_time"])
    if summary.get("bouncing_time_note"):  # a sound recording's bouncing time ends otherwise
        theory["total_bouncing_time"]["note"] = summary["bouncing_time_note"]
    itf = _itf(ball_type, summary, impacts, models, used, settings.itf_drop_height_m, settings.itf_rebound_min_m,
               settings.itf_rebound_max_m, settings.itf_drop_height_tolerance_m)
    resolvable = impacts["contact_resolvable"].astype(bool).to_numpy()
    drag = {
        "model": summary["drag_model"],
        "k_per_m": estimate(summary["drag_k_per_m"], summary["drag_k_se_per_m"], "1/m"),
        "bic_no_drag": summary["bic_no_drag"],
        "bic_quadratic_drag": summary["bic_quadratic_drag"],
        "why": summary.get("drag_why") or ("chosen by the Bayesian information criterion (lower wins)"
                                           if np.isfinite(summary["bic_quadratic_drag"]) and np.isfinite(summary["bic_no_drag"])
                                           else "fixed by the --drag option"),
    }
    if summary["drag_model"] == "nominal" and not summary.get("drag_why"):
        kind = ball_kind(attrs.get("ball_type"))
        # a free fit was made and weighed only where both models were compared; with --drag off k is the kind's
        combined = " combined with what the flights say about k" if np.isfinite(summary["bic_quadratic_drag"]) else ""
        drag["note"] = (f"k is not fitted freely: held at that of a smooth {kind.name} ball of its size and mass "
                        f"(C_d = {kind.drag_coefficient:g} ± {kind.drag_coefficient_se:g}){combined}; its standard "
                        f"error is carried into every e, height and contact time as a systematic error")
    size_note = summary.get("ball_size_note")
    if isinstance(size_note, str) and size_note:  # a regulation ball's size and mass stand in (NaN read back: none)
        drag["note"] = "; ".join(filter(None, (drag.get("note"), size_note)))
    result = {
        "status": "ok",
        "sample_id": attrs.get("sample_id"),
        "source": attrs.get("source"),
        "source_sha256": attrs.get("source_sha256"),
        "dropfit_version": __version__,
        "ball": {"type": ball_type, "radius_m": attrs.get("ball_radius_m"), "mass_kg": attrs.get("ball_mass_kg")},
        "calibration": attrs.get("calibration"),
        "scale": _scale_record(attrs),
        "time_base": _time_base_record(attrs),
        "restitution": _restitution_record(models, impacts, used),
        "restitution_models": models["models"],
        "drag": drag,
        "drop_height_m": estimate(summary["drop_height_m"], summary["drop_height_se_m"], "m"),
        "contact_height_m": estimate(summary["contact_height_m"], summary["contact_height_se_m"], "m"),
        "contact_time": _contact_time(summary, impacts[resolvable]),
        "contact_model": _contact_model(impacts, np.intersect1d(np.flatnonzero(resolvable), used), mass,
                                        summary["gravity_m_s2"], np.asarray(summary["e_contact_covariance"])),
        "noise_m": summary["noise_m"],
        "theory": theory,
        "itf": itf,
        "config": _config(summary, settings),
        "data": _data_record(summary),
        "notes": list(summary.get("notes") or []) + ([attrs["frames_note"]] if attrs.get("frames_note") else []),
    }
    if summary.get("sound_and_picture"):  # a video with sound (dropfit.audio.fuse): both sensors' e and combined
        result["sound_and_picture"] = summary["sound_and_picture"]
    return result


def _data_record(summary):
    """What of the recording entered the analysis: samples left out as the hand's, as tracking jumps and
    as outliers of the flight fit, the release time (s) and the noise (m)."""
    return {"hand_samples": summary.get("hand_samples"), "tracking_jump_samples": summary.get("tracking_jump_samples"),
            "residual_outlier_samples": summary.get("residual_outlier_samples"),
            "release_time_s": summary.get("release_time_s"), "noise_m": summary.get("noise_m")}


def _config(summary, settings):
    """The options the numbers were made with: the ITF window (m), g (m/s²) with its standard error and
    source, and the drag mode (from the analysis summary)."""
    options = summary.get("analysis_options") or {}
    gravity = summary.get("gravity") or {}
    return {"itf_drop_height_m": settings.itf_drop_height_m, "itf_rebound_min_m": settings.itf_rebound_min_m,
            "itf_rebound_max_m": settings.itf_rebound_max_m,
            "itf_drop_height_tolerance_m": settings.itf_drop_height_tolerance_m,
            "gravity_m_s2": summary["gravity_m_s2"], "gravity_se_m_s2": gravity.get("se"),
            "gravity_source": gravity.get("source"), "drag": options.get("drag")}


def _scale_record(attrs):
    """The length scale of a px recording: source, value, relative se, what the heights rest on
    (:func:`dropfit.heightlog.heights_basis`), the other scales' disagreements and the suspect ones'
    likely causes."""
    from .heightlog import heights_basis

    if "scale_m_per_px" not in attrs:
        return None
    prefix, suspect = "scale_disagreement_", "scale_suspect_"
    return {"source": attrs.get("scale_source", attrs.get("calibration")), "m_per_px": attrs["scale_m_per_px"],
            "rel_se": attrs.get("scale_rel_se", 0.0), "heights": heights_basis(attrs),
            "disagreement": {key[len(prefix):]: value for key, value in attrs.items() if key.startswith(prefix)},
            "suspect": {key[len(suspect):]: value for key, value in attrs.items() if key.startswith(suspect)},
            "ruler_note": attrs.get("ruler_note"), "target_note": attrs.get("target_note"),
            "tilt_note": attrs.get("tilt_note")}


def _time_base_record(attrs):
    """A video's capture rate (frames/s), where it came from and why."""
    if "capture_fps" not in attrs:
        return None
    return {"capture_fps": attrs["capture_fps"], "source": attrs.get("capture_fps_source"),
            "note": attrs.get("capture_rate_note")}


def _contact_time(summary, resolvable_rows):
    """Whether contact times are reported, why, and, with the floor not known, the contact time at 1 m/s
    that the flights and the ball kind's prior give (the model behind the contact height)."""
    if summary.get("contact_time_why"):  # a sound recording: the contact times are assumed, never measured
        return {"resolvable": False, "why": summary["contact_time_why"]}
    if not resolvable_rows.empty:
        return {"resolvable": True, "n_impacts": len(resolvable_rows),
                "why": "the floor is known, the sampling resolves the contact and each contact time stands "
                       "well clear of its uncertainty (impacts marked in the impacts table)"}
    if summary["contact_height_source"] == "given":
        return {"resolvable": False, "why": "the contact times are not resolved: shorter than two sample intervals "
                                            "or than five standard errors, or longer than this kind of ball can have"}
    prior, prior_se = summary.get("contact_time_prior_s") or (np.nan, np.nan)
    return {"resolvable": False,
            "why": ("the floor is not known: the contact height is modelled with contact times tau = tau_1 "
                    f"(v / 1 m/s)^-beta, tau_1 from the flights and the ball kind's prior ({1e3 * prior:.3g} ± "
                    f"{1e3 * prior_se:.2g} ms); give floor_m to measure each contact time"),
            "contact_time_1m_s": estimate(summary.get("contact_time_1m_s_s", np.nan),
                                          summary.get("contact_time_1m_s_se_s", np.nan), "s"),
            "exponent": estimate(summary.get("contact_time_exponent", np.nan),
                                 summary.get("contact_time_exponent_se", np.nan), "1")}


def fit_rows(impacts):
    """Positions (in table order) of the impacts that enter every fit: those with ``in_fit`` true and an e
    that is a number (a NaN e made the fits fail with "SVD did not converge", losing the recording).

    Without an ``in_fit`` column every impact enters; an empty cell counts as true (nothing says to
    leave the impact out), and text (a CSV column with an empty cell is read as text) is true when it
    reads true, 1 or yes.
    """
    def entered(flag):
        if pd.isna(flag):
            return True
        return flag.strip().lower() in ("true", "1", "yes") if isinstance(flag, str) else bool(flag)

    flagged = [entered(flag) for flag in impacts["in_fit"]] if "in_fit" in impacts else np.ones(len(impacts), bool)
    return np.flatnonzero(np.asarray(flagged, dtype=bool) & np.isfinite(impacts["e"].to_numpy(dtype=float)))


def _excluded_impacts(impacts, used):
    """The impacts left out of the fits: number and the analysis' note, in table order."""
    notes = [note if isinstance(note, str) else "" for note in impacts["note"]] if "note" in impacts \
        else [""] * len(impacts)
    return [{"impact": int(impacts["impact"].iloc[i]), "note": notes[i] or "marked not in_fit by the analysis"}
            for i in np.setdiff1d(np.arange(len(impacts)), used)]


#: The fields of the chosen model's record that ``restitution`` repeats (``restitution_models`` has them all).
_HEADLINE_FIELDS = ("model", "law", "description", "parameters", "n_parameters", "chi2", "dof", "chi2_per_dof",
                    "p_value", "verdict", "birge_factor", "note", "aic", "bic", "delta_bic")


def _restitution_record(models, impacts, used):
    """``restitution`` of the fit result: the chosen model and why, its headline e at the first fitted
    impact's speed, that impact's own e, the weights of the headline e over all impacts, which impacts
    were fitted and which laws could not be."""
    chosen = models["models"][models["chosen"]]
    weights = np.zeros(len(impacts))
    weights[used] = models["headline"]["weights"]
    first = impacts.iloc[used[0]]
    return {
        **{field: chosen[field] for field in _HEADLINE_FIELDS},
        "why": models["why"],
        "indistinguishable": models["indistinguishable"],
        "not_fitted": models["not_fitted"],
        "covariance_singular": models["covariance_singular"],
        "e": models["headline"]["e"],
        "reference_impact": models["reference"]["impact"],
        "reference_speed_m_s": models["reference"]["speed_m_s"],
        "e1": estimate(first["e"], first["e_se"], "1"),
        "weights": weights.tolist(),
        "n_impacts": int(used.size),
        "n_impacts_total": len(impacts),
        "impacts_used": [int(number) for number in impacts["impact"].iloc[used]],
        "impacts_excluded": _excluded_impacts(impacts, used),
    }


def _contact_model(impacts, rows, mass_kg, gravity_m_s2, e_contact_covariance):
    """Linear contact k, c from the impacts at positions ``rows`` (resolved contact times, in the fits;
    None if there are none); ``e_contact_covariance`` is that of all impacts' e and contact times (s)."""
    if rows.size == 0 or not mass_kg:
        return None
    physical = impacts["e"].iloc[rows].to_numpy()
    rows = rows[(physical > 0) & (physical < 1)]
    if rows.size == 0:
        return None
    used = impacts.iloc[rows]
    n = e_contact_covariance.shape[0] // 2
    block = np.concatenate([rows, n + rows])
    fitted = fit_linear_contact(mass_kg, used["v_in_m_s"], used["e"], 1e-3 * used["t_contact_ms"],
                                e_contact_covariance[np.ix_(block, block)], gravity_m_s2)
    return {
        "model": "linear (unilateral Kelvin-Voigt): F = max(0, k delta + c delta_dot)",
        "stiffness_n_m": estimate(*fitted["stiffness_n_m"], "N/m"),
        "damping_n_s_m": estimate(*fitted["damping_n_s_m"], "N s/m"),
        "mass_kg": mass_kg,
        "gravity_m_s2": gravity_m_s2,
        "impact_speed_m_s": float(used["v_in_m_s"].iloc[0]),
        "n_impacts": len(used),
        "why": "each impact's e and contact time inverted exactly, weighted by inverse variance; the standard "
               "errors propagate the full covariance of all e and contact times (they share flights)",
    }


def _itf(ball_type, summary, impacts, models, used, drop_height_itf, rebound_min, rebound_max, tolerance):
    limits = {"drop_height_m": drop_height_itf, "rebound_min_m": rebound_min, "rebound_max_m": rebound_max,
              "source": "ITF Rules of Tennis, Appendix I"}
    if ball_type != "tennis":
        return {"verdict": "not applicable", "why": f"the ITF rebound window is for tennis balls, this is {ball_type}",
                "limits": limits}
    # a prediction from another drop height is for a ball in air, with the analysis' drag (fitted, or that of
    # a smooth sphere of the ball's size where the data could not show drag), and e of the chosen law (or of
    # the best law, when no law describes the impacts) at the ITF impact speed
    drag_k, drag_k_se = summary["drag_k_per_m"], summary["drag_k_se_per_m"]
    e_drag = np.asarray(summary["e_drag_covariance"])[used]
    law_name, e_source = prediction_law(models)
    law = models["models"][law_name]
    itf_speed = float(speed_below_apex(drop_height_itf, drag_k, summary["gravity_m_s2"]))
    e, e_se = (float(x) for x in predict_e(law, itf_speed))
    e_drag_covariance = prediction_covariance(law, itf_speed, e_drag)
    if law_name != "constant":
        e_source += f" at the ITF impact speed {itf_speed:.2f} m/s"
    # the length scale's share of the heights' errors is common to both: the measured rebound scaled by
    # 254 cm / H, a ratio of two heights, keeps only the difference of their relative shares
    drop, drop_scale_se = summary["drop_height_m"], summary.get("drop_height_scale_se_m", 0.0)
    first = impacts.iloc[0]
    first_scale_se = first.get("h_after_scale_se_m", 0.0)
    drop_fit_se = np.sqrt(max(summary["drop_height_se_m"] ** 2 - drop_scale_se**2, 0.0))
    first_fit_se = np.sqrt(max(first["h_after_se_m"] ** 2 - first_scale_se**2, 0.0))
    rebound = itf_rebound(drop, drop_fit_se, first["h_after_m"], first_fit_se, e, e_se, drag_k,
                          summary["gravity_m_s2"], tolerance, drop_height_itf, e_source, drag_k_se, e_drag_covariance)
    if rebound["method"].startswith("measured"):
        ratio_scale_se = rebound["value"] * (first_scale_se / first["h_after_m"] - drop_scale_se / drop)
        rebound.update(estimate(rebound["value"], float(np.hypot(rebound["se"], ratio_scale_se)), "m"))
    verdict = itf_verdict(rebound, rebound_min, rebound_max)
    return {"verdict": verdict, "rebound_m": rebound, "limits": limits,
            "why": "pass: the 95 % interval lies inside the window; fail: wholly outside; "
                   "indeterminate: it straddles a limit"}
