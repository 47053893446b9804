"""Clips as phones film them (phonesim, an independent generator): dropfit's numbers against its truth.

phonesim renders with refsim's physics, H.264 or MPEG-4 through PyAV, and what real clips showed
(colour balls on near-isoluminant walls, shadows touching the ball, a hand holding and releasing it,
rotation metadata, repeated frames, flicker, rulers and tapes with ticks on whole pixel rows, ArUco
markers, a tilted camera). The tests hold dropfit to the issue's bar: e per impact within ±0.005 and
inside its 95 % interval, rebound heights within ±5 mm, the scale within 0.5 %.
"""

import math

import numpy as np
import pandas as pd
import pytest

import dropfit
from dropfit.video.targets import to_plane
from helpers import phone_clip

#: |e − e_true| allowed per impact, and |h − h_true| for rebound heights, m (the issue's bar).
E_TOLERANCE = 0.005
HEIGHT_TOLERANCE_M = 0.005
SCALE_TOLERANCE = 0.005


def _compare(result, truth, impacts_checked):
    """Per analysed impact: the truth's e and rebound height beside dropfit's."""
    true_impacts = pd.DataFrame(truth["physics"]["impacts"])
    impacts = result.impacts.head(impacts_checked)
    nearest = [int(np.argmin(np.abs(true_impacts["t_touchdown_s"].to_numpy() - t))) for t in impacts["t_touchdown_s"]]
    true = true_impacts.iloc[nearest].reset_index(drop=True)
    return pd.DataFrame({"e": impacts["e"].to_numpy(), "e_low": impacts["e_ci95_low"].to_numpy(),
                         "e_high": impacts["e_ci95_high"].to_numpy(), "e_true": true["e"].to_numpy(),
                         "h": impacts["h_after_m"].to_numpy(), "h_true": true["h_after_m"].to_numpy()})


def _check(result, truth, impacts_checked):
    table = _compare(result, truth, impacts_checked)
    assert len(table) == impacts_checked, result.impacts
    assert np.all(np.abs(table["e"] - table["e_true"]) <= E_TOLERANCE), table
    assert np.all((table["e_low"] <= table["e_true"]) & (table["e_true"] <= table["e_high"])), table
    assert np.all(np.abs(table["h"] - table["h_true"]) <= HEIGHT_TOLERANCE_M), table
    return table


def _vertical_px_per_m_at_floor(attrs, truth):
    """px per m up the drop line at the truth's floor point, as the trajectory's calibration has it: through
    a plane target's map (its ``plane_homography``, ``plane_down``) or the one scale."""
    if "plane_homography" not in attrs:
        return 1.0 / attrs["scale_m_per_px"]
    homography = np.reshape(attrs["plane_homography"], (3, 3))
    floor_px = np.array(truth["camera"]["floor_px_at_drop_line"])
    step_m = 0.01  # a cm up the plane's vertical
    floor_m = to_plane(homography, floor_px)[0]
    above_px = to_plane(np.linalg.inv(homography), floor_m - step_m * np.asarray(attrs["plane_down"]))[0]
    return float(np.hypot(*(above_px - floor_px))) / step_m


#: What stops each preset today, measured (issue 10 is open until these pass; strict, so a fix shows).
GREY_TRACKER_FAILS_YELLOW = ("the tracker works in grey levels: a yellow ball a few grey levels from a grey wall is "
                             "measured cleanly in 1 % of the frames and the clip is refused")
GREY_TRACKER_FAILS_CLUTTER = ("the cluttered, tilted clip's ball is measured cleanly in too few frames for three "
                              "impacts (the plane map itself is right on the truth's centres: tests/test_markers.py)")


@pytest.mark.parametrize("preset, options, impacts_checked", [
    pytest.param("yellow_flicker_portrait_120", {"ruler_tick_m": 0.01}, 3,
                 marks=pytest.mark.xfail(strict=True, reason=GREY_TRACKER_FAILS_YELLOW)),
    pytest.param("tennis_aruco_tilted", {"marker_size_m": 0.08}, 3,
                 marks=pytest.mark.xfail(strict=True, reason=GREY_TRACKER_FAILS_CLUTTER)),
])
def test_phone_clip_numbers(tmp_path, preset, options, impacts_checked):
    path, truth = phone_clip(preset, tmp_path, seed=3, downscale=0.5)
    physics = truth["physics"]
    result = dropfit.analyse_recording(path, ball_radius_m=physics["radius_m"], ball_mass_kg=physics["mass_kg"],
                                       ball_type=physics["ball_model"], **options)
    _check(result, truth, impacts_checked)
    assert math.isclose(_vertical_px_per_m_at_floor(result.trajectory.attrs, truth),
                        float(np.hypot(*truth["camera"]["vertical_px_per_m_at_drop_line"])), rel_tol=SCALE_TOLERANCE)
