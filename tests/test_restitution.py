"""Constant e, theory checks and the ITF verdict against closed forms and the published window."""

import numpy as np
import pytest

from dropfit.restitution import (ITF_REBOUND_MAX_M, ITF_REBOUND_MIN_M, Z95, constant_restitution, estimate,
                                 itf_rebound, itf_verdict, theory_checks)

G = 9.80665


def test_constant_e_of_independent_equal_impacts_is_the_mean():
    e = np.array([0.74, 0.75, 0.76, 0.75])
    sigma = 0.004
    result = constant_restitution(e, sigma**2 * np.eye(4))
    assert result["e"]["value"] == pytest.approx(0.75)
    assert result["e"]["se"] == pytest.approx(sigma / 2)
    assert result["chi2"] == pytest.approx(np.sum((e - 0.75) ** 2) / sigma**2)
    assert result["dof"] == 3


def test_constant_e_propagates_correlation():
    """Two impacts with correlation ρ: var of their mean = σ²(1 + ρ)/2."""
    sigma, rho = 0.002, -0.5
    cov = sigma**2 * np.array([[1, rho], [rho, 1]])
    result = constant_restitution(np.array([0.8, 0.8]), cov)
    assert result["e"]["se"] == pytest.approx(sigma * np.sqrt((1 + rho) / 2))


def test_itf_window_matches_the_seed():
    """Seed, Example 3: an approved ball has 0.728 < e < 0.761 (no drag)."""
    assert np.sqrt(ITF_REBOUND_MIN_M / 2.54) == pytest.approx(0.729, abs=0.001)
    assert np.sqrt(ITF_REBOUND_MAX_M / 2.54) == pytest.approx(0.761, abs=0.001)


@pytest.mark.parametrize("value, se, verdict", [
    (1.41, 0.01, "pass"),
    (1.36, 0.01, "indeterminate"),  # interval 1.34–1.38 straddles 1.35
    (1.30, 0.01, "fail"),
    (1.50, 0.005, "fail"),
    (1.465, 0.01, "indeterminate"),
])
def test_itf_verdict_is_guard_banded(value, se, verdict):
    assert itf_verdict(estimate(value, se, "m")) == verdict


def test_itf_rebound_measured_from_the_itf_height():
    rebound = itf_rebound(2.55, 0.001, 1.40, 0.002, 0.75, 0.001, 0.0, G)
    assert rebound["value"] == pytest.approx(1.40 * 2.54 / 2.55)
    assert "measured" in rebound["method"]


def test_itf_rebound_predicted_from_another_height_without_drag_is_e_squared_h():
    e, e_se = 0.745, 0.002
    rebound = itf_rebound(1.0, 0.001, 0.55, 0.002, e, e_se, 0.0, G)
    assert rebound["value"] == pytest.approx(e**2 * 2.54, rel=1e-12)
    assert rebound["se"] == pytest.approx(2 * e * 2.54 * e_se, rel=1e-4)
    assert rebound["ci95"][1] - rebound["value"] == pytest.approx(Z95 * rebound["se"])
    assert "predicted" in rebound["method"]


def test_theory_checks_reproduce_the_seed_example_3():
    """Seed, Example 3: h0 = 0.9 m, e = 0.745 → h_n = e^{2n} h0, t∞ = 2.93 s."""
    t0 = np.sqrt(2 * 0.9 / 9.81)
    heights = 0.9 * 0.745 ** (2 * np.arange(1, 6))
    checks = theory_checks(0.745, 0.001, 0.9, t0, heights, np.full(5, 1e-4), 2.93)
    np.testing.assert_allclose([h["predicted_m"] for h in checks["heights"]], [0.5, 0.277, 0.154, 0.085, 0.047],
                               atol=0.0006)  # m, seed rounding
    assert checks["total_bouncing_time"]["predicted"]["value"] == pytest.approx(2.93, abs=0.005)  # s


def test_itf_rebound_predicted_carries_the_drag_uncertainty():
    """The predicted rebound's se adds the drag parameter's se (and its covariance with e) to that of e:
    checked against the spread over draws of (e, k)."""
    e, e_se, k, k_se, cov = 0.75, 0.002, 0.01, 0.003, -3e-6  # 1, 1, 1/m, 1/m, 1/m
    rebound = itf_rebound(1.0, 0.001, 0.55, 0.002, e, e_se, k, G, drag_k_se_per_m=k_se, e_drag_covariance=cov)
    without = itf_rebound(1.0, 0.001, 0.55, 0.002, e, e_se, k, G)
    draws = np.random.default_rng(5).multivariate_normal([e, k], [[e_se**2, cov], [cov, k_se**2]], 2000)
    spread = np.std([itf_rebound(1.0, 0.001, 0.55, 0.002, de, 0.0, dk, G)["value"] for de, dk in draws], ddof=1)
    assert rebound["se"] == pytest.approx(spread, rel=0.06)  # 2000 draws: the spread is known to ~3 %
    assert rebound["se"] > 1.1 * without["se"]


def test_weighted_fit_covariance_matches_the_spread_of_correlated_data():
    """One estimator for every e law: inverse-variance weights, covariance through the full matrix."""
    from dropfit.restitution import weighted_fit

    speeds = np.array([6.0, 4.5, 3.4, 2.6, 2.0])  # m/s
    sigma = np.array([0.001, 0.0015, 0.002, 0.003, 0.004])
    correlation = np.eye(5) - 0.4 * (np.eye(5, k=1) + np.eye(5, k=-1))
    covariance = np.outer(sigma, sigma) * correlation
    design = np.column_stack([np.ones(5), -speeds])
    truth = design @ np.array([0.9, 0.03])
    draws = np.random.default_rng(9).multivariate_normal(truth, covariance, 3000)
    thetas = np.array([weighted_fit(design, d, covariance)["theta"] for d in draws])
    reported = np.sqrt(np.diag(weighted_fit(design, truth, covariance)["covariance"]))
    assert reported == pytest.approx(thetas.std(axis=0, ddof=1), rel=0.05)  # 3000 draws: spread known to ~1.3 %
    assert thetas.mean(axis=0) == pytest.approx([0.9, 0.03], abs=3 * reported.max() / np.sqrt(3000))
