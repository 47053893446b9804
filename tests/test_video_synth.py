"""Synthetic videos: sub-pixel rendering, motion blur, the video file, the ruler and contact flattening."""

from dataclasses import dataclass

import cv2
import numpy as np
import pytest

from dropfit.contact import LinearContact
from dropfit.synth import simulate_drop
from dropfit.video_synth import (Camera, FrameRenderer, Scene, render_background, render_frame,
                                 render_video)

CENTROID_TOL_PX = 0.01  # px, a still, sharp disc
BLUR_CENTROID_TOL_PX = 0.02  # px, a motion-blurred disc against the exposure-averaged centre
TICK_TOL_PX = 0.02  # px, darkness centroid of a tick mark
FLOOR_TOL_PX = 1.0  # px, bottom edge of a flattened ball against the floor row

PLAIN = Scene(ball_colour_bgr=(230.0, 230.0, 230.0), background_grey=100.0, ruler_column_px=5.0,
              ruler_width_px=10.0)


@dataclass
class HeldBall:
    """A ball held still at ``height_m`` (m): the part of DropTruth the renderer needs."""

    height_m: float
    radius_m: float
    release_time_s: float = 1e9
    drop_height_m: float = 0.0

    def height(self, time_s):
        return np.full(np.shape(time_s), self.height_m, dtype=float)


def _background_u8(camera, scene):
    return np.clip(render_background(camera, scene) + 0.5, 0, 255.5).astype(np.uint8)


def _centroid(frame, background):
    """Intensity-weighted centroid (column, row) in px of |frame − background| summed over channels."""
    weight = np.abs(frame.astype(float) - background.astype(float)).sum(axis=2)
    rows, cols = np.indices(weight.shape)
    return (weight * cols).sum() / weight.sum(), (weight * rows).sum() / weight.sum()


def test_sharp_disc_centroid_is_the_true_subpixel_centre():
    rng = np.random.default_rng(11)
    for _ in range(8):
        camera = Camera(320, 240, fps=100.0, exposure_s=0.0, px_per_m=1000.0, noise_sigma=0.0,
                        image_row_of_floor_px=225.0 + rng.random(), drop_column_px=150.0 + 20 * rng.random())
        truth = HeldBall(height_m=0.08 + 0.05 * rng.random(), radius_m=0.006 + 0.008 * rng.random())
        frame, row = render_frame(truth, camera, PLAIN, 0, seed=1)
        cx, cy = _centroid(frame, _background_u8(camera, PLAIN))
        assert row["visible"] and not row["in_contact"]
        assert abs(cx - row["x_px"]) < CENTROID_TOL_PX
        assert abs(cy - row["y_px"]) < CENTROID_TOL_PX
        assert row["y_px"] == pytest.approx(camera.image_row_of_floor_px - truth.height_m * 1000.0)


def test_blurred_disc_centroid_is_the_exposure_averaged_centre():
    truth = simulate_drop(0.25, 0.01, {"kind": "constant", "e0": 0.8}, release_time_s=0.0)
    camera = Camera(320, 240, fps=200.0, exposure_s=1 / 200, px_per_m=800.0, image_row_of_floor_px=230.0,
                    noise_sigma=0.0, blur_step_px=0.1)
    renderer = FrameRenderer(truth, camera, PLAIN, seed=2)
    background = _background_u8(camera, PLAIN)
    for k in (30, 38, 43):  # falling fast: 6–8 px of blur per frame
        frame, row = renderer.render(k)
        speed_px = abs(np.diff(truth.height(row["time_s"] + np.array([-0.0025, 0.0025])))[0]) * 800.0
        assert speed_px > 5.0  # the frame really is blurred
        cx, cy = _centroid(frame, background)
        assert abs(cx - row["centroid_x_px"]) < BLUR_CENTROID_TOL_PX
        assert abs(cy - row["centroid_y_px"]) < BLUR_CENTROID_TOL_PX
        # during free fall the averaged centre lies g·E²/24 (px) below the mid-exposure centre
        assert row["centroid_y_px"] - row["y_px"] == pytest.approx(9.80665 * (1 / 200) ** 2 / 24 * 800.0, abs=1e-3)


def test_written_video_reads_back(tmp_path):
    truth = simulate_drop(0.2, 0.01, {"kind": "constant", "e0": 0.8}, release_time_s=0.01)
    camera = Camera(320, 240, fps=240.0, px_per_m=800.0, image_row_of_floor_px=230.0, noise_sigma=2.0,
                    lighting_drift=0.05, tilt_deg=1.0, quality=85)
    scene = Scene(seam=True, hand=True, background_texture=5.0)
    frames = render_video(truth, camera, scene, duration_s=0.05, seed=3, path=tmp_path / "clip.avi")
    path = frames.attrs["video_path"]
    assert frames.attrs["codec"] in ("MJPG", "mp4v")
    assert sorted(p.name for p in tmp_path.iterdir()) == [path.rsplit("/", 1)[-1]]  # no temporary left
    capture = cv2.VideoCapture(path)
    try:
        assert capture.get(cv2.CAP_PROP_FRAME_WIDTH) == 320 and capture.get(cv2.CAP_PROP_FRAME_HEIGHT) == 240
        assert capture.get(cv2.CAP_PROP_FPS) == pytest.approx(240.0)
        read = []
        while True:
            ok, image = capture.read()
            if not ok:
                break
            read.append(image)
    finally:
        capture.release()
    assert len(read) == len(frames) == 12
    assert read[0].shape == (240, 320, 3)
    # the decoded frame is the rendered one up to noise and compression
    first, _ = FrameRenderer(truth, camera, scene, seed=3).render(0)
    assert np.abs(read[0].astype(float) - first).mean() < 3.0  # grey levels
    assert list(frames["frame"]) == list(range(12))
    np.testing.assert_allclose(frames["time_s"], np.arange(12) / 240.0)


def test_rendering_is_seeded():
    truth = HeldBall(0.1, 0.01)
    camera = Camera(160, 120, px_per_m=800.0, image_row_of_floor_px=115.0, noise_sigma=3.0)
    a, _ = FrameRenderer(truth, camera, PLAIN, seed=4).render(1)
    b, _ = FrameRenderer(truth, camera, PLAIN, seed=4).render(1)
    c, _ = FrameRenderer(truth, camera, PLAIN, seed=5).render(1)
    assert np.array_equal(a, b) and not np.array_equal(a, c)
    noise = a.astype(float) - _background_u8(camera, PLAIN)
    assert noise[60:110, 100:].std() == pytest.approx(3.0, rel=0.1)  # grey levels, away from the ball


def test_ruler_ticks_are_at_the_scale_rows():
    camera = Camera(320, 240, px_per_m=500.0, image_row_of_floor_px=230.3)
    scene = Scene(ruler_column_px=20.0, ruler_width_px=30.0, tick_width_px=2.0, ruler_top_m=0.45)
    grey = render_background(camera, scene)[:, :, 1]
    frame, _ = render_frame(HeldBall(0.1, 0.005), Camera(320, 240, exposure_s=0.0, px_per_m=500.0,
                            image_row_of_floor_px=230.3, noise_sigma=0.0), scene, 0)
    assert np.array_equal(frame[:, :80, 1], np.clip(grey[:, :80] + 0.5, 0, 255.5).astype(np.uint8))  # as filmed

    def tick_row(column, expected, half_window):
        rows = np.arange(int(round(expected)) - half_window, int(round(expected)) + half_window + 1)
        darkness = scene.ruler_grey - grey[rows, column]
        assert np.argmax(darkness) == half_window  # the darkest row is the nearest to the tick
        return (darkness * rows).sum() / darkness.sum()

    long_only = int(20 + 0.85 * 30)  # only the 10 cm ticks reach this column
    short = int(20 + 0.2 * 30)  # every 1 cm tick crosses this one
    for cm in (10, 20, 40):
        expected = 230.3 - cm * 0.01 * 500.0
        assert abs(tick_row(long_only, expected, 6) - expected) < TICK_TOL_PX
        assert grey[int(round(expected)) + 25, long_only] == scene.ruler_grey  # no 5 cm tick out there
    for cm in (1, 7, 33):
        expected = 230.3 - cm * 0.01 * 500.0
        assert abs(tick_row(short, expected, 2) - expected) < TICK_TOL_PX


def test_flattened_ball_keeps_its_bottom_on_the_floor():
    truth = simulate_drop(0.3, 0.02, mass_kg=0.057, release_time_s=0.0,
                          contact_model=LinearContact(30000.0, 8.2))
    touchdown, liftoff = truth.impacts[["t_s", "t_liftoff_s"]].iloc[0]
    camera = Camera(320, 240, fps=2000.0, exposure_s=0.0, px_per_m=2500.0, image_row_of_floor_px=200.4,
                    noise_sigma=0.0)
    scene = Scene(ball_colour_bgr=(230.0, 230.0, 230.0), background_grey=100.0, floor_grey=40.0,
                  ruler_column_px=5.0, ruler_width_px=10.0)
    start = touchdown - 0.001
    n = int((liftoff - start) * 2000.0) + 3
    renderer = FrameRenderer(truth, camera, scene, start_s=start)
    background = render_background(camera, scene).sum(axis=2)
    column = int(round(camera.drop_column))
    penetrations = []
    for k in range(n):
        frame, row = renderer.render(k)
        profile = frame[:, column].astype(float).sum(axis=1)
        alpha = (profile - background[:, column]) / (3 * 230.0 - background[:, column])
        below = int(round(row["centroid_y_px"]))
        bottom = below - 0.5 + alpha[below:].sum()  # the lower edge of the drawn ball in this column
        if row["in_contact"]:
            penetrations.append(row["penetration_m"] * camera.px_per_m)
            assert abs(bottom - camera.image_row_of_floor_px) < FLOOR_TOL_PX
            assert row["bottom_y_px"] == pytest.approx(camera.image_row_of_floor_px)
            top = below + 0.5 - alpha[:below + 1][::-1].sum()
            assert top == pytest.approx(row["y_px"] - row["radius_px"], abs=FLOOR_TOL_PX)  # the rigid ball's top
        else:
            assert bottom < camera.image_row_of_floor_px + 0.1
    assert len(penetrations) >= 3 and max(penetrations) > 5.0  # px: the flattening is visible
