"""Impulse, forces and central impact against the seed's Examples 1 and 2 and against conservation laws.

Seed: /work/shared/seed/impulse-momentum-impact.txt ("7.5 Impulse, momentum and impact"). Each
published number is checked to half a unit of its last printed digit; the tolerances are named with
their units. Two printed values lie exactly on a rounding boundary: J_y = m v2 sin 30° = 5.375 N·s
(printed 5.37) and F̄_y = 537.5 N (printed 537.0, i.e. rounded to whole newtons), so the comparison
allows the half unit itself plus a relative 1e-9 for floating point, and the exact values are
checked separately.
"""

import numpy as np
import pytest

from dropfit.impulse import (BallOnBlock, CentralImpact, average_force, ball_on_block, central_impact,
                             half_sine_peak_force, impulse)

G_SEED_M_S2 = 9.81  # the seed's g

# Half a unit of the last digit the seed prints.
IMPULSE_TOL_N_S = 0.005        # J printed to 0.01 N·s
FORCE_TOL_N = 0.5              # F̄ printed as 1576.0 / 537.0 / 1665: whole newtons
WEIGHT_MULTIPLE_TOL = 0.5      # 395 mg: whole multiples of mg
PEAK_FORCE_TOL_N = 50.0        # "about 2.6 kN": 0.1 kN
SPEED_TOL_M_S = 0.005          # speeds printed to 0.01 m/s
E_TOL = 0.005                  # e printed to 0.01 (dimensionless)
LOSS_FRACTION_TOL = 0.00005    # 12.80 % printed to 0.01 % (fraction)
CONSERVATION_TOL = 1e-12       # momentum, relative


def matches_print(actual, printed, half_unit):
    """|actual − printed| within half a unit of the printed digit (plus float slack)."""
    actual, printed = np.asarray(actual, float), np.asarray(printed, float)
    return bool(np.all(np.abs(actual - printed) <= half_unit * (1 + 1e-9)))


# --- Example 1: the kick ------------------------------------------------------------------------

M_BALL_KG, V1_M_S, V2_M_S, THETA_RAD, DT_S = 0.43, 15.0, 25.0, np.radians(30.0), 0.010


@pytest.fixture
def kick():
    v_before = np.array([-V1_M_S, 0.0])
    v_after = V2_M_S * np.array([np.cos(THETA_RAD), np.sin(THETA_RAD)])
    J = impulse(M_BALL_KG, v_before, v_after)
    return J, average_force(J, DT_S)


def test_kick_impulse_matches_seed(kick):
    J, _ = kick
    assert J.shape == (2,)
    assert matches_print(J, [15.76, 5.37], IMPULSE_TOL_N_S)
    assert matches_print(np.linalg.norm(J), 16.65, IMPULSE_TOL_N_S)
    # exact components: m (v2 cos θ + v1), m v2 sin θ
    assert J == pytest.approx([M_BALL_KG * (V2_M_S * np.cos(THETA_RAD) + V1_M_S), M_BALL_KG * V2_M_S / 2],
                              rel=1e-12)


def test_kick_average_force_matches_seed(kick):
    J, F = kick
    assert matches_print(F, [1576.0, 537.0], FORCE_TOL_N)
    assert matches_print(np.linalg.norm(F), 1665.0, FORCE_TOL_N)
    assert matches_print(np.linalg.norm(F) / (M_BALL_KG * G_SEED_M_S2), 395.0, WEIGHT_MULTIPLE_TOL)
    assert F == pytest.approx(J / DT_S, rel=1e-12)


def test_weight_impulse_is_small():
    """mg Δt = 0.04 N·s, a quarter of a percent of |J|: the weight is non-impulsive."""
    J_weight = impulse(M_BALL_KG, 0.0, -G_SEED_M_S2 * DT_S)  # the weight alone over Δt
    assert matches_print(abs(J_weight), 0.04, IMPULSE_TOL_N_S)


def test_half_sine_peak_force_matches_seed(kick):
    _, F = kick
    peak = half_sine_peak_force(np.linalg.norm(F))
    assert matches_print(peak, 2600.0, PEAK_FORCE_TOL_N)
    # the mean of a half sine of peak P over its duration is 2P/π
    t = np.linspace(0.0, 1.0, 200_001)
    pulse = peak * np.sin(np.pi * t)
    assert np.trapezoid(pulse, t) == pytest.approx(np.linalg.norm(F), rel=1e-9)


def test_impulse_shapes_and_inputs():
    assert impulse(2.0, 1.0, -3.0) == pytest.approx(-8.0)
    v1 = np.array([[1.0, 0.0], [0.0, 2.0]])
    v2 = np.array([[0.0, 1.0], [0.0, -2.0]])
    assert impulse(0.5, v1, v2) == pytest.approx(0.5 * (v2 - v1))
    with pytest.raises(ValueError):
        impulse(1.0, [1.0, 0.0], [1.0, 0.0, 0.0])
    with pytest.raises(ValueError):
        average_force(1.0, 0.0)


# --- Central impact and Example 2 ---------------------------------------------------------------

M1_KG, M2_KG, H_M, REBOUND_M = 0.1, 0.5, 1.0, 0.36


def kinetic_energy_j(m1, m2, v1, v2):
    return 0.5 * m1 * v1**2 + 0.5 * m2 * v2**2


def test_ball_on_block_matches_seed():
    r = ball_on_block(M1_KG, M2_KG, H_M, REBOUND_M, g=G_SEED_M_S2)
    assert isinstance(r, BallOnBlock)
    assert matches_print(r.ball_velocity_before_m_s, 4.43, SPEED_TOL_M_S)
    assert matches_print(r.ball_velocity_after_m_s, -2.66, SPEED_TOL_M_S)
    assert matches_print(r.block_speed_m_s, 1.42, SPEED_TOL_M_S)
    assert matches_print(r.e, 0.92, E_TOL)
    assert matches_print(r.energy_loss_fraction, 0.1280, LOSS_FRACTION_TOL)


def test_ball_on_block_agrees_with_central_impact():
    """Running central_impact on the example's speeds with its e reproduces the speeds after."""
    r = ball_on_block(M1_KG, M2_KG, H_M, REBOUND_M, g=G_SEED_M_S2)
    c = central_impact(M1_KG, M2_KG, r.ball_velocity_before_m_s, 0.0, r.e)
    assert c.v1_after_m_s == pytest.approx(r.ball_velocity_after_m_s, rel=1e-12)
    assert c.v2_after_m_s == pytest.approx(r.block_speed_m_s, rel=1e-12)
    T = kinetic_energy_j(M1_KG, M2_KG, r.ball_velocity_before_m_s, 0.0)
    assert c.energy_loss_j / T == pytest.approx(r.energy_loss_fraction, rel=1e-9)


CASES = [  # m1, m2, v1, v2, e
    (0.1, 0.5, 4.43, 0.0, 0.92),
    (1.0, 1.0, 3.0, -2.0, 0.5),
    (0.057, 80.0, 7.0, 0.0, 0.745),
    (2.0, 0.3, -1.5, -4.0, 0.2),
]


@pytest.mark.parametrize("m1, m2, v1, v2, e", CASES)
def test_central_impact_conserves_momentum_and_obeys_restitution(m1, m2, v1, v2, e):
    c = central_impact(m1, m2, v1, v2, e)
    assert isinstance(c, CentralImpact)
    p_before = m1 * v1 + m2 * v2
    p_after = m1 * c.v1_after_m_s + m2 * c.v2_after_m_s
    assert abs(p_after - p_before) <= CONSERVATION_TOL * max(abs(m1 * v1), abs(m2 * v2))
    assert (c.v2_after_m_s - c.v1_after_m_s) == pytest.approx(e * (v1 - v2), rel=1e-12)


@pytest.mark.parametrize("m1, m2, v1, v2, e", CASES)
def test_central_impact_energy_loss_equals_direct_difference(m1, m2, v1, v2, e):
    c = central_impact(m1, m2, v1, v2, e)
    direct = kinetic_energy_j(m1, m2, v1, v2) - kinetic_energy_j(m1, m2, c.v1_after_m_s, c.v2_after_m_s)
    assert c.energy_loss_j == pytest.approx(direct, rel=1e-9, abs=1e-12)
    assert c.energy_loss_j >= 0.0


@pytest.mark.parametrize("m1, m2, v1, v2, _", CASES)
def test_elastic_impact_loses_no_energy(m1, m2, v1, v2, _):
    c = central_impact(m1, m2, v1, v2, 1.0)
    assert c.energy_loss_j == 0.0
    after = kinetic_energy_j(m1, m2, c.v1_after_m_s, c.v2_after_m_s)
    assert after == pytest.approx(kinetic_energy_j(m1, m2, v1, v2), rel=1e-12)


@pytest.mark.parametrize("m1, m2, v1, v2, _", CASES)
def test_plastic_impact_moves_bodies_together(m1, m2, v1, v2, _):
    c = central_impact(m1, m2, v1, v2, 0.0)
    common = (m1 * v1 + m2 * v2) / (m1 + m2)
    assert c.v1_after_m_s == pytest.approx(common, rel=1e-12)
    assert c.v2_after_m_s == pytest.approx(common, rel=1e-12)


def test_central_impact_rejects_bad_input():
    with pytest.raises(ValueError):
        central_impact(0.0, 1.0, 1.0, 0.0, 0.5)
    with pytest.raises(ValueError):
        central_impact(1.0, 1.0, 1.0, 0.0, 1.2)
    with pytest.raises(ValueError):
        ball_on_block(0.1, 0.5, 0.0, 0.36)
