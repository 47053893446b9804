"""Repeated frames: a recorder repeats a frame in place of a capture it missed (the frames after it keep their
time stamps) or inserts it between two successive captures (every frame after it is stamped one interval late, as
in tennis_ball_table_aruco.mp4). The truth is a closed-form free flight sampled at the capture instants."""

import numpy as np
import pandas as pd

from dropfit.video.quality import QUALITY_DUPLICATE, QUALITY_OK, retime_inserted_repeats

FPS = 30.0
G_PX = 1.4 * FPS**2  # px/s²: 1.4 px a frame² as the tennis ball's 120 fps capture stored at 30 fps


def _table(inserted, repeat_at=8, frames=24, seed=1):
    """A rising flight (image rows point down) of ``frames`` file frames with frame ``repeat_at`` a repeat of the
    one before; the capture instant of each file frame from the closed form."""
    rng = np.random.default_rng(seed)
    captures = np.arange(frames, dtype=float)
    if inserted:  # the frames after the repeat show the captures one interval earlier than their stamps
        captures[repeat_at:] -= 1
    else:  # the repeat stands for a capture that was missed: the others keep theirs
        captures[repeat_at] -= 1
    t = captures / FPS
    y = 900.0 - 700.0 * t + 0.5 * G_PX * t**2 + rng.normal(0, 0.3, frames)
    quality = [QUALITY_OK] * frames
    quality[repeat_at] = QUALITY_DUPLICATE
    y[repeat_at] = np.nan
    return pd.DataFrame({"frame": np.arange(frames), "time_s": np.arange(frames) / FPS, "x_px": 500.0, "y_px": y,
                         "quality": quality}), t


def test_frames_after_an_inserted_repeat_get_their_capture_instants():
    table, truth = _table(inserted=True)
    kept = retime_inserted_repeats(table)
    assert kept.attrs["inserted_repeats"] == [8]
    assert len(kept) == len(table) - 1
    assert np.allclose(kept["time_s"].to_numpy(), np.delete(truth, 8))


def test_a_repeat_in_place_of_a_missed_capture_keeps_the_time_stamps():
    table, truth = _table(inserted=False)
    kept = retime_inserted_repeats(table)
    assert "inserted_repeats" not in kept.attrs
    assert np.allclose(kept["time_s"].to_numpy(), np.delete(truth, 8))


def test_a_repeat_of_a_ball_at_rest_tells_nothing():
    table, _ = _table(inserted=True)
    table["y_px"] = np.where(table["quality"] == QUALITY_OK, 700.0, np.nan)
    kept = retime_inserted_repeats(table)
    assert "inserted_repeats" not in kept.attrs
    assert np.allclose(kept["time_s"].to_numpy(), np.delete(table["time_s"].to_numpy(), 8))
