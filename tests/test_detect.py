"""The ball told from its shadow, a hand, flicker and a wall of its own brightness, in colour clips drawn here.

Each clip is drawn independently of the tracker: a textured coloured board, a soft darker shadow
that touches the ball, the ball as a disc of one colour anti-aliased by supersampling (and averaged
over sub-frames for motion blur), a skin-coloured hand and arm from the top edge, a global gain per
frame, and sensor noise independent per channel.
"""

import math

import cv2
import numpy as np
import pytest

from dropfit.video.background import estimate_background
from dropfit.errors import InputError
from dropfit.video.contrast import hand_pixels, skin_mask
from dropfit.video.detect import QUALITY_LOST, QUALITY_OCCLUDED, QUALITY_OK, QUALITY_SHADED, measure_ball
from dropfit.video.limits import check_recording
from dropfit.video.track import TrackerHints, track_frames, usable_rows
from helpers import centre_errors, disc_coverage, rms

SIZE = (240, 320)  # px, height and width
NOISE_GREY = 2.0  # grey levels, sensor noise per channel
RADIUS_PX = 14.0
SUBFRAMES = 8  # sub-frames averaged for motion blur
SKIN_BGR = (120.0, 150.0, 205.0)
#: A crimson ball as a phone films it (the real clip red_ball_portrait.mp4): YCrCb Cr 174, Cb 122, inside the skin
#: ranges of dropfit.video.contrast.skin_mask
CRIMSON_BGR = (62.0, 42.0, 135.0)
HAND_HALF_WIDTH_PX = 17.0  # wider than the ball: the hand is no narrow attachment
HAND_OVERLAP_PX = 5.0  # the fingers cover the ball's top by this much
# centre error tolerances, px (RMS over the clean frames; the worst frame within twice that)
SHADOW_TOLERANCE_PX = 0.1  # sharp ball, soft shadow touching it
BLUR_TOLERANCE_PX = 0.3  # motion blur over 0.8 frame intervals, strong shadow
FLICKER_TOLERANCE_PX = 0.1
ISOLUMINANT_TOLERANCE_PX = 0.15  # the ball differs from the wall in colour, hardly in brightness
HAND_TOLERANCE_PX = 0.1  # clean frames after the hand has gone
SHADED_TOLERANCE_PX = 0.3  # a light ball measured on its lit side, in its soft shadow


def board(rng, bgr, texture=3.0):
    """A coloured board: the colour plus a mild smooth texture (σ ≈ ``texture``) on a gentle gradient."""
    noise = cv2.GaussianBlur(rng.standard_normal(SIZE).astype(np.float32), (0, 0), 2.0)
    noise *= texture / noise.std()
    gradient = np.linspace(-8.0, 8.0, SIZE[1])[None, :]
    return np.asarray(bgr, float)[None, None, :] + (gradient + noise)[:, :, None]


def path(t, x0=80.3, y0=40.6, vx=4.1, g=0.35):
    """The ball's centre (x, y) at frame time ``t``: x linear, y a parabola, px."""
    return x0 + vx * t, y0 + 0.5 * g * t * t


def shadow_alpha(cx, cy, offset, softness_px=3.0):
    """A soft shadow of the ball on the board behind it, offset by ``offset`` (dx, dy) radii."""
    alpha = disc_coverage(SIZE, cx + offset[0] * RADIUS_PX, cy + offset[1] * RADIUS_PX, 1.05 * RADIUS_PX)
    return cv2.GaussianBlur(alpha.astype(np.float32), (0, 0), softness_px)


def hand_alpha(tip_x, tip_y):
    """A hand and forearm reaching down from the top edge to (tip_x, tip_y), anti-aliased."""
    rows, columns = np.mgrid[: SIZE[0], : SIZE[1]]
    arm = (np.abs(columns - tip_x) <= HAND_HALF_WIDTH_PX) & (rows <= tip_y)
    return cv2.GaussianBlur(arm.astype(np.float32), (0, 0), 0.7)


def draw_clip(rng, wall_bgr, ball_bgr, n=30, shadow=None, gains=None, blur=0.0, held_until=None):
    """Frames (uint8 BGR) and the true exposure-averaged centres (n, 2) of a ball thrown along :func:`path`.

    ``shadow`` is (dx, dy, darkening) with the offset in radii; ``blur`` the exposure in frame
    intervals; with ``held_until`` the ball hangs still from a hand until that frame, released then,
    and the hand moves up and to the right afterwards.
    """
    wall = board(rng, wall_bgr)
    ball = np.asarray(ball_bgr, float)
    frames, truth = [], []
    for k in range(n):
        t = k if held_until is None else max(k - held_until, 0.0)
        offsets = ((np.arange(SUBFRAMES) + 0.5) / SUBFRAMES - 0.5) * blur if blur else [0.0]
        centres = [path(t + o) if t > 0 or held_until is None else path(0.0) for o in offsets]
        cx, cy = np.mean(centres, axis=0)
        scene = wall.copy()
        if shadow is not None:
            scene *= 1.0 - (1.0 - shadow[2]) * shadow_alpha(cx, cy, shadow[:2])[:, :, None]
        a = np.mean([disc_coverage(SIZE, x, y, RADIUS_PX) for x, y in centres], axis=0)[:, :, None]
        image = scene * (1.0 - a) + ball * a
        if held_until is not None:
            away = max(k - held_until, 0) * 6.0
            x_hand, y_hand = path(0.0)
            h = hand_alpha(x_hand + away, y_hand - RADIUS_PX + HAND_OVERLAP_PX - away)[:, :, None]
            image = image * (1.0 - h) + np.asarray(SKIN_BGR) * h
        gain = 1.0 if gains is None else gains[k]
        image = gain * image + rng.normal(0.0, NOISE_GREY, image.shape)
        frames.append(np.clip(np.round(image), 0, 255).astype(np.uint8))
        truth.append((cx, cy))
    return frames, np.array(truth)


def report(capsys, text):
    with capsys.disabled():
        print(f"\n[detect] {text}")


def tracked(frames, **hints):
    return track_frames(frames, np.arange(len(frames)) / 120.0, hints=TrackerHints(**hints))


def tracked_ok_and_errors(frames, truth):
    """The tracked table, which of its rows are ``ok``, and each row's centre error against ``truth``, px."""
    table = tracked(frames)
    return table, table["quality"].to_numpy() == QUALITY_OK, centre_errors(table, truth)


@pytest.mark.parametrize("name, wall, ball, shadow", [
    ("green ball, white board", (215.0, 220.0, 225.0), (60.0, 165.0, 70.0), (0.5, 0.45, 0.55)),
    ("white ball, light grey wall", (200.0, 200.0, 195.0), (245.0, 245.0, 245.0), (0.6, 0.4, 0.75)),
])
def test_the_shadow_touching_the_ball_is_not_merged(name, wall, ball, shadow, capsys):
    """Decision: a shadow is the background darkened with its chromaticity kept; it is left out of
    the ball's foreground, and the ball's edge over it is measured against the shadowed board."""
    rng = np.random.default_rng(31)
    frames, truth = draw_clip(rng, wall, ball, shadow=shadow)
    table, ok, errors = tracked_ok_and_errors(frames, truth)
    report(capsys, f"[{table.attrs['contrast']}] {name}, shadow touching: {ok.sum()}/{len(ok)} ok, centre RMS "
                   f"{rms(errors[ok]):.4f} px, max {errors[ok].max():.4f} px, radius {table['radius_px'][ok].median():.3f} px")
    assert ok.all()
    assert rms(errors) <= SHADOW_TOLERANCE_PX and errors.max() <= 2 * SHADOW_TOLERANCE_PX
    assert table["radius_px"].to_numpy() == pytest.approx(RADIUS_PX, abs=0.2)


def test_a_dark_grey_ball_merged_with_its_shadow_is_flagged_not_measured(capsys):
    """Decision: a dark achromatic ball looks like a shadow, so its shadow cannot be told from it by
    colour; it is found by shape (the inscribed circle), flagged ``occluded`` and not used, and the
    refusal names the merging (and the options that could help), never a wrong cause."""
    rng = np.random.default_rng(41)
    frames, truth = draw_clip(rng, (200.0, 200.0, 195.0), (50.0, 50.0, 50.0), shadow=(0.6, 0.45, 0.6))
    table = tracked(frames)
    quality = table["quality"].to_numpy()
    errors = centre_errors(table, truth)
    with pytest.raises(InputError) as refusal:
        check_recording(table, "clip.mp4")
    report(capsys, f"dark grey ball, shadow touching: {np.mean(quality == QUALITY_OCCLUDED):.0%} occluded, "
                   f"approximate centre max error {errors[quality == QUALITY_OCCLUDED].max():.2f} px; {refusal.value}")
    # the first frame, before the ball's size is known, may pass for a lone disc; the clip is refused
    assert usable_rows(table)[1:].sum() == 0
    assert np.mean(quality == QUALITY_OCCLUDED) >= 0.9
    assert errors[quality == QUALITY_OCCLUDED].max() <= RADIUS_PX / 3
    assert "merged with something (its shadow, a hand)" in str(refusal.value)
    assert "--ball-colour" in str(refusal.value) and "\n" not in str(refusal.value)


@pytest.mark.parametrize("name, ball", [("red", (40.0, 40.0, 200.0)), ("crimson (skin-like)", CRIMSON_BGR)],
                         ids=["red", "crimson"])
def test_a_motion_blurred_ball_with_a_strong_shadow(name, ball, capsys):
    """The crimson ball's colour lies in the skin ranges: it was masked as a hand in every channel, and the ball was
    followed in grey levels merged with its shadow, every centre 5.6 px off."""
    rng = np.random.default_rng(32)
    frames, truth = draw_clip(rng, (190.0, 200.0, 205.0), ball, shadow=(0.6, 0.5, 0.45), blur=0.8)
    table = tracked(frames)
    usable = usable_rows(table)
    errors = centre_errors(table, truth)
    report(capsys, f"[{table.attrs['contrast']}] {name} ball, blur 0.8 frame, strong shadow: {usable.sum()}/{len(usable)} usable, "
                   f"centre RMS {rms(errors[usable]):.4f} px, max {errors[usable].max():.4f} px")
    assert usable.all()
    assert rms(errors) <= BLUR_TOLERANCE_PX and errors.max() <= 2 * BLUR_TOLERANCE_PX


@pytest.mark.parametrize("ball, held", [((40.0, 225.0, 205.0), QUALITY_OCCLUDED), (CRIMSON_BGR, QUALITY_LOST)],
                         ids=["yellow", "crimson"])
def test_the_hand_holding_the_ball_is_never_the_ball_and_its_frames_are_not_used(ball, held, capsys):
    """Decision: a skin-coloured hand wider than the ball holds it for 10 frames; those frames are
    ``occluded`` (not usable), the hand is never tracked, and once it has moved away the ball is ``ok``. A crimson
    ball (its colour inside the skin ranges) merges with the hand into one skin-coloured area that is no disc: it is
    hidden with the hand (``lost``) until it is a lone disc. Before, the hand's pieces were measured as the crimson
    ball (20-45 px off)."""
    rng = np.random.default_rng(33)
    held_until = 10
    frames, truth = draw_clip(rng, (215.0, 220.0, 225.0), ball, n=36, held_until=held_until)
    table = tracked(frames)
    quality = table["quality"].to_numpy()
    usable = usable_rows(table)
    errors = centre_errors(table, truth)
    free = np.arange(len(frames)) >= held_until + 2  # the fingers are 6 px higher each frame after release
    report(capsys, f"[{table.attrs['contrast']}] hand: held frames {sorted(set(quality[:held_until]))}, held centre max error "
                   f"{np.nanmax(errors[:held_until], initial=0.0):.3f} px; free frames {usable[free].sum()}/{free.sum()} "
                   f"usable, centre RMS {rms(errors[free]):.4f} px, max {errors[free].max():.4f} px")
    assert (quality[:held_until] == held).all()
    assert not usable[:held_until].any()
    assert np.nanmax(errors) <= RADIUS_PX / 4  # the hand is never taken for the ball
    assert (quality[free] == QUALITY_OK).all()
    assert rms(errors[free]) <= HAND_TOLERANCE_PX


def test_a_ball_of_a_skin_like_colour_is_no_hand():
    """Decision: a skin-coloured area that is a lone disc, clear of the image's border, is a ball whose colour lies in
    the skin ranges (crimson, orange, pink), not a hand: the hand mask leaves the crimson disc out (a highlight's
    notch in it too) and keeps the skin-coloured arm that reaches in from the top edge. Before, the disc was masked
    as a hand, and no channel showed the ball."""
    rng = np.random.default_rng(40)
    wall = board(rng, (160.0, 165.0, 170.0))
    ball = disc_coverage(SIZE, 200.3, 150.6, RADIUS_PX)
    ball[146:150, 203:216] = 0.0  # a highlight's streak from the rim inwards, wall-coloured
    arm = hand_alpha(80.0, 100.0)
    image = wall * (1.0 - ball[:, :, None]) + np.asarray(CRIMSON_BGR) * ball[:, :, None]
    image = image * (1.0 - arm[:, :, None]) + np.asarray(SKIN_BGR) * arm[:, :, None]
    frame = np.clip(np.round(image + rng.normal(0.0, NOISE_GREY, image.shape)), 0, 255).astype(np.uint8)
    background = np.clip(np.round(wall), 0, 255).astype(np.uint8)
    inside = disc_coverage(SIZE, 200.3, 150.6, RADIUS_PX - 2.0) > 0.5
    assert skin_mask(frame)[inside & (ball > 0.5)].mean() > 0.9  # the premise: the ball's colour is skin's
    hand = hand_pixels(frame, background)
    assert not hand[inside].any()
    assert hand[:90, 70:90].all()  # the arm is still a hand


def test_lighting_flicker_is_taken_out_by_the_frame_gain(capsys):
    """Decision: 100 Hz flicker filmed at 120 fps beats at 20 Hz; the frame's gain against the
    background (±20 %) is measured from sparse background pixels and the ball is tracked in every frame."""
    rng = np.random.default_rng(34)
    n = 30
    gains = 1.0 + 0.2 * np.sin(2 * np.pi * 20.0 * np.arange(n) / 120.0)
    frames, truth = draw_clip(rng, (150.0, 170.0, 185.0), (40.0, 40.0, 200.0), n=n, gains=gains)
    table, ok, errors = tracked_ok_and_errors(frames, truth)
    report(capsys, f"flicker ±20 %: {ok.sum()}/{n} ok, centre RMS {rms(errors):.4f} px, max {errors.max():.4f} px")
    assert ok.all()
    assert rms(errors) <= FLICKER_TOLERANCE_PX and errors.max() <= 2 * FLICKER_TOLERANCE_PX


def test_a_yellow_ball_on_a_wall_of_its_own_brightness_is_tracked_at_every_height(capsys):
    """Decision: the foreground is the largest channel difference in noise σ, so a yellow ball on a
    grey wall of the same luma (a few grey levels apart) stands out in blue; with ±10 % flicker it
    is tracked from the top of the frame to the bottom."""
    rng = np.random.default_rng(35)
    yellow = (30.0, 220.0, 230.0)
    luma = 0.114 * yellow[0] + 0.587 * yellow[1] + 0.299 * yellow[2]
    n = 30
    gains = 1.0 + 0.1 * np.sin(2 * np.pi * 20.0 * np.arange(n) / 120.0)
    frames, truth = draw_clip(rng, (luma,) * 3, yellow, n=n, gains=gains)
    table, ok, errors = tracked_ok_and_errors(frames, truth)
    report(capsys, f"yellow on grey of luma {luma:.0f}: {ok.sum()}/{n} ok (rows {truth[0, 1]:.0f}-{truth[-1, 1]:.0f}), "
                   f"centre RMS {rms(errors):.4f} px, max {errors.max():.4f} px")
    assert ok.all()
    assert rms(errors) <= ISOLUMINANT_TOLERANCE_PX and errors.max() <= 2 * ISOLUMINANT_TOLERANCE_PX


@pytest.mark.parametrize("hints", [dict(roi_px=(0, 0, 250, 240)), dict(ball_colour_bgr=(40.0, 40.0, 200.0)),
                                   dict(ball_at_px=(0, 80, 41))])
def test_hints_single_out_the_ball(hints):
    """Decision: a larger green disc moving down the frame beside the ball (a second ball, not in the
    background) draws the search without hints, and moving steadily it is followed as well as a ball
    would be; a region of interest, the ball's colour or its position in one frame make the tracker
    follow the red ball from the first frame."""
    rng = np.random.default_rng(36)
    frames, truth = draw_clip(rng, (150.0, 170.0, 185.0), (40.0, 40.0, 200.0), n=20)
    decoys = [disc_coverage(SIZE, 290.0, 60.0 + 5.0 * k, 1.2 * RADIUS_PX)[:, :, None] for k in range(len(frames))]
    frames = [np.round(frame * (1 - decoy) + np.array([60.0, 170.0, 60.0]) * decoy).astype(np.uint8)
              for frame, decoy in zip(frames, decoys)]
    unaided = tracked(frames)
    assert centre_errors(unaided, truth)[0] > RADIUS_PX  # the decoy is taken without hints
    table = tracked(frames, **hints)
    assert (table["quality"] == QUALITY_OK).all()
    assert centre_errors(table, truth).max() <= 2 * SHADOW_TOLERANCE_PX


@pytest.mark.parametrize("hints, said", [
    (dict(ball_at_px=(25, 80, 41)), "--ball-at-px names frame 25, but the clip's frames are 0-19"),
    (dict(ball_at_px=(0, 800, 41)), "--ball-at-px puts the ball at 800,41 px, outside the"),
    (dict(roi_px=(900, 0, 1000, 100)), "--roi-px 900,0,1000,100 lies outside the"),
])
def test_a_hint_that_cannot_apply_to_the_clip_is_refused(tmp_path, hints, said):
    """A frame beyond the clip, or a point or region outside the frame, was silently never used."""
    from dropfit.video.track import track_video
    from helpers import encode_clip

    frames, _ = draw_clip(np.random.default_rng(36), (150.0, 170.0, 185.0), (40.0, 40.0, 200.0), n=20)
    path = encode_clip(tmp_path / "clip.mp4", frames)
    with pytest.raises(InputError, match="clip.mp4: ") as refusal:
        track_video(path, hints=TrackerHints(**hints))
    assert said in str(refusal.value)


def test_a_blob_of_another_size_where_the_ball_should_be_is_not_taken_for_it():
    """Decision: once ``ok`` frames have given the ball's radius, a blob twice as large at the
    predicted position (the ball gone behind something, a ball-coloured object there) is not the ball."""
    rng = np.random.default_rng(38)
    frames, truth = draw_clip(rng, (150.0, 170.0, 185.0), (40.0, 40.0, 200.0), n=20)
    wall = board(np.random.default_rng(38), (150.0, 170.0, 185.0))  # the same board, without the ball
    x, y = truth[15]
    big = disc_coverage(SIZE, x, y, 2.0 * RADIUS_PX)[:, :, None]
    image = wall * (1 - big) + np.array([40.0, 40.0, 200.0]) * big + rng.normal(0.0, NOISE_GREY, wall.shape)
    frames[15] = np.clip(np.round(image), 0, 255).astype(np.uint8)
    table = tracked(frames)
    quality = table["quality"].to_numpy()
    assert quality[15] != QUALITY_OK and not usable_rows(table)[15]
    assert (np.delete(quality, 15) == QUALITY_OK).all()


def _small_ball(radius_px, hidden_right_of_px=None, seed=0):
    """A 41 x 41 window: a ball of ``radius_px`` (grey 200) on a grey-40 scene at (20.3, 20.6), the part
    of it right of column ``hidden_right_of_px`` hidden by something of the scene's colour, 1.5 levels
    of noise; returned as float32 frame and background."""
    cover = disc_coverage((41, 41), 20.3, 20.6, radius_px)
    if hidden_right_of_px is not None:
        cover[:, int(np.ceil(hidden_right_of_px)):] = 0.0
    noise = np.random.default_rng(seed).normal(0.0, 1.5, cover.shape)
    frame = (40.0 + 160.0 * cover + noise).astype(np.float32)
    return frame, np.full_like(frame, 40.0)


def test_a_small_balls_radius_scatter_is_not_taken_for_a_hidden_part():
    """A 4.5 px ball's measured radius scatters by ~0.15 px from frame to frame (the real ball toss: 4.42
    to 4.71 px); one reading 4.25 px against a median of 4.54 px is that scatter, not a hand hiding it.
    A quarter hidden stays flagged whatever the scatter."""
    frame, background = _small_ball(4.25)
    assert measure_ball(frame, background, 20.0, (20.0, 20.0), 4.54).quality == QUALITY_OCCLUDED  # no scatter known
    assert measure_ball(frame, background, 20.0, (20.0, 20.0), 4.54, radius_spread_px=0.15).quality == QUALITY_OK
    hidden, background = _small_ball(4.54, hidden_right_of_px=20.3 + 2.0)
    assert measure_ball(hidden, background, 20.0, (20.0, 20.0), 4.54,
                        radius_spread_px=0.15).quality == QUALITY_OCCLUDED
    assert measure_ball(hidden, background, 20.0, (20.0, 20.0), 4.54, radius_spread_px=1.0).quality == QUALITY_OCCLUDED


def draw_shaded_clip(rng, n=30):
    """A white ball lit from the upper left before a light grey wall (uint8 BGR frames, true centres):
    the ball fades from 245 grey levels at its lit side to 175 at its shaded side (the wall is 195),
    and its soft shadow darkens the wall about it over twice its radius, below and to the right."""
    wall = board(rng, (195.0, 195.0, 195.0))
    rows, columns = np.mgrid[: SIZE[0], : SIZE[1]]
    frames, truth = [], []
    for k in range(n):
        cx, cy = path(k)
        halo = np.exp(-((columns - cx - 0.3 * RADIUS_PX) ** 2 + (rows - cy - 0.3 * RADIUS_PX) ** 2)
                      / (2.0 * RADIUS_PX ** 2))
        scene = wall * (1.0 - 0.2 * halo)[:, :, None]
        # shading along the light's direction: 1 at the lit rim, 0 at the shaded one
        lit = np.clip(0.5 - ((columns - cx) + (rows - cy)) / (2.0 * math.sqrt(2.0) * RADIUS_PX), 0.0, 1.0)
        ball = (175.0 + 70.0 * lit)[:, :, None]
        a = disc_coverage(SIZE, cx, cy, RADIUS_PX)[:, :, None]
        image = scene * (1.0 - a) + ball * a + rng.normal(0.0, NOISE_GREY, wall.shape)
        frames.append(np.clip(np.round(image), 0, 255).astype(np.uint8))
        truth.append((cx, cy))
    return frames, np.array(truth)


def test_a_light_ball_merged_with_its_soft_shadow_is_measured_on_its_lit_side(capsys):
    """Decision: a white ball before a light grey wall, lit from one side, is as dark as the wall on its
    shaded side and sits in its own soft shadow, so that no channel sees it alone (white on grey has no
    hue). Where it is lighter than the wall it is measured: the outline of its lit side, where the contrast
    falls fastest, fitted with a circle (``shaded``), its radius fitted in the first frames, then held."""
    rng = np.random.default_rng(53)
    frames, truth = draw_shaded_clip(rng)
    table = tracked(frames)
    usable = usable_rows(table)
    errors = centre_errors(table, truth)
    shaded = table["quality"].to_numpy() == QUALITY_SHADED
    report(capsys, f"[{table.attrs['contrast']}] white ball in its soft shadow: {shaded.sum()}/{len(table)} shaded, "
                   f"{usable.sum()} usable, centre RMS {rms(errors[usable]):.3f} px, "
                   f"max {errors[usable].max():.3f} px, radius {np.median(table['radius_px'][shaded]):.2f} px")
    assert usable.sum() >= 0.8 * len(table)
    assert rms(errors[usable]) <= SHADED_TOLERANCE_PX and errors[usable].max() <= 2 * SHADED_TOLERANCE_PX
