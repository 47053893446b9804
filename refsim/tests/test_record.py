"""The recorder: units, noise, jitter, jumps, lost and dropped samples, CSV."""

import numpy as np
import pandas as pd
import pytest

from refsim import simulate
from refsim.record import Jumps, record, write_csv


@pytest.fixture(scope="module")
def truth():
    return simulate("tennis", 1.0, g_m_s2=9.81, t_end_s=12.0)


def test_units_and_points(truth):
    t0, dur = -0.2, 3.0
    m = record(truth, 100, t_start_s=t0, duration_s=dur, unit="m", rng=0)
    assert list(m.columns) == ["time_s", "y_m"] and len(m) == 301
    assert np.allclose(m["time_s"], t0 + np.arange(301) / 100)
    assert m["y_m"].iloc[0] == pytest.approx(1.0 + 0.0335)
    mm = record(truth, 100, t_start_s=t0, duration_s=dur, unit="mm", point="bottom", rng=0)
    assert mm["y_mm"].iloc[0] == pytest.approx(1000.0)
    cm = record(truth, 100, t_start_s=t0, duration_s=dur, unit="cm", point="top", floor_offset_m=0.01, rng=0)
    assert cm["y_cm"].iloc[0] == pytest.approx(100 * (1.0 + 2 * 0.0335 + 0.01))
    px = record(truth, 100, t_start_s=t0, duration_s=dur, unit="px", px_per_m=500, floor_row_px=1000,
                point="bottom", rng=0)
    assert px["y_px"].iloc[0] == pytest.approx(500.0)
    assert px["y_px"].max() == pytest.approx(1000.0)  # the bottom touches the floor row, never below
    with pytest.raises(ValueError):
        record(truth, 100, unit="px")


def test_noise_statistics_and_lag1(truth):
    t_rest = truth.t_settled_s
    log = record(truth, 1000, t_start_s=t_rest, duration_s=5.0, unit="mm", noise_sd=0.5, noise_lag1=0.6, rng=3)
    e = log["y_mm"].to_numpy() - 1000 * truth.y_rest_centre_m
    assert e.std() == pytest.approx(0.5, rel=0.05)
    assert np.corrcoef(e[:-1], e[1:])[0, 1] == pytest.approx(0.6, abs=0.03)


def test_resolution_and_determinism(truth):
    a = record(truth, 200, unit="mm", noise_sd=0.3, resolution=1.0, rng=7)
    b = record(truth, 200, unit="mm", noise_sd=0.3, resolution=1.0, rng=7)
    pd.testing.assert_frame_equal(a, b)
    assert np.all(a["y_mm"] == np.round(a["y_mm"]))


def test_jitter_epoch_and_dropped(truth):
    log, info = record(truth, 2000, t_start_s=0.0, duration_s=1.0, jitter_frac=0.1, time_offset_s=1.7e9,
                       drop_frac=0.01, rng=1, return_info=True)
    t = log["time_s"].to_numpy()
    assert np.all(np.diff(t) > 0)
    assert len(log) == 2001 - 20
    dt = np.diff(info.t_true_s) - 1 / 2000
    assert dt.std() == pytest.approx(np.sqrt(2) * 0.1 / 2000, rel=0.1)
    assert t[0] == pytest.approx(1.7e9, abs=1e-3)
    nominal = record(truth, 2000, t_start_s=0.0, duration_s=1.0, jitter_frac=0.1, timestamps="nominal", rng=1)
    assert np.allclose(np.diff(nominal["time_s"]), 1 / 2000)


def test_jumps_and_lost(truth, tmp_path):
    log, info = record(truth, 200, unit="px", px_per_m=2000, floor_row_px=1100, noise_sd=0.2,
                       jumps=Jumps(n=4, length=(1, 6)), lost_frac=0.02, lost_run=(1, 3), rng=5, return_info=True)
    y = log["y_px"].to_numpy()
    dev = np.abs(y - info.y_true)
    jumped = info.is_jump & ~info.is_lost
    assert 4 <= info.is_jump.sum() <= 24
    assert np.all(dev[jumped] > 45) and np.all(dev[jumped] < 205)
    assert np.nanmax(dev[~info.is_jump]) < 2.0
    # runs: 4 separate runs of 1-6 samples
    edges = np.flatnonzero(np.diff(info.is_jump.astype(int)) == 1)
    assert len(edges) == 4
    assert np.isnan(y[info.is_lost]).all() and info.is_lost.sum() >= 0.02 * len(y)
    path = tmp_path / "log.csv"
    write_csv(log, path, comments=["refsim test"])
    text = path.read_text().splitlines()
    assert text[0] == "# refsim test" and text[1] == "time_s,y_px"
    assert any(line.endswith(",") for line in text[2:])  # empty cells
    back = pd.read_csv(path, comment="#")
    assert back["y_px"].isna().sum() == info.is_lost.sum()
    assert np.allclose(back["time_s"], log["time_s"], rtol=0, atol=1e-12)


def test_metric_jumps_use_scale(truth):
    log, info = record(truth, 100, unit="m", px_per_m=1000, jumps=Jumps(n=3), rng=2, return_info=True)
    dev = np.abs(log["y_m"].to_numpy() - info.y_true)[info.is_jump]
    assert np.all((dev >= 0.05) & (dev <= 0.2))


def test_recording_continues_after_rest(truth):
    log, info = record(truth, 100, noise_sd=1e-3, rng=0, return_info=True)
    assert info.t_true_s[-1] >= truth.rest_time_s + 0.99
    after = log[log["time_s"] > truth.t_settled_s]
    assert len(after) > 0
    assert np.abs(after["y_m"] - truth.y_rest_centre_m).max() < 6e-3  # only noise


def test_horizontal_column():
    """x logged beside y: the truth's x at the sample instants plus its own noise, in the height's unit (px
    as columns), lost cells in both; the heights are those of the same log without x."""
    moving = simulate("tennis", 1.0, g_m_s2=9.81, u0_m_s=2.0, t_end_s=2.0)
    options = dict(t_start_s=0.0, duration_s=1.5, unit="mm", noise_sd=0.5, lost_frac=0.02, rng=4)
    log, info = record(moving, 100, horizontal=True, return_info=True, **options)
    assert list(log.columns) == ["time_s", "y_mm", "x_mm"]
    assert log["y_mm"].equals(record(moving, 100, **options)["y_mm"])
    error = log["x_mm"].to_numpy() - 1000 * moving.x(info.t_true_s)
    assert np.nanstd(error) == pytest.approx(0.5, rel=0.15)
    assert np.array_equal(np.isnan(log["x_mm"]), np.isnan(log["y_mm"])) and np.isnan(log["x_mm"]).any()
    px = record(moving, 100, t_start_s=0.0, duration_s=1.5, unit="px", px_per_m=500, floor_row_px=900,
                horizontal=True)
    assert np.allclose(px["x_px"], 500 * moving.x(px["time_s"].to_numpy()))
