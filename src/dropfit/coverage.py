"""Do the reported 95 % intervals cover the truth 95 % of the time? Seeded synthetic trials.

Each trial runs one scenario forwards (:mod:`dropfit.synth`) with its own seed, analyses the log and
fits it exactly as the workflow does (:func:`dropfit.pipeline.analyse_recording`, with the workflow's
defaults), and pairs every reported value and standard error with the
generator's truth: per impact e, impact speeds, rebound heights and contact times; per recording
the drop height, constant e, the e(v) law, the drag parameter, k and c, and the ITF rebound.
"""

from __future__ import annotations

import copy

import numpy as np
import pandas as pd

from .analysis import se_column_name
from .heightlog import make_trajectory
from .balls import ball_kind
from .physics import STANDARD_GRAVITY_M_S2, UNKNOWN_SITE_GRAVITY_SE_M_S2
from .pipeline import analyse_recording
from .restitution import ITF_DROP_HEIGHT_M, Z95
from .synth import simulate_drop, synthesize

#: Short scenarios (a few bounces each) that between them exercise every reported quantity; the
#: 254 cm rebound of the tennis balls is predicted from a constant e and from a linear e(v).
#: ``nominal_drag``: the ball's size and mass are given to the analysis, and the truth's C_d is drawn
#: from the prior the analysis assumes (the ball kind's C_d and its se); otherwise the analysis is not given the
#: mass, so it knows no drag (but a tennis or table-tennis ball's, from its rules' mass:
#: :func:`dropfit.heightlog.nominal_drag_of`). The truth's g is drawn from the spread the analysis assumes for a
#: site it is not told about (:func:`site_gravity_draw`); ``gravity_known``: the site's g is given (as a lab
#: that measured it would give it), so the intervals of the 2 kHz contact scenario are tested without
#: g's share, which would dominate them, and the long rubber log's drag choice without a g error that
#: a free drag would partly absorb.
SCENARIOS = {
    "tennis_drag_150cm": {
        "drop_height_m": 1.5, "duration_s": 3.0, "drag_coefficient": "prior", "nominal_drag": True,
        "ball": {"radius_m": 0.0335, "mass_kg": 0.057, "type": "tennis"},
        "restitution": {"kind": "constant", "e0": 0.76},
        "sensor": {"sample_rate_hz": 100, "noise_m": 0.001, "offset_m": 0.1, "dropout_fraction": 0.01},
    },
    "tennis_e_falls_120cm": {
        "drop_height_m": 1.2, "duration_s": 3.0, "drag_coefficient": "prior", "nominal_drag": True,
        "ball": {"radius_m": 0.0335, "mass_kg": 0.057, "type": "tennis"},
        "restitution": {"kind": "linear", "e0": 0.85, "slope_s_m": 0.015},
        "sensor": {"sample_rate_hz": 100, "noise_m": 0.001, "offset_m": 0.1},
    },
    "steel_weak_drag": {
        "drop_height_m": 0.5, "duration_s": 2.5, "drag_coefficient": "prior", "nominal_drag": True,
        "ball": {"radius_m": 0.0125, "mass_kg": 0.0642, "type": "steel"},
        "restitution": {"kind": "constant", "e0": 0.92},
        "sensor": {"sample_rate_hz": 100, "noise_m": 0.001, "offset_m": 0.0},
    },
    "rubber_no_drag": {
        "drop_height_m": 1.0, "duration_s": 3.0, "drag_coefficient": 0.0, "nominal_drag": False,
        "ball": {"radius_m": 0.025, "mass_kg": 0.05, "type": "rubber"},
        "restitution": {"kind": "constant", "e0": 0.8},
        "sensor": {"sample_rate_hz": 100, "noise_m": 0.001, "offset_m": 0.05},
    },
    "rubber_e_falls": {
        "drop_height_m": 1.5, "duration_s": 4.0, "drag_coefficient": 0.0, "nominal_drag": False,
        "gravity_known": True,
        "ball": {"radius_m": 0.025, "mass_kg": 0.05, "type": "rubber"},
        "restitution": {"kind": "linear", "e0": 0.9, "slope_s_m": 0.03},
        "sensor": {"sample_rate_hz": 100, "noise_m": 0.001, "offset_m": 0.05},
    },
    "tennis_contact_2khz": {
        "drop_height_m": 1.0, "duration_s": 1.6, "drag_coefficient": "prior", "nominal_drag": True,
        "floor_known": True, "gravity_known": True,
        "ball": {"radius_m": 0.0335, "mass_kg": 0.057, "type": "tennis"},
        "contact": {"model": "linear", "stiffness_n_m": 30000, "damping_n_s_m": 8.2},
        "sensor": {"sample_rate_hz": 2000, "noise_m": 0.0001, "offset_m": 0.0},
    },
}


def log_trial(scenario, seed):
    """Analyse one seeded synthetic log of ``scenario`` (a dict as in :data:`SCENARIOS`).

    Returns
    -------
    pairs : pandas.DataFrame
        One row per reported quantity: ``quantity``, ``value``, ``se`` and ``truth`` (SI units).
    fitted : dict
        The fit result, as ``fit.json`` holds it (:func:`dropfit.pipeline.fit_analysis`: chosen models and why).
    """
    rng = np.random.default_rng(seed)
    scenario = copy.deepcopy(scenario)
    if scenario["drag_coefficient"] == "prior":  # the truth drawn from the prior the analysis assumes
        kind = ball_kind(scenario["ball"]["type"])
        scenario["drag_coefficient"] = kind.drag_coefficient + kind.drag_coefficient_se * rng.standard_normal()
    scenario["gravity_m_s2"] = site_gravity_draw(rng)
    log, truth = synthesize(scenario, int(rng.integers(2**31)))
    ball = scenario["ball"]
    trajectory = make_trajectory(log["time_s"].to_numpy(), log["y_m"].to_numpy(), f"coverage log (seed {seed})",
                                 "synthetic log in m")
    result = analyse_recording(
        trajectory, ball_radius_m=ball["radius_m"], ball_type=ball["type"],
        ball_mass_kg=ball["mass_kg"] if scenario["nominal_drag"] or "contact" in scenario else None,
        floor_m=scenario["sensor"].get("offset_m", 0.0) if scenario.get("floor_known") else None,
        gravity_m_s2=scenario["gravity_m_s2"] if scenario.get("gravity_known") else None)
    return (pd.DataFrame(_pairs(scenario, truth, result.analysis, result.fit), columns=["quantity", "value", "se", "truth"]),
            result.fit)


def site_gravity_draw(rng):
    """g in m/s² of a site the analysis is not told about, drawn from the spread it then assumes
    (standard gravity ± :data:`dropfit.physics.UNKNOWN_SITE_GRAVITY_SE_M_S2`)."""
    return STANDARD_GRAVITY_M_S2 + UNKNOWN_SITE_GRAVITY_SE_M_S2 * rng.standard_normal()


def _pairs(scenario, truth, analysis, fitted):
    """(quantity, value, se, truth) of everything the analysis and the fit report."""
    impacts = analysis.impacts
    # impacts are matched by their numbers from the release; a trial whose touchdowns do not line up is reported
    true_impacts = pd.DataFrame(truth["impacts"]).iloc[impacts["impact"].to_numpy() - 1].reset_index(drop=True)
    matched = np.abs(impacts["t_touchdown_s"].to_numpy() - true_impacts["t_s"].to_numpy()) < 0.01
    if not matched.all():
        raise AssertionError(f"analysed touchdowns do not match the truth: {impacts['t_touchdown_s'].tolist()}")
    rows = []
    for column, true_column in (("e", "e"), ("v_in_m_s", "v_in_m_s"), ("v_out_m_s", "v_out_m_s"),
                                ("h_after_m", "rebound_height_m")):
        rows += [(column, v, s, t) for v, s, t in zip(impacts[column], impacts[se_column_name(column)], true_impacts[true_column])]
    resolvable = impacts["contact_resolvable"].to_numpy()
    rows += [("t_contact_s", 1e-3 * v, 1e-3 * s, t) for v, s, t, ok in zip(
        impacts["t_contact_ms"], impacts["t_contact_se_ms"], true_impacts["contact_time_s"], resolvable) if ok]
    rows.append(("drop_height_m", fitted["drop_height_m"]["value"], fitted["drop_height_m"]["se"],
                 truth["drop_height_m"]))
    law = scenario.get("restitution", {})
    models = fitted["restitution_models"]
    if law.get("kind") == "constant":
        e0 = models["constant"]["parameters"]["e0"]
        rows.append(("e_constant", e0["value"], e0["se"], law["e0"]))
    if law.get("kind") == "linear" and "linear" in models:
        parameters = models["linear"]["parameters"]
        rows += [(f"e_linear_{name}", parameters[name]["value"], parameters[name]["se"], law[key])
                 for name, key in (("e0", "e0"), ("slope_s_m", "slope_s_m"))]
    if fitted["drag"]["model"] != "none":
        rows.append(("drag_k_per_m", fitted["drag"]["k_per_m"]["value"], fitted["drag"]["k_per_m"]["se"],
                     truth["drag_k_per_m"]))
    contact = scenario.get("contact")
    if contact and fitted["contact_model"]:
        rows += [(name, fitted["contact_model"][name]["value"], fitted["contact_model"][name]["se"], contact[name])
                 for name in ("stiffness_n_m", "damping_n_s_m")]
    if fitted["itf"].get("rebound_m") and law.get("kind"):
        rows.append(("itf_rebound_m", fitted["itf"]["rebound_m"]["value"], fitted["itf"]["rebound_m"]["se"],
                     _itf_truth(scenario)))
    return rows


def _itf_truth(scenario):
    """First rebound in m of the scenario's ball dropped from the ITF height."""
    ball = scenario["ball"]
    drop = simulate_drop(ITF_DROP_HEIGHT_M, ball["radius_m"], scenario["restitution"], mass_kg=ball["mass_kg"],
                         drag_coefficient=scenario["drag_coefficient"], gravity_m_s2=scenario["gravity_m_s2"],
                         max_time_s=1.5)
    return float(drop.impacts["rebound_height_m"].iloc[0])


def coverage_table(trials):
    """Coverage of the 95 % intervals per quantity.

    Parameters
    ----------
    trials : pandas.DataFrame
        Rows of :func:`log_trial` (any number of trials), optionally with a ``scenario`` column.

    Returns
    -------
    pandas.DataFrame
        Per (scenario,) quantity: ``n`` pairs, ``coverage`` (fraction with |value − truth| ≤ 1.96 se),
        ``mean_z`` and ``std_z`` of (value − truth)/se.
    """
    z = (trials["value"] - trials["truth"]) / trials["se"]
    table = trials.assign(z=z, covered=np.abs(z) <= Z95)
    keys = [key for key in ("scenario", "quantity") if key in table]
    return table.groupby(keys).agg(n=("z", "size"), coverage=("covered", "mean"), mean_z=("z", "mean"),
                                   std_z=("z", "std")).reset_index()


#: A small, short, low-resolution clip for video coverage trials: a tennis ball dropped from 1 m,
#: filmed at 120 fps on a 48 × 200 px sensor (160 px/m) with noise and MJPEG, no motion blur.
VIDEO_SCENARIO = {"drop_height_m": 1.0, "radius_m": 0.0335, "mass_kg": 0.057, "e0": 0.76, "release_time_s": 0.05,
                  "duration_s": 1.6, "width_px": 48, "height_px": 200, "fps": 120.0, "px_per_m": 160.0,
                  "image_row_of_floor_px": 192.0, "noise_sigma": 2.0, "quality": 90}


def video_trial(seed, directory, scenario=None, floor_known=True):
    """Render, track and analyse one seeded synthetic clip (written into ``directory``, then removed).

    The clip goes through :func:`dropfit.pipeline.analyse_recording` as the workflow runs a video: the
    scale is given (as a ruler calibration would give it) and so is the floor (``floor_m``, as a rig
    that measured it would give it; with ``floor_known`` false it is found in the image, the
    workflow's default for a video without ``floor_m``, then at a sub-pixel row drawn per seed), and
    e and the rebound heights are tested;
    contact times are not resolvable at 120 fps. The ball's mass is not given (the rendered ball
    flies without drag); the site's g is drawn as in :func:`log_trial`. The e0 of the ball is drawn per seed from 0.70–0.80 so that the clips differ
    in more than their pixel noise.

    Raises
    ------
    dropfit.errors.InputError
        When dropfit refuses the clip (as the workflow would).

    Returns
    -------
    pandas.DataFrame
        As :func:`log_trial`: ``quantity``, ``value``, ``se``, ``truth`` (per impact e and rebound height).
    """
    from pathlib import Path

    from .video_synth import Camera, Scene, render_video

    spec = dict(VIDEO_SCENARIO, **(scenario or {}))
    rng = np.random.default_rng(seed)
    e0 = float(rng.uniform(0.70, 0.80))
    truth = simulate_drop(spec["drop_height_m"], spec["radius_m"], {"kind": "constant", "e0": e0},
                          mass_kg=spec["mass_kg"], release_time_s=spec["release_time_s"],
                          gravity_m_s2=site_gravity_draw(rng))
    # a floor to be found lies anywhere within its pixel row (a whole row is half-covered, found exactly)
    floor_row_px = spec["image_row_of_floor_px"] + (0.0 if floor_known else float(rng.uniform(-0.5, 0.5)))
    camera = Camera(spec["width_px"], spec["height_px"], spec["fps"], 0.0, px_per_m=spec["px_per_m"],
                    image_row_of_floor_px=floor_row_px, noise_sigma=spec["noise_sigma"], quality=spec["quality"])
    scene = Scene(ruler_column_px=2.0, ruler_width_px=6.0, ruler_top_m=spec["drop_height_m"] + 0.2)
    path = Path(directory) / f"coverage_{seed}.avi"
    frames = render_video(truth, camera, scene, spec["duration_s"], seed, path)
    try:
        floor_m = -floor_row_px / spec["px_per_m"] if floor_known else None  # heights: −row × scale
        analysis = analyse_recording(frames.attrs["video_path"], ball_radius_m=spec["radius_m"],
                                     scale_m_per_px=1.0 / spec["px_per_m"], floor_m=floor_m).analysis
    finally:
        Path(frames.attrs["video_path"]).unlink()
    impacts = analysis.impacts
    true_impacts = truth.impacts.iloc[impacts["impact"].to_numpy() - 1]  # numbered from the release
    if np.any(np.abs(impacts["t_touchdown_s"].to_numpy() - true_impacts["t_s"].to_numpy()) > 0.02):
        raise AssertionError(f"analysed touchdowns do not match the truth: {impacts['t_touchdown_s'].tolist()}")
    rows = [("e", v, s, t) for v, s, t in zip(impacts["e"], impacts["e_se"], true_impacts["e"])]
    rows += [("h_after_m", v, s, t) for v, s, t in zip(impacts["h_after_m"], impacts["h_after_se_m"],
                                                        true_impacts["rebound_height_m"])]
    return pd.DataFrame(rows, columns=["quantity", "value", "se", "truth"])
