"""The workflow's stages: each reads files, calls the pure functions and writes its outputs whole.

Every stage function takes paths and options and raises :class:`dropfit.errors.InputError` for a
problem with the recording; :func:`dropfit.cli.main` turns that into one line (or into failure
records, with ``--record-failure``).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import yaml

from . import __version__, video_limits
from .analysis import NOMINAL_DRAG_RELATIVE_SE, analyse_bounces
from .contact import fit_linear_contact
from .errors import InputError, one_line
from .files import atomic_output, sha256_of, write_json, write_text
from .heightlog import read_trajectory, trajectory_from_log
from .inputs import read_analysis, read_fit, read_flights, read_impacts, read_report_analysis
from .physics import SPHERE_DRAG_COEFFICIENT, STANDARD_GRAVITY_M_S2, drag_parameter, speed_below_apex
from .restitution import (ITF_DROP_HEIGHT_M, ITF_REBOUND_MAX_M, ITF_REBOUND_MIN_M, estimate, itf_rebound,
                          itf_verdict, theory_checks)
from .speed_dependence import fit_restitution_models, predict_e, prediction_covariance, prediction_law
from .synth import scenario_recordings, synthesize
from .tracking import TRACKED_CENTRE_CORRELATION
from .videolog import is_video, trajectory_from_video


def synth(scenarios_path, name, log_path, truth_path, seed=None):
    """Generate the height log and ground truth of scenario ``name`` from a scenarios YAML file."""
    try:
        scenarios = yaml.safe_load(Path(scenarios_path).read_text(encoding="utf-8"))["scenarios"]
        scenario, scenario_seed = scenario_recordings(scenarios)[name]
    except InputError as error:
        raise InputError(f"{scenarios_path}: {error}") from None
    except (OSError, KeyError, TypeError, yaml.YAMLError) as error:
        raise InputError(f"{scenarios_path}: no scenario {name!r} ({type(error).__name__}: {error})") from None
    log, truth = synthesize(scenario, scenario_seed if seed is None else seed)
    truth["scenario_name"] = name
    unit = log.columns[1]
    header = (f"# dropfit height log (synthetic scenario {name}, seed {truth['seed']})\n"
              f"# {unit}: height of the ball centre above the sensor zero; empty = dropout\n")
    with atomic_output(log_path) as tmp:
        tmp.write_text(header + log.to_csv(index=False, float_format="%.6f", na_rep=""), encoding="utf-8")
    write_json(truth_path, truth)


def synth_video(name, out_dir, seed=0):
    """Render the default synthetic video ``name`` with its per-frame and drop ground truth."""
    from .video_synth import default_clips, make_default_videos

    if name not in default_clips():
        raise InputError(f"no synthetic clip {name!r}; known: {', '.join(default_clips())}")
    make_default_videos(out_dir, seed=seed, names=[name])


def measure(log_path, out_path, sample_id=None, ball_radius_m=None, ball_mass_kg=None, ball_type=None,
            scale_m_per_px=None, gravity_m_s2=STANDARD_GRAVITY_M_S2, floor_m=None, capture_fps=None,
            ruler_tick_m=None):
    """Height log or video → trajectory NetCDF (heights in m, up; dropouts flagged).

    ``floor_m`` is the height of the floor surface in the log's frame, in m, where it is known;
    ``capture_fps`` the capture rate of a slow-motion video whose container says otherwise;
    ``ruler_tick_m`` the spacing in m of the finest ticks of a ruler filmed in the ball's plane.
    """
    attrs = {"sample_id": sample_id, "ball_radius_m": ball_radius_m, "ball_mass_kg": ball_mass_kg,
             "ball_type": ball_type, "floor_m": floor_m, "dropfit_version": __version__}
    if is_video(log_path):
        trajectory = trajectory_from_video(log_path, ball_radius_m, scale_m_per_px and abs(scale_m_per_px),
                                           capture_fps, gravity_m_s2, attrs, ruler_tick_m)
    else:
        trajectory = trajectory_from_log(log_path, scale_m_per_px=scale_m_per_px, gravity_m_s2=gravity_m_s2,
                                         attrs=attrs)
    trajectory.attrs["source_sha256"] = sha256_of(log_path)  # after the read: it has checked the file exists
    with atomic_output(out_path) as tmp:
        trajectory.to_netcdf(tmp)


def analyse(trajectory_path, impacts_path, flights_path, summary_path, drag="auto",
            gravity_m_s2=STANDARD_GRAVITY_M_S2):
    """Trajectory → impacts table, flights table and analysis summary (with the e covariance)."""
    trajectory = read_trajectory(trajectory_path)
    attrs = trajectory.attrs
    # with the floor and the radius known, the ball touches down where its centre is one radius up
    contact_height = attrs["floor_m"] + attrs["ball_radius_m"] if "floor_m" in attrs and "ball_radius_m" in attrs \
        else None
    # a video frame is exposed for up to one frame interval around its time: keep the flights half an
    # interval clear of the contacts, where a frame may show the ball flattened
    time = trajectory["time"].values
    frame_interval = float(np.median(np.diff(time)))
    guard = 0.5 * frame_interval if "video" in attrs else 0.0
    result = analyse_bounces(time, trajectory["y"].values, gravity_m_s2=gravity_m_s2,
                             drag=drag, contact_height_m=contact_height,
                             source=attrs.get("source", str(trajectory_path)),
                             scale_rel_se=float(attrs.get("scale_rel_se", 0.0)),
                             contact_height_se_m=float(attrs.get("floor_se_m", 0.0)), contact_guard_s=guard,
                             nominal_drag_k_per_m=nominal_drag(attrs.get("ball_radius_m"), attrs.get("ball_mass_kg")),
                             noise_correlation=TRACKED_CENTRE_CORRELATION if "video" in attrs else 0.0)
    if "video" in attrs:  # a video's later bounces may be too briefly filmed to resolve
        result = video_limits.select_resolved_impacts(result, attrs["video"], frame_interval)
    with atomic_output(impacts_path) as tmp:
        result.impacts.to_csv(tmp, index=False, float_format="%.9g")
    with atomic_output(flights_path) as tmp:
        result.flights.to_csv(tmp, index=False, float_format="%.9g")
    write_json(summary_path, analysis_summary(result, attrs))


def nominal_drag(radius_m, mass_kg):
    """Drag parameter in 1/m of a smooth sphere of the ball's size and mass (0 when either is unknown)."""
    return float(drag_parameter(SPHERE_DRAG_COEFFICIENT, radius_m, mass_kg)) if radius_m and mass_kg else 0.0


def analysis_summary(result, trajectory_attrs):
    """JSON-ready analysis summary: the analysis summary, the covariances and the trajectory's attributes."""
    summary = dict(result.summary)
    summary["e_covariance"] = result.e_covariance.tolist()
    summary["e_contact_covariance"] = result.e_contact_covariance.tolist()
    summary["e_drag_covariance"] = result.e_drag_covariance.tolist()
    summary["trajectory_attrs"] = {key: _plain(value) for key, value in trajectory_attrs.items()}
    return {key: _plain(value) for key, value in summary.items()}


def _plain(value):
    """JSON-ready Python value from numpy scalars."""
    if isinstance(value, np.generic):
        return value.item()
    return value


def fit(analysis_path, impacts_path, out_path, ball_type=None, itf_drop_height_m=ITF_DROP_HEIGHT_M,
        itf_rebound_min_m=ITF_REBOUND_MIN_M, itf_rebound_max_m=ITF_REBOUND_MAX_M, itf_drop_height_tolerance_m=0.02):
    """Impacts → fit result JSON: e with uncertainty, theory checks, ITF verdict, provenance."""
    # JSON has no NaN: the analysis wrote missing numbers (no rest seen, BIC of a model not tried) as null
    summary = read_analysis(analysis_path)
    impacts = read_impacts(impacts_path, summary, analysis_path)
    write_json(out_path, fit_result(summary, impacts, ball_type, itf_drop_height_m, itf_rebound_min_m,
                                    itf_rebound_max_m, itf_drop_height_tolerance_m))


def fit_result(summary, impacts, ball_type=None, itf_drop_height_m=ITF_DROP_HEIGHT_M,
               itf_rebound_min_m=ITF_REBOUND_MIN_M, itf_rebound_max_m=ITF_REBOUND_MAX_M,
               itf_drop_height_tolerance_m=0.02):
    """The fit result (JSON-ready dict) from an analysis summary (:func:`analysis_summary`) and its
    impacts table; the options as for :func:`fit`.

    Every fit (the restitution models, the ITF prediction, the contact k and c) uses only the impacts
    with ``in_fit`` true (:func:`fit_rows`) and the matching blocks of the covariances; the restitution
    models and the headline are those of :func:`dropfit.speed_dependence.fit_restitution_models`.
    Raises :class:`dropfit.errors.InputError` when no impact is left to fit.
    """
    attrs = summary.get("trajectory_attrs", {})
    ball_type = ball_type or attrs.get("ball_type")
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
    fall_time = impacts["t_touchdown_s"].iloc[0] - summary["drop_apex_time_s"]
    theory = theory_checks(constant["value"], constant["se"], summary["drop_height_m"], fall_time,
                           impacts["h_after_m"].to_numpy(), impacts["h_after_se_m"].to_numpy(),
                           summary["rest_time_s"] - summary["drop_apex_time_s"])
    itf = _itf(ball_type, summary, impacts, models, used, itf_drop_height_m, itf_rebound_min_m,
               itf_rebound_max_m, itf_drop_height_tolerance_m)
    resolvable = impacts["contact_resolvable"].astype(bool).to_numpy()
    drag = {
        "model": summary["drag_model"],
        "k_per_m": estimate(summary["drag_k_per_m"], summary["drag_k_se_per_m"], "1/m"),
        "bic_no_drag": summary["bic_no_drag"],
        "bic_quadratic_drag": summary["bic_quadratic_drag"],
        "why": "chosen by the Bayesian information criterion (lower wins)"
        if np.isfinite(summary["bic_quadratic_drag"]) and np.isfinite(summary["bic_no_drag"])
        else "fixed by the --drag option",
    }
    if summary["drag_model"] == "nominal":
        drag["note"] = (f"k is not fitted freely: held at that of a smooth sphere of this size and mass (C_d = "
                        f"{SPHERE_DRAG_COEFFICIENT}, {100 * NOMINAL_DRAG_RELATIVE_SE:.0f} % standard error) combined "
                        f"with what the flights say about k; its standard error is carried into every e, height and "
                        f"contact time as a systematic error")
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
        "config": {"itf_drop_height_m": itf_drop_height_m, "itf_rebound_min_m": itf_rebound_min_m,
                   "itf_rebound_max_m": itf_rebound_max_m, "itf_drop_height_tolerance_m": itf_drop_height_tolerance_m,
                   "gravity_m_s2": summary["gravity_m_s2"]},
    }
    return result


def _scale_record(attrs):
    """The length scale of a px recording: source, value, relative se and the other scales' disagreements."""
    if "scale_m_per_px" not in attrs:
        return None
    prefix = "scale_disagreement_"
    return {"source": attrs.get("scale_source", attrs.get("calibration")), "m_per_px": attrs["scale_m_per_px"],
            "rel_se": attrs.get("scale_rel_se", 0.0),
            "disagreement": {key[len(prefix):]: value for key, value in attrs.items() if key.startswith(prefix)},
            "ruler_note": attrs.get("ruler_note")}


def _time_base_record(attrs):
    """A video's capture rate (frames/s), where it came from and why."""
    if "capture_fps" not in attrs:
        return None
    return {"capture_fps": attrs["capture_fps"], "source": attrs.get("capture_fps_source"),
            "note": attrs.get("capture_rate_note")}


def _contact_time(summary, resolvable_rows):
    if not resolvable_rows.empty:
        return {"resolvable": True, "n_impacts": len(resolvable_rows),
                "why": "the floor is known, the sampling resolves the contact and each contact time stands "
                       "well clear of its uncertainty (impacts marked in the impacts table)"}
    if summary["contact_height_source"] == "given":
        why = "the contact times are not resolved: shorter than two sample intervals or than five standard errors"
    else:
        why = ("the floor height is not known, so the contact height was estimated where the flights meet, "
               "which assumes an instantaneous contact: give floor_m to measure contact times")
    return {"resolvable": False, "why": why}


def fit_rows(impacts):
    """Positions (in table order) of the impacts that enter every fit: those with ``in_fit`` true.

    Without an ``in_fit`` column every impact enters; an empty cell counts as true (nothing says to
    leave the impact out), and text (a CSV column with an empty cell is read as text) is true when it
    reads true, 1 or yes.
    """
    if "in_fit" not in impacts:
        return np.arange(len(impacts))

    def entered(flag):
        if pd.isna(flag):
            return True
        return flag.strip().lower() in ("true", "1", "yes") if isinstance(flag, str) else bool(flag)

    return np.flatnonzero([entered(flag) for flag in impacts["in_fit"]])


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


def report(trajectory_path, flights_path, impacts_path, analysis_path, fit_path, html_path, figure_path):
    """Per-recording HTML report and PNG figure."""
    from .report import write_recording_report

    write_recording_report(read_trajectory(trajectory_path), read_flights(flights_path), read_impacts(impacts_path),
                           read_report_analysis(analysis_path), read_fit(fit_path), html_path, figure_path)


def _read_fits(fit_paths):
    """Fit results of the recordings, a failed one as ``{"status": "failed", "error": ..., "sample_id": ...}``
    (the sample id is the name of the fit file's directory)."""
    rows = []
    for path in fit_paths:
        try:
            data = read_fit(path)
        except InputError as error:  # a failure record, or a file that is not a fit result
            data = {"status": "failed", "error": one_line(str(error)), "sample_id": Path(path).parent.name}
        data.setdefault("sample_id", Path(path).parent.name)
        rows.append(data)
    return rows


def summary(fit_paths, csv_path, html_path):
    """Batch summary over recordings: one row per fit result, failed recordings with their message."""
    from .report import batch_report_html, batch_rows

    table = batch_rows(_read_fits(fit_paths))
    with atomic_output(csv_path) as tmp:
        table.to_csv(tmp, index=False, float_format="%.6g")
    write_text(html_path, batch_report_html(table))


def qc(fit_paths, batch, html_path, figure_path, csv_path, ball_ids=None, itf_drop_height_m=ITF_DROP_HEIGHT_M,
       itf_rebound_min_m=ITF_REBOUND_MIN_M, itf_rebound_max_m=ITF_REBOUND_MAX_M):
    """Batch QC report: per-ball table (CSV), control chart (PNG) and HTML page over one batch's recordings.

    ``ball_ids`` names the ball of each fit result (default: every recording is a ball of its own);
    the ITF window is in m.
    """
    from .batch import ball_rows, batch_statistics, failed_recordings
    from .report import batch_rows, qc_chart_png, qc_report_html

    ball_ids = list(ball_ids) if ball_ids else [Path(path).parent.name for path in fit_paths]
    if len(ball_ids) != len(fit_paths):
        raise InputError(f"batch {batch}: {len(ball_ids)} ball ids for {len(fit_paths)} fit results; "
                         f"give one ball id per fit result")
    recordings = batch_rows(_read_fits(fit_paths))
    recordings.insert(1, "ball_id", ball_ids)
    window = {"drop_height_m": itf_drop_height_m, "rebound_min_m": itf_rebound_min_m,
              "rebound_max_m": itf_rebound_max_m}
    balls = ball_rows(recordings, itf_rebound_min_m, itf_rebound_max_m)
    statistics = batch_statistics(balls)
    png = qc_chart_png(batch, recordings, balls, statistics, window)
    with atomic_output(csv_path) as tmp:
        balls.to_csv(tmp, index=False, float_format="%.6g")
    with atomic_output(figure_path) as tmp:
        tmp.write_bytes(png)
    write_text(html_path, qc_report_html(batch, recordings, balls, statistics, failed_recordings(recordings),
                                         window, png))
