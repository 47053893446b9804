"""Where video analysis fails: each limit refuses a recording below it; above them e matches the truth."""

import math
import re

import numpy as np
import pandas as pd
import pytest
import xarray as xr

from dropfit import Ball, stages
from dropfit.video import limits as video_limits
from dropfit.analysis import analyse_bounces
from dropfit.contact import LinearContact
from dropfit.errors import InputError
from dropfit.heightlog import make_trajectory
from dropfit.pipeline import analyse_trajectory
from dropfit.physics import STANDARD_GRAVITY_M_S2
from dropfit.synth import simulate_drop
from dropfit.video.track import TrackedVideo
from dropfit.videolog import trajectory_from_video

from helpers import CLIP_BALL_RADIUS_M, CLIP_FLOOR_ROW_PX, CLIP_PX_PER_M, render_drop_clip

E_TOLERANCE = 0.002  # dimensionless: the sweep's clips above the limits are within 3e-4
NOISE_TOLERANCE = 0.15  # relative, robust noise estimate from ~100 third differences
PX_PER_M = CLIP_PX_PER_M  # image scale of the synthetic tables and clips, px/m
FLOOR_ROW_PX = CLIP_FLOOR_ROW_PX  # image row of the floor, px
BALL_RADIUS_M = CLIP_BALL_RADIUS_M
SPAN_TOLERANCE_FRAMES = 0.5  # frame intervals: fitted apex and contact times are good to a few ms


@pytest.fixture(scope="module")
def drop():
    """A 0.8 m drop through the seed's spring–damper contact (e ≈ 0.745), released at 0.1 s."""
    return simulate_drop(0.8, BALL_RADIUS_M, mass_kg=0.057, contact_model=LinearContact(30000.0, 8.2),
                         release_time_s=0.1)


def tracked_table(truth, fps, duration_s=1.7, radius_px=5.0, noise_px=0.02, clean_every=1, seed=0):
    """A tracked table as :func:`dropfit.video.track.track_video` returns it, from the truth (rows down, px).

    Every ``clean_every``-th frame is ``ok``; the others are ``lost`` (NaN).
    """
    rng = np.random.default_rng(seed)
    time = np.arange(int(round(duration_s * fps))) / fps
    rows = FLOOR_ROW_PX - truth.height(time) * PX_PER_M + rng.normal(0.0, noise_px, time.size)
    clean = np.arange(time.size) % clean_every == 0
    return pd.DataFrame({"frame": np.arange(time.size), "time_s": time, "x_px": np.where(clean, 100.0, np.nan),
                         "y_px": np.where(clean, rows, np.nan), "radius_px": np.where(clean, radius_px, np.nan),
                         "quality": np.where(clean, "ok", "lost"), "centre_se_px": np.nan, "fit_rms_px": np.nan,
                         "blur_px": 0.0})


def refusal_of(tmp_path, monkeypatch, table):
    """The one-line message with which trajectory_from_video refuses ``table`` as a tracked video."""
    with pytest.raises(InputError) as caught:
        trajectory_from_video(tmp_path / "clip.avi", ball_radius_m=BALL_RADIUS_M, tracked=TrackedVideo(table, None))
    return str(caught.value)


# --- the limit functions ------------------------------------------------------------------------


def test_recording_measures_match_the_table_they_were_made_from(drop):
    table = tracked_table(drop, fps=120.0, radius_px=6.0, noise_px=0.1, clean_every=2)
    measures = video_limits.recording_measures(table)
    assert measures["ball_radius_px"] == pytest.approx(6.0)
    assert measures["clean_fraction"] == pytest.approx(0.5, abs=1 / len(table))
    assert measures["centre_noise_px"] == pytest.approx(0.1, rel=NOISE_TOLERANCE)
    assert measures["travel_px"] == pytest.approx(0.8 * PX_PER_M, abs=1.0)  # from release to the floor


def test_duplicates_and_frames_before_or_after_the_ball_was_seen_do_not_count_as_lost(drop):
    table = tracked_table(drop, fps=120.0)
    table.loc[table.index % 4 == 1, "quality"] = "duplicate"
    table.loc[:30, "quality"] = "occluded"  # a hand holds the ball
    table.loc[len(table) - 50:, "quality"] = "lost"  # the ball has left the image
    assert video_limits.recording_measures(table)["clean_fraction"] == 1.0
    table.loc[100:109, "quality"] = "lost"  # 10 frames lost in mid-flight, of them 2 duplicates anyway
    between = table.loc[31:len(table) - 51, "quality"]
    expected = np.count_nonzero(between == "ok") / np.count_nonzero(between != "duplicate")
    assert video_limits.recording_measures(table)["clean_fraction"] == pytest.approx(expected)


def test_blurred_frames_count_as_clean(drop):
    """Decision: a ``blurred`` frame (a motion-blur streak, centre = exposure-mean centroid) is measured
    cleanly, like an ``ok`` one; an ``occluded`` one is not."""
    table = tracked_table(drop, fps=60.0)
    table.loc[table.index % 3 == 1, "quality"] = "blurred"
    assert video_limits.recording_measures(table)["clean_fraction"] == 1.0
    table.loc[table.index % 3 == 1, "quality"] = "occluded"
    assert video_limits.recording_measures(table)["clean_fraction"] == pytest.approx(2 / 3, abs=1 / len(table))


def test_recording_violations_name_each_limit_with_value_and_limit():
    good = dict(ball_radius_px=5.0, clean_fraction=0.9, clean_frames=200)
    assert video_limits.recording_violations(good) == []
    small = video_limits.recording_violations(dict(good, ball_radius_px=1.6))
    assert small == [f"tracked ball radius: 1.60 px < {video_limits.MIN_BALL_RADIUS_PX:g} px"]
    # a low fraction of clean frames over the clip is judged per flight (select_resolved_impacts), not here
    assert video_limits.recording_violations(dict(good, clean_fraction=0.1, ball_radius_px=np.nan)) == []
    one = video_limits.recording_violations(dict(good, clean_frames=1))  # one clean frame is 100 % of its span
    assert one == [f"frames measured cleanly: 1 < {video_limits.MIN_CLEAN_FRAMES} (the two flights of one impact "
                   f"need {video_limits.MIN_CLEAN_FRAMES_PER_FLIGHT} each)"]


def test_flight_violation_names_the_impact_and_the_short_flight():
    span, clean = video_limits.DENSE_FRAME_INTERVALS_PER_FLIGHT, video_limits.MIN_CLEAN_FRAMES_PER_FLIGHT
    least = video_limits.MIN_FRAME_INTERVALS_PER_FLIGHT
    row = dict(impact=1, n_samples_before=span + 10, n_samples_after=span + 10)  # every frame clean
    assert video_limits.flight_violation(row, span, span, 1 / 30) is None
    short = video_limits.flight_violation(dict(row, impact=2), span + 10, least - 0.5, 1 / 30)
    # 4.5 frame intervals at 30 frames/s last 0.15 s: 8 intervals (measured without widening) need 53.3 frames/s
    assert short == (f"impact 2: the flight after it lasts {least - 0.5:.1f} frame intervals at 30 frames/s, fewer "
                     f"than the {least} a flight needs to be told from its impacts (film at 54 frames/s or more, in "
                     f"slow motion)")
    # a sparsely filmed flight (from the lower bound to 8 intervals) holds fewer clean frames: 5 are enough there
    few = video_limits.MIN_CLEAN_FRAMES_PER_SPARSE_FLIGHT
    assert video_limits.flight_violation(dict(row, n_samples_after=few), span, least + 1, 1 / 30) is None
    assert video_limits.flight_violation(dict(row, n_samples_after=few - 1), span, least + 1, 1 / 30) == (
        f"impact 1: clean frames in the flight after it: {few - 1} < {few} (film at 53 frames/s or more, with a "
        f"shorter exposure)")
    sparse = video_limits.flight_violation(dict(row, impact=3, n_samples_after=clean - 5), span + 10, span + 10, 1 / 30)
    # 2 clean frames at 30 frames/s: as many in each interval, 7 need 105 frames/s
    assert sparse == (f"impact 3: clean frames in the flight after it: {clean - 5} < {clean} (film at 105 frames/s "
                      f"or more, with a shorter exposure)")
    none = video_limits.flight_violation(dict(row, n_samples_before=0), span + 10, span + 10, 1 / 30)
    assert none.endswith("0 < 7 (film at a higher frame rate, with a shorter exposure)")
    # 8 clean frames in a flight of 20 frame intervals: 40 % of its frames, below the limit
    faint = video_limits.flight_violation(dict(row, n_samples_after=8), span + 12, span + 12, 1 / 30)
    assert faint.startswith(f"impact 1: the flight after it is measured cleanly in 40% of its frames < "
                            f"{video_limits.MIN_CLEAN_FRACTION:.0%} (see the contact sheet")


def test_flight_spans_are_the_fall_of_the_drop_and_whole_bounces(drop):
    """At 60 frames/s the spans match the generator's flight times (the drop from its release)."""
    fps = 60.0
    table = tracked_table(drop, fps=fps, duration_s=2.6)
    heights = (FLOOR_ROW_PX - table["y_px"].to_numpy()) / PX_PER_M
    analysis = analyse_bounces(table["time_s"].to_numpy(), heights, contact_height_m=BALL_RADIUS_M)
    before, after = video_limits.flight_spans(analysis, 1.0 / fps)
    touchdowns = drop.impacts["t_s"].to_numpy()[: len(before) + 1]
    true_before = np.diff(np.concatenate([[drop.release_time_s], touchdowns]))[: len(before)] * fps
    # the last flight may run past the clip, so its span is twice its rise: compare the others
    assert before == pytest.approx(true_before, abs=SPAN_TOLERANCE_FRAMES)
    assert after[:-1] == pytest.approx(true_before[1:], abs=SPAN_TOLERANCE_FRAMES)


def test_late_short_flights_cost_only_their_own_impacts_and_the_early_ones_are_kept(drop):
    """Judged as 30 Hz captures (a 30 Hz clip in a 60 fps file), the flights last 12, 18, 13, 10, 7.4, 5.5, 4.1, 3 …
    capture intervals: the impacts whose flight before or after is shorter than the limit keep their rows with no
    e and the reason; those whose shorter flight lasts from the limit to 8 intervals keep their e with its interval
    widened by the sparse sampling's term and a note saying so; the others keep their e as fitted."""
    table = tracked_table(drop, fps=60.0, duration_s=2.6)
    heights = (FLOOR_ROW_PX - table["y_px"].to_numpy()) / PX_PER_M
    analysis = analyse_bounces(table["time_s"].to_numpy(), heights, contact_height_m=BALL_RADIUS_M)
    captures = 2.0 / 60.0
    kept = video_limits.select_resolved_impacts(analysis, "clip.avi", captures)
    before, after = video_limits.flight_spans(analysis, captures)
    shorter = np.minimum(before, after)
    short = shorter < video_limits.MIN_FRAME_INTERVALS_PER_FLIGHT
    sparse = ~short & (shorter < video_limits.DENSE_FRAME_INTERVALS_PER_FLIGHT)
    first_short = int(np.argmax(short))
    assert 1 <= first_short < len(analysis.impacts)  # the test needs every kind of impact
    assert sparse.sum() >= 2 and (~short & ~sparse).sum() >= 2
    assert len(kept.impacts) == len(analysis.impacts) == kept.summary["n_impacts"]  # every impact found stays
    assert len(kept.flights) == len(analysis.flights)
    assert kept.summary["impacts_unmeasured"] == int(short.sum())
    assert kept.summary["impacts_sparsely_filmed"] == int(sparse.sum())
    assert kept.impacts["in_fit"].tolist() == (~short).tolist()
    assert np.isnan(kept.impacts["e"][short]).all()
    assert kept.impacts["note"][first_short].startswith("the flight after it lasts")
    assert np.all(kept.e_covariance[short] == 0.0) and np.all(kept.e_covariance[:, short] == 0.0)
    true_e = drop.impacts["e"].to_numpy()[: len(kept.impacts)]
    assert np.all(np.abs(kept.impacts["e"].to_numpy()[~short] - true_e[~short]) < E_TOLERANCE)
    # impact first_short's flight before it was filmed well: its impact speed stays
    assert np.isfinite(kept.impacts["v_in_m_s"][first_short]) and np.isnan(kept.impacts["v_out_m_s"][first_short])
    # the densely filmed impacts are untouched; the sparsely filmed ones widened by the sparse sampling's term (none
    # for bounces: the sweep found their fits' intervals covered it), in the table and the covariance, with a note
    fitted_se = analysis.impacts["e_se"].to_numpy()
    dense = ~short & ~sparse
    assert kept.impacts["e_se"][dense].tolist() == fitted_se[dense].tolist()
    assert np.all(kept.impacts["note"][dense].fillna("") == analysis.impacts["note"][dense].fillna(""))
    for i in np.flatnonzero(sparse):
        extra = video_limits.sparse_flight_e_se(kept.impacts["e"][i], before[i], after[i], drop_before=i == 0)
        widened = math.hypot(fitted_se[i], extra)
        assert kept.impacts["e_se"][i] == pytest.approx(widened)
        assert kept.impacts["e_ci95_high"][i] - kept.impacts["e_ci95_low"][i] == pytest.approx(2 * 1.959964 * widened)
        assert kept.e_covariance[i, i] == pytest.approx(analysis.e_covariance[i, i] + extra ** 2)
        note = kept.impacts["note"][i]
        assert note.startswith("sparsely filmed: the flight ") and "at 30 frames/s (fewer than 8): e's 95 % " \
            "interval" in note, note
        assert ("widened from ±" in note) == (extra > 0.0), note
        assert f"the flight after it lasts {after[i]:.1f} frame intervals" in note, note
    # a drop of 6 intervals is widened by its measured term; a bounce's term is zero
    assert video_limits.sparse_flight_e_se(0.8, 6.0, 9.0, drop_before=True) == pytest.approx(
        0.8 * video_limits.SPARSE_DROP_SPEED_RELATIVE_SE) and video_limits.SPARSE_DROP_SPEED_RELATIVE_SE > 0.0
    assert video_limits.sparse_flight_e_se(0.8, 9.0, 9.0, drop_before=True) == 0.0


def _occluded(drop, fps, flight, seen=5, seed=0):
    """Time (s) and heights (m, NaN where not clean) of a clip at ``fps`` whose flight number ``flight`` (0: the
    drop) is hidden (a hand, a passer-by) after its first ``seen`` frames."""
    table = tracked_table(drop, fps=fps, duration_s=2.6, seed=seed)
    time = table["time_s"].to_numpy()
    heights = (FLOOR_ROW_PX - table["y_px"].to_numpy()) / PX_PER_M
    contacts = np.r_[drop.release_time_s, drop.impacts["t_s"].to_numpy()]
    inside = np.flatnonzero((time > contacts[flight] + 0.01) & (time < contacts[flight + 1] - 0.01))
    heights[inside[seen:]] = np.nan
    return time, heights


def test_an_occluded_middle_flight_costs_its_two_impacts_and_keeps_those_on_both_sides(drop):
    """Flight 2 (between impacts 2 and 3) is seen in 6 clean frames only, one fewer than the limit: impacts 2 and
    3 have no e, each with the reason; impact 1 before and impacts 4-6 after keep theirs, within tolerance of the
    generator's (before: impact 1 kept, 2 and every later one dropped)."""
    time, heights = _occluded(drop, 60.0, flight=2)
    analysis = analyse_bounces(time, heights, contact_height_m=BALL_RADIUS_M)
    kept = video_limits.select_resolved_impacts(analysis, "clip.avi", 1.0 / 60.0)
    impacts = kept.impacts.set_index("impact")
    clean = video_limits.MIN_CLEAN_FRAMES_PER_FLIGHT
    assert not impacts.loc[2, "in_fit"] and not impacts.loc[3, "in_fit"]
    assert impacts.loc[2, "note"].startswith(f"clean frames in the flight after it: {clean - 1} < {clean}")
    assert impacts.loc[3, "note"].startswith(f"clean frames in the flight before it: {clean - 1} < {clean}")
    assert np.isnan(impacts.loc[[2, 3], "e"]).all()
    assert np.isfinite(impacts.loc[2, "v_in_m_s"]) and np.isfinite(impacts.loc[3, "v_out_m_s"])
    for number in (1, 4, 5, 6):
        assert impacts.loc[number, "in_fit"]
        assert abs(impacts.loc[number, "e"] - drop.impacts["e"].iloc[number - 1]) < E_TOLERANCE


def test_a_fall_filmed_in_too_few_clean_frames_leaves_e1_out_and_keeps_the_later_impacts(drop):
    """A clip that sees the drop's fall in 6 clean frames (the hand hides the ball before, blur in between: 3 at
    its top, 3 near the floor): impact 1 has no e (its note says why) and is in no fit; the impacts after it
    are kept, with the generator's e."""
    fps = 60.0
    table = tracked_table(drop, fps=fps, duration_s=2.6)
    time = table["time_s"].to_numpy()
    heights = (FLOOR_ROW_PX - table["y_px"].to_numpy()) / PX_PER_M
    fall = np.flatnonzero((time > drop.release_time_s) & (time < float(drop.impacts["t_s"].iloc[0])))
    heights[time <= drop.release_time_s] = np.nan
    heights[fall[3:-3]] = np.nan
    analysis = analyse_bounces(time, heights, contact_height_m=BALL_RADIUS_M)
    kept = video_limits.select_resolved_impacts(analysis, "clip.avi", 1.0 / fps)
    clean = video_limits.MIN_CLEAN_FRAMES_PER_FLIGHT
    first = kept.impacts.iloc[0]
    assert np.isnan(first["e"]) and np.isnan(first["v_in_m_s"]) and not first["in_fit"]
    before = int(first["n_samples_before"])
    assert first["note"] == (f"clean frames in the flight before it: {before} < {clean} (film at "
                             f"{math.ceil(fps * clean / before)} frames/s or more, with a shorter exposure): its e is "
                             f"not given")
    assert kept.e_covariance[0].tolist() == [0.0] * len(kept.impacts)
    later = kept.impacts.iloc[1:]
    measured = later[later["in_fit"]]
    assert len(measured) >= 2 and measured.index[0] == 1
    true_e = drop.impacts["e"].to_numpy()[measured["impact"].to_numpy() - 1]
    assert np.all(np.abs(measured["e"].to_numpy() - true_e) < E_TOLERANCE)
    # the last flights are too short: those impacts keep their rows, with the reason
    assert all("frame intervals" in note for note in later[~later["in_fit"]]["note"])


def _fall_seen_at_its_top_only(drop, fps=60.0, clean_frames=6):
    """Time (s) and heights (m) of a clip whose drop shows in its first ``clean_frames`` falling frames only."""
    table = tracked_table(drop, fps=fps, duration_s=2.6)
    time = table["time_s"].to_numpy()
    heights = (FLOOR_ROW_PX - table["y_px"].to_numpy()) / PX_PER_M
    fall = np.flatnonzero((time > drop.release_time_s) & (time < float(drop.impacts["t_s"].iloc[0])))
    heights[time <= drop.release_time_s] = np.nan
    heights[fall[clean_frames:]] = np.nan
    return time, heights


def test_a_first_flight_that_rises_from_the_floor_is_named_a_bounce_with_no_drop_height(drop):
    """Without a frame near the floor, impact 1 is not found: the analysis starts at flight 1, whose rise
    from the floor is in the samples. It says so, and gives no drop height (a release at its apex it is not)."""
    time, heights = _fall_seen_at_its_top_only(drop)
    analysis = analyse_bounces(time, heights, contact_height_m=BALL_RADIUS_M)
    assert analysis.impacts["t_touchdown_s"].iloc[0] == pytest.approx(drop.impacts["t_s"].iloc[1], abs=1e-3)
    assert any(note.startswith("flight 0 is a bounce, not a drop") for note in analysis.summary["notes"])
    assert not any(note.startswith("the ball was held") for note in analysis.summary["notes"])
    assert np.isnan(analysis.summary["drop_height_m"]) and analysis.summary["first_flight_is_a_bounce"]


def test_a_ball_tossed_up_from_a_hand_is_a_drop_from_its_apex(drop):
    """The same flight rising from a hand at 0.7 of its apex height (a toss) is a drop from the apex."""
    fps = 60.0
    table = tracked_table(drop, fps=fps, duration_s=2.6)
    time = table["time_s"].to_numpy()
    heights = (FLOOR_ROW_PX - table["y_px"].to_numpy()) / PX_PER_M
    apex = float(drop.height(np.array([0.0]))[0])
    rise_s = np.sqrt(2 * 0.3 * (apex - BALL_RADIUS_M) / STANDARD_GRAVITY_M_S2)  # from 0.7 of the apex height
    before = time < drop.release_time_s
    rising = before & (time > drop.release_time_s - rise_s)
    heights[rising] = apex - 0.5 * STANDARD_GRAVITY_M_S2 * (time[rising] - drop.release_time_s) ** 2
    heights[before & ~rising] = np.nan  # in the hand
    analysis = analyse_bounces(time, heights, contact_height_m=BALL_RADIUS_M)
    assert not analysis.summary["first_flight_is_a_bounce"]
    assert analysis.summary["drop_height_m"] == pytest.approx(apex - BALL_RADIUS_M, abs=2e-3)


def test_a_clip_with_no_resolved_impact_is_refused_naming_the_first(drop):
    table = tracked_table(drop, fps=60.0, duration_s=2.6)
    heights = (FLOOR_ROW_PX - table["y_px"].to_numpy()) / PX_PER_M
    analysis = analyse_bounces(table["time_s"].to_numpy(), heights, contact_height_m=BALL_RADIUS_M)
    with pytest.raises(InputError) as refused:
        video_limits.select_resolved_impacts(analysis, "clip.avi", 1.0)  # 1 frame/s: no flight spans 8 frames
    message = str(refused.value)
    assert message.startswith("clip.avi: not analysable: no impact can be measured: impact 1: the flight before it "
                              "lasts")
    # each impact with its reason, the advice once
    for number in analysis.impacts["impact"]:
        assert f"; impact {number}: the flight" in message or number == 1
    assert message.count("film at") == 1


# --- refusals through the workflow's own entry points ---------------------------------------------


def test_a_ball_tracked_smaller_than_the_limit_is_refused(tmp_path, monkeypatch, drop):
    message = refusal_of(tmp_path, monkeypatch, tracked_table(drop, fps=120.0, radius_px=1.6))
    assert message == f"{tmp_path / 'clip.avi'}: not analysable: tracked ball radius: 1.60 px < 2 px"


def test_a_recording_whose_every_flight_is_mostly_unclean_is_refused_with_each_impact(tmp_path, monkeypatch, drop):
    """A ball measured in one frame of five throughout (a ball too small or faint for the tracker): every flight
    has 20 % of its frames clean, below the limit, and no impact is measured."""
    table = tracked_table(drop, fps=120.0, clean_every=5)
    trajectory = trajectory_from_video(tmp_path / "clip.avi", ball_radius_m=BALL_RADIUS_M,
                                       tracked=TrackedVideo(table, None))
    with pytest.raises(InputError) as refused:
        analyse_trajectory(trajectory)
    message = str(refused.value)
    assert re.match(re.escape(f"{tmp_path / 'clip.avi'}: not analysable: no impact can be measured: impact 1: the "
                              f"flight before it is measured cleanly in ") + r"\d+% of its frames < 45%", message)
    assert "impact 2: the flight before it is measured cleanly in" in message
    assert "the ball not found in 80% of the frames" in message
    assert "--ball-at-px" in message and "--roi-px" in message and "--ball-colour" in message
    assert "\n" not in message


def test_a_recording_with_too_few_clean_frames_for_one_impact_is_refused(tmp_path, monkeypatch, drop):
    table = tracked_table(drop, fps=120.0, clean_every=20)
    table.loc[table.index[len(table) // 2:], ["y_px", "x_px", "radius_px"]] = np.nan
    table.loc[table.index[len(table) // 2:], "quality"] = "lost"
    message = refusal_of(tmp_path, monkeypatch, table)
    assert message.startswith(f"{tmp_path / 'clip.avi'}: not analysable: frames measured cleanly: 6 < 14")
    assert "--ball-at-px" in message


def test_a_hand_in_the_hold_and_an_empty_scene_after_do_not_refuse_well_filmed_flights(tmp_path, drop):
    """A ball held for 2 s before it is dropped, half hidden by the hand (occluded), and a clip running 3 s
    after it stops bouncing with the ball lost: 19 % of the frames from the first clean one to the last are clean
    (the clip's fraction, refused before: "frames measured cleanly: 19% < 45%"), every flight fully; the impacts
    are measured with the generator's e."""
    fps = 60.0
    flight = tracked_table(drop, fps=fps, duration_s=2.1)
    hold_frames = int(2.0 * fps)
    flight["time_s"] = flight["time_s"] + hold_frames / fps
    hold = flight.iloc[[0] * hold_frames].copy()
    hold["time_s"] = np.arange(hold_frames) / fps
    hold["quality"] = np.where(np.arange(hold_frames) % 6 == 0, "ok", "occluded")
    after = flight.iloc[[-1] * int(3.5 * fps)].copy()
    after["time_s"] = flight["time_s"].iloc[-1] + (np.arange(len(after)) + 1) / fps
    after["quality"] = "lost"
    after.loc[:, ["x_px", "y_px", "radius_px"]] = np.nan
    after.iloc[-1, after.columns.get_loc("quality")] = "ok"  # seen again at the end, at rest
    after.iloc[-1, [after.columns.get_loc(c) for c in ("x_px", "y_px", "radius_px")]] = (100.0, FLOOR_ROW_PX, 5.0)
    table = pd.concat([hold, flight, after], ignore_index=True)
    table["frame"] = np.arange(len(table))
    assert video_limits.recording_measures(table)["clean_fraction"] < video_limits.MIN_CLEAN_FRACTION
    trajectory = trajectory_from_video(tmp_path / "clip.avi", ball_radius_m=BALL_RADIUS_M, scale_m_per_px=1 / PX_PER_M,
                                       tracked=TrackedVideo(table, None))
    analysis = analyse_trajectory(trajectory)
    measured = analysis.impacts[analysis.impacts["in_fit"]]
    assert len(measured) >= 3
    true_e = drop.impacts["e"].to_numpy()[measured["impact"].to_numpy() - 1]
    assert np.all(np.abs(measured["e"].to_numpy() - true_e) < E_TOLERANCE)


def render(tmp_path, truth, fps, seed=0):
    """A 160 × 220 px clip of ``truth`` (:func:`helpers.render_drop_clip`); returns its path."""
    return render_drop_clip(tmp_path / "clip.avi", truth, fps, seed).attrs["video_path"]


def measure_and_analyse(tmp_path, video):
    stages.measure(video, tmp_path / "t.nc", Ball(radius_m=BALL_RADIUS_M))
    stages.analyse(tmp_path / "t.nc", tmp_path / "impacts.csv", tmp_path / "flights.csv", tmp_path / "analysis.json")
    return pd.read_csv(tmp_path / "impacts.csv")


def test_a_15_fps_clip_is_measured_with_notes_and_intervals_that_cover_the_truth(tmp_path, drop):
    """15 frames/s: the 0.4 s fall lasts 6.3 frame intervals, where the sweep saw e₁ go wrong (refused before the
    sparsely filmed flights were measured). Both impacts are measured, each with its note, and each interval holds
    the generator's e (measured: e₁ 0.844 ± 0.060, e₂ 0.804 ± 0.032 against 0.745: fewer than 2 se)."""
    impacts = measure_and_analyse(tmp_path, render(tmp_path, drop, fps=15.0))
    measured = impacts[impacts["in_fit"]]
    assert len(measured) >= 2, impacts
    assert measured["note"].str.startswith("sparsely filmed: the flight ").all(), measured["note"].tolist()
    assert "widened from ±" in measured["note"].iloc[0]  # the drop's term
    true_e = drop.impacts["e"].to_numpy()[measured["impact"].to_numpy() - 1]
    assert np.all((measured["e_ci95_low"] <= true_e) & (true_e <= measured["e_ci95_high"])), measured


def test_a_clip_above_the_limits_gives_e_within_tolerance_of_the_truth(tmp_path, drop):
    impacts = measure_and_analyse(tmp_path, render(tmp_path, drop, fps=120.0))
    measured = impacts[impacts["in_fit"]]
    assert len(measured) >= 2
    true_e = drop.impacts["e"].to_numpy()[measured["impact"].to_numpy() - 1]
    assert np.all(np.abs(measured["e"].to_numpy() - true_e) < E_TOLERANCE)


def test_a_tracked_ball_that_does_not_fall_with_g_is_refused_with_what_was_tracked(tmp_path):
    """A video whose tracked flights do not fall with g (the ball lost in its flights, seen only near the
    floor) is refused with what the tracker measured and the options that help, not with a log's advice
    about column units."""
    time = np.arange(300) / 60.0
    quality = np.where(np.arange(300) % 3 == 0, 0, 1)
    heights = np.where(np.arange(300) % 2 == 0, 0.02, 0.03)  # a 1 cm jitter near the floor
    trajectory = xr.Dataset({"y": ("time", heights), "quality": ("time", quality)}, coords={"time": time})
    message = video_limits.not_free_fall(tmp_path / "clip.mov", 0.005, trajectory)
    assert message.startswith(f"{tmp_path / 'clip.mov'}: not analysable: the tracked ball falls with 0.005 m/s², "
                              f"not g: it was measured in 100 of 300 frames, over 0.01 m of height")
    assert "--ball-at-px" in message and "column names" not in message and "\n" not in message


def test_a_video_whose_capture_rate_came_from_gravity_is_refused_with_that_rate_named(tmp_path):
    """The capture rate inferred from flights found in the file's time (1120 fps of a 120 fps phone clip, from
    flights read upside down) and the flights at it not falling with g: the refusal names the inferred rate and
    the option that overrides it before the tracking."""
    time = np.arange(300) / 1120.0
    heights = 1.0 - 0.5 * 842.0 * (time - time[0]) ** 2
    trajectory = xr.Dataset({"y": ("time", heights), "quality": ("time", np.zeros(300, np.int8))},
                            coords={"time": time})
    note = "gravity gives 1120 fps against the file's 120.002 fps, not within 2 % of a common rate: the estimate is used"
    trajectory.attrs.update(capture_fps=1120.4, capture_fps_source="inferred from gravity (not a common rate)",
                            capture_rate_note=note)
    message = video_limits.not_free_fall(tmp_path / "clip.mov", 842.0, trajectory)
    assert message.startswith(f"{tmp_path / 'clip.mov'}: not analysable: the tracked ball falls with 842 m/s², not g")
    assert note in message and "--capture-fps" in message and "\n" not in message
    assert message.index("--capture-fps") < message.index("--ball-at-px")
    trajectory.attrs.update(capture_fps=120.0, capture_fps_source="container")
    assert "--capture-fps" not in video_limits.not_free_fall(tmp_path / "clip.mov", 842.0, trajectory)


def test_a_video_whose_every_impact_gains_height_is_refused_with_the_tracking_as_the_cause(tmp_path):
    """Flights that rise higher after each bounce (apexes 0.20, 0.26, 0.33, 0.42 m: a tracker that followed
    something else): no impact gives a physical e, and the refusal says so with what was tracked, not that
    nothing is left to fit."""
    fps, g = 60.0, STANDARD_GRAVITY_M_S2
    apexes = [0.20, 0.26, 0.33, 0.42]
    times, heights, start = [], [], 0.2
    for number, apex in enumerate(apexes):
        half = np.sqrt(2 * apex / g)
        t_apex = start if number == 0 else start + half
        end = t_apex + half
        t = np.arange(np.ceil(start * fps), np.floor(end * fps) + 1) / fps
        times.append(t)
        heights.append(np.maximum(apex - 0.5 * g * (t - t_apex) ** 2, 0.0))
        start = end
    time, height = np.concatenate(times), np.concatenate(heights)
    height = height + np.random.default_rng(0).normal(0.0, 2e-4, height.size)
    trajectory = make_trajectory(time, height, str(tmp_path / "clip.mov"), "scale from gravity",
                                 {"video": str(tmp_path / "clip.mov"), "ball_radius_m": BALL_RADIUS_M})
    trajectory["quality"] = ("time", np.zeros(time.size, np.int8))
    with pytest.raises(InputError) as refused:
        analyse_trajectory(trajectory)
    message = str(refused.value)
    assert message.startswith(f"{tmp_path / 'clip.mov'}: not analysable: no impact gives a physical e (impact 1: "
                              f"e > 1"), message


def test_an_analysis_refusal_of_a_poorly_tracked_video_says_what_was_tracked(tmp_path):
    """A bounce the analysis cannot use, in a video where the ball was measured in a third of the frames
    over 1 cm of height (white on a light wall, seen over the table only): the refusal adds that, and
    the options that help; in a well tracked video it stays the analysis's own."""
    time = np.arange(300) / 60.0
    heights = np.where(np.arange(300) % 2 == 0, 0.02, 0.03)
    said = f"{tmp_path / 'clip.mov'}: no bounce with at least 5 samples in the flights before and after it"
    poorly = xr.Dataset({"y": ("time", heights), "quality": ("time", np.where(np.arange(300) % 3 == 0, 0, 1))},
                        coords={"time": time})
    message = video_limits.analysis_refusal(said, poorly)
    assert message.startswith(f"{said}: it was measured in 100 of 300 frames, over 0.01 m of height")
    assert "--ball-at-px" in message and "\n" not in message
    well = poorly.assign(quality=("time", np.zeros(300, int)))
    assert video_limits.analysis_refusal(said, well) == said


def test_the_fit_and_the_headline_count_every_impact_found(tmp_path, drop):
    """A 60 frames/s video whose flight 4 (15 frame intervals) is seen in 6 clean frames: the fit uses the measured
    impacts, counts every one found (n of M in the headline), and names each one left out with its reason (before
    flights of 5-8 intervals were measured, the late short flights were left out here)."""
    from dropfit.pipeline import fit_analysis

    table = tracked_table(drop, fps=60.0, duration_s=2.6)
    time, heights = _occluded(drop, 60.0, flight=4, seen=6)
    table.loc[~np.isfinite(heights), ["x_px", "y_px", "radius_px"]] = np.nan
    table.loc[~np.isfinite(heights), "quality"] = "lost"
    trajectory = trajectory_from_video(tmp_path / "clip.avi", ball_radius_m=BALL_RADIUS_M, scale_m_per_px=1 / PX_PER_M,
                                       tracked=TrackedVideo(table, None))
    analysis = analyse_trajectory(trajectory)
    measured = int(analysis.impacts["in_fit"].sum())
    assert 2 <= measured < len(analysis.impacts)
    restitution = fit_analysis(analysis, trajectory.attrs)["restitution"]
    assert (restitution["n_impacts"], restitution["n_impacts_total"]) == (measured, len(analysis.impacts))
    left_out = {item["impact"]: item["note"] for item in restitution["impacts_excluded"]}
    assert sorted(left_out) == analysis.impacts["impact"][~analysis.impacts["in_fit"]].tolist()
    assert all("frame intervals" in note or "clean" in note for note in left_out.values())


def test_a_refusal_names_the_flights_the_analysis_could_not_fit(drop):
    """Flight 2 seen in 4 frames only ends the analysed sequence after impact 1; at a frame rate too low for any
    flight (4 frames/s), the refusal gives impact 1 its reason and says why no later impact is among them."""
    time, heights = _occluded(drop, 60.0, flight=2, seen=4)
    analysis = analyse_bounces(time, heights, contact_height_m=BALL_RADIUS_M)
    assert analysis.impacts["impact"].tolist() == [1]
    with pytest.raises(InputError) as refused:
        video_limits.select_resolved_impacts(analysis, "clip.avi", 1.0 / 4.0)
    message = str(refused.value)
    assert message.startswith("clip.avi: not analysable: no impact can be measured: impact 1: the flight before it")
    assert "; flight 2 has fewer than 5 samples: the bounce sequence ends before it;" in message


def test_a_flight_hidden_but_for_4_frames_costs_its_two_impacts_and_the_later_ones_are_measured(drop):
    """Flight 2 seen in 4 frames (fewer than a flight's fit needs: the analysed sequence ended before it, and
    every later impact was lost): the samples after it are analysed as a sequence of their own, numbered from the
    release by the time between the two (one flight); impacts 2 and 3 beside the hidden flight keep rows with no
    e and the reason, impacts 4-6 are measured within tolerance of the generator's e."""
    from dropfit.pipeline import fit_analysis

    time, heights = _occluded(drop, 60.0, flight=2, seen=4)
    trajectory = make_trajectory(time, heights, "clip.avi", "scale given",
                                 {"video": "clip.avi", "ball_radius_m": BALL_RADIUS_M})
    trajectory["quality"] = ("time", np.where(np.isfinite(heights), 0, 1).astype(np.int8))
    analysis = analyse_trajectory(trajectory)
    impacts = analysis.impacts.set_index("impact")
    assert impacts.index.tolist()[:6] == [1, 2, 3, 4, 5, 6]
    for number in (2, 3):
        assert not impacts.loc[number, "in_fit"] and np.isnan(impacts.loc[number, "e"])
        assert "too few to fit (hidden or lost)" in impacts.loc[number, "note"]
    for number in (1, 4, 5, 6):
        assert impacts.loc[number, "in_fit"]
        assert abs(impacts.loc[number, "e"] - drop.impacts["e"].iloc[number - 1]) < E_TOLERANCE
    assert any(note.startswith("flight 2 is seen in") for note in analysis.summary["notes"])
    restitution = fit_analysis(analysis, trajectory.attrs)["restitution"]
    assert restitution["n_impacts"] == int(analysis.impacts["in_fit"].sum()) >= 4
    true_e = drop.impacts["e"].iloc[:6]
    assert true_e.min() - E_TOLERANCE < restitution["e"]["value"] < true_e.max() + E_TOLERANCE
