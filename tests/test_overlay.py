"""What was tracked, drawn on the video: the contact sheet, the annotated clip and the drawing itself,
on small synthetic clips rendered by dropfit.video_synth."""

import av
import numpy as np
import pytest

from dropfit import Ball, stages
from dropfit.cli import main
from dropfit.errors import InputError
from dropfit.fitrecord import analysis_summary
from dropfit.pipeline import analyse_trajectory, measure_recording, track_recording
from dropfit.synth import simulate_drop
from dropfit.video.opencv import cv2
from dropfit.video.overlay import (CURVE_COLOUR_BGR, LABEL_HEIGHT_PX, QUALITY_COLOURS_BGR, SHEET_COLUMNS, SHEET_TILES,
                                   TILE_BOX_PX, OverlayScene, annotate_frame, contact_sheet, decoded_frames,
                                   overlay_scene)
from dropfit.video.track import QUALITY_OK, usable_rows
import phonesim
from phonesim.camera import PlaneView

from helpers import CLIP_BALL_RADIUS_M, assert_one_line_error, dropfit, render_drop_clip, stage_args

#: The drawn circle's centre must lie this close to the renderer's true centre, px.
CENTRE_TOLERANCE_PX = 1.0
#: The fitted flights, mapped back to rows, must pass this close to the tracked centres, px.
CURVE_TOLERANCE_PX = 0.5
#: A refused clip's clean frames run at most this far (frame intervals) into a flight's ends, where it meets a contact.
CONTACT_GUARD_FRAMES = 1


@pytest.fixture(scope="module")
def drop():
    """A 0.8 m drop of the clip's 5 px ball (e = 0.75), released at 0.1 s."""
    return simulate_drop(0.8, CLIP_BALL_RADIUS_M, {"kind": "constant", "e0": 0.75}, mass_kg=0.057,
                         release_time_s=0.1)


@pytest.fixture(scope="module")
def analysed_clip(drop, tmp_path_factory):
    """A 120 frames/s clip, its renderer's truth, and the overlay's scene of its tracking and analysis."""
    truth = render_drop_clip(tmp_path_factory.mktemp("clip") / "clip.avi", drop, fps=120.0)
    video = truth.attrs["video_path"]
    ball = Ball(radius_m=CLIP_BALL_RADIUS_M)
    tracked = track_recording(video)
    table = tracked.table
    trajectory = measure_recording(video, ball, tracked=tracked)
    analysis = analyse_trajectory(trajectory)
    scene = overlay_scene(table, trajectory, analysis.flights, analysis.impacts,
                          analysis_summary(analysis, trajectory.attrs))
    return video, truth, scene


def test_the_contact_sheet_shows_tiles_of_the_release_and_every_impact(analysed_clip):
    video, _, scene = analysed_clip
    image, rows = contact_sheet(video, scene)
    assert len(rows) == SHEET_TILES and rows == sorted(set(rows))
    tile_width, tile_height = TILE_BOX_PX[0], TILE_BOX_PX[1] + LABEL_HEIGHT_PX
    assert image.shape[1] == SHEET_COLUMNS * tile_width
    header = image.shape[0] - SHEET_TILES // SHEET_COLUMNS * tile_height
    assert 0 < header < 100  # a legend and two caption lines
    times = scene.frame_time_s
    first_impact = scene.impacts.iloc[0]
    assert int(np.searchsorted(times, first_impact["t_touchdown_s"])) - 1 in rows  # the last frame before it
    assert int(np.searchsorted(times, first_impact["t_liftoff_s"])) in rows  # the first after it
    assert {0, len(scene.table) - 1} <= set(rows)


def test_the_drawn_circle_lies_on_the_ball_in_its_flags_colour(analysed_clip):
    video, truth, scene = analysed_clip
    row = int(np.flatnonzero(scene.table["quality"] == QUALITY_OK)[40])
    (_, frame), = decoded_frames(video, [row])
    annotated = annotate_frame(frame, scene, row)
    drawn = np.all(annotated == QUALITY_COLOURS_BGR[QUALITY_OK], axis=2) & np.any(annotated != frame, axis=2)
    ys, xs = np.nonzero(drawn)
    assert xs.size > 10
    assert np.hypot(xs.mean() - truth["x_px"][row], ys.mean() - truth["y_px"][row]) < CENTRE_TOLERANCE_PX
    radii = np.hypot(xs - scene.table["x_px"][row], ys - scene.table["y_px"][row])
    assert np.median(radii) == pytest.approx(scene.table["radius_px"][row], abs=1.0)


def test_the_fitted_curve_passes_through_the_tracked_centres(analysed_clip):
    video, _, scene = analysed_clip
    table, times = scene.table, scene.frame_time_s
    in_flight = np.zeros(len(table), bool)
    interval = float(np.median(np.diff(times)))
    for flight in scene.flights.itertuples(index=False):
        in_flight |= (times > flight.t_start_s + interval) & (times < flight.t_end_s - interval)
    tracked = usable_rows(table) & in_flight
    assert np.count_nonzero(tracked) > 100
    misses = scene.fitted_row_px(times[tracked]) - table["y_px"].to_numpy()[tracked]
    assert np.max(np.abs(misses)) < CURVE_TOLERANCE_PX
    # and it is drawn there: the curve's colour on the tracked column, at the row of the fitted centre
    row = int(np.flatnonzero(tracked)[10])
    (_, frame), = decoded_frames(video, [row])
    annotated = annotate_frame(frame, scene, row)
    column = round(table["x_px"][row])
    curve_rows = np.flatnonzero(np.all(annotated[:, column - 1: column + 2] == CURVE_COLOUR_BGR, axis=2).any(axis=1))
    assert curve_rows.min() < table["y_px"][row] < curve_rows.max()


def test_the_command_writes_the_sheet_and_an_h264_clip_of_every_frame(analysed_clip, tmp_path):
    video, truth, _ = analysed_clip
    sheet, clip = tmp_path / "sheet.png", tmp_path / "annotated.mp4"
    assert main(["overlay", video, "--out", str(sheet), "--clip", str(clip), "--ball-radius-m",
                 str(CLIP_BALL_RADIUS_M)]) == 0
    image = cv2.imread(str(sheet))
    assert image.shape[1] == SHEET_COLUMNS * TILE_BOX_PX[0]
    with av.open(str(clip)) as container:
        stream = container.streams.video[0]
        assert stream.codec_context.name == "h264"
        assert sum(1 for _ in container.decode(video=0)) == len(truth)
    assert len(list(decoded_frames(clip, [0, 5]))) == 2  # an H.264 file reads back too


def test_a_refused_clip_gets_a_sheet_with_its_reason(drop, tmp_path):
    """10 frames/s: the fall is too briefly filmed. Through the workflow's stages: measure keeps the
    tracked table, analyse records the refusal, the overlay reads both."""
    video = render_drop_clip(tmp_path / "slow.avi", drop, fps=10.0).attrs["video_path"]
    out = tmp_path / "results"
    assert main(["measure", video, "--out", str(out / "trajectory.nc"), "--track", str(out / "track.csv"),
                 "--ball-radius-m", str(CLIP_BALL_RADIUS_M)]) == 0
    assert main(["analyse", str(out / "trajectory.nc"), "--impacts", str(out / "impacts.csv"), "--flights",
                 str(out / "flights.csv"), "--summary", str(out / "analysis.json"), "--record-failure"]) == 0
    scene = stages.scene_from_results(out)
    assert scene.caption[-1].startswith(f"refused: {video}: not analysable: ")
    assert "film at" in scene.caption[-1]  # the frame rate that would do (the caption is shortened in the middle)
    assert scene.flights is None and scene.scale_m_per_px is not None
    sheet = out / "contact_sheet.png"
    assert main(["overlay", video, "--out", str(sheet), "--results", str(out)]) == 0
    image = cv2.imread(str(sheet))
    assert image.shape[1] == SHEET_COLUMNS * TILE_BOX_PX[0]
    # the report's failure page shows the sheet under the reason
    report = [str(arg) for arg in stage_args(out, video)["report"]]
    assert main([*report, "--contact-sheet", str(sheet), "--record-failure"]) == 0
    page = (out / "report.html").read_text(encoding="utf-8")
    assert "not analysable" in page and "contact sheet of the video" in page


def test_a_clip_refused_while_measured_keeps_its_tracked_table(drop, tmp_path, monkeypatch):
    """A refusal in measure (here by the recording-wide limits, stood in for) leaves the tracked table, whole,
    beside the trajectory's failure record."""
    video = render_drop_clip(tmp_path / "clip.avi", drop, fps=120.0).attrs["video_path"]
    reason = f"{video}: not analysable: frames measured cleanly: 20% < 45%"

    def refuse(table, source):
        raise InputError(reason)

    monkeypatch.setattr("dropfit.video.limits.check_recording", refuse)
    assert main(["measure", video, "--out", str(tmp_path / "trajectory.nc"), "--track", str(tmp_path / "track.csv"),
                 "--record-failure"]) == 0
    scene = stages.scene_from_results(tmp_path)
    assert len(scene.table) == 204 and scene.caption[-1] == f"refused: {reason}"
    assert scene.scale_m_per_px is None


def test_an_unreadable_video_gives_one_line(tmp_path):
    bad = tmp_path / "broken.avi"
    bad.write_bytes(b"RIFF\x00\x00\x00\x00AVI " + bytes(range(256)) * 8)
    result = dropfit("overlay", bad, "--out", tmp_path / "sheet.png", cwd=tmp_path)
    assert result.returncode == 1
    assert_one_line_error(result.stderr, "broken.avi")
    assert not (tmp_path / "sheet.png").exists()


def test_heights_in_a_target_plane_go_back_to_a_tilted_cameras_rows():
    """Through a plane target's map, a height comes back to phonesim's tilted camera's row in any column:
    the plane (X right, Y up, m) as the trajectory has it, its scale 5 % above the one chosen."""
    config = phonesim.PRESETS["tennis_aruco_tilted"].scaled(0.5)
    view = PlaneView.build(config.camera, config.width_px, config.height_px, 1.0, config.drop_height_m)
    chosen_m_per_px, plane_m_per_px = 0.002, 0.0021
    scene = OverlayScene(table=None, frame_time_s=np.empty(0), scale_m_per_px=chosen_m_per_px,
                         plane=(np.linalg.inv(view.plane_to_px), np.array([0.0, -1.0]), plane_m_per_px / chosen_m_per_px))
    across_m, up_m = np.meshgrid([-0.1, 0.0, 0.15], np.linspace(0.0, 0.9, 7))
    columns, rows = view.to_px(across_m.ravel(), up_m.ravel())
    heights = up_m.ravel() * chosen_m_per_px / plane_m_per_px  # heights are the plane's rows × the chosen scale
    assert np.abs(scene.image_row_px(heights, columns) - rows).max() < 1e-6


def test_a_video_refused_by_run_leaves_its_tracked_table_and_a_sheet_of_its_frames(drop, tmp_path, capsys):
    """``dropfit run --record-failure`` of a 10 frames/s clip (every flight too briefly filmed: refused): its
    ``track.csv`` is the tracked table, a row per frame, and its contact sheet shows the frames, the ball circled
    in its quality's colour, under the refusal (before: both were failure records, the sheet a strip of text)."""
    import pandas as pd

    video = render_drop_clip(tmp_path / "slow.avi", drop, fps=10.0).attrs["video_path"]
    out = tmp_path / "results"
    assert main(["run", video, "--out", str(out), "--ball-radius-m", str(CLIP_BALL_RADIUS_M), "--record-failure"]) == 0
    message = capsys.readouterr().err.strip().splitlines()[-1][len("dropfit: error: "):]
    assert "not analysable" in message
    table = pd.read_csv(out / "track.csv")
    assert len(table) == len(stages.read_table(out / "track.csv", "tracked table")) > 15
    assert {"frame", "x_px", "y_px", "quality"} <= set(table.columns) and (table["quality"] == QUALITY_OK).sum() >= 5
    sheet = cv2.imread(str(out / "contact_sheet.png"))
    tile_height = TILE_BOX_PX[1] + LABEL_HEIGHT_PX
    assert sheet.shape[1] == SHEET_COLUMNS * TILE_BOX_PX[0] and sheet.shape[0] > SHEET_TILES // SHEET_COLUMNS * tile_height
    tiles = sheet[-SHEET_TILES // SHEET_COLUMNS * tile_height:]
    circled = np.all(np.abs(tiles.astype(int) - QUALITY_COLOURS_BGR[QUALITY_OK]) <= 30, axis=2)
    assert np.count_nonzero(circled) > 100  # the balls' green circles, drawn on the frames
    assert np.count_nonzero(tiles.max(axis=2) > 40) > 0.3 * tiles.shape[0] * tiles.shape[1]  # frames, not a blank
    scene = stages.scene_from_results(out)
    assert scene.caption[-1] == f"refused: {message}"
    page = (out / "report.html").read_text(encoding="utf-8")
    assert "not analysable" in page and "contact sheet of the video" in page
    for name in ("trajectory.nc", "impacts.csv", "fit.json"):
        assert (out / name).exists()
