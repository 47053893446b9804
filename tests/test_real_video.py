"""A real clip filmed by someone else: Tracker's ball toss (../shared/realdata/tracker-balltoss).

A small white ball tossed past a metre stick, a hand in view, 640 × 480 H.264 at 30 fps. Its Tracker
project holds 11 hand-marked ball positions (every other frame of a 13-frame excerpt of the clip) and
the stick's calibration; they are the truth the automatic track is held to.
"""

import numpy as np

from dropfit.video.track import track_video, usable_rows
from helpers import excerpt_frames_in_clip, grey_frames, real_recording, tracker_point_mass

def _track_at_the_marks():
    """The automatic track at the hand-marked frames: (which marks are usable rows, their distance to the
    marks in px, the marks' own scatter in px)."""
    clip = real_recording("tracker-balltoss", "BallTossOut.mp4")
    trz = real_recording("tracker-balltoss", "BallToss.trz")
    marks, _ = tracker_point_mass(trz)
    in_clip = excerpt_frames_in_clip(trz, grey_frames(clip))
    assert np.all(np.diff(in_clip) == 2)  # the excerpt is every other frame of the clip
    # the hand marks' own scatter: their residual about a parabola in time (the toss is ballistic)
    steps = marks[:, 0]
    scatter = np.hypot(*(marks[:, k] - np.polyval(np.polyfit(steps, marks[:, k], 2), steps) for k in (1, 2)))
    marks_scatter_px = float(np.sqrt(np.mean(scatter ** 2)) * np.sqrt(len(steps) / (len(steps) - 3)))

    table = track_video(clip)
    at_marks = in_clip[marks[:, 0].astype(int)]
    usable = usable_rows(table)[at_marks]  # the rows dropfit fits trajectories with
    distance = np.hypot(table["x_px"].to_numpy()[at_marks] - marks[:, 1],
                        table["y_px"].to_numpy()[at_marks] - marks[:, 2])
    return usable, distance, marks_scatter_px


def test_ball_toss_track_agrees_with_the_hand_marks():
    """10 of the 11 marks usable (measured: 1.36 px RMS from them against a bound of 1.63 px). The hands in
    view are followed first; the ball's flight, found among the frames' round blobs, puts the tracker on
    it. The last mark, 5 px above the image's bottom edge, is not usable (the tracker measures a partial
    ball at the edge, 9.7 px away)."""
    usable, distance, marks_scatter_px = _track_at_the_marks()
    assert usable.sum() >= len(usable) - 1, (usable, distance)
    assert np.all(distance[usable] <= 2.0), distance  # the ball, not a hand (tens of px away)
    # the hand marks scatter by ~1.1 px (a click on a ball ~10 px across); the tracked centre is within that
    assert np.sqrt(np.mean(distance[usable] ** 2)) <= 1.5 * marks_scatter_px, (distance, marks_scatter_px)


