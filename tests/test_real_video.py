"""Real clips filmed by someone else: Tracker's ball toss (../shared/realdata/tracker-balltoss), and the phone clips
of issue 32 (../shared/realdata/phone-clips, its README: what each shows and its reference e).

A small white ball tossed past a metre stick, a hand in view, 640 × 480 H.264 at 30 fps. Its Tracker
project holds 11 hand-marked ball positions (every other frame of a 13-frame excerpt of the clip) and
the stick's calibration; they are the truth the automatic track is held to.
"""

import numpy as np
import pytest

import dropfit
from dropfit.pipeline import process_recording, track_recording
from dropfit.settings import Ball, Settings, parse_ball_colour
from dropfit.video.quality import QUALITY_OFF_TRACK, QUALITY_OK
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




def _positions_within(table, marks, tolerance_px):
    """Whether the tracked centres at ``marks`` ({frame: (x, y) px read by eye on the frame}) are usable rows within
    ``tolerance_px`` of them; the distances, px."""
    usable = usable_rows(table)
    distance = {frame: float(np.hypot(table["x_px"][frame] - x, table["y_px"][frame] - y))
                for frame, (x, y) in marks.items()}
    return all(usable[frame] and distance[frame] <= tolerance_px for frame in marks), distance


@pytest.mark.slow
def test_green_ball_before_a_white_board_is_measured_alone_in_its_flights():
    """green_ball_white_board.avi (1920 x 1080, 29.97 fps), the ball's radius given (43 px, read on the frames):
    its flights after impact 1 (frames 80-125) are measured cleanly, on the ball. Before, the radius learnt from the
    frame the hand let it go (46.7 px, a finger's edge with it) flagged the ball occluded in every flight frame
    (41-44.5 px alone: 5 % short), 13 clean frames in all. Centres read by eye on frames 84, 94 and 99 (the circle
    drawn on crops of them: 2 px is the reading's own error on a 88 px ball)."""
    table = track_video(real_recording("phone-clips", "green_ball_white_board.avi"), expected_radius_px=43.0)
    flights = table.iloc[80:126]
    ok = flights["quality"] == QUALITY_OK
    assert ok.sum() >= 30, flights["quality"].value_counts()
    assert flights["radius_px"][ok].between(41.0, 46.0).all(), flights[ok]
    within, distance = _positions_within(table, {84: (963.0, 596.0), 94: (935.0, 850.0), 99: (926.0, 828.0)}, 3.0)
    assert within, distance
    assert not (table["quality"] == QUALITY_OFF_TRACK).any()


@pytest.mark.slow
def test_white_pingpong_ball_before_a_light_wall_is_tracked_in_its_flights():
    """white_pingpong_ruler.mov (30 Hz in a 60 fps MOV): every other frame is a repeat, the 98 captures hold 72 usable
    centres, and the ballistic gate leaves none out (flights of 7 captures, then hops and rolling: none of it is
    judged a jump). Centres read by eye on the crops of frames 66, 76 and 88 (the ball 80 px across)."""
    table = track_video(real_recording("phone-clips", "white_pingpong_ruler.mov"))
    assert usable_rows(table).sum() >= 70
    assert not (table["quality"] == QUALITY_OFF_TRACK).any()
    within, distance = _positions_within(table, {66: (451.0, 443.0), 76: (451.0, 490.0), 88: (455.0, 592.0)}, 3.0)
    assert within, distance


@pytest.mark.slow
def test_tennis_ball_on_a_table_gives_both_impacts():
    """tennis_ball_table_aruco.mp4 (1080 x 1080, 120 fps stored at 30): the ball is tracked in every frame after the
    hand lets it go but three as the hand leaves (the hand's pieces measured there are not usable), bounces at
    frames 35-37 and 86-90, and the clip ends 2 frames after the apex that follows the second bounce. Frame 92
    repeats frame 91 and the frames after it are stamped one interval late (the ball rises 21 px from 91 to 93, as
    in one interval): kept at their stamps, the flight after impact 2 fitted 19 px off and the sequence was cut
    before it. Its rise to the apex gives v_out: both impacts have e in the README's range (0.5-0.85; measured
    0.750 and 0.748 ± 0.003)."""
    clip = real_recording("phone-clips", "tennis_ball_table_aruco.mp4")
    table = track_video(clip)
    usable = usable_rows(table)
    assert usable[16:].sum() >= len(table) - 16 - 8, table["quality"].value_counts()
    assert not (table["quality"] == QUALITY_OFF_TRACK).any()
    y = table["y_px"].to_numpy()
    lowest = [int(np.nanargmax(y[30:45])) + 30, int(np.nanargmax(y[80:95])) + 80]  # image rows point down
    assert 35 <= lowest[0] <= 37 and 86 <= lowest[1] <= 90, lowest
    apex = int(np.nanargmin(y[95:])) + 95
    assert len(table) - 1 - apex <= 3, (apex, len(table))
    result = dropfit.analyse_recording(clip, ball_type="tennis", ball_radius_m=0.0335, ball_mass_kg=0.057)
    measured = result.impacts[result.impacts["in_fit"]]
    assert len(measured) >= 2, result.impacts
    assert measured["e"].between(0.5, 0.85).all(), result.impacts


@pytest.mark.slow
def test_green_ball_picture_agrees_with_its_sound_with_the_scale_from_g():
    """green_ball_white_board.avi, its radius given as 30 mm (the ball's is about 36: the diameter's scale makes the
    flights fall with 8.24 m/s²): the picture measures impacts 2 and 3 with the scale from g (the diameter's named
    suspect). Impact 2, its flights filmed in 8 intervals or more, agrees with the sound track's e, an independent
    sensor, within 3 standard errors of the two (measured: picture 0.7039 ± 0.0010, sound 0.7052 ± 0.0006); impact
    3, its rebound filmed in 7.6 intervals, is 3.6 se from it (0.7131 ± 0.0021, 0.7211 ± 0.0008), and the headline
    says DISAGREE. Before, the ball held at the frame's edge and the hand's jumps read the image rows as pointing up,
    no gravity scale was found and the picture was refused."""
    clip = real_recording("phone-clips", "green_ball_white_board.avi")
    result = dropfit.analyse_recording(clip, ball_type="rubber", ball_radius_m=0.03, ball_mass_kg=0.05)
    fusion = result.to_dict()["sound_and_picture"]
    assert fusion["source"] == "sound and picture", fusion
    paired = {pair["impact_picture"]: pair for pair in fusion["pairs"]
              if pair["e_picture"] is not None and pair["e_sound"] is not None}
    assert 2 in paired, fusion["pairs"]
    for pair in paired.values():
        assert 0.3 < pair["e_picture"] < 0.95
    dense = paired[2]
    assert abs(dense["e_picture"] - dense["e_sound"]) < 3 * np.hypot(dense["e_picture_se"], dense["e_sound_se"])
    assert fusion["agree"] or "DISAGREE" in result.summary()
    assert "heights from g" in result.report() and "diameter scale" in result.report()


@pytest.mark.parametrize("colour", [None, "red"], ids=["unaided", "ball_colour_red"])
def test_crimson_ball_whose_colour_is_skin_like_gives_e(colour):
    """red_ball_portrait.mp4 (1080 x 1920, 29.97 fps): the crimson ball (YCrCb Cr 174, Cb 122) lies in the skin ranges.
    Before, it was masked as a hand in every channel, the tracker followed specks on the floor (9 clean frames) and
    the clip was refused; named "red", its colour did not match the name (chromaticity 0.19 off) and no ball was
    found. Now it is measured cleanly in its flights, on the ball (centres within 3 px of those of its red pixels on
    frames 12, 24 and 34; the ball 105 px across), and impacts 2 and 3 give e in the README's range (measured 0.728 ±
    0.002 and 0.736 ± 0.005; the flight after impact 3 lasts 7.1 frame intervals: sparsely filmed, with its note).
    Impact 1 is left out by the limits, truly: the ball enters the frame falling and is seen cleanly in 5 frames
    before it (7 needed)."""
    clip = real_recording("phone-clips", "red_ball_portrait.mp4")
    ball = Ball(radius_m=0.03, mass_kg=0.05, type="rubber", colour=parse_ball_colour(colour) if colour else None)
    tracked = track_recording(clip, Settings(), ball)
    assert usable_rows(tracked.table)[2:38].sum() >= 30, tracked.table["quality"].value_counts()
    within, distance = _positions_within(tracked.table, {12: (402.0, 767.0), 24: (516.0, 1076.0),
                                                         34: (658.0, 1218.0)}, 3.0)
    assert within, distance
    result = process_recording(clip, ball, Settings(), tracked=tracked)
    measured = result.impacts[result.impacts["in_fit"]]
    assert list(measured["impact"]) == [2, 3], result.impacts
    assert measured["e"].between(0.3, 0.95).all(), result.impacts
    notes = dict(zip(result.impacts["impact"], result.impacts["note"].astype(str)))
    assert "clean frames in the flight before it" in notes[1] and "sparsely filmed" in notes[3], notes


@pytest.mark.slow
def test_white_pingpong_ball_gives_every_impact_and_flags_its_sound():
    """white_pingpong_ruler.mov: flights of 6.0-7.6 capture intervals (30 Hz) beside impacts 1, 3 and 4 left them out
    (fewer than 8); now all four are measured, those three noted as sparsely filmed, each e in the README's range for
    table tennis on wood (0.75-0.95; measured 0.863-0.883). The sound's chain of clicks takes a rattle for a bounce:
    the headline flags the disagreement and names the sound suspect, and its e is the picture's."""
    clip = real_recording("phone-clips", "white_pingpong_ruler.mov")
    result = dropfit.analyse_recording(clip, ball_type="table_tennis", ball_radius_m=0.02, ball_mass_kg=0.0027)
    measured = result.impacts[result.impacts["in_fit"]]
    assert len(measured) >= 2 and measured["e"].between(0.75, 0.95).all(), result.impacts
    notes = result.impacts["note"].astype(str)
    assert notes.str.contains("sparsely filmed").sum() >= 2, notes
    fusion = result.to_dict()["sound_and_picture"]
    assert fusion["source"] == "picture" and fusion["suspect"] == "sound" and "DISAGREE" in result.summary()
