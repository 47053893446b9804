"""Contact models against the seed chapter's Example 4, closed forms, and their own inverses."""

import numpy as np
import pytest

from dropfit.contact import (DAMPING_FORMS, HuntCrossleyContact, LinearContact, calibrate_damping, damping_ratio,
                             hunt_crossley_from_measurements, linear_from_measurements, linear_vibration_restitution,
                             simulate_contact)

# Seed, Example 4: tennis ball, k = 3·10⁴ N/m, dropped from 2.54 m, g = 9.81 m/s²
MASS_KG, STIFFNESS_N_M, DROP_M, G = 0.057, 3e4, 2.54, 9.81
V0 = np.sqrt(2 * G * DROP_M)  # m/s
E_TARGET = 0.745


@pytest.fixture(scope="module")
def seed_contact():
    damping = calibrate_damping(MASS_KG, STIFFNESS_N_M, V0, E_TARGET, G)
    return damping, simulate_contact(LinearContact(STIFFNESS_N_M, damping), MASS_KG, V0, G)


def test_seed_example_4_numbers(seed_contact):
    """c = 8.21 N·s/m, ζ = 0.099, e_linear = 0.731, 4.36 ms, 258 N, 58 N jump, ΔT = −0.632 J (seed rounding)."""
    damping, result = seed_contact
    zeta = damping_ratio(STIFFNESS_N_M, damping, MASS_KG)
    assert damping == pytest.approx(8.21, abs=0.005)  # N·s/m
    assert zeta == pytest.approx(0.099, abs=0.0005)
    assert linear_vibration_restitution(zeta) == pytest.approx(0.731, abs=0.0005)
    assert result.e == pytest.approx(E_TARGET, abs=1e-12)
    assert 1e3 * result.contact_time_s == pytest.approx(4.36, abs=0.005)  # ms
    assert result.peak_force_n == pytest.approx(258, abs=0.5)  # N
    assert result.touchdown_force_n == pytest.approx(58, abs=0.5)  # N
    assert result.kinetic_energy_change_j == pytest.approx(-0.6320, abs=5e-5)  # J
    # the seed's Euler steps left 0.3 % between ΔT and the work; the closed form closes the balance
    assert result.contact_work_j == pytest.approx(result.kinetic_energy_change_j, rel=1e-10)
    # the force peaks before the penetration does (the damper adds to the spring on the way in)
    assert result.peak_force_time_s < result.time_s[np.argmax(result.penetration_m)]


def test_linear_contact_without_gravity_is_the_half_period_oscillator():
    """g = 0, c = 0: e = 1 and contact time π √(m/k) exactly."""
    result = simulate_contact(LinearContact(STIFFNESS_N_M, 0.0), MASS_KG, V0, 0.0)
    assert result.e == pytest.approx(1.0, abs=1e-12)
    assert result.contact_time_s == pytest.approx(np.pi * np.sqrt(MASS_KG / STIFFNESS_N_M), rel=1e-12)
    assert result.peak_force_n == pytest.approx(V0 * np.sqrt(STIFFNESS_N_M * MASS_KG), rel=1e-9)


def test_linear_closed_form_agrees_with_the_integrator():
    """The linear model written as a Hunt–Crossley-type force is not available, so integrate it directly."""
    from scipy.integrate import solve_ivp

    model = LinearContact(STIFFNESS_N_M, 8.0)

    def rhs(_, state):
        return [state[1], G - float(model.force(state[0], state[1])) / MASS_KG]

    def liftoff(_, state):
        return state[0]

    liftoff.terminal, liftoff.direction = True, -1
    solution = solve_ivp(rhs, (0, 1), [0.0, V0], method="DOP853", rtol=1e-12, atol=1e-16, events=liftoff)
    exact = simulate_contact(model, MASS_KG, V0, G)
    assert exact.e == pytest.approx(-solution.y_events[0][0][1] / V0, rel=1e-8)
    assert exact.contact_time_s == pytest.approx(solution.t_events[0][0], rel=1e-8)


@pytest.mark.parametrize("form", sorted(DAMPING_FORMS))
def test_hunt_crossley_has_no_touchdown_jump_and_balances_energy(form):
    model = HuntCrossleyContact.from_restitution(1e6, 1.5, E_TARGET, V0, form)
    result = simulate_contact(model, MASS_KG, V0, G)
    assert result.touchdown_force_n == 0.0
    assert result.force_n[0] == 0.0
    assert 0.5 < result.e < 1.0
    assert result.contact_work_j == pytest.approx(result.kinetic_energy_change_j, rel=1e-8)


def test_hertz_elastic_contact_time_matches_the_closed_form():
    """χ = 0, g = 0, n = 3/2: t_c = 2.9432 (m²/(K² v₀))^{1/5} (Hertz), e = 1."""
    stiffness = 1e6
    result = simulate_contact(HuntCrossleyContact(stiffness, 1.5, 0.0), MASS_KG, V0, 0.0)
    hertz = 2.9432 * (MASS_KG**2 / (stiffness**2 * V0)) ** 0.2 * (5 / 4) ** 0.4
    assert result.e == pytest.approx(1.0, abs=1e-9)
    assert result.contact_time_s == pytest.approx(hertz, rel=1e-4)


def test_inverse_linear_recovers_stiffness_and_damping(seed_contact):
    damping, result = seed_contact
    stiffness, recovered = linear_from_measurements(MASS_KG, V0, result.e, result.contact_time_s, G)
    assert stiffness == pytest.approx(STIFFNESS_N_M, rel=1e-8)
    assert recovered == pytest.approx(damping, rel=1e-8)


def test_inverse_hunt_crossley_recovers_its_parameters():
    model = HuntCrossleyContact(2e6, 1.5, 0.08)
    result = simulate_contact(model, MASS_KG, V0, G)
    stiffness, chi = hunt_crossley_from_measurements(MASS_KG, V0, result.e, result.contact_time_s, 1.5, G)
    assert stiffness == pytest.approx(2e6, rel=1e-6)
    assert chi == pytest.approx(0.08, rel=1e-6)


def test_integrator_gives_eight_significant_digits():
    """A Hunt–Crossley contact with n = 1 and χ = 0 is the undamped linear spring: the integrator's
    e and contact time agree with the closed form to 1e-9 (gravity included)."""
    integrated = simulate_contact(HuntCrossleyContact(STIFFNESS_N_M, 1.0, 0.0), MASS_KG, V0, G)
    exact = simulate_contact(LinearContact(STIFFNESS_N_M, 0.0), MASS_KG, V0, G)
    assert integrated.e == pytest.approx(exact.e, rel=1e-9)
    assert integrated.contact_time_s == pytest.approx(exact.contact_time_s, rel=1e-9)
    assert integrated.peak_force_n == pytest.approx(exact.peak_force_n, rel=1e-8)


SE_RATIO_MIN, SE_RATIO_MAX = 0.85, 1.15  # reported se / Monte-Carlo spread (dimensionless), 400 draws


def test_fit_linear_contact_propagates_correlated_errors(seed_contact):
    """e and contact time share flights, so their errors correlate: the reported se of k and c must
    match the spread of k and c over draws of correlated (e, contact time), and differ from the se
    that treats them as independent."""
    from dropfit.contact import fit_linear_contact

    _, result = seed_contact
    e_se, time_se, rho = 0.002, 2e-5, 0.8  # dimensionless, s, correlation
    covariance = np.array([[e_se**2, rho * e_se * time_se], [rho * e_se * time_se, time_se**2]])
    fitted = fit_linear_contact(MASS_KG, [V0], [result.e], [result.contact_time_s], covariance, G)
    independent = fit_linear_contact(MASS_KG, [V0], [result.e], [result.contact_time_s],
                                     np.diag(np.diag(covariance)), G)
    draws = np.random.default_rng(3).multivariate_normal([result.e, result.contact_time_s], covariance, 400)
    spread = np.array([linear_from_measurements(MASS_KG, V0, e, tc, G) for e, tc in draws]).std(axis=0, ddof=1)
    for j, name in enumerate(("stiffness_n_m", "damping_n_s_m")):
        assert SE_RATIO_MIN < fitted[name][1] / spread[j] < SE_RATIO_MAX
    # treating them as independent would fail the same check
    assert not SE_RATIO_MIN < independent["damping_n_s_m"][1] / spread[1] < SE_RATIO_MAX
