"""Ball tracker against frames rendered here with known sub-pixel centres (seeded)."""

import math
import time

import cv2
import numpy as np
import pandas as pd
import pytest

from dropfit.errors import InputError
from dropfit.synth import simulate_drop
from dropfit.video.background import estimate_background
from dropfit.video.detect import (QUALITY_BLURRED, QUALITY_DUPLICATE, QUALITY_LOST, QUALITY_OCCLUDED, QUALITY_OK,
                                  QUALITY_PARTIAL)
from dropfit.video.track import (OCCLUDED_FULL_SEARCH_STRIDE, TRACKED_CENTRE_CORRELATION, BallTracker, track_frames,
                                 track_video, usable_rows)
from dropfit.video_synth import Camera, FrameRenderer, Scene, default_clips
from helpers import centre_errors, disc_coverage, rms

CLEAN_RMS_TOLERANCE_PX = 0.1  # px, centre error RMS on clean frames
NOISY_RMS_TOLERANCE_PX = 0.3  # px, centre error RMS with noise σ = 5 grey levels and motion blur
RADIUS_TOLERANCE_PX = 0.2  # px
HAND_BIAS_TOLERANCE_PX = 0.3  # px, centre error of ok frames after release with a hand nearby
HELD_TOLERANCE_PX = 1.5  # px, approximate centre of occluded (held) frames
TIME_TOLERANCE_S = 1e-6  # s
PARTIAL_RMS_TOLERANCE_PX = 0.3  # px, centre error RMS of partial (edge-cut) frames, noise σ = 2 grey levels
NOISE_GREY = 5.0  # grey levels
SUBFRAMES = 8  # sub-frames averaged for motion blur
EXPOSURE_FRAMES = 0.8  # exposure, in frame intervals
SIZE = (240, 320)  # px, height and width


def textured_background(rng, shape=SIZE, level=100.0, texture=6.0):
    """Mild smooth texture (σ ≈ texture grey levels) on a gentle gradient."""
    noise = cv2.GaussianBlur(rng.standard_normal(shape).astype(np.float32), (0, 0), 2.0)
    noise *= texture / noise.std()
    gradient = np.linspace(-10, 10, shape[1])[None, :]
    return level + gradient + noise


def render(background, centres, radius, ball_grey, rng=None, noise=0.0, colour=True, overlay=None):
    """One uint8 frame: the disc averaged over the exposure's centres, optional noise and overlay."""
    a = np.mean([disc_coverage(background.shape, cx, cy, radius) for cx, cy in centres], axis=0)
    image = background * (1 - a) + ball_grey * a
    if overlay is not None:
        mask, value = overlay
        image = np.where(mask, value, image)
    if noise:
        image = image + rng.normal(0, noise, image.shape)
    image = np.clip(np.round(image), 0, 255).astype(np.uint8)
    return np.repeat(image[:, :, None], 3, axis=2) if colour else image


def parabola(t, x0=60.2, y0=40.3, vx=3.3, vy=0.5, g=0.2):
    return x0 + vx * t, y0 + vy * t + 0.5 * g * t * t


def exposure_centres(t, blur):
    if not blur:
        return [parabola(t)]
    offsets = ((np.arange(SUBFRAMES) + 0.5) / SUBFRAMES - 0.5) * EXPOSURE_FRAMES
    return [parabola(t + o) for o in offsets]


def clip_frames(rng, n=40, radius=12.3, ball_grey=220.0, noise=0.0, blur=False, colour=True):
    background = textured_background(rng)
    frames, truth = [], []
    for t in range(n):
        centres = exposure_centres(t, blur)
        frames.append(render(background, centres, radius, ball_grey, rng, noise, colour))
        truth.append(np.mean(centres, axis=0))
    return frames, np.array(truth)


def report(capsys, text):
    with capsys.disabled():
        print(f"\n[tracking] {text}")


@pytest.mark.parametrize("ball_grey, colour", [(220.0, True), (30.0, False)])
def test_clean_frames_centre_and_radius(ball_grey, colour, capsys):
    rng = np.random.default_rng(1)
    radius = 12.3
    frames, truth = clip_frames(rng, radius=radius, ball_grey=ball_grey, colour=colour)
    table = track_frames(frames, np.arange(len(frames)) / 100.0)
    assert (table["quality"] == QUALITY_OK).all()
    errors = centre_errors(table, truth)
    radius_error = np.abs(table["radius_px"].to_numpy() - radius)
    report(capsys, f"clean, ball grey {ball_grey:g}: centre RMS {rms(errors):.4f} px, max {errors.max():.4f} px, "
                   f"radius max error {radius_error.max():.4f} px")
    assert rms(errors) <= CLEAN_RMS_TOLERANCE_PX
    assert radius_error.max() <= RADIUS_TOLERANCE_PX


@pytest.mark.parametrize("radius", [10.0, 15.7, 20.0])
def test_noisy_blurred_frames_centre(radius, capsys):
    rng = np.random.default_rng(2)
    frames, truth = clip_frames(rng, radius=radius, noise=NOISE_GREY, blur=True)
    table = track_frames(frames, np.arange(len(frames)) / 100.0)
    assert (table["quality"] == QUALITY_OK).all()
    errors = centre_errors(table, truth)
    radius_error = np.abs(table["radius_px"].to_numpy() - radius)
    report(capsys, f"noise σ={NOISE_GREY:g} + blur, r={radius:g}: centre RMS {rms(errors):.4f} px, "
                   f"max {errors.max():.4f} px, radius max error {radius_error.max():.4f} px")
    assert rms(errors) <= NOISY_RMS_TOLERANCE_PX
    assert radius_error.max() <= RADIUS_TOLERANCE_PX


def test_ball_leaving_the_image_is_flagged():
    rng = np.random.default_rng(3)
    background = textured_background(rng)
    radius, width = 12.0, SIZE[1]
    xs = 250.4 + 4.0 * np.arange(30)
    frames = [render(background, [(x, 120.6)], radius, 220.0, rng, 2.0) for x in xs]
    table = track_frames(frames, np.arange(30) / 100.0)
    inside = xs + radius < width - 0.5 - 1.0
    cut = xs + radius > width - 0.5 + 1.0
    gone = xs - radius > width - 0.5
    assert (table["quality"][inside] == QUALITY_OK).all()
    assert not (table["quality"][cut] == QUALITY_OK).any()
    assert (table["quality"][gone] == QUALITY_LOST).all()
    assert table["x_px"][gone].isna().all()
    errors = np.abs(table["x_px"][inside] - xs[inside])
    assert rms(errors) <= CLEAN_RMS_TOLERANCE_PX


def held_ball_frames(n, release, hand_until, radius=12.0, g=0.2):
    """``n`` frames of a ball (radius px) that a dark hand reaching from the top holds still until frame
    ``release``, then falls (g px/frame²); the hand stays until frame ``hand_until``. Returns the frames, the
    true centres (n × 2, px), the frames where the ball's top is within 1 px of the hand, and those where the
    ball is wholly in view."""
    rng = np.random.default_rng(4)
    background = textured_background(rng)
    cx0, cy0, overlap = 160.3, 40.7, 4.0
    s = np.maximum(np.arange(n) - release + 0.5, 0.0)
    truth = np.column_stack([cx0 + 0.3 * s, cy0 + 0.5 * g * s * s])
    yy, xx = np.mgrid[: SIZE[0], : SIZE[1]]
    hand = (np.abs(xx - cx0) <= 8) & (yy <= cy0 - radius + overlap)
    frames = [render(background, [tuple(truth[t])], radius, 220.0, rng, 2.0,
                     overlay=(hand, 60.0) if t <= hand_until else None) for t in range(n)]
    touching = truth[:, 1] - radius < cy0 - radius + overlap + 1.0
    touching[hand_until + 1:] = False
    visible = truth[:, 1] + radius < SIZE[0] - 0.5 - 1.0
    return frames, truth, touching, visible


def test_hand_holding_the_ball_is_flagged_then_ignored(capsys):
    """A dark hand reaching from the top overlaps the ball until frame 20; the ball drops at frame 10.

    Decision: frames where the hand touches the ball are flagged ``occluded`` (approximate centre
    from a circle fit to the free outline); once the hand is a separate blob, frames are ``ok`` and
    unbiased by it. The ball leaves the image at the bottom at the end.
    """
    n, release, hand_until = 80, 10, 20
    frames, truth, touching, visible = held_ball_frames(n, release, hand_until)
    table = track_frames(frames, np.arange(n) / 100.0)
    quality = table["quality"].to_numpy()
    errors = centre_errors(table, truth)
    ok = quality == QUALITY_OK
    near_hand = ok & ~touching & (np.arange(n) <= hand_until)
    report(capsys, f"hand: held frames {quality[release - 1]}, held centre max error {errors[:release].max():.3f} px; "
                   f"ok with the hand nearby: {near_hand.sum()} frames, max error {errors[near_hand].max():.4f} px; "
                   f"all ok frames: RMS {rms(errors[ok]):.4f} px, max {errors[ok].max():.4f} px")
    assert (quality[touching] == QUALITY_OCCLUDED).all()
    assert errors[touching].max() <= HELD_TOLERANCE_PX
    assert near_hand.sum() >= 2
    assert ok[~touching & visible].all()
    assert errors[ok].max() <= HAND_BIAS_TOLERANCE_PX
    assert not ok[~visible].any()


def test_a_ball_held_still_is_searched_for_in_few_frames(monkeypatch):
    """Held still by the hand for 30 frames, the ball is searched for (over the whole frame) in every
    ``OCCLUDED_FULL_SEARCH_STRIDE``-th of them only, not in each (30 searches before); the frames after its
    release are measured as when it was searched for in every frame."""
    n, release, hand_until = 100, 30, 34
    frames, truth, touching, visible = held_ball_frames(n, release, hand_until)
    searched = []
    real_search = BallTracker._search
    monkeypatch.setattr(BallTracker, "_search",
                        lambda self, frame, near=None: searched.append(self._index) or real_search(self, frame, near))
    table = track_frames(frames, np.arange(n) / 100.0)
    quality = table["quality"].to_numpy()
    held = np.flatnonzero(touching & (np.arange(n) < release))
    assert len(held) >= 25 and (quality[held] == QUALITY_OCCLUDED).all()
    # (the first frame, with nothing to predict from, and the first of the run are searched too)
    assert len([index for index in searched if index in held]) <= len(held) // OCCLUDED_FULL_SEARCH_STRIDE + 2
    ok = quality == QUALITY_OK
    assert ok[~touching & visible].all()
    assert centre_errors(table, truth)[ok].max() <= HAND_BIAS_TOLERANCE_PX


def test_duplicated_frames_are_flagged():
    rng = np.random.default_rng(5)
    frames, truth = clip_frames(rng, n=30, noise=2.0)
    for i in (8, 20):
        frames[i] = frames[i - 1].copy()
    table = track_frames(frames, np.arange(30) / 100.0)
    duplicate = table["quality"] == QUALITY_DUPLICATE
    assert np.flatnonzero(duplicate).tolist() == [8, 20]
    assert table["x_px"][duplicate].isna().all()
    assert (table["quality"][~duplicate] == QUALITY_OK).all()


def _write_avi(path, frames, fps):
    height, width = frames[0].shape[:2]
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), fps, (width, height))
    assert writer.isOpened()
    for frame in frames:
        writer.write(frame)
    writer.release()


def test_track_video_counts_and_times(tmp_path, capsys):
    rng = np.random.default_rng(6)
    frames, truth = clip_frames(rng, n=40, noise=2.0)
    path = tmp_path / "drop.avi"
    _write_avi(path, frames, 50.0)
    table = track_video(path)
    assert len(table) == 40
    assert np.allclose(table["time_s"], np.arange(40) / 50.0, atol=TIME_TOLERANCE_S)
    ok = table["quality"] == QUALITY_OK
    assert ok.all()
    errors = centre_errors(table, truth)
    report(capsys, f"MJPG AVI: centre RMS {rms(errors):.4f} px; time source: {table.attrs['time_source']}")
    assert rms(errors) <= NOISY_RMS_TOLERANCE_PX
    slow = track_video(path, capture_fps=500.0)
    assert np.allclose(slow["time_s"], np.arange(40) / 500.0, atol=TIME_TOLERANCE_S)


def test_unreadable_inputs_raise_input_error(tmp_path):
    broken = tmp_path / "broken.avi"
    broken.write_bytes(np.random.default_rng(7).integers(0, 256, 20000, dtype=np.uint8).tobytes())
    with pytest.raises(InputError, match="broken.avi"):
        track_video(broken)
    empty = tmp_path / "empty.avi"
    empty.write_bytes(b"")
    with pytest.raises(InputError, match="empty.avi"):
        track_video(empty)
    with pytest.raises(InputError, match="missing.avi"):
        track_video(tmp_path / "missing.avi")


def test_no_ball_raises_input_error():
    rng = np.random.default_rng(8)
    background = textured_background(rng)
    frames = [render(background, [(-100.0, -100.0)], 10.0, 220.0, rng, 2.0) for _ in range(10)]
    with pytest.raises(InputError, match="clip-7: the ball was never found"):
        track_frames(frames, np.arange(10) / 100.0, source="clip-7")
    with pytest.raises(InputError, match="no frames"):
        track_frames([], [])


def test_throughput_against_decoding(tmp_path, capsys):
    """Printed, not asserted: frames per second of track_video and of decoding alone, 1280×720."""
    rng = np.random.default_rng(9)
    shape, n, radius = (720, 1280), 200, 15.0
    background = textured_background(rng, shape)
    base = np.clip(np.round(background + rng.normal(0, 2.0, shape)), 0, 255).astype(np.uint8)
    base = np.repeat(base[:, :, None], 3, axis=2)
    frames = []
    for t in range(n):
        cx, cy = 200.3 + 4.1 * t, 60.2 + 0.012 * t * t
        x0, x1, y0, y1 = int(cx - 20), int(cx + 21), int(cy - 20), int(cy + 21)
        a = disc_coverage((y1 - y0, x1 - x0), cx - x0, cy - y0, radius)[:, :, None]
        frame = base.copy()
        frame[y0:y1, x0:x1] = np.round(frame[y0:y1, x0:x1] * (1 - a) + 220.0 * a).astype(np.uint8)
        frames.append(frame)
    path = tmp_path / "hd.avi"
    _write_avi(path, frames, 120.0)

    start = time.perf_counter()
    capture = cv2.VideoCapture(str(path))
    decoded = 0
    while capture.read()[0]:
        decoded += 1
    capture.release()
    decode_fps = decoded / (time.perf_counter() - start)
    start = time.perf_counter()
    table = track_video(path)
    track_fps = len(table) / (time.perf_counter() - start)
    report(capsys, f"1280×720 MJPG, {n} frames: decode only {decode_fps:.0f} fps, track_video {track_fps:.0f} fps "
                   f"({100 * track_fps / decode_fps:.0f} % of decoding); ok frames {(table['quality'] == 'ok').sum()}")
    assert decoded == n == len(table)


@pytest.fixture(scope="module")
def edge_cut_clip():
    """40 frames at 2000 fps of the tennis ball's first touchdown, its right side cut by the image edge.

    Rendered by dropfit.video_synth (seam, textured background, sensor noise σ = 2, no codec) with the
    drop line 20 px from the right edge: 13.5 px of the 33.5 px radius are outside the image.
    """
    clip = default_clips()["contact_2000fps_closeup"]
    truth = simulate_drop(**clip["truth"])
    camera = Camera(320, 240, 2000.0, 1e-4, px_per_m=1000.0, image_row_of_floor_px=200.0, drop_column_px=300.0,
                    noise_sigma=2.0)
    renderer = FrameRenderer(truth, camera, Scene(seam=True, background_texture=4.0, ruler_column_px=20.0),
                             seed=10, start_s=clip["start_s"])
    frames, rows = zip(*(renderer.render(k) for k in range(40)))
    return list(frames), pd.DataFrame(rows)


def test_partial_frames_circle_fit_with_known_radius(edge_cut_clip, capsys):
    """Decision: with the radius known (from clean frames, here given), the centre of a ball cut by the
    image edge comes from a fixed-radius circle fit to the sub-pixel outline; in flight it is within
    PARTIAL_RMS_TOLERANCE_PX of the renderer's truth and usable for the trajectory."""
    frames, truth = edge_cut_clip
    radius = truth["radius_px"].iloc[0]
    table = track_frames(frames, truth["time_s"], expected_radius_px=radius)
    flight = ~truth["in_contact"].to_numpy()
    assert (table["quality"] == QUALITY_PARTIAL).all()
    errors = centre_errors(table, truth[["x_px", "y_px"]].to_numpy())
    report(capsys, f"partial, radius held: centre RMS {rms(errors[flight]):.4f} px, max {errors[flight].max():.4f} px, "
                   f"median centre se {table['centre_se_px'].median():.4f} px")
    assert rms(errors[flight]) <= PARTIAL_RMS_TOLERANCE_PX
    assert np.isfinite(table["centre_se_px"]).all() and np.isfinite(table["fit_rms_px"]).all()
    assert usable_rows(table, radius)[flight].all()
    assert not usable_rows(table).any()  # no clean frame and no radius given: none usable



def render_clip(camera, scene, duration_s, release_s, seed):
    """Frames and ground-truth rows of a 0.8 m drop of a 33 mm ball (e = 0.75) filmed by ``camera``."""
    truth = simulate_drop(0.8, 0.033, {"kind": "constant", "e0": 0.75}, release_time_s=release_s)
    renderer = FrameRenderer(truth, camera, scene, seed=seed)
    frames, rows = zip(*(renderer.render(k) for k in range(int(round(duration_s * camera.fps)))))
    return list(frames), pd.DataFrame(rows)


def test_noise_free_clip_is_tracked_and_only_repeated_frames_are_duplicates(capsys):
    """Decision: a frame is a duplicate only when the whole frame repeats the previous one while the
    ball was predicted to move. A noise-free clip (identical background in every frame) is tracked
    in full, the ball held still before release included; frames copied over their successor in
    mid-flight are still flagged."""
    camera = Camera(320, 400, 240.0, px_per_m=400.0, image_row_of_floor_px=380.0, noise_sigma=0.0)
    frames, truth = render_clip(camera, Scene(), 1.7, 0.1, seed=11)
    copied = [100, 101, 250]  # two in a row, and one more
    for i in copied:
        frames[i] = frames[i - 1]
    table = track_frames(frames, truth["time_s"])
    quality = table["quality"].to_numpy()
    assert np.flatnonzero(quality == QUALITY_DUPLICATE).tolist() == copied
    ok = quality == QUALITY_OK
    errors = centre_errors(table, truth[["centroid_x_px", "centroid_y_px"]].to_numpy())
    report(capsys, f"noise-free, {len(frames)} frames: {ok.mean():.1%} ok, centre RMS {rms(errors[ok]):.4f} px")
    assert ok.mean() >= 0.95
    assert rms(errors[ok]) <= CLEAN_RMS_TOLERANCE_PX


def test_ball_blurred_longer_than_its_diameter_is_measured(capsys):
    """Decision: at 60 fps with the shutter open for the whole frame interval the ball travels up to
    its diameter during the exposure near the floor, a streak up to twice as long as the ball. Such a
    streak (a stadium of the ball's radius along its motion) is measured as ``blurred``, centre =
    coverage-weighted centroid, and compared with the renderer's exposure-averaged centroid; the ball
    held still by a hand is not taken for a streak."""
    camera = Camera(320, 400, 60.0, 1 / 60.0, px_per_m=400.0, image_row_of_floor_px=380.0, noise_sigma=2.0)
    frames, truth = render_clip(camera, Scene(hand=True), 1.7, 0.1, seed=12)
    table = track_frames(frames, truth["time_s"])
    quality = table["quality"].to_numpy()
    streak_px = np.abs(np.gradient(truth["y_px"].to_numpy())) * camera.exposure * camera.fps
    long_streak = (streak_px > truth["radius_px"]) & truth["visible"].to_numpy()  # 1.5 diameters or longer
    blurred = quality == QUALITY_BLURRED
    errors = centre_errors(table, truth[["centroid_x_px", "centroid_y_px"]].to_numpy())
    report(capsys, f"60 fps, full-interval exposure: {long_streak.sum()} frames streaked over > 1.5 diameters, "
                   f"{blurred.sum()} blurred; their centre RMS {rms(errors[blurred]):.4f} px, "
                   f"max {errors[blurred].max():.4f} px")
    assert long_streak.sum() >= 10
    assert np.isin(quality[long_streak], [QUALITY_OK, QUALITY_BLURRED]).all()
    assert blurred.sum() >= 10
    assert errors[blurred].max() <= NOISY_RMS_TOLERANCE_PX
    assert usable_rows(table)[long_streak].all()
    assert not blurred[truth["time_s"].to_numpy() < 0.1].any()  # held still by the hand until 0.1 s


CORRELATION_TOLERANCE = 0.1  # dimensionless, lag-1 autocorrelation averaged over 4 clips of ~200 frames


def test_tracked_centre_errors_are_as_correlated_as_the_analysis_assumes(tmp_path):
    """The analysis of a video treats the tracked centre's errors as AR(1) with TRACKED_CENTRE_CORRELATION;
    measured against the renderer's truth, their lag-1 autocorrelation averages about that."""
    from dropfit.video_synth import render_video

    truth = simulate_drop(0.8, 0.0335, {"kind": "constant", "e0": 0.75}, mass_kg=0.057, release_time_s=0.05)
    correlations = []
    for seed, (fps, px_per_m, width, height) in enumerate([(120.0, 160.0, 48, 200), (240.0, 350.0, 320, 400)] * 2):
        camera = Camera(width, height, fps, 0.0, px_per_m=px_per_m, image_row_of_floor_px=height - 10.0,
                        noise_sigma=2.0, quality=90)
        frames = render_video(truth, camera, Scene(), 1.0, seed, tmp_path / f"clip{seed}.avi")
        table = track_video(frames.attrs["video_path"])
        error = np.where(table["quality"] == QUALITY_OK, table["y_px"] - frames["y_px"].to_numpy(), np.nan)
        error -= np.nanmean(error)
        pairs = np.isfinite(error[:-1]) & np.isfinite(error[1:])
        correlations.append(np.corrcoef(error[:-1][pairs], error[1:][pairs])[0, 1])
    print(f"\n[tracking] lag-1 autocorrelation of centre errors: {np.round(correlations, 3)}")
    assert np.mean(correlations) == pytest.approx(TRACKED_CENTRE_CORRELATION, abs=CORRELATION_TOLERANCE)


def test_background_keeps_the_scene_in_colour_for_rulers_and_markers():
    """The median background of BGR frames keeps its colour (per channel), what the ruler reader and the
    marker detector read; grey frames give none."""
    rng = np.random.default_rng(4)
    frames = [rng.integers(0, 256, (12, 16, 3), dtype=np.uint8) for _ in range(5)]
    background = estimate_background(frames)
    assert np.array_equal(background.colour, np.median(np.stack(frames), axis=0).astype(np.uint8))
    assert background.image() is background.colour
    grey = estimate_background([frame[:, :, 1] for frame in frames])
    assert grey.colour is None and grey.image().shape == (12, 16)


def test_a_repeated_capture_the_frame_test_missed_is_told_by_a_ball_that_did_not_move():
    """A 30 Hz capture in a 60 fps file: every capture is shown twice, and the codec re-encodes the copy with
    changes elsewhere in the frame, so the frame test takes it for a new one (phonesim's white MOV: 116 of 213
    copies). Measured again, its ball sits within 0.05 px of the previous frame's, while a new capture's moved
    on. Every copy in flight (the ball at least 1 px a frame on both sides, the same way) is a duplicate, and a
    copy fitted to the bit at an apex too; no new capture is, nor a ball that bounces, is caught or is held."""
    from dropfit.video.track import REPEAT_MIN_SPEED_PX, refitted_repeats

    truth = simulate_drop(0.6, 0.02, {"kind": "constant", "e0": 0.89}, release_time_s=0.2)
    rng = np.random.default_rng(3)
    captures = np.arange(0.0, 2.0, 1 / 30)
    rows = 840.0 - 750.0 * truth.height(captures)  # image rows, 750 px/m
    caught = captures > 1.6  # a hand stops the ball: the new captures show it still
    rows[caught] = rows[np.flatnonzero(caught)[0]] + rng.normal(0.0, 0.02, caught.sum())
    y = np.repeat(rows, 2)
    x = np.full(y.size, 300.0)
    copy = np.arange(y.size) % 2 == 1
    y[copy] += rng.normal(0.0, 0.05, copy.sum())  # the copy's centre refitted on re-encoded pixels
    apex = int(np.argmin(rows[(captures > 0.9) & (captures < 1.3)])) + np.flatnonzero(captures > 0.9)[0]
    y[2 * apex + 1] = y[2 * apex]  # one copy fitted to the bit, at the top of a flight
    quality = np.full(y.size, "shaded", dtype=object)
    quality[np.repeat(captures < 0.2, 2)] = "occluded"  # held: the hand moves it, and it is merged with it
    y[np.repeat(captures < 0.2, 2)] += np.repeat(np.linspace(0.0, 3.0, (captures < 0.2).sum()), 2)
    flagged = refitted_repeats(x, y, quality)
    assert not flagged[~copy].any()  # no new capture
    # capture k's copy (frame 2k + 1) lies between capture k and capture k + 1, each a frame away
    before, after = np.diff(rows)[:-1], np.diff(rows)[1:]
    in_flight = np.zeros(rows.size, dtype=bool)
    in_flight[1:-1] = ((np.minimum(np.abs(before), np.abs(after)) >= REPEAT_MIN_SPEED_PX) & (before * after > 0)
                       & (captures[1:-1] > 0.2) & ~caught[2:])
    assert in_flight.sum() >= 30 and flagged[1::2][in_flight].all(), np.flatnonzero(in_flight & ~flagged[1::2])
    assert flagged[2 * apex + 1]
    assert not flagged[np.repeat(caught, 2)].any()
    assert not flagged[quality == "occluded"].any()


def test_motion_blur_is_measured_from_the_coverage_moments():
    """A ball exposed over a whole frame interval at 60 fps is smeared along its path by its step; the tracker's
    ``blur_px`` (the coverage's second moments) matches the renderer's |v| × exposure within 10 % wherever that is
    5 px or more (up to 16 px here), and is under 2 px on a ball at rest near its apex."""
    fps = 60.0
    camera = Camera(120, 260, fps, 1 / fps, px_per_m=250.0, image_row_of_floor_px=240.0, noise_sigma=2.0)
    frames, truth = render_clip(camera, Scene(), 1.2, 0.05, seed=3)
    table = track_frames(frames, truth["time_s"])
    step_px = np.abs(np.gradient(truth["y_px"].to_numpy()))  # px a frame, = the blur at this exposure
    # a frame whose exposure may hold a bounce (which may fall between frames) has no one step
    direction = np.sign(np.diff(truth["y_px"].to_numpy()))
    turning = np.r_[True, direction[1:] != direction[:-1], True] | truth["in_contact"].to_numpy()
    turning |= np.r_[turning[1:], True] | np.r_[True, turning[:-1]]
    clean = table["quality"].isin([QUALITY_OK, QUALITY_BLURRED]).to_numpy()
    blurred, still = clean & ~turning & (step_px >= 5.0), clean & (step_px < 0.5)
    measured = table["blur_px"].to_numpy()
    assert blurred.sum() >= 10 and still.sum() >= 3
    assert np.all(np.abs(measured[blurred] / step_px[blurred] - 1) <= 0.10), np.c_[step_px, measured][blurred]
    assert np.all(measured[still] < 2.0), measured[still]


def test_positions_off_the_ballistic_track_are_left_out_and_counted(tmp_path):
    """Issue 32: a tennis ball before a dark door (20 fps, 314 × 486 px) with its circle 60 px beside the ball in 6
    frames about impacts 2-4 gave e = 0.708 ± 0.015 against its sound's 0.670 ± 0.002: a tracking jump taken for a
    measurement. phonesim's clip of that scene, tracked, with six positions about impacts 2-4 moved 55 px aside and
    25 px up as such a jump: those six, and no other, are flagged ``off_track``, left out, counted in the trajectory
    and named in the notes, and e stays within 0.005 of the truth with the truth inside its interval."""
    from helpers import phone_clip

    from dropfit.pipeline import process_recording, split_options
    from dropfit.settings import Settings
    from dropfit.video.quality import QUALITY_OFF_TRACK, mark_off_track
    from dropfit.video.track import TrackedVideo, track_video_and_background

    path, truth = phone_clip("tennis_door", tmp_path, seed=1, downscale=1.0, duration_s=4.0)
    tracked = track_video_and_background(path)
    table = tracked.table
    assert not (table["quality"] == QUALITY_OFF_TRACK).any(), table[table["quality"] == QUALITY_OFF_TRACK]
    usable = np.flatnonzero(usable_rows(table))
    jumped = []
    for impact in truth["physics"]["impacts"][1:4]:
        jumped += list(usable[np.argsort(np.abs(table["time_s"].to_numpy()[usable] - impact["t_touchdown_s"]))[:2]])
    table = table.copy()
    table.loc[jumped, "x_px"] += 55.0
    table.loc[jumped, "y_px"] -= 25.0
    assert sorted(np.flatnonzero(mark_off_track(table)["quality"] == QUALITY_OFF_TRACK)) == sorted(jumped)
    physics = truth["physics"]
    ball, _ = split_options({"ball_radius_m": physics["radius_m"], "ball_mass_kg": physics["mass_kg"],
                             "ball_type": physics["ball_model"]})
    result = process_recording(path, ball, Settings(), tracked=TrackedVideo(table, tracked.background))
    assert result.trajectory.attrs["frames_off_track"] == 6
    assert any("off the ballistic track" in note for note in result.notes), result.notes
    true_e = pd.DataFrame(physics["impacts"])
    measured = result.impacts[np.isfinite(result.impacts["e"])]  # (an impact whose flight is too short: no e)
    assert len(measured) >= 2, result.impacts
    for _, impact in measured.iterrows():
        e_true = true_e["e"].iloc[int(np.argmin(np.abs(true_e["t_touchdown_s"] - impact["t_touchdown_s"])))]
        assert abs(impact["e"] - e_true) <= 0.005, result.impacts
        assert impact["e_ci95_low"] <= e_true <= impact["e_ci95_high"], result.impacts


def test_a_radius_learnt_too_large_is_learnt_again_from_the_balls_in_flight(capsys):
    """The green ball's real clip (issue 32): the radius learnt from the frame the hand let the ball go was 46.7 px
    (a finger's edge with it), the ball then measured 41-44.5 px alone in every flight frame, and each was flagged
    occluded (5 % short: partly hidden), so no ``ok`` ball could correct the radius: 19 % of the frames clean.
    Here the radius expected is 9 % too large: once the ball has been measured alone at one smaller size in four
    frames in a row while in flight, it is ``ok`` again, at its true radius and centre."""
    rng = np.random.default_rng(7)
    radius = 12.3
    frames, truth = clip_frames(rng, radius=radius)
    table = track_frames(frames, np.arange(len(frames)) / 100.0, expected_radius_px=1.09 * radius)
    ok = (table["quality"] == QUALITY_OK).to_numpy()
    report(capsys, f"radius expected 9 % too large: {ok.sum()} of {len(ok)} frames ok, from frame "
                   f"{np.flatnonzero(ok)[0] if ok.any() else None}")
    assert ok.sum() >= 12
    assert ok[-10:].all()
    errors = centre_errors(table, truth)[ok]
    assert rms(errors) <= CLEAN_RMS_TOLERANCE_PX
    assert np.abs(table["radius_px"].to_numpy()[ok] - radius).max() <= RADIUS_TOLERANCE_PX


def test_a_ball_streaked_longer_than_predicted_is_measured_as_blurred(tmp_path):
    """Issue 32: a white table-tennis ball before a dark door, 20 fps, 314 × 486 px, was measured in 46-63 of 104
    frames and refused. phonesim's clip of that scene, exposed for the whole frame interval (a dim room): the
    falling ball is a streak longer than the travel the tracker predicts from the hand that held it, or from
    earlier streaks' centres fitted at one end, and each was flagged occluded (11 frames in a row after the release,
    centres 13-31 px short), so the prediction never caught up. Measured along its own long axis, the streak is
    ``blurred`` at its middle: two thirds of the first fall's frames usable within 3 px of the truth (6 of 9; 2
    before), and e within 0.01 of the truth's (refused before: too few clean frames after impact 2)."""
    from helpers import phone_clip

    import dropfit

    path, truth = phone_clip("white_pingpong_door", tmp_path, seed=2, downscale=1.0, duration_s=5.2)
    table = track_video(path)
    frames = pd.read_csv(path.with_suffix(".frames.csv"))
    first_touchdown = truth["physics"]["impacts"][0]["t_touchdown_s"]
    falling = ((frames["phase"] == "flight") & (frames["capture_time_s"] < first_touchdown)).to_numpy()
    usable = usable_rows(table)
    error = np.hypot(table["x_px"] - frames["x_px"], table["y_px"] - frames["y_px"]).to_numpy()
    good = usable & (error <= 3.0)
    assert good[falling].sum() >= 2 / 3 * falling.sum(), table[falling]
    physics = truth["physics"]
    result = dropfit.analyse_recording(path, ball_radius_m=physics["radius_m"], ball_mass_kg=physics["mass_kg"],
                                       ball_type=physics["ball_model"])
    true_e = pd.DataFrame(physics["impacts"])
    measured = result.impacts[np.isfinite(result.impacts["e"])]
    assert len(measured) >= 2, result.impacts
    for _, impact in measured.iterrows():
        e_true = true_e["e"].iloc[int(np.argmin(np.abs(true_e["t_touchdown_s"] - impact["t_touchdown_s"])))]
        assert abs(impact["e"] - e_true) <= 0.01, result.impacts


def _speck_scene():
    """A grey scene (400 × 300 px) with a dark ball (radius 20 px) held by a dark hand reaching in from the top, and
    a lone codec speck (radius 3 px) elsewhere: the ball is merged with the hand, the speck is a lone disc."""
    import cv2

    background = np.full((300, 400), 200, np.uint8)
    frame = background.copy()
    cv2.circle(frame, (120, 80), 20, 60, -1)
    cv2.rectangle(frame, (112, 0), (128, 70), 60, -1)  # the hand's finger, narrower than the ball
    cv2.circle(frame, (320, 220), 3, 60, -1)
    return background, frame


def test_a_search_with_the_channels_ball_size_does_not_take_a_speck():
    """Issue 32, the speck trap (green ball's real clip: 5.7 px learnt from a codec speck, the 44 px ball merged
    with the hand never looked for again): with the channel's ball size from the clip's samples, the first search
    takes the held ball (occluded, radius about 20 px), not the lone 3 px speck."""
    from dataclasses import replace

    from dropfit.video.background import estimate_background
    from dropfit.video.contrast import GREY, contrast_of

    background_image, frame = _speck_scene()
    background = estimate_background([background_image] * 3)
    contrast = replace(contrast_of(GREY, (), background), ball_radius_px=20.0)
    x, y, radius, quality, *_ = BallTracker(background, contrast=contrast).update(frame)
    assert math.hypot(x - 120, y - 80) < 5 and 15 < radius < 25, (x, y, radius, quality)


def _clip_at_rest_for_most_of_it(path, frames, shape=(240, 320), radius=30, scale_px_per_m=900.0, fps=100.0,
                                 drop_m=0.2, e=0.85, seed=5):
    """A ball drawn with OpenCV's anti-aliased disc (no code of the tracker's), dropped from ``drop_m`` at
    frame 0 and bouncing with ``e`` until its rebound speed is below 0.05 m/s, then at rest to the end;
    MJPEG. Returns the impact times, s."""
    g = 9.80665
    impacts, speeds = [math.sqrt(2 * drop_m / g)], [e * math.sqrt(2 * g * drop_m)]
    while speeds[-1] > 0.05:
        impacts.append(impacts[-1] + 2 * speeds[-1] / g)
        speeds.append(speeds[-1] * e)
    height_px, width_px = shape
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), fps, (width_px, height_px))
    rng = np.random.default_rng(seed)
    for index in range(frames):
        t = index / fps
        flight = int(np.searchsorted(impacts, t))
        tau = t - impacts[flight - 1] if 0 < flight < len(impacts) else 0.0
        height = drop_m - 0.5 * g * t * t if flight == 0 else (
            speeds[flight - 1] * tau - 0.5 * g * tau * tau if flight < len(impacts) else 0.0)
        image = (40 + rng.integers(0, 5, (height_px, width_px, 3))).astype(np.uint8)
        centre_y = height_px - 10 - radius - max(height, 0.0) * scale_px_per_m
        cv2.circle(image, (width_px // 2 * 16, int(round(centre_y * 16))), radius * 16, (60, 200, 230), -1,
                   lineType=cv2.LINE_AA, shift=4)
        writer.write(image)
    writer.release()
    return np.array(impacts)


@pytest.mark.parametrize("frames", [440, 600])
def test_a_ball_at_rest_for_most_of_the_clip_keeps_its_drop_and_every_impact(tmp_path, frames):
    """The bounces end after 2.43 s; at rest for the 45 % (60 %) of the frames after, the ball was in the
    median background: its ghost there was tracked instead of the falling ball (the drop and first impact
    lost), the low bounces were shaded by it, and the rest's noise-free centres made a flight's noise read as
    tracking jumps (6 impacts of 11 and no drop height; 5 and 64 samples left out)."""
    from dropfit import analyse_recording

    path = tmp_path / "rest.avi"
    impacts = _clip_at_rest_for_most_of_it(path, frames)
    result = analyse_recording(path, ball_radius_m=30 / 900.0)
    fit = result.to_dict()
    assert not any("tracking jumps" in note for note in fit["notes"]), fit["notes"]
    # every impact with a flight of at least 5 frames after it, numbered from the drop
    measurable = int(np.sum(np.diff(impacts) * 100.0 >= 5))
    assert fit["restitution"]["n_impacts"] >= measurable - 1 >= 9
    assert abs(fit["drop_height_m"]["value"] - 0.2) < 0.002
    assert abs(fit["restitution"]["e"]["value"] - 0.85) < 0.002
