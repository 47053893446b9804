"""Time from the import: dropped and duplicated frames in tracking tables are handled, not taken for motion.

The truth is the tests' closed-form bouncing ball sampled at the instants the frames were really taken;
each table is written as its tool writes it, with the fault in it.
"""

import numpy as np
import pytest

from dropfit import analyse_recording
from dropfit.errors import InputError
from dropfit.importers import ImportOptions, read_track

from helpers import bouncing_ball

FPS = 30.0  # frames/s of the exports
DROP_M, E_TRUE, CENTRE_M = 1.0, 0.6, 0.02  # m, 1, m
PX_PER_M, FLOOR_ROW_PX = 400.0, 450.0  # px/m, image row of height 0
NOISE_M = 0.0005  # m, the tracked height's scatter (seeded)
#: e from a 30 fps track with that noise (its bounces' flights last 13–16 frames): several of its se.
E_TOL = 0.01  # 1
LATE_FRAME, LATE_BY_S = 20, 0.035 - 1 / FPS  # the frame after a 35 ms step (a 30 fps camera's late frame)


def heights(time_s, seed=0):
    noise = np.random.default_rng(seed).normal(0.0, NOISE_M, np.size(time_s))
    return bouncing_ball(time_s, DROP_M, E_TRUE) + CENTRE_M + noise


def tracker_table(time_s, y_m, x_m):
    """Tracker's text export: the track's name, then t x y with tabs, s and m."""
    return "mass A\nt\tx\ty\n" + "".join(f"{t:.4f}\t{x:.5f}\t{y:.5f}\n" for t, x, y in zip(time_s, x_m, y_m))


def mtrack2_table(frames, rows_px, columns_px):
    lines = ["Tracks 1 to 1", "Frame\tX1\tY1\tFlag1"]
    lines += [f"{f}\t{c:.3f}\t{r:.3f}\t0" for f, c, r in zip(frames, columns_px, rows_px)]
    return "\n".join(lines) + "\n"


def e_of(path, **options):
    return analyse_recording(path, **options).fit["restitution"]["e"]["value"]


def test_a_late_frame_in_a_timed_table_keeps_its_own_time(tmp_path):
    """A 35 ms step in a 30 fps export: the samples keep the times the export gives (the ball was where the
    late frame shows it, 1.7 ms later), and e comes back."""
    time = np.arange(60) / FPS
    time[LATE_FRAME:] += LATE_BY_S
    path = tmp_path / "late.txt"
    path.write_text(tracker_table(time, heights(time), 0.3 * time))
    track = read_track(path)
    np.testing.assert_allclose(track.time_s, np.round(time, 4), atol=1e-9)
    assert e_of(path) == pytest.approx(E_TRUE, abs=E_TOL)


def test_a_dropped_frame_leaves_a_gap_in_a_frame_indexed_table(tmp_path):
    """MTrack2 rows of frames 1–60 with frame 21 dropped: times come from the frame numbers (a gap of two frame
    intervals), not from the row count (which would shift every later sample by a frame and bias e)."""
    frames = np.setdiff1d(np.arange(1, 61), [21])
    time = (frames - 1) / FPS
    path = tmp_path / "Results.txt"
    path.write_text(mtrack2_table(frames, FLOOR_ROW_PX - PX_PER_M * heights(time), 50 + 10 * time))
    track = read_track(path, ImportOptions(fps=FPS))
    np.testing.assert_allclose(track.time_s, time, atol=1e-12)
    assert np.diff(track.time_s).max() == pytest.approx(2 / FPS)
    assert e_of(path, fps=FPS) == pytest.approx(E_TRUE, abs=E_TOL)


def test_the_same_frame_or_time_twice_is_dropped(tmp_path):
    """A row exported twice (the same frame number, or the same time) is read once, with a note."""
    frames = np.arange(1, 61)
    time = (frames - 1) / FPS
    rows, columns = FLOOR_ROW_PX - PX_PER_M * heights(time), 50 + 10 * time
    twice = np.insert(np.arange(60), 31, 30)
    mtrack2 = tmp_path / "twice.txt"
    mtrack2.write_text(mtrack2_table(frames[twice], rows[twice], columns[twice]))
    track = read_track(mtrack2, ImportOptions(fps=FPS))
    np.testing.assert_allclose(track.time_s, time, atol=1e-12)
    assert "1 row of a frame already seen" in track.notes[0]
    tracker = tmp_path / "twice_tracker.txt"
    tracker.write_text(tracker_table(time[twice], heights(time)[twice], 0.3 * time[twice]))
    track = read_track(tracker)
    np.testing.assert_allclose(track.time_s, np.round(time, 4), atol=1e-9)
    assert "1 sample repeating the one before (a row exported twice) dropped" in track.notes[0]
    assert e_of(tracker) == pytest.approx(E_TRUE, abs=E_TOL)


@pytest.mark.parametrize("kind", ["mtrack2", "tracker"])
def test_a_duplicated_video_frame_is_a_dropout_not_a_pause(kind, tmp_path):
    """The video showed frame 25 twice: the table repeats its position at the next frame's time. That sample is
    made a dropout (its time is not when the ball was there); a ball at rest (many equal positions) is kept."""
    frames = np.arange(1, 61)
    time = (frames - 1) / FPS
    y_m, x_m = heights(time), 0.1 + 0.25 * time
    y_m[25], x_m[25] = y_m[24], x_m[24]  # frame 26 shows frame 25 again
    path = tmp_path / f"{kind}.txt"
    if kind == "mtrack2":
        path.write_text(mtrack2_table(frames, FLOOR_ROW_PX - PX_PER_M * y_m, PX_PER_M * x_m))
        options = {"fps": FPS}
    else:
        path.write_text(tracker_table(time, y_m, x_m))
        options = {}
    track = read_track(path, ImportOptions(**options))
    assert np.isnan(track.y[25]) and np.isfinite(track.y[24]) and np.isfinite(track.y[26])
    assert "1 repeated position (a duplicated video frame) set as dropout" in track.notes
    assert e_of(path, **options) == pytest.approx(E_TRUE, abs=E_TOL)


def height_table(header, time_s, y_m):
    """A table of time and height alone (no x): ``header``, then one row per sample, s and m."""
    return header + "\n" + "".join(f"{t:.4f},{y:.5f}\n" for t, y in zip(time_s, y_m))


@pytest.mark.parametrize("header", ["Time (s),Height (m)", "time_s,y_m"])
def test_a_duplicated_video_frame_is_a_dropout_with_the_height_alone(header, tmp_path):
    """Frames 11 and 26 show the frame before again in a table of heights alone, while the ball falls: the repeat breaks the smooth motion, so it becomes a dropout as with x and y (it was kept, and its
    wrong time biased e)."""
    time = np.arange(90) / FPS
    y_m = heights(time)
    y_m[10], y_m[25] = y_m[9], y_m[24]
    path = tmp_path / "heights.csv"
    path.write_text(height_table(header, time, y_m))
    track = read_track(path)
    assert np.isnan(track.y[[10, 25]]).all() and np.isfinite(np.delete(track.y, [10, 25])).all()
    assert "2 repeated positions (a duplicated video frame) set as dropouts" in track.notes
    assert e_of(path) == pytest.approx(E_TRUE, abs=E_TOL)


@pytest.mark.parametrize("resolution_mm, noise_mm", [(1.0, 0.0), (0.1, 0.5)])
def test_a_quantised_sensor_may_repeat_a_height_where_the_ball_turns_or_rests(resolution_mm, noise_mm, tmp_path):
    """A 50 Hz sensor rounding to 1 mm repeats a height near each apex and on the floor (the ball turning); one
    rounding to 0.1 mm with 0.5 mm noise repeats one at random while the ball rests (its neighbours moving
    by noise); a ball held still repeats it for many samples: none is a duplicated frame, all are kept."""
    time = np.arange(200) / 50.0
    noise = np.random.default_rng(3).normal(0.0, noise_mm, time.size)
    y_mm = np.round((1000 * (bouncing_ball(time, DROP_M, E_TRUE) + CENTRE_M) + noise) / resolution_mm)
    y_mm = y_mm * resolution_mm
    y_mm[:5] = y_mm[0]  # held still before the release
    path = tmp_path / "sensor.csv"
    path.write_text("Time (s),Height (mm)\n" + "".join(f"{t:.3f},{y:.1f}\n" for t, y in zip(time, y_mm)))
    assert np.count_nonzero(np.diff(y_mm)[5:] == 0) >= 3  # the repeats the rule has to keep
    track = read_track(path)
    assert np.isfinite(track.y).all() and not track.notes


def test_heights_to_the_mm_in_m_repeat_without_a_duplicated_frame(tmp_path):
    """At 1000 Hz, heights written in m to 3 decimals repeat each value a few samples where the ball is slow; a
    one-step move reads 1.0000000000000009 mm against a smallest gap of 0.9999999999998899 mm in binary, and
    285 repeats were made dropouts (a review's file: held, then at rest, the noise estimate 0). A move must span two
    steps: none is."""
    time = np.arange(5000) / 1000.0
    height = np.where(time < 1.5, DROP_M, bouncing_ball(time - 1.5, DROP_M, 0.8))  # held, then at rest: no noise
    path = tmp_path / "fine.csv"
    path.write_text("Time (s),Height (m)\n" + "".join(f"{t:.3f},{y:.3f}\n" for t, y in zip(time, height)))
    assert not read_track(path).notes


def test_a_row_exported_twice_reads_alike_in_both_layouts(tmp_path):
    """dropfit's own log (time_s,y_m) and a named table drop a row repeated exactly, with a note (the own log
    refused it); the same time with another height is refused in both, one line naming the time."""
    time = np.arange(60) / FPS
    y_m = heights(time)
    twice = np.insert(np.arange(60), 31, 30)
    for header in ("time_s,y_m", "Time (s),Height (m)"):
        path = tmp_path / "twice.csv"
        path.write_text(height_table(header, time[twice], y_m[twice]))
        track = read_track(path)
        np.testing.assert_allclose(track.time_s, np.round(time, 4), atol=1e-9)
        assert "1 sample repeating the one before (a row exported twice) dropped" in track.notes
        assert e_of(path) == pytest.approx(E_TRUE, abs=E_TOL)
        changed = y_m[twice]
        changed[31] += 0.01
        path.write_text(height_table(header, time[twice], changed))
        with pytest.raises(InputError, match=r"twice.csv: time 1 s is given twice with different positions \(.*; remove the wrong row"):
            read_track(path)
