"""The synthetic drop against closed-form bounce sequences, and its reproducibility."""

import numpy as np
import pytest

from dropfit.physics import total_bouncing_time
from dropfit.errors import InputError
from dropfit.synth import scenario_recordings, simulate_drop, synthesize

from conftest import sensor_log

G = 9.80665


def test_vacuum_bounces_follow_the_geometric_sequence(vacuum_truth):
    e, h0 = 0.775, 2.54
    n = 8
    rebounds = vacuum_truth.impacts["rebound_height_m"].to_numpy()[:n]
    np.testing.assert_allclose(rebounds, h0 * e ** (2 * np.arange(1, n + 1)), rtol=1e-12)
    t0 = np.sqrt(2 * h0 / G)
    # impact n comes at t0 + 2 t0 (e + … + e^(n−1)) after the release
    expected = vacuum_truth.release_time_s + t0 + 2 * t0 * np.cumsum(np.r_[0, e ** np.arange(1, n)])
    np.testing.assert_allclose(vacuum_truth.impacts["t_s"].to_numpy()[:n], expected, rtol=1e-12)
    # the ball rests at t∞ less the bounces lower than REST_RISE_M, which are not followed:
    # the last of those rises h and would have lasted 2√(2h/g)/(1 − e) in all
    t_inf = vacuum_truth.release_time_s + total_bouncing_time(e, t0)
    last_rise = vacuum_truth.impacts["rebound_height_m"].iloc[-1]
    tail = 2 * np.sqrt(2 * last_rise / G) / (1 - e)
    assert vacuum_truth.rest_time_s + tail == pytest.approx(t_inf, abs=1e-9)  # s


def test_height_is_continuous_through_impacts(tennis_truth):
    for t_impact in tennis_truth.impacts["t_s"][:5]:
        around = tennis_truth.height([t_impact - 1e-9, t_impact, t_impact + 1e-9])
        np.testing.assert_allclose(around, tennis_truth.radius_m, atol=1e-7)  # m


def test_falling_e_follows_its_law():
    truth = simulate_drop(1.5, 0.025, {"kind": "linear", "e0": 0.9, "slope_s_m": 0.03})
    impacts = truth.impacts
    np.testing.assert_allclose(impacts["e"], 0.9 - 0.03 * impacts["v_in_m_s"], rtol=1e-12)
    np.testing.assert_allclose(impacts["v_out_m_s"], impacts["e"] * impacts["v_in_m_s"], rtol=1e-12)


def test_sensor_noise_offset_and_dropouts(tennis_truth):
    log = sensor_log(tennis_truth, seed=5, noise_m=0.002, offset_m=0.3, dropout_fraction=0.05)
    error = log["y_m"] - 0.3 - tennis_truth.height(log["time_s"])
    assert error.std() == pytest.approx(0.002, rel=0.1)  # m
    assert error.isna().mean() == pytest.approx(0.05, abs=0.02)


def test_synthesize_is_reproducible_and_seeded():
    scenario = {"drop_height_m": 1.0, "ball": {"radius_m": 0.02, "mass_kg": 0.05},
                "restitution": {"kind": "constant", "e0": 0.8}, "duration_s": 4.0,
                "sensor": {"sample_rate_hz": 200, "noise_m": 0.001, "unit": "mm"}}
    log_a, truth_a = synthesize(scenario, seed=7)
    log_b, truth_b = synthesize(scenario, seed=7)
    log_c, _ = synthesize(scenario, seed=8)
    assert log_a.equals(log_b) and truth_a == truth_b
    assert not log_a.equals(log_c)
    assert list(log_a.columns) == ["time_s", "y_mm"]


def test_drops_expand_to_seeded_recordings_whose_e0_varies():
    """A scenario with ``drops: n`` stands for n recordings, seeded seed … seed + n − 1, each with its own e0."""
    ball = {"drop_height_m": 2.54, "ball": {"radius_m": 0.0335, "mass_kg": 0.057}, "duration_s": 2.0,
            "restitution": {"kind": "constant", "e0": 0.775, "e0_sd_between_drops": 0.002},
            "sensor": {"sample_rate_hz": 100, "noise_m": 0.001}}
    recordings = scenario_recordings({"lot": {**ball, "drops": 3, "seed": 10}, "single": {**ball, "seed": 4}})
    assert {name: seed for name, (_, seed) in recordings.items()} == {"lot_drop1": 10, "lot_drop2": 11,
                                                                       "lot_drop3": 12, "single": 4}
    e_first = [synthesize(scenario, seed)[1]["impacts"][0]["e"] for scenario, seed in recordings.values()]
    assert len(set(e_first)) == 4  # every drop draws its own e0
    # the drawn e0 is the seeded normal draw; a constant law keeps it for every impact of the drop
    assert e_first[0] == pytest.approx(np.random.default_rng(10).normal(0.775, 0.002), abs=1e-15)
    _, truth = synthesize(*recordings["lot_drop2"])
    assert {impact["e"] for impact in truth["impacts"]} == {e_first[1]}


def test_recording_named_twice_is_an_input_error():
    ball = {"drop_height_m": 1.0, "ball": {"radius_m": 0.02, "mass_kg": 0.05},
            "restitution": {"kind": "constant", "e0": 0.8}, "sensor": {"sample_rate_hz": 100}}
    with pytest.raises(InputError, match="lot_drop1"):
        scenario_recordings({"lot": {**ball, "drops": 2}, "lot_drop1": ball})
