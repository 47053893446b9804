"""Closed forms of dropfit.physics against the equation of motion and the seed chapter's numbers."""

import numpy as np
import pytest

from dropfit.physics import (apex_rise, bounce_heights, drag_parameter, flight_height, flight_velocity, restitution,
                             speed_below_apex, time_from_apex, total_bouncing_time)

G = 9.81
K_TENNIS = drag_parameter(0.55, 0.0335, 0.057)  # 1/m


@pytest.mark.parametrize("k", [0.0, K_TENNIS, 0.3])
def test_flight_satisfies_equation_of_motion(k):
    """ÿ = −g − k ẏ|ẏ| on both sides of the apex, checked by finite differences."""
    t = np.linspace(-0.6, 0.6, 2401)
    y = flight_height(t, 0.0, 2.0, k, G)
    step = t[1] - t[0]
    velocity = np.gradient(y, step)
    accel = np.gradient(velocity, step)
    expected = -G - k * velocity * np.abs(velocity)
    inner = slice(5, -5)
    assert np.max(np.abs(accel[inner] - expected[inner])) < 1e-3  # m/s²
    assert np.max(np.abs(velocity[inner] - flight_velocity(t, 0.0, 2.0, k, G)[inner])) < 1e-5  # m/s


@pytest.mark.parametrize("k", [0.0, K_TENNIS])
def test_speed_time_and_rise_agree_with_flight(k):
    drop = 1.7  # m below the apex
    fall = time_from_apex(drop, k, G)
    assert flight_height(fall, 0.0, 0.0, k, G) == pytest.approx(-drop, abs=1e-12)
    assert abs(flight_velocity(fall, 0.0, 0.0, k, G)) == pytest.approx(speed_below_apex(drop, k, G), rel=1e-12)
    rise_time = time_from_apex(drop, k, G, rising=True)
    launch = speed_below_apex(drop, k, G, rising=True)
    assert flight_height(-rise_time, 0.0, 0.0, k, G) == pytest.approx(-drop, abs=1e-12)
    assert apex_rise(launch, k, G) == pytest.approx(drop, rel=1e-12)


def test_tennis_drag_costs_about_three_percent_of_impact_speed():
    """DESIGN.md: a tennis ball from 254 cm loses about 3 % of its impact speed to drag."""
    loss = 1 - speed_below_apex(2.54, K_TENNIS, G) / speed_below_apex(2.54, 0.0, G)
    assert 0.02 < loss < 0.035


def test_seed_example_3_bounce_sequence():
    """Seed, Example 3: e = 0.745, h0 = 0.9 m: heights 0.5, 0.277, 0.154, 0.085, 0.047 m; t∞ = 2.93 s."""
    heights = bounce_heights(0.745, 0.9, 5)
    np.testing.assert_allclose(heights, [0.5, 0.277, 0.154, 0.085, 0.047], atol=0.0006)  # m, seed rounding
    t0 = np.sqrt(2 * 0.9 / G)
    assert total_bouncing_time(0.745, t0) == pytest.approx(2.93, abs=0.005)  # s


def test_restitution_laws():
    v = np.array([1.0, 4.0])
    np.testing.assert_allclose(restitution(v, {"kind": "constant", "e0": 0.8}), [0.8, 0.8])
    np.testing.assert_allclose(restitution(v, {"kind": "linear", "e0": 0.9, "slope_s_m": 0.03}), [0.87, 0.78])
    np.testing.assert_allclose(restitution(v, {"kind": "power", "coefficient": 0.1, "exponent": 0.2}),
                               1 - 0.1 * v**0.2)
