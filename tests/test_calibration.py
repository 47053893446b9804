"""Video calibration: ruler scale, scale precedence and disagreement, capture rate from gravity,
against the renderer's known image scale and frame rate."""

import xml.etree.ElementTree as ElementTree
import zipfile

import cv2
import numpy as np
import pytest
from helpers import real_data_dir, ruler_image

from dropfit.analysis import analyse_bounces
from dropfit.video.calibrate import (CAPTURE_RATE_SNAP_TOLERANCE, COMMON_CAPTURE_RATES_FPS, SCALE_PRECEDENCE,
                                     choose_scale, infer_capture_rate, keystoned_rows, mark_numbers, rectify_rows,
                                     ruler_scale, slow_motion_reading)
from dropfit.physics import STANDARD_GRAVITY_M_S2
from dropfit.synth import simulate_drop
from dropfit.video_synth import Camera, FrameRenderer, Scene, default_clips, render_background
from dropfit.video.track import track_video_and_background
from dropfit.videolog import trajectory_from_video

#: The ruler's scale must match the renderer's px/m to this relative accuracy.
RULER_SCALE_RTOL = 1e-3  # 1 (0.1 %)
#: ... and lie within this many of its own standard errors of it.
RULER_ERROR_IN_SE = 4.0  # 1
#: The gravity scale of the small test clip (short flights, 0.55 m drop) must be this close to the truth.
CLIP_GRAVITY_SCALE_RTOL = 0.01  # 1 (1 %)

#: A small, fast clip: a rubber ball dropped from 0.55 m beside a cm ruler, 700 px/m, 240 fps capture.
PX_PER_M = 700.0  # px/m
CAPTURE_FPS = 240.0  # frames/s
BALL = dict(drop_height_m=0.55, radius_m=0.02, mass_kg=0.05, restitution_model={"kind": "constant", "e0": 0.8},
            release_time_s=0.05)


def _grey(image_bgr):
    return cv2.cvtColor(np.clip(image_bgr, 0, 255).astype(np.uint8), cv2.COLOR_BGR2GRAY)


def write_clip(path, container_fps, duration_s=1.0, scene=None, seed=0):
    """Render the small clip captured at CAPTURE_FPS and store it as MJPEG AVI at ``container_fps``."""
    camera = Camera(200, 480, CAPTURE_FPS, px_per_m=PX_PER_M, image_row_of_floor_px=460.0, noise_sigma=2.0,
                    quality=90)
    renderer = FrameRenderer(simulate_drop(**BALL), camera, scene or Scene(), seed)
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), container_fps, (200, 480))
    for index in range(int(round(duration_s * CAPTURE_FPS))):
        writer.write(renderer.render(index)[0])
    writer.release()
    return path


@pytest.fixture(scope="module")
def slow_motion_clip(tmp_path_factory):
    """The small clip, captured at 240 fps and stored as a 30 fps file (8× slow motion)."""
    return write_clip(tmp_path_factory.mktemp("calibration") / "slow_motion.avi", container_fps=30.0)


def test_ruler_scale_from_a_rendered_video_matches_px_per_m(slow_motion_clip):
    """Through MJPEG and noise: 1 cm ticks 7 px apart, the count checked against the 10 cm ticks, read off
    the background the tracker built (as the video path reads it)."""
    ruler, note = ruler_scale(track_video_and_background(slow_motion_clip).background.image(), 0.01)
    assert ruler is not None, note
    assert ruler.ticks_per_step == 1
    error = ruler.scale_m_per_px * PX_PER_M - 1.0
    assert abs(error) < RULER_SCALE_RTOL
    assert abs(error) < RULER_ERROR_IN_SE * ruler.scale_se_m_per_px * PX_PER_M


def test_ruler_with_unresolved_fine_ticks_uses_the_5_and_10_cm_marks():
    """At 250 px/m the 1 cm ticks are 2.5 px apart: the 5 cm ticks carry the scale, 5 ticks per step."""
    camera = default_clips()["phone_240fps_tennis_254cm"]["camera"]
    flat = Camera(camera.width_px, camera.height_px, px_per_m=camera.px_per_m,
                  image_row_of_floor_px=camera.image_row_of_floor_px)
    ruler, note = ruler_scale(_grey(render_background(flat, Scene(ruler_top_m=2.75))), 0.01)
    assert ruler is not None, note
    assert ruler.ticks_per_step == 5
    assert ruler.scale_m_per_px * camera.px_per_m == pytest.approx(1.0, rel=RULER_SCALE_RTOL)


#: Drawn rulers: the scale must be within this of the truth ...
DRAWN_RULER_RTOL = 0.005  # 1 (0.5 %)
MM_TICKS = ((1, 0.25), (5, 0.4), (10, 0.6))  # mm, half-cm and cm ticks: (every, length / ruler width)
#: name → (ruler_image arguments, tick_m, expected marks, finest ticks per fitted step)
DRAWN_RULERS = {
    "green mm ruler with numbers, mm unresolved": (
        dict(px_per_m=1537.3, length_m=0.3, tick_m=0.001, tick_levels=MM_TICKS, numbers_every=10, tick_width_px=0.6),
        0.001, "ticks, count checked", 5),
    "green mm ruler on a green wall": (
        dict(px_per_m=4312.7, length_m=0.1, tick_m=0.001, tick_levels=MM_TICKS, numbers_every=10, tick_width_px=0.8,
             wall_bgr=(60, 140, 70)), 0.001, "ticks, count checked", None),
    "cm ruler, ticks on whole rows 4-5 px apart": (
        dict(px_per_m=447.0, length_m=1.0, tick_m=0.01, tick_levels=((1, 0.3), (5, 0.5), (10, 0.8)), whole_rows=True,
             face_bgr=(230, 230, 230), wall_bgr=(120, 120, 120), blur_px=0.0, noise=2.0), 0.01, "ticks, count checked", 1),
    "yellow tape measure lying, black marks and numbers": (
        dict(px_per_m=2113.0, length_m=0.25, tick_m=0.001, tick_levels=((1, 0.2), (5, 0.3), (10, 0.45)),
             numbers_every=10, face_bgr=(30, 210, 235), wall_bgr=(90, 100, 110), lying=True, tick_width_px=0.6),
        0.001, "ticks, count checked", 5),
    "metre stick in red and white 10 cm bands on a dark wall": (
        dict(px_per_m=398.7, length_m=1.0, tick_m=0.1, tick_levels=(), bands=True, face_bgr=(240, 240, 240),
             mark_bgr=(40, 40, 200), wall_bgr=(30, 30, 30), width_px=12), 0.1, "band edges", 1),
    "banded stick lying on a green wall": (
        dict(px_per_m=612.3, length_m=1.0, tick_m=0.1, tick_levels=(), bands=True, face_bgr=(240, 240, 240),
             mark_bgr=(40, 40, 200), wall_bgr=(160, 180, 150), width_px=14, lying=True), 0.1, "band edges", 1),
}


@pytest.mark.parametrize("name", DRAWN_RULERS)
def test_drawn_rulers_of_any_colour_and_orientation_give_the_scale(name):
    """Rulers drawn from the truth (blur, noise, numbers): the scale within 0.5 % and within
    RULER_ERROR_IN_SE of its own standard error."""
    drawing, tick_m, marks, per_step = DRAWN_RULERS[name]
    ruler, note = ruler_scale(ruler_image(**drawing), tick_m)
    assert ruler is not None, note
    assert ruler.marks == marks
    assert per_step is None or ruler.ticks_per_step == per_step
    assert ruler.orientation == ("lying" if drawing.get("lying") else "upright")
    error = ruler.scale_m_per_px * drawing["px_per_m"] - 1.0
    assert abs(error) < DRAWN_RULER_RTOL
    assert abs(error) < RULER_ERROR_IN_SE * ruler.scale_se_m_per_px * drawing["px_per_m"]


def test_mark_numbers_do_not_drift_on_whole_pixel_steps():
    """Marks 4.47 px apart rounded to whole rows (steps of 4 and 5): numbered 0 … n−1, spacing 4.47."""
    rows = np.rint(3.2 + 4.47 * np.arange(60))
    kept, numbers, spacing = mark_numbers(rows)
    assert np.array_equal(numbers, np.arange(60))
    assert spacing == pytest.approx(4.47, abs=0.02)
    kept, numbers, _ = mark_numbers(np.delete(rows, [10, 11]))  # two missing marks keep their numbers
    assert numbers[10] == 12


#: The real clip's stick must agree with Tracker's hand calibration within this many of their
#: combined standard errors.
REAL_SCALE_AGREEMENT_IN_SE = 2.0  # 1
#: Standard error of each end of a hand-placed Tracker calibration stick, px.
HAND_POINT_SE_PX = 1.0  # px


def _tracker_calibration(trz_path):
    """(px per m of Tracker's coordinate system, ends of its calibration stick in px) from a .trz project."""
    with zipfile.ZipFile(trz_path) as archive:
        name = next(item for item in archive.namelist() if item.endswith(".trk"))
        root = ElementTree.fromstring(archive.read(name))
    values = {item.get("name"): float(item.text) for item in root.iter("property")
              if item.get("type") == "double" and item.get("name") in ("xscale", "x1", "y1", "x2", "y2")}
    return values["xscale"], np.array([[values["x1"], values["y1"]], [values["x2"], values["y2"]]])


def test_real_clip_stick_scale_agrees_with_trackers_hand_calibration():
    """Tracker's BallToss clip (640 x 480 H.264): the metre stick's 10 cm marks, found automatically in the
    per-pixel median of the frames, against Tracker's calibration stick placed by hand (398.7 px/m)."""
    folder = real_data_dir("tracker-balltoss")
    if folder is None:
        pytest.skip("the real data folder ../shared/realdata/tracker-balltoss is absent (set DROPFIT_REALDATA)")
    import av

    with av.open(str(folder / "BallTossOut.mp4")) as container:
        frames = [frame.to_ndarray(format="bgr24") for frame in container.decode(video=0)]
    background = np.median(np.stack(frames[::2]), axis=0).astype(np.uint8)  # the hand and ball leave
    ruler, note = ruler_scale(background, 0.1)
    assert ruler is not None, note
    tracker_px_per_m, ends = _tracker_calibration(folder / "BallToss.trz")
    stick_px = float(np.hypot(*(ends[1] - ends[0])))
    assert tracker_px_per_m == pytest.approx(stick_px, rel=1e-6)  # the stick is 1 m
    tracker_rel_se = np.sqrt(2.0) * HAND_POINT_SE_PX / stick_px  # two ends placed by hand
    found_px_per_m = 1.0 / ruler.scale_m_per_px
    combined = np.hypot(tracker_rel_se, ruler.scale_se_m_per_px / ruler.scale_m_per_px)
    assert abs(found_px_per_m / tracker_px_per_m - 1.0) < REAL_SCALE_AGREEMENT_IN_SE * combined


def test_no_ruler_is_said_not_raised():
    """A textured background without a ruler gives no scale and a sentence saying so."""
    camera = Camera(320, 240, px_per_m=500.0, image_row_of_floor_px=230.0)
    background = _grey(render_background(camera, Scene(ruler_width_px=0.0, background_texture=8.0)))
    ruler, note = ruler_scale(background, 0.01)
    assert ruler is None
    assert note.startswith("no ruler")


def test_choose_scale_follows_the_precedence_and_reports_each_disagreement():
    scales = {"diameter": (0.00101, 1e-6), "gravity": (0.00099, 1e-7), "ruler": (0.00100, 2e-7)}
    chosen, disagreement, suspects = choose_scale(scales)
    assert chosen == "ruler" and suspects == {}
    assert disagreement == pytest.approx({"diameter": 0.01, "gravity": -0.01})
    assert choose_scale({**scales, "given": (0.002, 0.0)})[0] == "given"
    assert choose_scale({"diameter": scales["diameter"], "gravity": scales["gravity"]})[0] == "gravity"
    assert SCALE_PRECEDENCE == ("given", "points", "target", "ruler", "gravity", "diameter")


def test_g_arbitrates_a_diameter_or_ruler_that_disagrees_with_it():
    """A diameter 19 % off gravity's scale (known to 4.4 %, as on white_pingpong_ruler.mov, where the tracked ball
    fell with 11.8 m/s² through its diameter) is suspect and not used; so is a ruler 15 % off a precise gravity
    scale, with the cause named; a given scale is used as stated. Before, the diameter was used and the clip
    refused."""
    gravity = (0.000409, 0.000409 * 0.044)
    chosen, disagreement, suspects = choose_scale({"diameter": (0.000487, 0.000487 * 0.02), "gravity": gravity})
    assert chosen == "gravity" and disagreement["diameter"] == pytest.approx(0.19, abs=0.005)
    assert "halo" in suspects["diameter"] and "blur" in suspects["diameter"]
    chosen, _, suspects = choose_scale({"ruler": (0.00115, 1e-6), "gravity": (0.001, 2e-6),
                                        "diameter": (0.00101, 2e-5)})
    assert chosen == "gravity" and set(suspects) == {"ruler"} and "plane" in suspects["ruler"]
    assert choose_scale({"given": (0.00115, 0.0), "gravity": (0.001, 2e-6)})[0] == "given"


def test_an_imprecise_gravity_scale_comes_before_an_agreeing_diameter():
    """Gravity known to 5 % and a diameter known to 2 %, 8 % apart (within 3 standard errors): gravity's scale is
    used (e takes no bias from it) and the diameter is reported, not suspect. Before, gravity's scale was refused
    above 1 %."""
    chosen, disagreement, suspects = choose_scale({"diameter": (0.00108, 2.16e-5), "gravity": (0.001, 5e-5)})
    assert chosen == "gravity" and suspects == {} and disagreement["diameter"] == pytest.approx(0.08)


@pytest.mark.parametrize("capture_fps, file_fps", [(1000.0, 30.0), (240.0, 30.0), (960.0, 30.0)])
def test_slow_motion_reading_names_the_capture_rate(capture_fps, file_fps):
    """Flights that fall (file/capture)² times g in the file's time point to slow motion at the capture rate."""
    reading = slow_motion_reading((file_fps / capture_fps) ** 2 * 1.01, file_fps)
    assert "slow-motion" in reading and f"about {capture_fps:g} fps" in reading
    assert f"--capture-fps {capture_fps:g}" in reading
    assert f"falls {(capture_fps / file_fps) ** 2 / 1.01:.0f} times slower than g" in reading
    assert slow_motion_reading(0.85, file_fps) is None and slow_motion_reading(100.0, file_fps) is None


@pytest.mark.parametrize("capture_fps, file_fps", [(240.0, 30.0), (960.0, 30.0), (1000.0, 25.0)])
def test_infer_capture_rate_snaps_to_the_common_rate(capture_fps, file_fps):
    """A = g / s · (file/capture)² in file time; a 1 % scale error still snaps to the true rate."""
    scale = 0.002  # m/px
    acceleration = STANDARD_GRAVITY_M_S2 / scale * (file_fps / capture_fps) ** 2  # px/s² of file time
    rate = infer_capture_rate(acceleration, scale * 1.01, file_fps, STANDARD_GRAVITY_M_S2)
    assert rate["snapped"] and rate["capture_fps"] == capture_fps
    assert rate["estimate_fps"] == pytest.approx(capture_fps / np.sqrt(1.01), rel=1e-12)


def test_infer_capture_rate_keeps_a_matching_file_rate_and_an_uncommon_estimate():
    scale = 0.002  # m/px
    real_time = STANDARD_GRAVITY_M_S2 / scale  # px/s²
    assert infer_capture_rate(real_time, scale * 1.02, 240.0, STANDARD_GRAVITY_M_S2)["capture_fps"] == 240.0
    uncommon = 700.0  # fps, 27 % from the nearest common rate (960) and 40 % from 500
    assert min(abs(np.asarray(COMMON_CAPTURE_RATES_FPS) / uncommon - 1)) > 10 * CAPTURE_RATE_SNAP_TOLERANCE
    rate = infer_capture_rate(real_time * (30.0 / uncommon) ** 2, scale, 30.0, STANDARD_GRAVITY_M_S2)
    assert not rate["snapped"]
    assert rate["capture_fps"] == pytest.approx(uncommon, rel=1e-9)


def test_infer_capture_rate_blames_the_scale_for_an_estimate_near_the_files_rate():
    """A ball measured 15 % too large (its shadow merged): at the file's 30 fps gravity then says 34.5 fps,
    no common rate and no slow motion; the file's rate is kept and the scale is named as off."""
    scale = 0.0018  # m/px
    real_time = STANDARD_GRAVITY_M_S2 / scale  # px/s² at the true scale
    rate = infer_capture_rate(real_time, scale / 1.15, 30.0, STANDARD_GRAVITY_M_S2)
    assert rate["estimate_fps"] == pytest.approx(30.0 * np.sqrt(1.15), rel=1e-9)
    assert rate["capture_fps"] == 30.0 and not rate["snapped"]
    assert "+15 % off" in rate["why"]


def test_slow_motion_file_gets_its_capture_rate_from_gravity(slow_motion_clip):
    """240 fps stored at 30 fps: the diameter scale and the flights' acceleration say 240 fps."""
    attrs = trajectory_from_video(slow_motion_clip, ball_radius_m=BALL["radius_m"]).attrs
    assert attrs["capture_fps"] == CAPTURE_FPS
    assert attrs["capture_fps_source"] == "inferred from gravity"
    assert attrs["capture_fps_estimate"] == pytest.approx(CAPTURE_FPS, rel=CAPTURE_RATE_SNAP_TOLERANCE)
    # with the capture rate fixed, gravity gives the scale again, as the independent check it is
    assert attrs["scale_gravity_m_per_px"] * PX_PER_M == pytest.approx(1.0, rel=CLIP_GRAVITY_SCALE_RTOL)
    assert set(attrs) >= {"scale_disagreement_diameter", "scale_rel_se"}
    # --capture-fps overrides the inference
    given = trajectory_from_video(slow_motion_clip, ball_radius_m=BALL["radius_m"], capture_fps=CAPTURE_FPS).attrs
    assert given["capture_fps_source"] == "given"
    assert given["scale_gravity_m_per_px"] == pytest.approx(attrs["scale_gravity_m_per_px"], rel=1e-9)


def test_ruler_takes_precedence_and_all_scales_disagree_with_it(slow_motion_clip):
    """With a ruler, ball radius and gravity: the ruler's scale is used, the others relative to it."""
    trajectory = trajectory_from_video(slow_motion_clip, ball_radius_m=BALL["radius_m"], ruler_tick_m=0.01)
    attrs = trajectory.attrs
    assert attrs["scale_source"] == "ruler"
    assert attrs["scale_m_per_px"] * PX_PER_M == pytest.approx(1.0, rel=RULER_SCALE_RTOL)
    assert attrs["scale_rel_se"] == pytest.approx(attrs["scale_ruler_se_m_per_px"] / attrs["scale_ruler_m_per_px"])
    for other in ("gravity", "diameter"):
        expected = attrs[f"scale_{other}_m_per_px"] / attrs["scale_ruler_m_per_px"] - 1.0
        assert attrs[f"scale_disagreement_{other}"] == pytest.approx(expected)
    assert attrs["capture_fps"] == CAPTURE_FPS  # inferred with the ruler as the length standard


#: The linearised scale terms must predict the change of a real 0.5 % rescaling to this fraction.
SCALE_RESPONSE_RTOL = 0.05  # 1


def test_scale_terms_predict_what_a_rescaled_recording_does(tennis_truth, tmp_path):
    """Through the analyse and fit stages: the scale's share of the first rebound's and the ITF
    rebound's standard errors (scale_rel_se = 0.5 %) matches how much they move when the same
    recording's heights are really multiplied by 1.005. The drag is fitted in all three runs: a
    linearised response cannot foresee the BIC switching from the ball's drag to a fitted one between
    the recording and its rescaled copy (it does here), a jump of its own."""
    from conftest import sensor_log
    from dropfit import stages
    from dropfit.files import read_json, read_table
    from dropfit.heightlog import make_trajectory
    from dropfit.settings import Settings

    log = sensor_log(tennis_truth, seed=1, offset_m=0.0)
    rel = 0.005
    runs = {}
    for name, factor, scale_rel_se in (("plain", 1.0, 0.0), ("with_se", 1.0, rel), ("rescaled", 1.0 + rel, 0.0)):
        out = tmp_path / name
        out.mkdir()
        attrs = {"ball_radius_m": 0.0335, "ball_mass_kg": 0.057, "ball_type": "tennis", "scale_rel_se": scale_rel_se}
        make_trajectory(log["time_s"], log["y_m"] * factor, "synthetic", "test", attrs).to_netcdf(out / "traj.nc")
        stages.analyse(out / "traj.nc", out / "impacts.csv", out / "flights.csv", out / "analysis.json",
                       Settings(drag="on"))
        stages.fit(out / "analysis.json", out / "impacts.csv", out / "fit.json")
        runs[name] = read_table(out / "impacts.csv").iloc[0], read_json(out / "fit.json")["itf"]["rebound_m"]
    (first, itf), (first_se, itf_se), (first_moved, itf_moved) = runs["plain"], runs["with_se"], runs["rescaled"]
    assert first_se["h_after_scale_se_m"] == pytest.approx(abs(first_moved["h_after_m"] - first["h_after_m"]),
                                                            rel=SCALE_RESPONSE_RTOL)
    itf_scale_se = np.sqrt(itf_se["se"] ** 2 - itf["se"] ** 2)
    assert itf_scale_se == pytest.approx(abs(itf_moved["value"] - itf["value"]), rel=SCALE_RESPONSE_RTOL)


#: Rectified ruler rows must be a straight line in the camera's untilted rows to this, px (the
#: ticks' centroids scatter by about 0.01 px; the keystone alone bows a line by 0.5 px).
RECTIFIED_LINE_TOLERANCE_PX = 0.03
#: The first impact's v_in must match the generator's to this relative accuracy (the keystone read
#: through one scale made it 0.37 % low).
V_IN_RTOL = 5e-4  # 1 (0.05 %)
#: ... and every e must lie within this many of its standard errors of the truth.
E_ERROR_IN_SE = 3.0  # 1


def test_ruler_keystone_rectifies_the_tilted_phone_clip_so_v_in_and_e_match_the_truth():
    """The default phone clip's 0.5° tilt (issue 10): the ruler's ticks measure the keystone, and the
    ball's true image rows, rectified with it and scaled, give v_in and e of the generator's truth."""
    clip = default_clips()["phone_240fps_tennis_254cm"]
    camera, scene = clip["camera"], clip["scene"]
    truth = simulate_drop(**clip["truth"])
    ruler, note = ruler_scale(_grey(FrameRenderer(truth, camera, scene, 0).background), 0.01)
    assert ruler is not None, note

    flat_rows = np.linspace(20.0, camera.image_row_of_floor_px, 60)
    _, image_rows = camera.flat_to_image(camera.drop_column, flat_rows)
    rectified = rectify_rows(image_rows, ruler.keystone_per_px, ruler.keystone_row_px)
    line = np.polyval(np.polyfit(flat_rows, rectified, 1), flat_rows)
    assert np.abs(rectified - line).max() < RECTIFIED_LINE_TOLERANCE_PX
    assert keystoned_rows(rectified, ruler.keystone_per_px, ruler.keystone_row_px) == pytest.approx(image_rows)

    # the tracked centres as the renderer placed them, with 0.05 px of seeded tracking noise, from
    # 0.1 s after the release (the hand) to the clip's end
    time = np.arange(round((truth.release_time_s + 0.1) * camera.fps), round(clip["duration_s"] * camera.fps)) / camera.fps
    rows = camera.world_to_image(0.0, truth.height(time))[1] + np.random.default_rng(10).normal(0.0, 0.05, time.size)
    height = -rectify_rows(rows, ruler.keystone_per_px, ruler.keystone_row_px) * ruler.scale_m_per_px
    floor_row = camera.world_to_image(0.0, 0.0)[1]
    floor = -rectify_rows(floor_row, ruler.keystone_per_px, ruler.keystone_row_px) * ruler.scale_m_per_px
    analysis = analyse_bounces(time, height, contact_height_m=floor + truth.radius_m)
    impacts, true_impacts = analysis.impacts, truth.impacts
    assert len(impacts) >= 3
    assert impacts["v_in_m_s"].iloc[0] == pytest.approx(true_impacts["v_in_m_s"].iloc[0], rel=V_IN_RTOL)
    for row, true_e in zip(impacts.head(3).itertuples(), true_impacts["e"]):
        assert abs(row.e - true_e) < E_ERROR_IN_SE * row.e_se
