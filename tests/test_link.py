"""The ball found by its ballistic flight among things that move otherwise (dropfit.video.link).

The clips are drawn here (a textured wall, a hand-like blob that wanders, a small ball tossed from
it), with the ball's true centre known in every frame; nothing is shared with the tracker.
"""

import numpy as np
import pytest

from dropfit.video.link import longest_flight
from dropfit.video.track import track_frames, usable_rows
from helpers import disc_coverage, rms

SHAPE = (240, 320)  # px, height and width
BALL_RADIUS_PX = 5.0
RELEASE_FRAME = 6
FRAMES = 40


def _ball_centre(frame):
    """The ball's true centre, px: carried by the hand (up and right) until RELEASE_FRAME, then tossed
    and falling."""
    t = frame - RELEASE_FRAME
    if t < 0:
        return 70.3 + 3.0 * t, 150.4 - 4.0 * t
    return 70.3 + 5.1 * t, 150.4 - 9.2 * t + 0.5 * 0.8 * t * t


def _hand_centre(frame, rng_steps):
    """The hand's centre, px: holds the ball, then wanders off to the left by a seeded random walk."""
    if frame < RELEASE_FRAME:
        return _ball_centre(frame)
    x, y = _ball_centre(RELEASE_FRAME)
    walk = np.cumsum(rng_steps[:frame - RELEASE_FRAME + 1], axis=0)[-1]
    return x - 4.0 * (frame - RELEASE_FRAME) + walk[0], y + 3.0 * (frame - RELEASE_FRAME) + walk[1]


def _tossed_ball_clip(seed=0):
    """Frames (BGR uint8) of a small white ball tossed out of a hand-like blob on a textured grey wall,
    and the ball's true centres (n, 2), px.

    The hand is a round blob larger than the ball (lone and disc-like while it holds the ball, which
    it hides), then an elongated one (an arm) that wanders: the blob a whole-frame search takes for the
    ball in the first frame."""
    rng = np.random.default_rng(seed)
    wall = 110.0 + rng.normal(0.0, 4.0, SHAPE)
    steps = rng.normal(0.0, 3.0, (FRAMES, 2))
    rows, columns = np.indices(SHAPE)
    frames, truth = [], []
    for frame in range(FRAMES):
        image = wall.copy()
        x, y = _ball_centre(frame)
        coverage = disc_coverage(SHAPE, x, y, BALL_RADIUS_PX)
        image = image * (1 - coverage) + 235.0 * coverage
        hx, hy = _hand_centre(frame, steps)
        # a fist of radius 13 px, then an arm reaching to the left of it (an ellipse 30 x 11 px)
        half_length, half_width = (13.0, 13.0) if frame < RELEASE_FRAME else (30.0, 11.0)
        hand = ((columns - hx) / half_length) ** 2 + ((rows - hy) / half_width) ** 2 <= 1.0
        image[hand] = 190.0
        image += rng.normal(0.0, 2.0, SHAPE)
        frames.append(np.repeat(np.clip(np.rint(image), 0, 255).astype(np.uint8)[:, :, None], 3, axis=2))
        truth.append((x, y))
    return frames, np.array(truth)


def test_a_ball_tossed_from_a_hand_is_tracked_not_the_hand():
    """The first whole-frame search takes the fist for the ball; the flight of the small ball found among
    the frames' round blobs puts the tracker on the ball: the ball's free frames are usable and within
    0.3 px of its true centre, and no usable row is on the hand."""
    frames, truth = _tossed_ball_clip()
    table = track_frames(frames, np.arange(FRAMES) / 60.0)
    usable = usable_rows(table)
    error = np.hypot(table["x_px"].to_numpy() - truth[:, 0], table["y_px"].to_numpy() - truth[:, 1])
    in_view = (truth[:, 0] + BALL_RADIUS_PX < SHAPE[1]) & (truth[:, 1] + BALL_RADIUS_PX < SHAPE[0])
    free = in_view & (np.arange(FRAMES) >= RELEASE_FRAME + 2)  # clear of the hand
    assert usable[free].mean() >= 0.9, table[free]
    assert np.all(error[usable] <= 1.0), table[usable]
    assert rms(error[usable & free]) <= 0.3


def _candidates(rng, count, flight=None):
    """Per frame, random blobs (x, y, radius px) plus a fixture and, from frame 5, the ball's ``flight``."""
    frames = []
    for frame in range(count):
        blobs = [np.column_stack([rng.uniform(0, 640, 8), rng.uniform(0, 480, 8), rng.uniform(3, 12, 8)]),
                 [[600.0, 40.0, 6.0]]]  # a fixture: a blob that stays
        if flight is not None and 5 <= frame < 5 + len(flight):
            blobs.append([flight[frame - 5]])
        frames.append(np.vstack(blobs))
    return frames


def test_the_longest_flight_is_the_ball_among_random_and_fixed_blobs():
    """Among eight random blobs a frame and a fixture, the ball's 20-frame parabola is the flight found,
    every one of its frames linked."""
    t = np.arange(20.0)
    flight = np.column_stack([100.0 + 7.0 * t, 300.0 - 20.0 * t + 0.5 * 2.0 * t * t, np.full(t.size, 6.0)])
    found = longest_flight(_candidates(np.random.default_rng(4), 40, flight))
    assert found is not None
    assert list(found.frames) == list(range(5, 25))
    assert np.allclose(found.x_px, flight[:, 0]) and np.allclose(found.y_px, flight[:, 1])


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_no_flight_among_random_and_fixed_blobs(seed):
    """Random blobs and a fixture make no flight: a fixture does not move, random blobs do not keep to a
    parabola."""
    assert longest_flight(_candidates(np.random.default_rng(seed), 40)) is None


def test_a_repeated_frame_before_the_flight_is_flagged_as_the_later_one():
    """Frames before the flight are tracked backwards from it; a frame the recorder repeated is still
    flagged on its later copy, as a forward pass flags it (its time stamp is not its content's)."""
    frames, _ = _tossed_ball_clip(seed=1)
    frames[3] = frames[2].copy()
    table = track_frames(frames, np.arange(FRAMES) / 60.0)
    assert table["quality"].iloc[3] == "duplicate"
    assert table["quality"].iloc[2] != "duplicate"


@pytest.mark.parametrize("release_frame", [6, 7, 8, 9])
def test_a_ball_leaving_a_still_hand_is_found_in_its_first_free_frame(release_frame):
    """A ball held in a skin-coloured hand (measured occluded frame after frame, where only every 4th
    frame is searched whole) and thrown down leaves a finger behind, grey (not skin-coloured) and
    touching the hand, where the tracker looks first. The ball is still tracked from its first frame
    clear of the hand, whichever frame of that run it is: it is looked for near the finger in every
    frame. The hand stays three frames after the throw, then leaves (in view for a third of the clip:
    not in the background)."""
    rng = np.random.default_rng(release_frame)
    wall = np.full(SHAPE + (3,), 110.0) + rng.normal(0.0, 4.0, SHAPE)[:, :, None]
    rows, columns = np.indices(SHAPE)
    held = (160.3, 76.2)
    hand = ((columns - held[0]) / 30.0) ** 2 + ((rows - held[1] + 15.0) / 11.0) ** 2 <= 1.0
    finger = ((columns - held[0]) / 4.0) ** 2 + ((rows - held[1]) / 6.5) ** 2 <= 1.0
    frames, truth = [], []
    for frame in range(release_frame + 30):
        t = max(frame - release_frame, 0)
        x, y = held[0], held[1] + 16.0 * t + 0.5 * 1.5 * t * t
        image = wall.copy()
        if frame <= release_frame + 3:
            image[finger] = 190.0  # grey, not skin: seen as foreground
            image[hand] = (120.0, 160.0, 220.0)  # BGR of skin (YCrCb 173, 161, 98)
        coverage = disc_coverage(SHAPE, x, y, BALL_RADIUS_PX)[:, :, None]
        image = image * (1 - coverage) + 235.0 * coverage
        image += rng.normal(0.0, 2.0, SHAPE + (3,))
        frames.append(np.clip(np.rint(image), 0, 255).astype(np.uint8))
        truth.append((x, y))
    truth = np.array(truth)
    table = track_frames(frames, np.arange(len(frames)) / 60.0, expected_radius_px=BALL_RADIUS_PX)
    first_free = release_frame + 1
    assert usable_rows(table)[first_free], table.iloc[release_frame - 2:first_free + 2]
    error = np.hypot(table["x_px"] - truth[:, 0], table["y_px"] - truth[:, 1]).to_numpy()
    assert error[first_free] <= 0.3
