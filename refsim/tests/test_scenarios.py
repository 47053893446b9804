"""The ready-made scenarios: shapes, time bases, reproducibility."""

import numpy as np
import pytest

from refsim import scenarios


@pytest.mark.parametrize("name", sorted(scenarios.SCENARIOS))
def test_scenario(name):
    log, truth = scenarios.SCENARIOS[name](0)
    assert list(log.columns)[0] == "time_s" and log.columns[1].startswith("y_")
    assert len(truth.impacts) >= 3
    assert truth.recording is not None and truth.recording.column == log.columns[1]
    t = log["time_s"].to_numpy()
    assert np.all(np.diff(t) > 0)
    # the truth's time base is the log's: the first touchdown lies inside the log
    assert t[0] < truth.impacts["t_touchdown_s"].iloc[0] < t[-1]
    # noise-free values at the true instants are the truth's, converted
    info = truth.recording
    st = info.settings
    y = truth.y_point(info.t_true_s[::50], st["point"]) - truth.floor_m
    if st["unit"] == "px":
        scale = st["px_per_m"]
        expect = st["floor_row_px"] - y * scale
    else:
        scale = {"m": 1.0, "cm": 100.0, "mm": 1000.0}[st["unit"]]
        expect = (y + st["floor_offset_m"]) * scale
    # an epoch time base (1.7e9 s) resolves only ~2.4e-7 s: ~2e-6 m at 7 m/s
    tol_m = 1e-10 if truth.time_offset_s == 0 else 1e-5
    assert np.allclose(info.y_true[::50], expect, rtol=0, atol=tol_m * scale)
    # the logged values are those plus noise (and jumps, lost cells)
    ok = info.kept & ~info.is_jump & ~info.is_lost
    logged = np.full(info.kept.size, np.nan)
    logged[info.kept] = log[info.column].to_numpy()
    resid = logged[ok] - info.y_true[ok]
    assert np.abs(resid).max() < 6 * st["noise_sd"] + (st["resolution"] or 0)


def test_scenarios_are_seeded():
    a, _ = scenarios.marble_paper_200fps_px(4)
    b, _ = scenarios.marble_paper_200fps_px(4)
    c, _ = scenarios.marble_paper_200fps_px(5)
    assert a.equals(b) and not a.equals(c)


def test_epoch_scenario_time_base():
    log, truth = scenarios.tennis_bottom_2khz(0)
    assert truth.time_offset_s == 1.7e9
    assert log["time_s"].iloc[0] == pytest.approx(1.7e9 - 0.1, abs=1e-3)
    assert log["y_mm"].iloc[-100:].mean() == pytest.approx(2.0, abs=0.05)  # floor reads 2 mm
    assert truth.impacts["h_before_m"].iloc[0] == pytest.approx(2.54, abs=1e-12)


def test_marble_hand_release_moving():
    log, truth = scenarios.marble_paper_200fps_px(0)
    assert truth.v_release_m_s > 0.05
    assert truth.recording.is_jump.sum() >= 4
    assert log["y_px"].isna().any()


def test_seed_example3_oblique():
    """The seed's Example 3 on refsim: a smooth floor keeps u = 3 m/s, e = 0.745 within 1e-4 at every
    impact, the peaks are e^{2n} h0 to 0.2 mm, and x is logged."""
    log, truth = scenarios.seed_example3_oblique(0)
    assert list(log.columns) == ["time_s", "y_m", "x_m"]
    impacts = truth.impacts.iloc[:6]
    assert np.allclose(impacts[["u_in_m_s", "u_out_m_s"]], 3.0, atol=1e-9)
    assert np.allclose(impacts["e"], 0.745, atol=1e-4)
    assert np.allclose(impacts["h_after_m"], 0.9 * 0.745 ** (2 * np.arange(1, 7)), atol=2e-4)
