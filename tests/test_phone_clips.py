"""Clips as phones film them (phonesim, an independent generator): dropfit's numbers against its truth.

phonesim renders with refsim's physics, H.264 or MPEG-4 through PyAV, and what real clips showed
(colour balls on near-isoluminant walls, shadows touching the ball, a hand holding and releasing it,
rotation metadata, repeated frames, flicker, rulers and tapes with ticks on whole pixel rows, ArUco
markers, a tilted camera). The tests hold dropfit to the issue's bar: e per impact within ±0.005 and
inside its 95 % interval, rebound heights within ±5 mm, the scale within 0.5 %.
"""

import io
import math
import re

import numpy as np
import pandas as pd
import pytest

import dropfit
from dropfit.errors import InputError
from dropfit.video.targets import to_plane
from dropfit.video.track import track_video, usable_rows
from helpers import phone_clip

#: |e − e_true| allowed per impact, and |h − h_true| for rebound heights, m (the issue's bar).
E_TOLERANCE = 0.005
HEIGHT_TOLERANCE_M = 0.005
SCALE_TOLERANCE = 0.005


def _compare(result, truth, impacts_checked):
    """Per analysed impact: the truth's e and rebound height beside dropfit's."""
    true_impacts = pd.DataFrame(truth["physics"]["impacts"])
    impacts = result.impacts.head(impacts_checked)
    nearest = [int(np.argmin(np.abs(true_impacts["t_touchdown_s"].to_numpy() - t))) for t in impacts["t_touchdown_s"]]
    true = true_impacts.iloc[nearest].reset_index(drop=True)
    return pd.DataFrame({"e": impacts["e"].to_numpy(), "e_low": impacts["e_ci95_low"].to_numpy(),
                         "e_high": impacts["e_ci95_high"].to_numpy(), "e_true": true["e"].to_numpy(),
                         "h": impacts["h_after_m"].to_numpy(), "h_true": true["h_after_m"].to_numpy()})


def _check(result, truth, impacts_checked):
    """The issue's bar."""
    table = _compare(result, truth, impacts_checked)
    assert len(table) == impacts_checked, result.impacts
    assert np.all(np.abs(table["e"] - table["e_true"]) <= E_TOLERANCE), table
    assert np.all(np.abs(table["h"] - table["h_true"]) <= HEIGHT_TOLERANCE_M), table
    inside = (table["e_low"] <= table["e_true"]) & (table["e_true"] <= table["e_high"])
    # 95 % intervals: of five or more impacts one may miss (2 or more miss with probability 3 % for six)
    assert (~inside).sum() <= (1 if len(table) >= 5 else 0), table
    return table


def _vertical_px_per_m_at_floor(attrs, truth):
    """px per m up the drop line at the truth's floor point, as the trajectory's calibration has it: through
    a plane target's map (its ``plane_homography``, ``plane_down``) or the one scale."""
    if "plane_homography" not in attrs:
        return 1.0 / attrs["scale_m_per_px"]
    homography = np.reshape(attrs["plane_homography"], (3, 3))
    floor_px = np.array(truth["camera"]["floor_px_at_drop_line"])
    step_m = 0.01  # a cm up the plane's vertical
    floor_m = to_plane(homography, floor_px)[0]
    above_px = to_plane(np.linalg.inv(homography), floor_m - step_m * np.asarray(attrs["plane_down"]))[0]
    return float(np.hypot(*(above_px - floor_px))) / step_m


#: A phone's HDR video: HEVC with 10 bits a sample, in a MOV (as an iPhone films it by default).
HEVC_10_BIT_MOV = {"suffix": ".mov", "codec": "libx265", "bit_depth": 10}


@pytest.mark.parametrize("preset, options, impacts_checked, seed, encoding", [
    # each clip is rendered and analysed end to end (1-2.5 min): slow tests, run in CI
    pytest.param("yellow_flicker_portrait_120", {"ruler_tick_m": 0.01}, 2, 3, {}, marks=pytest.mark.slow,
                 id="yellow_flicker_portrait_120"),
    pytest.param("yellow_flicker_portrait_120", {"ruler_tick_m": 0.01}, 2, 3, HEVC_10_BIT_MOV,
                 marks=pytest.mark.slow, id="yellow_flicker_portrait_120_hevc_10_bit_mov"),
    # HEVC, 8 bits: the hand that holds the ball is taken for it in one frame, alone among frames where the ball is
    # lost; that position's jump, with no neighbour to cancel it, turned the rows' sign (rows read as heights up):
    # "falls with 842 m/s², not g"
    pytest.param("yellow_flicker_portrait_120", {"ruler_tick_m": 0.01}, 3, 2, {"suffix": ".mov", "codec": "libx265"},
                 marks=pytest.mark.slow, id="yellow_flicker_portrait_120_hevc_mov_seed_2"),
    pytest.param("tennis_aruco_tilted", {"marker_size_m": 0.08}, 3, 3, {}, marks=pytest.mark.slow,
                 id="tennis_aruco_tilted"),
    # 30 frames/s, scale from gravity (the board has none; the tape's cm ticks are not resolved at half size)
    pytest.param("green_board_avi", {}, 4, 3, {}, marks=pytest.mark.slow, id="green_board_avi"),
    pytest.param("yellow_green_tape", {}, 4, 3, {}, marks=pytest.mark.slow, id="yellow_green_tape"),
    # 30 frames/s, blurred over half a frame interval: its centre reads up to 0.5 px off in the fast frames (H.264),
    # which the speed-dependent error's parts carry (impact 4's e 0.0009 high, 2.1 se, was 2.7)
    pytest.param("red_blur_portrait", {}, 6, 3, {}, marks=pytest.mark.slow, id="red_blur_portrait"),
])
def test_phone_clip_numbers(tmp_path, preset, options, impacts_checked, seed, encoding):
    """The clip gives e per impact within the bar and inside its interval, and the scale within 0.5 %. The ball's
    diameter, whose scale is reported beside the one chosen, covers the truth's within its 95 % interval (it was
    1.5 % off on the yellow ball with a standard error of 0.05 %)."""
    path, truth = phone_clip(preset, tmp_path, seed=seed, downscale=0.5, **encoding)
    physics = truth["physics"]
    result = dropfit.analyse_recording(path, ball_radius_m=physics["radius_m"], ball_mass_kg=physics["mass_kg"],
                                       ball_type=physics["ball_model"], **options)
    attrs = result.trajectory.attrs
    true_px_per_m = float(np.hypot(*truth["camera"]["vertical_px_per_m_at_drop_line"]))
    assert math.isclose(_vertical_px_per_m_at_floor(attrs, truth), true_px_per_m, rel_tol=SCALE_TOLERANCE)
    if "plane_homography" not in attrs:  # (a tilted camera's diameter scale is the ball's plane's at its own height)
        diameter_error = attrs["scale_diameter_m_per_px"] * true_px_per_m - 1.0
        assert abs(diameter_error) < 1.96 * attrs["scale_diameter_se_m_per_px"] / attrs["scale_diameter_m_per_px"]
    _check(result, truth, impacts_checked)


@pytest.mark.parametrize("preset, seed, min_fraction", [
    # measured (seed, downscale 0.5): 80 of 80, 131 of 131, 106 of 154 visible free frames usable (the white
    # ball in grey levels, measured on its lit side: 83 in chroma, where it shows over the table only, before
    # the lit side was measured); the white ball's clip repeats every other frame of its 30 Hz capture, and
    # the repeats that the codec coded again are found only in part: they count as not usable here
    ("green_board_avi", 1, 0.95),
    ("yellow_green_tape", 1, 0.9),
    ("white_pingpong_mov", 1, 0.65),
    # 707 frames too many to keep whole: the tracker's later passes run on crops about the first pass's ball
    ("yellow_flicker_portrait_120", 0, 0.8),
])
def test_phone_clip_ball_is_tracked_in_colour(tmp_path, preset, seed, min_fraction, capsys):
    """The ball a phone films (green on a white board with its shadow touching it and a hand catching it;
    yellow on a green wall; white on a light grey wall, portrait with rotation metadata) is tracked in
    most of the frames where it is in view, free of the hand, within half a pixel of the truth once a
    constant offset (the shaded ball's colour centroid, lit from above: at most 2 px) is taken out."""
    path, _ = phone_clip(preset, tmp_path, seed=seed, downscale=0.5)
    truth = pd.read_csv(path.with_suffix(".frames.csv"))
    table = track_video(path, progress_stream=io.StringIO())
    n = min(len(table), len(truth))
    table, truth = table.iloc[:n], truth.iloc[:n]
    visible = (truth["in_frame"].astype(bool) & ~truth["hand_visible"].astype(bool) & ~truth["is_duplicate"]
               & (truth["occluded_fraction"] < 0.01)).to_numpy()
    usable = usable_rows(table) & visible
    dx = table["x_px"].to_numpy() - truth["x_px"].to_numpy()
    dy = table["y_px"].to_numpy() - truth["y_px"].to_numpy()
    offset = np.median(dx[usable]), np.median(dy[usable])
    scatter = np.hypot(dx[usable] - offset[0], dy[usable] - offset[1])
    with capsys.disabled():
        print(f"\n[phone clips] {preset} [{table.attrs['contrast']}]: {usable.sum()} of {visible.sum()} visible frames "
              f"usable, offset ({offset[0]:.2f}, {offset[1]:.2f}) px, scatter RMS {np.sqrt(np.mean(scatter ** 2)):.3f} "
              f"px, max {scatter.max():.2f} px")
    assert usable.sum() >= min_fraction * visible.sum()
    assert np.hypot(*offset) <= 2.0
    assert np.sqrt(np.mean(scatter ** 2)) <= 0.5


def test_the_hand_that_lets_the_ball_go_is_not_followed(tmp_path):
    """The blurred red ball falls from a hand that moves away (seed 1, 30 frames/s): the tracker had followed the
    hand in 9 of the 11 frames from 3 after the release to the first impact (its history mixed the hand's pieces
    with the ball a search found, and the prediction from them pointed at the hand), and impact 1 was lost. The ball is followed instead:
    within a radius of the truth (the blurred centre reads about 1 px high) in every frame of the fall."""
    path, clip = phone_clip("red_blur_portrait", tmp_path, seed=1, downscale=0.5)
    truth = pd.read_csv(path.with_suffix(".frames.csv"))
    table = track_video(path, progress_stream=io.StringIO())
    falling = (truth["phase"] == "flight") & (truth["time_s"] < clip["physics"]["impacts"][0]["t_touchdown_s"])
    fall = table[falling.to_numpy()[:len(table)]].iloc[3:]  # from a ball clear of the hand (3 frames after release)
    distance = np.hypot(fall["x_px"] - truth["x_px"][fall.index], fall["y_px"] - truth["y_px"][fall.index])
    assert len(fall) >= 10 and np.all(distance <= truth["radius_px"][fall.index]), pd.DataFrame(
        {"quality": fall["quality"], "distance_px": distance})


def test_a_light_ball_is_told_from_the_hand_that_drops_it_and_from_its_shadow(tmp_path):
    """phonesim's white ball (seed 7, half size, 30 Hz in a 60 fps MOV) falls from a hand and bounces on a table
    whose wood its shadow darkens. Measured before: the tracker followed the hand's pieces through the whole fall
    (0 of 7 frames within a radius of the ball), and near the floor it took the shadow for the ball in 17
    frames (up to 770 px off): the search ranked a speck of the hand's fringe, a lone disc, above the ball merged
    with its shadow on the wall, and a blob with no lighter part was measured as a light ball. Now every frame of
    the fall is within a radius of the truth and no frame after the release is more than two radii off; the clip
    was refused, and now gives the one impact whose flights are sampled cleanly enough, within the bar."""
    path, clip = phone_clip("white_pingpong_mov", tmp_path, seed=7, downscale=0.5)
    truth = pd.read_csv(path.with_suffix(".frames.csv"))
    table = track_video(path, progress_stream=io.StringIO())
    n = min(len(table), len(truth))
    table, truth = table.iloc[:n], truth.iloc[:n]
    distance = np.hypot(table["x_px"] - truth["x_px"], table["y_px"] - truth["y_px"]).to_numpy()
    radius = truth["radius_px"].to_numpy()
    found = ~table["quality"].isin(["lost", "duplicate"]).to_numpy()
    time = truth["time_s"].to_numpy()
    released = time[(truth["phase"] != "held").to_numpy()][0]
    in_view = (truth["in_frame"].astype(bool) & (truth["phase"] != "held") & ~truth["is_duplicate"]).to_numpy()
    fall = in_view & (time > released + 0.1) & (time < clip["physics"]["impacts"][0]["t_touchdown_s"])
    assert fall.sum() >= 6 and np.all(found[fall] & (distance[fall] <= radius[fall])), distance[fall]
    far = found & in_view & (distance > 2 * radius)
    assert not far.any(), np.flatnonzero(far)
    physics = clip["physics"]
    result = dropfit.analyse_recording(path, ball_radius_m=physics["radius_m"], ball_mass_kg=physics["mass_kg"],
                                       ball_type=physics["ball_model"])
    _check(result, clip, 1)


@pytest.mark.parametrize("seed", [1, 3])
def test_a_light_ball_whose_first_flights_are_too_blurred_keeps_its_impacts_numbered(tmp_path, seed):
    """The white ball's fall and first rebound, blurred at 30 Hz, are measured cleanly in too few frames to fit, but
    the ball is seen in them: its bounces are found on every frame it was seen in, and the fit starts after them.
    Measured before: seed 1 was refused ('no impact is left to measure') and seed 3 too ('impact 1: clean frames in
    the flight before it: 5 < 7'); with the copies of its 30 Hz captures counted as frames, the one impact
    measured on seed 7 was numbered 1 and said to follow a hand that held the ball until 2.69 s. Now each gives
    impact 3, numbered as the generator's, within the bar, and the note says why the first two are not measured."""
    path, clip = phone_clip("white_pingpong_mov", tmp_path, seed=seed, downscale=0.5)
    physics = clip["physics"]
    result = dropfit.analyse_recording(path, ball_radius_m=physics["radius_m"], ball_mass_kg=physics["mass_kg"],
                                       ball_type=physics["ball_model"])
    measured = result.impacts[np.isfinite(result.impacts["e"])]
    touchdowns = np.array([impact["t_touchdown_s"] for impact in physics["impacts"]])
    numbers = [int(np.argmin(np.abs(touchdowns - t))) + 1 for t in measured["t_touchdown_s"]]
    assert measured["impact"].tolist() == numbers and numbers[0] == 3, measured
    _check(result, clip, 1)
    assert any("the impacts keep their numbers from the release" in note for note in result.notes), result.notes
    assert not any("held or moved by hand" in note for note in result.notes), result.notes


def test_impacts_beside_flights_of_6_to_7_frame_intervals_are_measured_and_their_intervals_cover_the_truth(tmp_path):
    """Issue 32: phone clips at 20-30 frames/s film flights of 6-8 frame intervals, and an impact beside one was left
    out (fewer than the 8 a flight needed). phonesim's tennis ball before a door, 20 frames/s, dropped from 0.6 m:
    flights of 7.0, 10.8, 8.4, 6.7 and 5.3 intervals; impacts 1, 3 and 4 were left out, impact 2 alone measured. Now
    each of the four is measured, the three beside a flight of fewer than 8 intervals with a note saying so and how
    far e's interval was widened, and each e is within the bar and its 95 % interval of the generator's."""
    from dropfit.video import limits

    path, truth = phone_clip("tennis_door", tmp_path, seed=1, downscale=1.0, duration_s=3.5, drop_height_m=0.6)
    physics = truth["physics"]
    result = dropfit.analyse_recording(path, ball_radius_m=physics["radius_m"], ball_mass_kg=physics["mass_kg"],
                                       ball_type=physics["ball_model"])
    impacts = result.impacts
    measured = impacts[np.isfinite(impacts["e"])]
    assert measured["impact"].tolist() == [1, 2, 3, 4], impacts
    sparse = measured["note"].fillna("").str.startswith("sparsely filmed: the flight ")
    assert sparse.tolist() == [True, False, True, True], measured["note"].tolist()
    assert all(f"(fewer than {limits.DENSE_FRAME_INTERVALS_PER_FLIGHT}): e's 95 % interval" in note
               for note in measured["note"][sparse]), measured["note"].tolist()
    table = _check(result, truth, 4)
    assert ((table["e_low"] <= table["e_true"]) & (table["e_true"] <= table["e_high"])).all(), table
    assert result.fit["restitution"]["n_impacts"] == 4


def test_a_light_ball_clip_too_blurred_is_refused_in_one_line_with_the_cause(tmp_path):
    """Seed 4 of the white ball: no flight after the first two is measured cleanly in enough frames; the refusal
    names each impact by its number from the release with its reason, the frame rate that would give enough clean frames, what the
    frames not measured cleanly were, and the options that help the tracker."""
    path, clip = phone_clip("white_pingpong_mov", tmp_path, seed=4, downscale=0.5)
    physics = clip["physics"]
    # each impact with its own reason, the advice once
    refusal = (r"not analysable: no impact can be measured: impact 2: clean frames in the flight before it: 5 < 7; "
               r"impact 3: clean frames in the flight after it: \d < 7; .*; film at 4[23] frames/s or more, with a "
               r"shorter exposure; the frames not clean: .*too blurred to measure on its lit side in \d+% of "
               r"the frames.*; see the contact sheet \(dropfit overlay\); help the tracker with --ball-at-px")
    with pytest.raises(InputError, match=refusal) as refused:
        dropfit.analyse_recording(path, ball_radius_m=physics["radius_m"], ball_mass_kg=physics["mass_kg"],
                                  ball_type=physics["ball_model"])
    assert "\n" not in str(refused.value)


@pytest.mark.slow
def test_a_floor_edge_does_not_set_the_contact_height_of_a_ball_measured_in_colour(tmp_path):
    """yellow_green_tape seed 9: the floor's edge is found 0.35 px below where the ball touches, and the ball's
    colour centre reads 0.85 px high (its shaded lower half has less colour). Used as the contact height, that
    floor put impacts 3 and 4 at 6.5 and 8 standard errors high (5 with the true floor given). The edge is drawn,
    not used: the contact height is modelled from the flights and every e covers the truth."""
    path, truth = phone_clip("yellow_green_tape", tmp_path, seed=9, downscale=0.5)
    physics = truth["physics"]
    result = dropfit.analyse_recording(path, ball_radius_m=physics["radius_m"], ball_mass_kg=physics["mass_kg"],
                                       ball_type=physics["ball_model"])
    assert "floor_m" not in result.trajectory.attrs and "floor_row_px" in result.trajectory.attrs
    assert any(note.startswith("floor note: the floor's edge is seen") for note in result.notes), result.notes
    _check(result, truth, 4)


@pytest.mark.slow
def test_a_ruler_read_in_the_wrong_marks_is_named_suspect_and_gravity_scales_the_clip(tmp_path):
    """The tape's cm ticks are not resolved at half size; told they are 1 cm apart, the marks found (every
    10 cm) would give a scale 10 times too fine, and a capture rate inferred through it a false slow motion.
    The ball's diameter contradicts it and gravity agrees with the diameter: the ruler is suspect, named with the
    spacing its marks really have, and gravity's scale is used (it was refused, issue 32)."""
    # filmed at a high bit rate (crf 10): at crf 18 the tape's 10 cm marks are too soft at half size to be
    # found at all, and the clip is measured with gravity's scale
    path, truth = phone_clip("yellow_green_tape", tmp_path, seed=3, downscale=0.5, crf=10)
    physics = truth["physics"]
    result = dropfit.analyse_recording(path, ball_radius_m=physics["radius_m"], ball_mass_kg=physics["mass_kg"],
                                       ball_type=physics["ball_model"], ruler_tick_m=0.01)
    scale = result.fit["scale"]
    assert scale["source"] == "gravity" and set(scale["suspect"]) == {"ruler"}
    spacing_m = float(re.search(r"the marks found are ([0-9.]+) m apart", scale["suspect"]["ruler"]).group(1))
    assert scale["disagreement"]["ruler"] == pytest.approx(-0.9, abs=0.02)
    assert spacing_m == pytest.approx(0.1, rel=0.1) and "--ruler-tick-m" in scale["suspect"]["ruler"]
    assert result.fit["time_base"]["capture_fps"] == pytest.approx(float(truth["clip"]["capture_fps_hz"]))


@pytest.mark.slow
@pytest.mark.parametrize("drag_factor, seed", [
    (1.1, 3), (0.9, 3),
    # its hand was followed for a while, jumping hundreds of px: the jumps' sum turned the image rows' sign (the
    # clip was refused, "falls with 736 m/s², not g") where the flights' median curvature gives it
    (1.1, 0)])
def test_a_ball_whose_drag_is_not_its_kinds_is_covered(tmp_path, drag_factor, seed):
    """The small yellow ball at 120 frames/s with 1.1 or 0.9 times the C_d its kind is analysed with. Its
    H.264 centres read up to 0.45 px higher falling than rising near the floor (none of it in the same clip encoded
    losslessly), and the free drag fit took that for 20 % more drag: e came out 2.0-3.4 se high. A video's flights'
    k is now widened by what a centre error of 1 px growing with speed makes of it and combined with the kind's
    value (11 % se), and a ball whose C_d is not the nominal one is covered too."""
    import dataclasses

    import phonesim
    import refsim

    ball = phonesim.PRESETS["yellow_flicker_portrait_120"].ball
    ball = dataclasses.replace(ball, drag_coefficient=drag_factor * refsim.preset(ball.model).drag_coefficient)
    path, truth = phone_clip("yellow_flicker_portrait_120", tmp_path, seed=seed, downscale=0.5, ball=ball)
    physics = truth["physics"]
    result = dropfit.analyse_recording(path, ball_radius_m=physics["radius_m"], ball_mass_kg=physics["mass_kg"],
                                       ball_type=physics["ball_model"], ruler_tick_m=0.01)
    assert result.analysis.summary["drag_model"] == "nominal"
    assert "curvature takes such an error for drag" in result.analysis.summary["drag_why"]
    _check(result, truth, 2)


@pytest.mark.slow
def test_a_search_about_a_ball_predicted_below_the_frame_is_not_made(tmp_path):
    """green_board_avi seed 4, its ball with 1.1 times the preset's C_d: once, the tracker searched the square of
    210 px about a position it predicted 420 px below the 540 px frame; the square was empty, and OpenCV's resize
    raised (a traceback, no result). A square wholly outside the frame is not searched now, and the clip is
    measured."""
    import dataclasses

    import phonesim
    import refsim

    ball = phonesim.PRESETS["green_board_avi"].ball
    ball = dataclasses.replace(ball, drag_coefficient=1.1 * refsim.preset(ball.model).drag_coefficient)
    path, truth = phone_clip("green_board_avi", tmp_path, seed=4, downscale=0.5, ball=ball)
    physics = truth["physics"]
    result = dropfit.analyse_recording(path, ball_radius_m=physics["radius_m"], ball_mass_kg=physics["mass_kg"],
                                       ball_type=physics["ball_model"])
    _check(result, truth, 4)
