"""Project and camera files: Tracker's .trk/.trz (synthetic and the real ball toss) and Photron MRAW (real).

The synthetic Tracker project is written here from Tracker's XML as its ``ImageCoordSystem`` documents
it: the world-to-image transform rotates about the world origin by the angle of the world x axis
(counter-clockwise from the image x axis, saved in degrees), scales to px and translates to the origin;
the world y axis points up, image rows down.
"""

import math
import zipfile

import numpy as np
import pytest

from dropfit import analyse_recording
from dropfit.errors import InputError
from dropfit.heightlog import trajectory_from_log
from dropfit.importers import ImportOptions, read_track

from helpers import BALL_TOSS_G_M_S2, bouncing_ball, depth_motion_fit, real_recording

START_FRAME, START_TIME_MS, DELTA_T_MS = 3, 100.0, 20.0  # the clip: first frame, its time (ms), ms per frame
PX_PER_M = 500.0  # px/m, the calibration
#: Key frames of the coordinate system: frame → (origin x px, origin y px, angle deg); the camera was bumped.
KEY_FRAMES = {0: (100.0, 450.0, 10.0), 40: (104.0, 452.5, 10.0)}
DROP_M, E_TRUE, CENTRE_M = 0.5, 0.6, 0.02  # m, 1, m
E_TOL = 0.01  # 1, e from a noise-free 50 fps track (the analysis' own bias)
MARK_ROUNDING_M = 1e-6  # m: the marks are written to 1e-4 px, 2e-7 m at 500 px/m


def _to_image(world_x, world_y, frame, key_frames):
    key = max(k for k in key_frames if k <= frame)
    x0, y0, angle_deg = key_frames[key]
    cos, sin = math.cos(math.radians(angle_deg)), math.sin(math.radians(angle_deg))
    return (PX_PER_M * (cos * world_x - sin * world_y) + x0,
            -PX_PER_M * (sin * world_x + cos * world_y) + y0)


def _prop(name, kind, value):
    return f'<property name="{name}" type="{kind}">{value}</property>'


def _point_mass(name, frames, xs, ys):
    items = "".join(f'<property name="[{f}]" type="object"><object class="org.opensourcephysics.cabrillo.tracker.'
                    f'PointMass$FrameData">{_prop("x", "double", f"{x:.4f}")}{_prop("y", "double", f"{y:.4f}")}'
                    f'</object></property>' for f, x, y in zip(frames, xs, ys))
    return (f'<property name="item" type="object"><object class="org.opensourcephysics.cabrillo.tracker.PointMass">'
            f'{_prop("mass", "double", 0.2)}{_prop("name", "string", name)}<property name="framedata" type="array" '
            f'class="[Lorg.opensourcephysics.cabrillo.tracker.PointMass$FrameData;">{items}</property></object>'
            f'</property>')


def tracker_project(key_frames=KEY_FRAMES):
    """A .trk of a bouncing ball drifting sideways (and a hand marked in a few frames), its coordinate system's
    ``key_frames`` (frame → origin x, origin y in px, angle in degrees), and the truth."""
    frames = np.arange(START_FRAME, START_FRAME + 80)
    time = (START_TIME_MS + (frames - START_FRAME) * DELTA_T_MS) / 1000.0
    world_y = bouncing_ball(time - time[0], DROP_M, E_TRUE) + CENTRE_M
    world_x = 0.2 + 0.3 * (time - time[0])
    image = [_to_image(x, y, f, key_frames) for x, y, f in zip(world_x, world_y, frames)]
    coords = "".join(f'<property name="[{k}]" type="object"><object class="org.opensourcephysics.media.core.'
                     f'ImageCoordSystem$FrameData">{_prop("xorigin", "double", x0)}{_prop("yorigin", "double", y0)}'
                     f'{_prop("angle", "double", a)}{_prop("xscale", "double", PX_PER_M)}'
                     f'{_prop("yscale", "double", PX_PER_M)}</object></property>' for k, (x0, y0, a) in key_frames.items())
    xml = (
        '<?xml version="1.0" encoding="UTF-8"?>\n'
        '<object class="org.opensourcephysics.cabrillo.tracker.TrackerPanel">'
        '<property name="videoclip" type="object"><object class="org.opensourcephysics.media.core.VideoClip">'
        f'{_prop("startframe", "int", START_FRAME)}{_prop("stepsize", "int", 1)}'
        f'{_prop("starttime", "double", START_TIME_MS)}</object></property>'
        '<property name="clipcontrol" type="object"><object class="org.opensourcephysics.media.core.'
        f'StepperClipControl">{_prop("delta_t", "double", DELTA_T_MS)}</object></property>'
        '<property name="coords" type="object"><object class="org.opensourcephysics.media.core.ImageCoordSystem">'
        f'<property name="framedata" type="array" class="[Lorg.opensourcephysics.media.core.ImageCoordSystem'
        f'$FrameData;">{coords}</property></object></property>'
        f'{_prop("length_unit", "string", "m")}'
        '<property name="tracks" type="collection" class="java.util.ArrayList">'
        + _point_mass("hand", frames[:5], [300.0] * 5, [200.0, 201.0, 202.5, 203.0, 205.0])
        + _point_mass("ball", frames, *zip(*image))
        + '</property></object>\n')
    return xml, time, world_x, world_y


def test_tracker_project_is_read_with_its_calibration_and_timing(tmp_path):
    """Key-framed origin, the angle in degrees, the scale, the clip's start frame, start time and delta_t: the
    world positions and times are the truth, x carried; the ball is picked over the hand; e comes back."""
    xml, time, world_x, world_y = tracker_project()
    path = tmp_path / "drop.trk"
    path.write_text(xml, encoding="utf-8")
    track = read_track(path)
    assert track.source_format == "tracker" and "'ball'" in track.mapping and track.unit == "m"
    np.testing.assert_allclose(track.time_s, time, atol=1e-12)
    np.testing.assert_allclose(track.y, world_y, atol=MARK_ROUNDING_M)
    np.testing.assert_allclose(track.x, world_x, atol=MARK_ROUNDING_M)
    hand = read_track(path, ImportOptions(track_id=1))
    assert hand.time_s.size == 5
    result = analyse_recording(path)
    assert result.fit["restitution"]["e"]["value"] == pytest.approx(E_TRUE, abs=E_TOL)
    np.testing.assert_allclose(result.trajectory["x"].values, world_x, atol=MARK_ROUNDING_M)


def test_trz_project_is_the_zipped_trk(tmp_path):
    xml, time, _, world_y = tracker_project()
    path = tmp_path / "drop.trz"
    with zipfile.ZipFile(path, "w") as archive:
        archive.writestr("drop_thumbnail.png", b"\x89PNG\r\n\x1a\n")
        archive.writestr("drop.trk", xml)
    np.testing.assert_allclose(read_track(path).y, world_y, atol=MARK_ROUNDING_M)
    with zipfile.ZipFile(tmp_path / "other.trz", "w") as archive:
        archive.writestr("notes.txt", "no project")
    with pytest.raises(InputError, match=r"other.trz: is a zip archive without a Tracker project \(.trk\) in it"):
        read_track(tmp_path / "other.trz")


def test_tracker_projects_that_cannot_be_read_say_why(tmp_path):
    path = tmp_path / "broken.trk"
    path.write_text('<?xml version="1.0"?>\n<object class="org.opensourcephysics.cabrillo.tracker.TrackerPanel">')
    with pytest.raises(InputError, match=r"broken.trk: is not a readable Tracker project \(XML error"):
        read_track(path)
    path.write_text('<?xml version="1.0"?>\n<object class="org.example.Other"></object>')
    with pytest.raises(InputError, match=r"broken.trk: is XML but not a Tracker project"):
        read_track(path)
    xml, *_ = tracker_project()
    path.write_text(xml.replace(f'{_prop("delta_t", "double", DELTA_T_MS)}', ""))
    with pytest.raises(InputError, match=r"broken.trk: the Tracker project gives no frame timing \(delta_t\); give the "
                                         r"frame rate with --fps"):
        read_track(path)
    assert read_track(path, ImportOptions(fps=50.0)).time_s[1] == pytest.approx(0.1 + 0.02)


def test_a_tracker_step_cut_to_the_whole_ms_names_the_rate_and_fps_overrides_it(tmp_path):
    """A step of a whole number of ms that no whole rate has (33 ms: 30.3 fps) names the rate it was cut
    from; a step a whole rate has exactly (the fixture's 20 ms, 50 fps) says nothing more. --fps replaces
    the project's step, and the line says so."""
    xml, *_ = tracker_project()
    path = tmp_path / "cut.trk"
    path.write_text(xml.replace(_prop("delta_t", "double", DELTA_T_MS), _prop("delta_t", "double", 33.0)))
    assert read_track(path).mapping.endswith("frames 33 ms apart (Tracker's delta_t); a step given to the whole "
                                             "ms, 30.3 fps: if the camera ran at 30 fps (33.333 ms), give --fps 30")
    given = read_track(path, ImportOptions(fps=30.0))
    np.testing.assert_allclose(np.diff(given.time_s), 1 / 30)
    assert given.mapping.endswith("frames 33.3333 ms apart (--fps 30; the project says 33 ms)")
    path.write_text(xml)
    assert read_track(path).mapping.endswith("frames 20 ms apart (Tracker's delta_t)")


# --- the real ball toss ---------------------------------------------------------------------------

#: The ball toss's calibration as its README gives it (a metre stick): 398.7 px/m.
BALL_TOSS_PX_PER_M = 398.7
#: Tracker's own clip: 13 frames 66 ms apart (an excerpt of every other frame of a 30 fps clip).
BALL_TOSS_DELTA_T_S = 0.066


def test_real_ball_toss_is_read_with_its_calibration():
    """The 11 hand marks of Tracker's BallToss.trz come out in m with the metre stick's calibration, time in
    Tracker's 66 ms steps; the origin is at the first mark. Its toss is ballistic: the fitted g lies within 5 %
    of 9.81 m/s² (a unit or a transform mistake is off by far more)."""
    trz = real_recording("tracker-balltoss", "BallToss.trz")
    track = read_track(trz)
    assert track.unit == "m" and track.time_s.size == 11
    assert track.calibration["tracker_px_per_unit"] == pytest.approx(BALL_TOSS_PX_PER_M, abs=0.05)
    np.testing.assert_allclose(np.diff(track.time_s), BALL_TOSS_DELTA_T_S, atol=1e-12)
    assert (track.x[0], track.y[0]) == pytest.approx((0.0, 0.0), abs=1e-9)
    a = np.polyfit(track.time_s, track.y, 2)[0]
    assert -2 * a == pytest.approx(9.81, rel=0.05)
    assert "point mass 'ball' (11 marks)" in track.mapping


def _g_range_over_the_flight(track):
    """g of the depth-motion fit referenced to the ball's depth at the first and at the last mark, less and
    plus 2 se: the metre stick's calibration holds where the ball crosses the stick's plane, at an instant
    the marks do not tell."""
    fit = depth_motion_fit(track.time_s, track.x, track.y)
    first, last = (fit["g"] / (1 + fit["c"] * t) for t in (track.time_s[0], track.time_s[-1]))
    return min(first, last) - 2 * fit["g_se"], max(first, last) + 2 * fit["g_se"]


def test_real_ball_toss_gives_g_within_its_uncertainty():
    """The project's step, 66 ms, is cut to the whole ms: its excerpt is every other frame of the 30 fps
    clip, 66.67 ms apart (tests/test_real_video.py checks that frame by frame), and the import names 15 fps.

    The toss is not a parabola in the stick's plane: its horizontal acceleration is 0.19 ± 0.02 m/s². Fitted
    with a steady motion in depth, the scale changes by 3.6 % over the flight, and g's uncertainty spans g at
    the ball's depth at the first mark to g at the last one (each ± 2 se): measured [9.72, 10.20] m/s² with
    --fps 15, which holds the local 9.80, and [9.92, 10.41] with the stated 66 ms, which does not (the
    parabola: 10.06 and 10.27 ± 0.04)."""
    trz = real_recording("tracker-balltoss", "BallToss.trz")
    stated = read_track(trz)
    assert "a step given to the whole ms, 15.15 fps: if the camera ran at 15 fps (66.667 ms), give --fps 15" \
        in stated.mapping
    track = read_track(trz, ImportOptions(fps=15.0))
    assert "frames 66.6667 ms apart (--fps 15; the project says 66 ms)" in track.mapping
    np.testing.assert_allclose(np.diff(track.time_s), 1 / 15, rtol=1e-12)
    (ax, _, _), cov = np.polyfit(track.time_s, track.x, 2, cov=True)
    assert abs(2 * ax) > 4 * 2 * math.sqrt(cov[0, 0])  # the parabola misfits: the ball moves in depth
    low, high = _g_range_over_the_flight(track)
    assert low <= BALL_TOSS_G_M_S2 <= high and high - low < 0.1 * BALL_TOSS_G_M_S2, (low, high)
    assert _g_range_over_the_flight(stated)[0] > BALL_TOSS_G_M_S2


# --- the real Photron clip ------------------------------------------------------------------------

#: The clip's README: a ball about 125 px across falling 2.65 px per frame, 15 frames at 30 000 fps.
MRAW_FPS, MRAW_DIAMETER_PX, MRAW_STEP_PX = 30000.0, 125.0, 2.65
#: The tracked centre's step may scatter by this per frame (a real backlit edge at 12 bit).
MRAW_STEP_TOL_PX = 0.2


def test_real_photron_clip_is_tracked_in_every_frame():
    """The frame rate comes from the .cihx; the backlit ball is found in all 15 frames, ~125 px across, falling
    2.65 px per frame (the clip's README); too short (0.5 ms) to see gravity (1 µm), so it is refused as a
    recording, saying so."""
    cihx = real_recording("photron-mraw", "ball_12bit.cihx")
    track = read_track(cihx)
    assert track.frame_rate_hz == MRAW_FPS and track.unit == "px" and track.source_format == "mraw"
    assert np.count_nonzero(np.isfinite(track.y)) == 15
    np.testing.assert_allclose(np.diff(track.time_s), 1 / MRAW_FPS, rtol=1e-12)
    assert 2 * track.calibration["ball_radius_px"] == pytest.approx(MRAW_DIAMETER_PX, rel=0.03)
    steps = np.diff(track.y)
    assert np.mean(steps) == pytest.approx(MRAW_STEP_PX, abs=0.05)
    assert np.all(np.abs(steps - MRAW_STEP_PX) < MRAW_STEP_TOL_PX + 0.1)
    assert read_track(cihx.with_suffix(".mraw")).time_s.size == 15  # the .mraw finds its .cihx
    with pytest.raises(InputError, match=r"ball_12bit.cihx: no bounce found .*: a px track is scaled from its flights' "
                                         r"curvature, which needs a bounce; give the scale with --scale-m-per-px"):
        trajectory_from_log(cihx)
    scale = -1e-4  # m/px, given (image rows point down)
    trajectory = trajectory_from_log(cihx, scale_m_per_px=scale)
    np.testing.assert_allclose(trajectory["y"].values, track.y * scale)
    np.testing.assert_allclose(trajectory["x"].values, track.x * abs(scale))


def test_uncalibrated_tracker_project_gives_image_px(tmp_path):
    """Without a coordinate system (Tracker's default: 1 px per unit) the marks stay image px, y down, and are
    calibrated from gravity as a px log is: the scale comes back within 0.5 % and e within its tolerance."""
    xml, time, _, world_y = tracker_project({0: (100.0, 450.0, 0.0)})  # a level camera that stays put
    start, end = xml.index('<property name="coords"'), xml.index('<property name="length_unit"')
    path = tmp_path / "uncalibrated.trk"
    path.write_text(xml[:start] + xml[end:], encoding="utf-8")
    track = read_track(path)
    assert track.unit == "px" and "no calibration" in track.mapping
    result = analyse_recording(path)
    assert result.trajectory.attrs["scale_m_per_px"] == pytest.approx(-1 / PX_PER_M, rel=5e-3)
    assert result.fit["restitution"]["e"]["value"] == pytest.approx(E_TRUE, abs=E_TOL)


# --- axes turned any way --------------------------------------------------------------------------

#: An upright camera filming a drop: the image px of the release, px per m, frame rate (frames/s), mark noise (px).
UPRIGHT_RELEASE_PX, UPRIGHT_PX_PER_M, UPRIGHT_FPS, UPRIGHT_NOISE_PX = (320.0, 60.0), 500.0, 30.0, 0.3
UPRIGHT_DROP_M, UPRIGHT_E = 0.8, 0.8  # m, 1
UPRIGHT_DRIFT_M_S = 0.05  # m/s sideways
#: e within this of the truth (0.3 px marks at 30 fps give ± 0.0002; a vertical found 0.5° off moves e by 0.0004),
#: heights within this fraction (axes 0.4° off the vertical move the late ones by 0.4 %)
UPRIGHT_E_TOL, UPRIGHT_HEIGHT_REL_TOL = 0.001, 0.005


def upright_marks(seed=1):
    """Frames, times (s) and the image px (column, row) of an upright camera's marks of a ball dropped from the
    release (image up is up: rows are ``release row + px/m × (drop − height)``, the closed-form bounce),
    drifting sideways, with Gaussian mark noise (seeded)."""
    frames = np.arange(int(2.5 * UPRIGHT_FPS))
    time = frames / UPRIGHT_FPS
    height = bouncing_ball(time, UPRIGHT_DROP_M, UPRIGHT_E)
    rng = np.random.default_rng(seed)
    x0, y0 = UPRIGHT_RELEASE_PX
    column = x0 + UPRIGHT_PX_PER_M * UPRIGHT_DRIFT_M_S * time + rng.normal(0, UPRIGHT_NOISE_PX, time.size)
    row = y0 + UPRIGHT_PX_PER_M * (UPRIGHT_DROP_M - height) + rng.normal(0, UPRIGHT_NOISE_PX, time.size)
    return frames, time, column, row


def upright_camera_project(angle_deg, seed=1):
    """A .trk of :func:`upright_marks`, whose coordinate system has its origin at the release and its x axis
    turned ``angle_deg`` counter-clockwise from the image x axis; the truth does not depend on the axes."""
    frames, time, column, row = upright_marks(seed)
    x0, y0 = UPRIGHT_RELEASE_PX
    system = (f'<property name="[0]" type="object"><object class="org.opensourcephysics.media.core.ImageCoordSystem'
              f'$FrameData">{_prop("xorigin", "double", x0)}{_prop("yorigin", "double", y0)}'
              f'{_prop("angle", "double", angle_deg)}{_prop("xscale", "double", UPRIGHT_PX_PER_M)}'
              f'{_prop("yscale", "double", UPRIGHT_PX_PER_M)}</object></property>')
    return (
        '<?xml version="1.0" encoding="UTF-8"?>\n'
        '<object class="org.opensourcephysics.cabrillo.tracker.TrackerPanel">'
        '<property name="videoclip" type="object"><object class="org.opensourcephysics.media.core.VideoClip">'
        f'{_prop("startframe", "int", 0)}{_prop("starttime", "double", 0.0)}</object></property>'
        '<property name="clipcontrol" type="object"><object class="org.opensourcephysics.media.core.'
        f'StepperClipControl">{_prop("delta_t", "double", 1000.0 / UPRIGHT_FPS)}</object></property>'
        '<property name="coords" type="object"><object class="org.opensourcephysics.media.core.ImageCoordSystem">'
        f'<property name="framedata" type="array" class="[Lorg.opensourcephysics.media.core.ImageCoordSystem'
        f'$FrameData;">{system}</property></object></property>{_prop("length_unit", "string", "m")}'
        '<property name="tracks" type="collection" class="java.util.ArrayList">'
        + _point_mass("ball", frames, column, row) + '</property></object>\n')


@pytest.mark.parametrize("angle_deg", [0.0, 90.0, -179.6, 180.0, 30.0, -120.0])
def test_tracker_axes_at_any_angle_give_the_same_bounces(tmp_path, angle_deg):
    """y up (0°), x up (90°), y down with the origin at the release (−179.6°, 180°: read upside down and refused
    before), axes turned 30° or −120° on an upright camera (read along the tilted y axis before: e = 0.824 at
    30°): e and every height are the upright truth's."""
    path = tmp_path / f"axes_{angle_deg:g}.trk"
    path.write_text(upright_camera_project(angle_deg), encoding="utf-8")
    result = analyse_recording(path)
    assert result.fit["restitution"]["e"]["value"] == pytest.approx(UPRIGHT_E, abs=UPRIGHT_E_TOL)
    impacts = result.impacts
    assert len(impacts) >= 4
    np.testing.assert_allclose(impacts["h_before_m"], UPRIGHT_DROP_M * UPRIGHT_E ** (2 * np.arange(len(impacts))),
                               rtol=UPRIGHT_HEIGHT_REL_TOL)
    np.testing.assert_allclose(impacts["e"], UPRIGHT_E, atol=3 * UPRIGHT_E_TOL)


def upright_camera_data_table(angle_deg, seed=1):
    """The same marks as :func:`upright_camera_project` as Tracker's exported data table (``mass A``, then
    ``t x y`` in m, tabs): Tracker's image-to-world transform of its ``ImageCoordSystem`` (the inverse of
    rotate, scale to px with image rows down, translate to the origin), written here from its documentation."""
    frames, time, column, row = upright_marks(seed)
    x0, y0 = UPRIGHT_RELEASE_PX
    along, across = (column - x0) / UPRIGHT_PX_PER_M, (y0 - row) / UPRIGHT_PX_PER_M  # image right and up, m
    cos, sin = math.cos(math.radians(angle_deg)), math.sin(math.radians(angle_deg))
    world_x, world_y = cos * along + sin * across, -sin * along + cos * across
    return "mass A\nt\tx\ty\n" + "".join(f"{t:.6f}\t{x:.6f}\t{y:.6f}\n" for t, x, y in zip(time, world_x, world_y))


@pytest.mark.parametrize("angle_deg", [90.0, -179.6, 180.0, 30.0])
def test_tracker_data_tables_of_turned_axes_give_the_same_bounces(tmp_path, angle_deg):
    """Tracker's exported table of axes turned any way: x up (90°), y down (−179.6°, 180°: refused before as
    'the heights point down'), 30°: e and every height are the upright truth's."""
    path = tmp_path / f"table_{angle_deg:g}.txt"
    path.write_text(upright_camera_data_table(angle_deg), encoding="utf-8")
    result = analyse_recording(path)
    assert result.fit["restitution"]["e"]["value"] == pytest.approx(UPRIGHT_E, abs=UPRIGHT_E_TOL)
    impacts = result.impacts
    np.testing.assert_allclose(impacts["h_before_m"], UPRIGHT_DROP_M * UPRIGHT_E ** (2 * np.arange(len(impacts))),
                               rtol=UPRIGHT_HEIGHT_REL_TOL)
