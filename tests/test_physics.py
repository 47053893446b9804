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


def _log_cosh_and_cos(x, digits=50):
    """log cosh x and log cos x to ``digits`` digits (decimal arithmetic: exp and ln, and cos by its series)."""
    from decimal import Decimal, localcontext

    with localcontext() as context:
        context.prec = digits
        x = Decimal(float(x))
        cosh = (x.exp() + (-x).exp()) / 2
        cos, term, n = Decimal(1), Decimal(1), 0
        while abs(term) > Decimal(10) ** -(digits + 5):
            n += 2
            term = -term * x * x / (n * (n - 1))
            cos += term
        return float(cosh.ln()), float(cos.ln())


@pytest.mark.parametrize("k", [1e-9, 1e-6, 1e-3, 0.02])
def test_flight_height_is_exact_to_rounding_when_drag_barely_bends_the_flight(k):
    """The closed forms log cos(√(gk) t) / k and −log cosh(√(gk) t) / k lose ~10⁻¹⁶ / x² of their value to rounding
    where x = √(gk) t is small: 0.1 µm at k = 10⁻⁹ 1/m, as much as 10⁻⁷ 1/m of drag moves a height, so the
    numerical derivative by k of a fit with k near 0 was rounding noise (a free-drag fit stuck at k = 0, and the
    drag it combined into a white ball's e moved with the length scale 7 times as fast as its slope said)."""
    g = 9.81
    for dt in np.linspace(-0.6, 0.6, 25):
        log_cosh, log_cos = _log_cosh_and_cos(np.sqrt(g * k) * abs(dt))
        expected = 1.0 + (log_cos if dt < 0 else -log_cosh) / k
        assert flight_height(dt, 0.0, 1.0, k, g) == pytest.approx(expected, rel=0, abs=1e-12)


def test_flight_height_derivative_by_drag_near_zero_is_the_series():
    """Near k = 0 a flight's height changes with k by ∓g² t⁴ / 12 (rising, falling side), the first term of the
    series of log cos and log cosh: a central difference of 10⁻⁷ 1/m about k = 10⁻⁶ 1/m gives it within 0.1 %."""
    g, k, step = 9.81, 1e-6, 1e-7
    dt = np.array([-0.5, -0.3, 0.3, 0.5])
    derivative = (flight_height(dt, 0.0, 0.0, k + step, g) - flight_height(dt, 0.0, 0.0, k - step, g)) / (2 * step)
    np.testing.assert_allclose(derivative, np.where(dt < 0, -1.0, 1.0) * g**2 * dt**4 / 12.0, rtol=1e-3)
