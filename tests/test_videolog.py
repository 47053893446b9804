"""A synthetic drop-test video through tracking, calibration and the bounce analysis, against its truth."""

import json

import numpy as np
import pytest

from dropfit.analysis import analyse_bounces
from dropfit.video_synth import make_default_videos
from dropfit.videolog import trajectory_from_video

E_TOLERANCE = 0.005  # dimensionless, per impact (issue 4)
REBOUND_TOLERANCE_M = 0.005  # m
SCALE_TOLERANCE = 0.01  # relative
RULER_SCALE_TOLERANCE = 0.001  # relative (0.1 %)
GRAVITY_SCALE_TOLERANCE = 0.003  # relative (0.3 %; the 0.5° tilt alone gives +0.20 %)


@pytest.mark.slow
def test_default_phone_clip_gives_e_and_rebounds_within_tolerance(tmp_path):
    """The default 240 fps phone clip of a tennis ball from 254 cm (hand, seam, blur, noise, tilt, MJPEG)."""
    name = "phone_240fps_tennis_254cm"
    (video,) = make_default_videos(tmp_path, names=[name])
    truth = json.loads((tmp_path / f"{name}.truth.json").read_text(encoding="utf-8"))
    true_impacts = truth["drop"]["impacts"]
    px_per_m = truth["camera"]["px_per_m"]

    trajectory = trajectory_from_video(video, ball_radius_m=0.0335, ruler_tick_m=0.01)
    attrs = trajectory.attrs
    assert attrs["scale_source"] == "ruler"
    # the 0.5° tilt's keystone makes the image scale vary by ±0.5 % over the frame; a line through the
    # ruler's ticks averages it to −0.026 % of the renderer's px/m
    assert attrs["scale_m_per_px"] == pytest.approx(1 / px_per_m, rel=RULER_SCALE_TOLERANCE)
    # gravity with drag: +0.42 % before drag was fitted; what is left is the keystone's curvature
    assert attrs["scale_gravity_m_per_px"] == pytest.approx(1 / px_per_m, rel=GRAVITY_SCALE_TOLERANCE)
    assert attrs["scale_diameter_m_per_px"] == pytest.approx(1 / px_per_m, rel=SCALE_TOLERANCE)
    assert abs(attrs["scale_disagreement_diameter"]) < 2 * SCALE_TOLERANCE
    assert attrs["capture_fps"] == truth["camera"]["fps"]
    assert attrs["capture_fps_source"] == "container"

    contact = attrs["floor_m"] + 0.0335  # m, centre height at touchdown in the trajectory's frame
    analysis = analyse_bounces(trajectory["time"].values, trajectory["y"].values, contact_height_m=contact)
    impacts = analysis.impacts
    assert len(impacts) >= 2
    for row, true in zip(impacts.itertuples(), true_impacts):
        assert abs(row.e - true["e"]) < E_TOLERANCE
        assert abs(row.h_after_m - true["rebound_height_m"]) < REBOUND_TOLERANCE_M
    # 4.4 ms contacts filmed every 4.2 ms: no contact time may be claimed
    assert not impacts["contact_resolvable"].any()
