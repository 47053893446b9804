"""A synthetic drop-test video through tracking, calibration and the bounce analysis, against its truth."""

import json

import numpy as np
import pandas as pd
import pytest

from dropfit.analysis import analyse_bounces
from dropfit.video_synth import make_default_videos
from dropfit.videolog import trajectory_from_video

E_TOLERANCE = 0.005  # dimensionless, per impact (issue 4)
REBOUND_TOLERANCE_M = 0.005  # m
SCALE_TOLERANCE = 0.01  # relative


@pytest.mark.slow
def test_default_phone_clip_gives_e_and_rebounds_within_tolerance(tmp_path):
    """The default 240 fps phone clip of a tennis ball from 254 cm (hand, seam, blur, noise, tilt, MJPEG)."""
    name = "phone_240fps_tennis_254cm"
    (video,) = make_default_videos(tmp_path, names=[name])
    truth = json.loads((tmp_path / f"{name}.truth.json").read_text(encoding="utf-8"))
    true_impacts = truth["drop"]["impacts"]
    px_per_m = truth["camera"]["px_per_m"]

    trajectory = trajectory_from_video(video, ball_radius_m=0.0335)
    attrs = trajectory.attrs
    assert attrs["scale_m_per_px"] == pytest.approx(1 / px_per_m, rel=SCALE_TOLERANCE)
    assert attrs["scale_diameter_m_per_px"] == pytest.approx(1 / px_per_m, rel=SCALE_TOLERANCE)
    assert abs(attrs["scale_disagreement"]) < 2 * SCALE_TOLERANCE

    contact = attrs["floor_m"] + 0.0335  # m, centre height at touchdown in the trajectory's frame
    analysis = analyse_bounces(trajectory["time"].values, trajectory["y"].values, contact_height_m=contact)
    impacts = analysis.impacts
    assert len(impacts) >= 2
    for row, true in zip(impacts.itertuples(), true_impacts):
        assert abs(row.e - true["e"]) < E_TOLERANCE
        assert abs(row.h_after_m - true["rebound_height_m"]) < REBOUND_TOLERANCE_M
    # 4.4 ms contacts filmed every 4.2 ms: no contact time may be claimed
    assert not impacts["contact_resolvable"].any()


CONTACT_TIME_TOLERANCE_MS = 0.2  # ms (issue 4)
CONTACT_MODEL_TOLERANCE = 0.10  # relative, k and c (issue 4)
MAX_STANDARD_ERRORS = 4.0  # a result this many of its reported standard errors off the truth is not honest


@pytest.fixture(scope="module")
def closeup_fit(tmp_path_factory):
    """The default 2000 fps close-up through ``dropfit measure``, ``analyse`` and ``fit``, and its truth."""
    from dropfit.cli import main

    name = "contact_2000fps_closeup"
    out = tmp_path_factory.mktemp("closeup")
    (video,) = make_default_videos(out, names=[name])
    truth = json.loads((out / f"{name}.truth.json").read_text(encoding="utf-8"))
    ball = truth["scene"]["ball_radius_m"]
    assert main(["measure", str(video), "--out", str(out / "t.nc"), "--ball-radius-m", str(ball),
                 "--ball-mass-kg", "0.057", "--ball-type", "tennis"]) == 0
    assert main(["analyse", str(out / "t.nc"), "--impacts", str(out / "i.csv"), "--flights", str(out / "f.csv"),
                 "--summary", str(out / "a.json")]) == 0
    assert main(["fit", "--analysis", str(out / "a.json"), "--impacts", str(out / "i.csv"),
                 "--out", str(out / "fit.json"), "--ball-type", "tennis"]) == 0
    impacts = pd.read_csv(out / "i.csv")
    fit = json.loads((out / "fit.json").read_text(encoding="utf-8"))
    return impacts.iloc[0], fit, truth


@pytest.mark.slow
def test_closeup_contact_time_e_k_c_within_tolerance(closeup_fit, capsys):
    """The close-up (ball in view all along, flattened in contact): scale from the ball's diameter (gravity
    over 30 ms is too imprecise), floor found in the image, contact from where the flights cross floor + R."""
    impact, fit, truth = closeup_fit
    true_impact = truth["drop"]["impacts"][0]
    model = fit["contact_model"]
    k, c = model["stiffness_n_m"], model["damping_n_s_m"]
    with capsys.disabled():
        print(f"\n[closeup] t_contact {impact['t_contact_ms']:.5f} ± {impact['t_contact_se_ms']:.5f} ms "
              f"(truth {1e3 * true_impact['contact_time_s']:.5f}); e {impact['e']:.6f} ± {impact['e_se']:.6f} "
              f"(truth {true_impact['e']:.6f}); k {k['value']:.1f} ± {k['se']:.1f} N/m; "
              f"c {c['value']:.4f} ± {c['se']:.4f} N·s/m; {fit['calibration']}")
    assert fit["calibration"] == "scale from the ball's diameter"
    assert bool(impact["contact_resolvable"])
    assert abs(impact["t_contact_ms"] - 1e3 * true_impact["contact_time_s"]) <= CONTACT_TIME_TOLERANCE_MS
    assert abs(impact["e"] - true_impact["e"]) <= E_TOLERANCE
    assert abs(impact["e"] - true_impact["e"]) <= MAX_STANDARD_ERRORS * impact["e_se"]
    assert k["value"] == pytest.approx(30000.0, rel=CONTACT_MODEL_TOLERANCE)
    assert c["value"] == pytest.approx(8.2, rel=CONTACT_MODEL_TOLERANCE)
    assert abs(c["value"] - 8.2) <= MAX_STANDARD_ERRORS * c["se"]


@pytest.mark.slow
@pytest.mark.xfail(strict=True, reason="the contact time's standard error is statistical only: the ~0.015 px "
                                       "bias of the tracked centre against the floor edge (≈1.4 µs) is not in it")
def test_closeup_contact_time_and_k_within_their_standard_errors(closeup_fit):
    impact, fit, truth = closeup_fit
    true_impact = truth["drop"]["impacts"][0]
    k = fit["contact_model"]["stiffness_n_m"]
    assert abs(impact["t_contact_ms"] - 1e3 * true_impact["contact_time_s"]) <= MAX_STANDARD_ERRORS * impact["t_contact_se_ms"]
    assert abs(k["value"] - 30000.0) <= MAX_STANDARD_ERRORS * k["se"]
