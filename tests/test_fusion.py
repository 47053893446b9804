"""Sound and picture together (:mod:`dropfit.audio.fuse`): a video with a sound track is measured both ways
by default, by ``dropfit run``, ``dropfit batch`` and the notebooks' :func:`dropfit.analyse_recording`.

The clips come from phonesim (its pictures) with a sound track from :mod:`phonesim.sound` (refsim's clicks at
each contact, room noise and hum, AAC, an offset between the sound's clock and the frames'): the truth is
refsim's impacts and the offset given, never dropfit's.
"""

from __future__ import annotations

import dataclasses
import json
from fractions import Fraction

import numpy as np
import pytest

import phonesim
from phonesim.sound import SoundTrack

from dropfit.pipeline import process_recording, track_recording
from dropfit.settings import Ball, Settings
from helpers import dropfit

#: The microphone's distance from the impact in phonesim's sound (refsim.sound's default, m) / speed of sound.
TRAVEL_S = 0.3 / 343.0


def clip_with_sound(directory, seed=0, offset_s=0.037, downscale=0.4, name="clip.mp4", duration_s=2.5, tiny=False,
                    timing=None, drop_height_m=0.5, **track):
    """A yellow tennis ball clip (phonesim's yellow_green_tape, dropped from 0.5 m after 0.3 s in the hand),
    with its sound track; ``tiny``: a ball too small to be seen (1.6 mm across) and no hand; ``timing``:
    changes to its frame timing. (path, truth, ball)."""
    base = phonesim.PRESETS["yellow_green_tape"]
    changes = dict(ball=dataclasses.replace(base.ball, radius_m=0.0008)) if tiny else {}
    config = dataclasses.replace(base.scaled(downscale), duration_s=duration_s, drop_height_m=drop_height_m,
                                 hand=dataclasses.replace(base.hand, hold_s=0.3, visible=not tiny),
                                 timing=dataclasses.replace(base.timing, **(timing or {})), **changes)
    path = directory / name
    truth = phonesim.render_clip(config, path, seed=seed, sound=SoundTrack(offset_s=offset_s, **track))
    physics = truth.summary["physics"]
    return path, truth, Ball(radius_m=physics["radius_m"], mass_kg=physics["mass_kg"], type="tennis")


def assert_sound_e_right(impacts, truth, slow_motion=1):
    """Every impact heard with an e is timed at a click's true onset (0.5 ms; on the capture clock) and its e
    is refsim's for that impact within 3 se."""
    heard = impacts[np.isfinite(impacts["e"])]
    assert len(heard) >= 3
    onsets = truth.sound["onset_s"].to_numpy() / slow_motion
    for row in heard.itertuples():
        n = int(np.argmin(np.abs(onsets - row.t_touchdown_s)))
        assert abs(row.t_touchdown_s - onsets[n]) < 0.5e-3
        assert abs(row.e - truth.impacts["e"].iloc[int(truth.sound["impact"].iloc[n]) - 1]) < 3 * row.e_se


def fusion_of(fit):
    """The sound-and-picture record of a fit result, typed."""
    from dropfit.audio.fuse import SoundAndPicture

    return SoundAndPicture.from_record(fit["sound_and_picture"])


def ball_options(ball):
    return ["--ball-type", ball.type, "--ball-radius-m", str(ball.radius_m), "--ball-mass-kg", str(ball.mass_kg)]


def reference_truth(fusion, truth):
    """The true e of the impact the combined e is given at (the combined model's reference impact)."""
    note = next(note for note in fusion.notes if note.startswith("combined e"))
    return float(truth.impacts["e"].iloc[int(note.rsplit("impact ", 1)[1]) - 1])


@pytest.fixture(scope="module")
def clip(tmp_path_factory):
    return clip_with_sound(tmp_path_factory.mktemp("fusion"))


def test_run_measures_sound_and_picture_by_default(clip, tmp_path):
    """``dropfit run`` on a video with sound, no option: the headline says the e is the sound's and the
    picture's combined, fit.json and analysis.json hold both and the offset (37.9 ms: the 37 ms given plus the
    sound's 0.9 ms to the microphone) within its standard error's 3, the paired impacts' e of each sensor
    are within 3 se of refsim's, the combined e's 95 % interval holds the truth, and the report has the
    section."""
    path, truth, ball = clip
    out = tmp_path / "out"
    result = dropfit("run", path, "--out", out, *ball_options(ball), cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert "sound and picture combined" in result.stdout
    assert "DISAGREE" not in result.stdout
    fit = json.loads((out / "fit.json").read_text(encoding="utf-8"))
    analysis = json.loads((out / "analysis.json").read_text(encoding="utf-8"))
    assert analysis["sound_and_picture"] == fit["sound_and_picture"]
    fusion = fusion_of(fit)
    assert fusion.source == "sound and picture" and fusion.agree
    true_offset = 0.037 + TRAVEL_S
    assert abs(fusion.offset_s - true_offset) < 3 * fusion.offset_se_s < 3e-3
    paired = [pair for pair in fusion.pairs if np.isfinite(pair.e_sound) and np.isfinite(pair.e_picture)]
    assert len(paired) >= 2  # impacts measured by both (the picture leaves out one whose flight it sees too briefly)
    for pair in paired:
        true_e = float(truth.impacts["e"].iloc[pair.impact_picture - 1])
        assert abs(pair.e_sound - true_e) < 3 * pair.e_sound_se
        assert abs(pair.e_picture - true_e) < 3 * pair.e_picture_se
        assert pair.e_combined_se < min(pair.e_sound_se, pair.e_picture_se)
    low, high = fusion.e.ci95
    assert low < reference_truth(fusion, truth) < high
    assert fusion.e_picture is not None and fusion.e_sound is not None
    report = (out / "report.html").read_text(encoding="utf-8")
    assert "Sound and picture" in report and "offset sound − picture" in report
    assert (out / "track.csv").exists() and (out / "contact_sheet.png").exists()


def test_batch_rows_carry_the_sensors(clip, tmp_path):
    """``dropfit batch`` (the workflow's video rows) does the same: its line and the summary row say where
    the e comes from."""
    path, _, ball = clip
    sheet = tmp_path / "samples.tsv"
    sheet.write_text("sample_id\tkind\tpath\tball_type\tball_radius_m\tball_mass_kg\n"
                     f"v1\tvideo\t{path}\t{ball.type}\t{ball.radius_m}\t{ball.mass_kg}\n", encoding="utf-8")
    result = dropfit("batch", "--samples", sheet, "--results", tmp_path / "results", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert "sound and picture combined" in result.stdout
    fit = json.loads((tmp_path / "results" / "v1" / "fit.json").read_text(encoding="utf-8"))
    assert fit["sound_and_picture"]["source"] == "sound and picture"
    from dropfit.report import batch_rows

    row = batch_rows([fit]).iloc[0]
    assert row["e_from"] == "sound and picture"
    assert row["e"] == pytest.approx(fit["sound_and_picture"]["e"]["value"])


def tiny_ball_clip(directory, seed=2, **track):
    """A ball too small to be seen at 0.25 scale, with its sound track; (path, truth, ball)."""
    return clip_with_sound(directory, seed=seed, offset_s=0.02, downscale=0.25, name="tiny.mp4", tiny=True, **track)


def test_a_refused_picture_and_a_missed_click_is_not_passed_unflagged(tmp_path):
    """No picture, and the click of impact 2 not heard: the sound alone reads two flights as one (e far off
    at one impact). That flight outlasts the one before: its impacts are detection errors, left out of every
    fit with the reason, and the e of the impacts kept are the generator's, each within 3 se."""
    path, truth, ball = tiny_ball_clip(tmp_path, seed=4, missed_impacts=(2,))
    result = process_recording(path, ball, Settings())
    assert result.fusion.source == "sound" and result.fusion.picture_refusal
    impacts = result.impacts
    flagged = impacts[impacts["detection_error"].astype(bool)]
    assert len(flagged) >= 1 and not flagged["in_fit"].astype(bool).any()
    assert flagged["note"].str.startswith("detection error").all()
    kept = impacts[impacts["in_fit"].astype(bool)]
    assert len(kept) >= 2 and f"{len(kept)} of {len(impacts)} impacts" in result.summary()
    true_touchdown_s = truth.impacts["t_touchdown_s"].to_numpy(float) + 0.02 + TRAVEL_S
    for _, row in kept.iterrows():
        nearest = int(np.argmin(np.abs(true_touchdown_s - row["t_touchdown_s"])))
        assert abs(true_touchdown_s[nearest] - row["t_touchdown_s"]) < 0.005
        assert abs(row["e"] - float(truth.impacts["e"].iloc[nearest])) < 3 * row["e_se"]


def test_a_refused_picture_gives_the_sound_e(tmp_path):
    """A ball too small to be seen (1.5 mm across at this scale: no ball found in the picture): the sound's e
    is the result, the headline and the report say so and keep the picture's reason, the tracked table and
    contact sheet are still written; the sound's e of each impact is within 3 se of the truth."""
    path, truth, ball = tiny_ball_clip(tmp_path)
    out = tmp_path / "out"
    result = dropfit("run", path, "--out", out, *ball_options(ball), cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert "from the sound (the picture is refused)" in result.stdout and "CHECK" not in result.stdout
    fit = json.loads((out / "fit.json").read_text(encoding="utf-8"))
    fusion = fusion_of(fit)
    assert fusion.source == "sound" and fusion.picture_refusal and fusion.e_picture is None
    assert "picture refused" in (out / "report.html").read_text(encoding="utf-8")
    assert (out / "track.csv").exists() and (out / "contact_sheet.png").exists()
    assert_sound_e_right(process_recording(path, ball, Settings()).impacts, truth)


def test_a_silent_sound_track_gives_the_picture_e(tmp_path):
    """The room only, no click: the picture's e, and the note that the sound gives none and why."""
    path, _, ball = clip_with_sound(tmp_path, seed=1, silent=True)
    result = process_recording(path, ball, Settings())
    fusion = result.fusion
    assert fusion.source == "picture" and fusion.e_sound is None
    assert "impacts heard" in fusion.sound_refusal
    assert fusion.e.value == pytest.approx(result.fit["restitution"]["e"]["value"])
    assert "from the picture" in result.summary()
    assert any("the sound gives no e" in note for note in result.notes)


def test_a_bug_in_the_sound_costs_not_the_picture(clip, monkeypatch):
    """A bug met analysing the sound track (here forced) leaves the picture's e as the result, the bug named
    in the record, not a traceback for a video whose picture measures."""
    import dropfit.pipeline

    path, _, ball = clip

    def broken(*args, **kwargs):
        raise ZeroDivisionError("forced")

    monkeypatch.setattr(dropfit.pipeline, "_sound_result", broken)
    result = process_recording(path, ball, Settings())
    assert result.fusion.source == "picture"
    assert "internal error in dropfit while analysing its sound track (ZeroDivisionError: forced)" in \
        result.fusion.sound_refusal


def test_a_wrong_tracking_is_flagged_in_the_headline(clip):
    """The picture's heights in the flight after impact 2 squeezed towards the floor by a fifth (a tracking
    that follows something else there, as the circle 60 px beside a tennis ball): its e2 reads low and e3
    high, the sound's do not; the headline says DISAGREE and the combined interval is not the tight one."""
    path, _, ball = clip
    tracked = track_recording(path, Settings(), ball)
    table = tracked.table.copy()
    clean = process_recording(path, ball, Settings(), tracked=tracked)
    impacts = clean.impacts
    start, end = (float(impacts["t_touchdown_s"].iloc[k]) for k in (1, 2))
    floor_row = float(np.nanmax(table["y_px"]))
    flight = (table["time_s"] > start + 0.02) & (table["time_s"] < end - 0.02)
    table.loc[flight, "y_px"] = floor_row - 0.8 * (floor_row - table.loc[flight, "y_px"])
    wrong = process_recording(path, ball, Settings(), tracked=tracked._replace(table=table))
    assert clean.fusion.agree
    fusion = wrong.fusion
    assert fusion.agree is False and fusion.flag
    assert "DISAGREE" in wrong.summary()
    assert fusion.e.se > 2 * clean.fusion.e.se or fusion.source == "sound"


def test_a_missed_click_is_left_out_by_the_sound_and_the_e_combined_from_the_rest(tmp_path):
    """The click of impact 2 not heard (too faint): the sound reads flights 1 and 2 as one and its e there is far
    off (0.35 for 0.79). The sound's own sequence test flags it a detection error, left out of every fit: paired
    with impact 3 seen, it is compared (far apart) but never combined, and the e combined from the impacts both
    measured is refsim's within 3 se. (Before the picture measured its sparsely filmed impacts 4 and 5 no impact had
    an e from both, and the headline e, of different impacts, were compared: DISAGREE.)"""
    path, truth, ball = clip_with_sound(tmp_path, seed=4, missed_impacts=(2,))
    result = process_recording(path, ball, Settings())
    fusion = result.fusion
    missed = next(pair for pair in fusion.pairs if pair.impact_picture == 3)
    assert abs(missed.difference_se) > 10 and not np.isfinite(missed.e_combined)
    combined = [pair for pair in fusion.pairs if np.isfinite(pair.e_combined)]
    assert len(combined) >= 2
    for pair in combined:
        assert abs(pair.e_combined - truth.impacts["e"].iloc[pair.impact_picture - 1]) < 3 * pair.e_combined_se
    assert fusion.source == "sound and picture" and fusion.agree
    low, high = fusion.e.ci95
    assert low < reference_truth(fusion, truth) < high


SLOW_MOTION = dict(capture_fps=Fraction(120), slow_motion=4)


def test_a_slow_motion_clip_s_sound_is_put_on_the_capture_clock(tmp_path):
    """120 fps stored at 30 fps, its sound slowed with it (as phones store slow motion; the clicks 4 times
    later on the file's clock and 4 times lower): the capture rate told by gravity puts the sound on the
    capture clock, so the impacts pair (none did on the file's clock: 0.3 s apart at most), the offset is the
    truth's within 3 se, and the sound's e of each paired impact is refsim's within 3 se."""
    path, truth, ball = clip_with_sound(tmp_path, offset_s=0.01, name="slow.mp4", duration_s=2.2, timing=SLOW_MOTION)
    fusion = process_recording(path, ball, Settings()).fusion
    assert fusion.source == "sound and picture" and fusion.agree
    assert abs(fusion.offset_s - 0.01 - TRAVEL_S) < 3 * fusion.offset_se_s
    paired = [pair for pair in fusion.pairs if np.isfinite(pair.e_sound)]
    assert len(paired) >= 3
    for pair in paired:
        assert abs(pair.e_sound - truth.impacts["e"].iloc[pair.impact_picture - 1]) < 3 * pair.e_sound_se


def test_a_slow_motion_clip_refused_by_its_picture_takes_the_capture_rate_given(tmp_path):
    """The picture refused (a ball too small to see) in a slow-motion clip: with --capture-fps the sound is
    still put on the capture clock, and its e (which needs the flight times in s: the contact time and the
    drag are subtracted from them) are refsim's within 3 se."""
    path, truth, ball = clip_with_sound(tmp_path, seed=5, offset_s=0.01, downscale=0.25, name="slow_tiny.mp4",
                                        duration_s=2.2, tiny=True, timing=SLOW_MOTION)
    result = process_recording(path, ball, Settings(capture_fps=120.0))
    assert result.fusion.source == "sound"
    assert_sound_e_right(result.impacts, truth, slow_motion=4)


@pytest.mark.slow
def test_fused_e_covers_the_truth_at_its_rate(tmp_path):
    """Eight seeds (drop 0.4–0.6 m, offsets −60…60 ms): the combined e's 95 % interval holds refsim's e at
    its reference impact in at least 7 of 8 (the binomial's 94 % for a 95 % rate), and the offset is within
    2 of its standard errors of the truth in at least 7."""
    covered = offsets = 0
    seeds = range(8)
    for seed in seeds:
        rng = np.random.default_rng(seed)
        offset = float(rng.uniform(-0.06, 0.06))
        path, truth, ball = clip_with_sound(tmp_path, seed=seed, offset_s=offset, name=f"seed{seed}.mp4",
                                            drop_height_m=float(rng.uniform(0.4, 0.6)))
        fusion = process_recording(path, ball, Settings()).fusion
        assert fusion.source == "sound and picture"
        low, high = fusion.e.ci95
        covered += low < reference_truth(fusion, truth) < high
        offsets += abs(fusion.offset_s - offset - TRAVEL_S) < 2 * fusion.offset_se_s
    assert covered >= 7 and offsets >= 7


def test_clicks_offset_found_where_the_chain_of_bounces_took_other_clicks():
    """The impacts seen pair with the clicks heard (every click found), not with a chain of bounces that
    took a rattle for bounces: the offset is that of the clicks (closed form: seen − 0.109 s)."""
    from dropfit.audio.compare import clicks_offset, pair_impacts

    seen = np.array([0.554, 0.895, 1.186, 1.439])
    offset = -0.109
    true_clicks = np.array([0.045, 0.445, 0.786, 1.330])  # 1.077 s missed; the first impact is not seen
    rattle = 1.359 + 0.008 * np.arange(8)
    clicks = np.sort(np.concatenate([true_clicks, rattle, [1.743, 1.995, 2.168, 2.255, 2.293]]))
    chain = np.array([0.045, 0.786, 1.359, 1.743, 1.995, 2.168, 2.255, 2.293])  # the chain chosen
    assert pair_impacts(seen, chain)[0].size == 1
    paired, between = clicks_offset(seen, clicks)
    assert paired == 3
    assert between == pytest.approx(offset, abs=2e-3)
