"""A synthetic drop-test video through tracking, calibration and the bounce analysis, against its truth."""

import dataclasses
import json

import numpy as np
import pandas as pd
import pytest

from dropfit.analysis import analyse_bounces
from dropfit.synth import simulate_drop
from dropfit.video_synth import default_clips, make_default_videos, render_video
from dropfit.videolog import FLOOR_ROW_SE_PX, find_floor_row, trajectory_from_video

E_TOLERANCE = 0.005  # dimensionless, per impact (issue 4)
REBOUND_TOLERANCE_M = 0.005  # m
SCALE_TOLERANCE = 0.01  # relative
RULER_SCALE_TOLERANCE = 0.001  # relative (0.1 %)
GRAVITY_SCALE_TOLERANCE = 0.003  # relative (0.3 %; the 0.5° tilt gave +0.20 % before its keystone was rectified)
V_IN_RTOL = 0.001  # relative (0.1 %; the keystone read through one scale made impact 1's 0.37 % low)


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
    # the 0.5° tilt's keystone makes the image scale vary by ±0.5 % over the frame: the ruler measures it
    # (the homography's 6.8e-6 1/px), and the scale at the ticks' mean row is the renderer's px/m there
    assert attrs["keystone_per_px"] == pytest.approx(-truth["camera"]["homography"][2][1], rel=0.05)
    assert attrs["scale_m_per_px"] == pytest.approx(1 / px_per_m, rel=RULER_SCALE_TOLERANCE)
    # gravity with drag on the rectified rows: +0.42 % before drag was fitted, +0.20 % before the keystone
    assert attrs["scale_gravity_m_per_px"] == pytest.approx(1 / px_per_m, rel=GRAVITY_SCALE_TOLERANCE)
    assert attrs["scale_diameter_m_per_px"] == pytest.approx(1 / px_per_m, rel=SCALE_TOLERANCE)
    assert abs(attrs["scale_disagreement_diameter"]) < 2 * SCALE_TOLERANCE
    assert attrs["capture_fps"] == truth["camera"]["fps"]
    assert attrs["capture_fps_source"] == "container"

    contact = attrs["floor_m"] + 0.0335  # m, centre height at touchdown in the trajectory's frame
    analysis = analyse_bounces(trajectory["time"].values, trajectory["y"].values, contact_height_m=contact)
    impacts = analysis.impacts
    assert len(impacts) >= 3
    assert impacts["v_in_m_s"].iloc[0] == pytest.approx(true_impacts[0]["v_in_m_s"], rel=V_IN_RTOL)
    for row, true in zip(impacts.itertuples(), true_impacts):
        assert abs(row.e - true["e"]) < E_TOLERANCE
        assert abs(row.h_after_m - true["rebound_height_m"]) < REBOUND_TOLERANCE_M
    # 4.4 ms contacts filmed every 4.2 ms: no contact time may be claimed
    assert not impacts["contact_resolvable"].any()


CONTACT_TIME_TOLERANCE_MS = 0.2  # ms (issue 4)
CONTACT_MODEL_TOLERANCE = 0.10  # relative, k and c (issue 4)
MAX_STANDARD_ERRORS = 4.0  # a result this many of its reported standard errors off the truth is not honest


@pytest.fixture(scope="module", params=[2000.0, 1000.0], ids=["2000fps", "1000fps"])
def closeup_fit(request, tmp_path_factory):
    """The default close-up (at 2000 fps, and the same at 1000 fps) through ``dropfit measure``,
    ``analyse`` and ``fit``; the fit's first impact, the fit result and the generator's truth (first
    impact's contact time and e, the contact model's k and c)."""
    from dropfit.cli import main

    clip = default_clips()["contact_2000fps_closeup"]
    camera = dataclasses.replace(clip["camera"], fps=request.param)
    truth = simulate_drop(**clip["truth"])
    out = tmp_path_factory.mktemp("closeup")
    frames = render_video(truth, camera, clip["scene"], clip["duration_s"], 1, out / "closeup.avi",
                          start_s=clip["start_s"])
    video = frames.attrs["video_path"]
    assert main(["measure", video, "--out", str(out / "t.nc"), "--ball-radius-m", str(truth.radius_m),
                 "--ball-mass-kg", "0.057", "--ball-type", "tennis"]) == 0
    assert main(["analyse", str(out / "t.nc"), "--impacts", str(out / "i.csv"), "--flights", str(out / "f.csv"),
                 "--summary", str(out / "a.json")]) == 0
    assert main(["fit", "--analysis", str(out / "a.json"), "--impacts", str(out / "i.csv"),
                 "--out", str(out / "fit.json"), "--ball-type", "tennis"]) == 0
    impacts = pd.read_csv(out / "i.csv")
    fit = json.loads((out / "fit.json").read_text(encoding="utf-8"))
    first = truth.impacts.iloc[0]
    model = clip["truth"]["contact_model"]
    true_impact = {"contact_time_s": first["t_liftoff_s"] - first["t_s"], "e": first["e"],
                   "stiffness_n_m": model.stiffness_n_m, "damping_n_s_m": model.damping_n_s_m}
    return impacts.iloc[0], fit, true_impact


@pytest.mark.slow
def test_closeup_contact_time_e_k_c_within_tolerance(closeup_fit, capsys):
    """The close-up (ball in view all along, flattened in contact): scale from the ball's diameter (gravity
    over 30 ms is too imprecise), floor found in the image, contact from where the flights cross floor + R.
    Truth: the generator's first impact (contact time, e) and its contact model (k = 30 kN/m, c = 8.2 N·s/m)."""
    impact, fit, true_impact = closeup_fit
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
    true_k, true_c = true_impact["stiffness_n_m"], true_impact["damping_n_s_m"]
    assert k["value"] == pytest.approx(true_k, rel=CONTACT_MODEL_TOLERANCE)
    assert c["value"] == pytest.approx(true_c, rel=CONTACT_MODEL_TOLERANCE)
    assert abs(c["value"] - true_c) <= MAX_STANDARD_ERRORS * c["se"]
    # the floor row's uncertainty (FLOOR_ROW_SE_PX) is in these standard errors
    assert abs(impact["t_contact_ms"] - 1e3 * true_impact["contact_time_s"]) <= MAX_STANDARD_ERRORS * impact["t_contact_se_ms"]
    assert abs(k["value"] - true_k) <= MAX_STANDARD_ERRORS * k["se"]



def _floor_scene(floor_row_px, wall, floor, seed):
    """A 60 x 80 px background: a wall (stripes across, a 2-level grain) with a light ruler strip (dark ticks every 2.5 px) standing on a floor whose edge
    is at ``floor_row_px`` (pixel centres on whole rows), each pixel the area-weighted mix of what
    covers it, and 0.7 grey levels of noise."""
    rng = np.random.default_rng(seed)
    rows, columns = np.mgrid[:60, :80].astype(float)
    scene = wall + 6.0 * np.sin(columns / 3.0) + rng.normal(0.0, 2.0, (60, 80))
    strip = (columns >= 10) & (columns < 22)
    tick = np.abs(((rows + 0.3) / 2.5) % 1.0 - 0.5) > 0.35
    scene[strip] = np.where(tick[strip], wall - 60.0, wall + 80.0)
    below = np.clip(rows + 0.5 - floor_row_px, 0.0, 1.0)  # the part of each pixel under the edge
    scene = (1.0 - below) * scene + below * floor
    return np.clip(np.rint(scene + rng.normal(0.0, 0.7, scene.shape)), 0, 255).astype(np.uint8)


@pytest.mark.parametrize("floor_row_px", [40.0, 40.3, 40.5, 40.77])
@pytest.mark.parametrize(("wall", "floor"), [(110.0, 60.0), (90.0, 170.0)])
def test_floor_edge_is_found_to_a_few_hundredths_of_a_pixel_with_a_ruler_standing_on_it(floor_row_px, wall, floor):
    """The coverage clips' floor read 0.13 px low when the halfway level came from the rows' means
    (a lighter ruler and a textured wall above it): each column's own levels set its crossing."""
    errors = np.array([find_floor_row(_floor_scene(floor_row_px, wall, floor, seed), 38.0, 6.0) - floor_row_px
                       for seed in range(5)])
    assert abs(errors.mean()) < 0.02 and np.abs(errors).max() < FLOOR_ROW_SE_PX, errors


def test_speed_dependent_centre_error_by_codec_and_blur():
    """Closed forms of :func:`dropfit.video.quality.speed_dependent_centre_error_px`: a clip coded with motion
    prediction gets the measured constant; an intra-frame clip MOTION_BLUR_CENTRE_ERROR_FRACTION of its blur at the
    largest step, the blur taken as the whole step when it was not measured, a still ball's anisotropy removed."""
    from dropfit.video.quality import (MOTION_BLUR_CENTRE_ERROR_FRACTION, SPEED_DEPENDENT_CENTRE_ERROR_PX,
                                       speed_dependent_centre_error_px)

    time = np.arange(40) / 30.0
    rows = 0.5 * 3000.0 * time ** 2  # a fall at 3000 px/s²: steps of up to 1500 × 77 / 900 ≈ 128 px
    largest = rows[-1] - rows[-2]
    steps = np.r_[np.diff(rows), np.diff(rows)[-1]]
    half_exposure = 0.5 * steps  # the blur of a frame exposed over half its interval
    assert speed_dependent_centre_error_px("h264", rows, time, half_exposure) == SPEED_DEPENDENT_CENTRE_ERROR_PX
    assert speed_dependent_centre_error_px(None, rows, time) == SPEED_DEPENDENT_CENTRE_ERROR_PX
    assert speed_dependent_centre_error_px("mjpeg", rows, time) == pytest.approx(
        MOTION_BLUR_CENTRE_ERROR_FRACTION * largest)
    measured = speed_dependent_centre_error_px("mjpeg", rows, time, half_exposure)
    assert measured == pytest.approx(MOTION_BLUR_CENTRE_ERROR_FRACTION * 0.5 * largest, rel=0.02)
    # a 3 px anisotropy of every frame, still or not, adds in blur⁴ and is taken off again
    anisotropic = (half_exposure ** 4 + 3.0 ** 4) ** 0.25
    assert speed_dependent_centre_error_px("raw", rows, time, anisotropic) == pytest.approx(measured, rel=0.02)
    # an instantaneous exposure: the anisotropy alone, no error
    assert speed_dependent_centre_error_px("mjpeg", rows, time, np.full(40, 3.0)) == pytest.approx(0.0, abs=1e-9)
    # lost frames (NaN) are skipped, a step over a gap scaled to one interval
    gappy = rows.copy()
    gappy[::3] = np.nan
    assert speed_dependent_centre_error_px("mjpeg", gappy, time) == pytest.approx(
        MOTION_BLUR_CENTRE_ERROR_FRACTION * largest, rel=0.05)


# --- scales that disagree, and slow motion (phonesim, independent of dropfit) ------------------------------

#: The small phonesim clip of the scale tests: a tennis ball (radius 33.5 mm) from 0.4 m before a green wall,
#: 30 frames/s, a fifth of the preset's size (164 px/m): gravity's scale is known to about 2 % only.
SMALL_CLIP = dict(preset="yellow_green_tape", downscale=0.2, duration_s=1.6, drop_height_m=0.4)


def _small_clip(directory, capture_fps=30, **changes):
    """Render :data:`SMALL_CLIP` (held 0.1 s) at ``capture_fps``; (path, truth)."""
    from fractions import Fraction

    import phonesim
    from helpers import phone_clip

    preset = phonesim.PRESETS[SMALL_CLIP["preset"]]
    return phone_clip(SMALL_CLIP["preset"], directory, downscale=SMALL_CLIP["downscale"],
                      duration_s=SMALL_CLIP["duration_s"], drop_height_m=SMALL_CLIP["drop_height_m"],
                      hand=dataclasses.replace(preset.hand, hold_s=0.1),
                      timing=dataclasses.replace(preset.timing, capture_fps=Fraction(capture_fps)), **changes)


def test_a_wrong_ball_radius_is_named_suspect_and_gravity_scales_the_clip(tmp_path):
    """A ball radius given 15 % too large: the diameter's scale is suspect (g known to 0.3 %, a tracked outline
    not), named with its disagreement and likely cause, and gravity's scale is used: the drop height's interval
    holds the truth. Before, gravity's scale (known to 1.8 %) was refused and the diameter's used: 0.459 ±
    0.017 m for a 0.4 m drop."""
    import dropfit

    path, truth = _small_clip(tmp_path)
    radius = truth["physics"]["radius_m"]
    result = dropfit.analyse_recording(path, ball_radius_m=1.15 * radius, ball_mass_kg=truth["physics"]["mass_kg"],
                                       ball_type="tennis")
    scale = result.fit["scale"]
    assert scale["source"] == "gravity" and set(scale["suspect"]) == {"diameter"}
    assert "blur" in scale["suspect"]["diameter"] and "radius" in scale["suspect"]["diameter"]
    assert 0.10 < scale["disagreement"]["diameter"] < 0.20  # the tracked outline itself is a few % off
    assert scale["m_per_px"] == pytest.approx(1 / truth["camera"]["nominal_scale_px_per_m"], rel=3 * scale["rel_se"])
    assert "diameter scale is" in result.summary() and "suspect" in result.summary()
    drop = result.params["drop_height"]
    assert abs(drop.value - truth["physics"]["drop_height_m"]) < 3 * drop.stderr
    assert result.fit["restitution"]["n_impacts"] >= 2
    # without the radius the same clip was refused: "no scale: ... the flights give the scale only to 1.8 %"
    unsized = dropfit.analyse_recording(path, ball_type="tennis")
    assert unsized.fit["scale"]["heights"].startswith("heights from g: scale known to")
    assert unsized.params["e"].value == pytest.approx(result.params["e"].value, abs=0.01)


def _slow_motion_clip(path, capture_fps, file_fps, duration_s=1.0, seed=0):
    """The small clip captured at ``capture_fps`` and stored (MJPEG AVI) at ``file_fps``, as a phone stores slow
    motion: phonesim's frames, written at another rate. Returns phonesim's truth of the impacts (``e`` …)."""
    from fractions import Fraction

    import cv2
    import phonesim
    from phonesim.render import ClipRenderer

    preset = phonesim.PRESETS[SMALL_CLIP["preset"]].scaled(0.25)
    config = dataclasses.replace(preset, duration_s=duration_s, drop_height_m=SMALL_CLIP["drop_height_m"],
                                 hand=dataclasses.replace(preset.hand, hold_s=0.05),
                                 timing=dataclasses.replace(preset.timing, capture_fps=Fraction(capture_fps),
                                                            exposure_s=0.5 / capture_fps))
    width, height = config.frame_size_px
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), file_fps, (width, height))
    renderer = ClipRenderer(config, seed)
    for _, rgb in renderer.frames():
        writer.write(cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR))
    writer.release()
    return renderer.motion.truth.impacts


@pytest.fixture(scope="module")
def slow_motion_1000(tmp_path_factory):
    """1 s captured at 1000 frames/s, stored at 30 frames/s (33 times slow)."""
    path = tmp_path_factory.mktemp("slow") / "slow_1000_in_30.avi"
    return path, _slow_motion_clip(path, 1000, 30.0)


def test_a_slow_motion_clip_without_a_size_is_refused_naming_slow_motion_and_its_capture_rate(slow_motion_1000):
    """Without the ball's radius nothing tells the time base: the refusal says the ball falls about 1100 times
    slower than g, as slow motion does, and names 1000 fps. Before: "no scale ... no flight with at least 5
    samples between bounces"."""
    import dropfit

    path, _ = slow_motion_1000
    with pytest.raises(dropfit.InputError) as refusal:
        dropfit.analyse_recording(path, ball_type="tennis")
    message = str(refusal.value)
    assert "slow-motion" in message and "about 1000 fps" in message and "--capture-fps 1000" in message
    ratio = float(message.split("falls ")[1].split(" times slower")[0])
    assert 900 < ratio < 1300  # (1000 / 30)² = 1111


def test_a_slow_motion_clip_gets_its_capture_rate_from_the_ball_size_and_gives_e(slow_motion_1000):
    """With the ball's radius the capture rate is inferred (1000 fps, snapped) and e is given; given with
    --capture-fps it is the same. Before: "falls with 0.00775 m/s², not g" (the flights found in the file's
    time, 33 times too slow for the segmentation's times)."""
    import dropfit

    path, impacts = slow_motion_1000
    inferred = dropfit.analyse_recording(path, ball_radius_m=0.0335, ball_type="tennis")
    assert inferred.fit["time_base"]["capture_fps"] == 1000.0
    assert inferred.fit["time_base"]["source"] == "inferred from gravity"
    given = dropfit.analyse_recording(path, ball_type="tennis", capture_fps=1000.0)
    assert given.fit["time_base"]["source"] == "given"
    for result in (inferred, given):
        e = result.params["e"]
        assert result.fit["restitution"]["n_impacts"] >= 1
        assert abs(e.value - impacts["e"].iloc[0]) < max(3 * e.stderr, 0.01)


def _white_pingpong():
    from helpers import real_data_dir

    folder = real_data_dir("phone-clips")
    if folder is None or not (folder / "white_pingpong_ruler.mov").is_file():
        pytest.skip("../shared/realdata/phone-clips/white_pingpong_ruler.mov is absent (real clips are kept outside "
                    "the repository)")
    return folder / "white_pingpong_ruler.mov"


@pytest.mark.slow
def test_the_real_pingpong_clip_is_scaled_by_gravity_with_its_diameter_named_suspect():
    """white_pingpong_ruler.mov (30 Hz in a 60 fps MOV, a 40 mm ball): its tracked outline (about 40 px in radius)
    makes a scale 17-19 % coarser than its flights' curvature over g (known to 0.7 % since the tracker keeps the
    ball's apex frames; 4.4 % before), and the clip was refused,
    "the tracked ball falls with 11.8 m/s², not g". Now gravity's scale is used and the diameter named
    suspect with the disagreement; whatever else stops the clip, it is not that."""
    import dropfit
    from dropfit.pipeline import analyse_trajectory, measure_recording, track_recording

    path = _white_pingpong()
    ball = dropfit.Ball(radius_m=0.02, mass_kg=0.0027, type="table_tennis")
    trajectory = measure_recording(path, ball, tracked=track_recording(path, None, ball))
    attrs = trajectory.attrs
    assert attrs["scale_source"] == "gravity" and 0.1 < attrs["scale_disagreement_diameter"] < 0.3
    assert 0.001 < attrs["scale_rel_se"] < 0.1 and "halo" in attrs["scale_suspect_diameter"]
    try:
        analyse_trajectory(trajectory)
    except dropfit.InputError as refusal:
        assert "not g" not in str(refusal)
