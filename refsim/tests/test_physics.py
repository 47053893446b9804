"""Physics checks of refsim.ball (all seeded / deterministic, fast)."""

import math

import numpy as np
import pytest
from scipy.special import beta

import refsim
from refsim import Ball, HertzDamped, HuntCrossley, LinearSpringDamper, impact_response, simulate

G = 9.80665  # deliberately not refsim's default, passed explicitly


def hertz_constant():
    """T = c (m/K)^(2/5) v^(-1/5) for F = K delta^(3/2) (no gravity, no damping).

    T = 2 delta_max / v * int_0^1 ds / sqrt(1 - s^(5/2)),
    delta_max = (5 m v^2 / (4 K))^(2/5),  int = (2/5) B(2/5, 1/2).
    """
    return 2.0 * 1.25**0.4 * 0.4 * beta(0.4, 0.5)


def test_hertz_constant_value():
    assert hertz_constant() == pytest.approx(3.218065, abs=2e-6)


@pytest.mark.parametrize("v", [0.05, 0.5, 3.0, 20.0])
def test_undamped_hertz_contact_time_and_penetration(v):
    m, K = 0.05, 1e6
    ball = Ball("h", m, 0.02, HertzDamped(K, 0.0), drag_coefficient=0.0)
    r = impact_response(ball, v, g_m_s2=0.0)
    T = hertz_constant() * (m / K) ** 0.4 * v**-0.2
    assert r["contact_time_s"] == pytest.approx(T, rel=1e-8)
    assert r["max_penetration_m"] == pytest.approx((1.25 * m * v * v / K) ** 0.4, rel=1e-8)
    assert r["peak_force_N"] == pytest.approx(K * r["max_penetration_m"] ** 1.5, rel=1e-7)
    assert abs(r["e"] - 1.0) < 1e-7


def test_hertz_contact_time_scaling_exponent():
    ball = Ball("h", 0.057, 0.0335, HertzDamped(3e5, 0.0), drag_coefficient=0.0)
    v = np.array([0.3, 1.0, 3.0, 10.0])
    T = np.array([impact_response(ball, x, g_m_s2=0.0)["contact_time_s"] for x in v])
    slope = np.polyfit(np.log(v), np.log(T), 1)[0]
    assert slope == pytest.approx(-0.2, abs=1e-8)


def test_linear_undamped_half_period():
    m, k = 0.0027, 2.7e4
    ball = Ball("l", m, 0.02, LinearSpringDamper(k, 0.0), drag_coefficient=0.0)
    r = impact_response(ball, 2.0, g_m_s2=0.0)
    assert r["contact_time_s"] == pytest.approx(math.pi * math.sqrt(m / k), rel=1e-9)
    assert abs(r["e"] - 1.0) < 1e-8


@pytest.mark.parametrize("law", [HertzDamped(3.2e5, 0.0), HuntCrossley(3.2e5, 0.0), LinearSpringDamper(2e4, 0.0)])
def test_no_damping_gives_e_one_in_full_simulation(law):
    ball = Ball("b", 0.057, 0.0335, law, drag_coefficient=0.0)
    tr = simulate(ball, 1.0, g_m_s2=G, t_end_s=1.6)
    im = tr.impacts
    assert len(im) >= 2
    assert np.all(np.abs(im["e"] - 1.0) < 1e-6)
    assert im["h_after_m"].notna().sum() >= 1
    assert np.allclose(im["h_after_m"].dropna(), 1.0, atol=1e-6)
    # gravity acts during the contact: the contact is symmetric in time
    assert np.allclose(im["t_max_penetration_s"] - im["t_touchdown_s"], 0.5 * im["contact_time_s"], rtol=1e-6)


def test_kuwabara_kono_exact_scaling():
    """Without gravity e depends on C v^(1/5) K^(-3/5) m^(-2/5) only."""
    m, K, C = 0.057, 3.2e5, 200.0
    b1 = Ball("a", m, 0.0335, HertzDamped(K, C), drag_coefficient=0.0)
    b2 = Ball("b", m, 0.0335, HertzDamped(K, C / 2.0), drag_coefficient=0.0)
    e1 = impact_response(b1, 1.0, g_m_s2=0.0)["e"]
    e2 = impact_response(b2, 32.0, g_m_s2=0.0)["e"]  # 32^(1/5) = 2
    assert e1 == pytest.approx(e2, abs=1e-8)
    # and e falls with speed
    es = [impact_response(b1, v, g_m_s2=0.0)["e"] for v in (0.5, 2.0, 8.0)]
    assert es[0] > es[1] > es[2]


def test_hunt_crossley_exact_scaling():
    """Without gravity e depends on alpha v only; e ~ 1 - alpha v for small alpha v."""
    b1 = Ball("a", 0.0054, 0.008, HuntCrossley(2.7e6, 0.02), drag_coefficient=0.0)
    b2 = Ball("b", 0.0054, 0.008, HuntCrossley(2.7e6, 0.01), drag_coefficient=0.0)
    e1 = impact_response(b1, 1.0, g_m_s2=0.0)["e"]
    e2 = impact_response(b2, 2.0, g_m_s2=0.0)["e"]
    assert e1 == pytest.approx(e2, abs=1e-8)
    assert 1.0 - e1 == pytest.approx(0.02, rel=0.05)


def test_drag_free_apex_and_fall_time():
    ball = refsim.preset("tennis").without_drag()
    tr = simulate(ball, 1.2, g_m_s2=G, t_end_s=2.5)
    im = tr.impacts
    assert np.allclose(im["h_after_m"], im["v_out_m_s"] ** 2 / (2 * G), rtol=0, atol=1e-10)
    assert np.allclose(im["h_before_m"], im["v_in_m_s"] ** 2 / (2 * G), rtol=0, atol=1e-10)
    assert im["t_touchdown_s"].iloc[0] == pytest.approx(math.sqrt(2 * 1.2 / G), abs=1e-11)
    assert im["v_in_m_s"].iloc[0] == pytest.approx(math.sqrt(2 * G * 1.2), rel=1e-11)
    # energy: e^2 = h_after / h_before exactly without drag
    assert np.allclose(im["e"] ** 2, im["h_after_m"] / im["h_before_m"], rtol=1e-9)


def test_drag_lowers_the_fall_speed():
    with_drag = simulate("table_tennis", 1.0, g_m_s2=G, t_end_s=0.8)
    k = with_drag.drag_k_1_m
    assert k == pytest.approx(1.2 * 0.5 * math.pi * 0.02**2 / (2 * 0.0027), rel=1e-12)
    v_in = with_drag.impacts["v_in_m_s"].iloc[0]
    # exact fall with quadratic drag from rest: v^2 = g/k (1 - exp(-2 k h))
    assert v_in == pytest.approx(math.sqrt(G / k * (1 - math.exp(-2 * k * 1.0))), rel=1e-8)


def test_liftoff_by_force_precedes_separation():
    tr = simulate("tennis", 1.0, g_m_s2=G, t_end_s=1.5)
    im = tr.impacts
    assert (im["t_force_zero_s"] < im["t_liftoff_s"]).all()
    assert (im["contact_time_force_s"] < im["contact_time_s"]).all()
    # between force zero and separation only gravity and drag act: the ball slows down
    assert (im["v_out_m_s"] < im["v_force_zero_m_s"]).all()
    s_fz = tr.sample(im["t_force_zero_s"].to_numpy())
    s_lo = tr.sample(im["t_liftoff_s"].to_numpy())
    assert np.all(np.abs(s_fz["force_N"]) < 1e-6)
    assert np.all(s_fz["y_centre_m"] < tr.contact_height_m)  # still pressed in
    assert np.allclose(s_lo["y_centre_m"], tr.contact_height_m, atol=1e-12)
    # peak force: between touchdown and force zero, positive, and larger than m g
    assert ((im["t_peak_force_s"] > im["t_touchdown_s"]) & (im["t_peak_force_s"] < im["t_force_zero_s"])).all()
    assert (im["peak_force_N"] > 10 * 0.057 * G).all()


def test_energy_bound_never_increases_in_contact():
    tr = simulate("tennis", 0.5, g_m_s2=G, t_end_s=1.0)
    r = tr.impacts.iloc[0]
    t = np.linspace(r["t_touchdown_s"], r["t_liftoff_s"], 2001)
    s = tr.sample(t)
    z = s["y_centre_m"].to_numpy() - tr.contact_height_m
    d = np.maximum(-z, 0.0)
    E = 0.5 * 0.057 * s["v_m_s"].to_numpy() ** 2 + 0.057 * G * z + tr.ball.contact.elastic_energy(d)
    assert np.all(np.diff(E) < 1e-9)


def test_convergence_with_tolerance():
    a = simulate("tennis", 1.0, g_m_s2=G, t_end_s=2.5, rtol=1e-10, atol=1e-12)
    b = simulate("tennis", 1.0, g_m_s2=G, t_end_s=2.5, rtol=1e-12, atol=1e-14)
    n = min(len(a.impacts), len(b.impacts))
    assert n >= 4
    for col, tol in [("t_touchdown_s", 1e-9), ("t_liftoff_s", 1e-9), ("e", 1e-8), ("h_after_m", 1e-9),
                     ("peak_force_N", 1e-6), ("max_penetration_m", 1e-11)]:
        diff = np.abs(a.impacts[col].to_numpy()[:n] - b.impacts[col].to_numpy()[:n])
        assert np.nanmax(diff) < tol, (col, np.nanmax(diff))


def test_rest_and_settling():
    tr = simulate("table_tennis", 0.305, g_m_s2=G, t_end_s=10.0)
    assert tr.status == "rest"
    assert tr.rest_time_s > tr.impacts["t_liftoff_s"].iloc[-1]
    assert tr.t_settled_s >= tr.rest_time_s
    t = np.linspace(tr.rest_time_s, tr.rest_time_s + 2.0, 20001)
    z = tr.y_centre(t) - tr.contact_height_m
    assert z.max() < tr.h_rest_m
    late = tr.sample(np.linspace(tr.t_settled_s, tr.t_settled_s + 3.0, 11))
    assert np.allclose(late["y_centre_m"], tr.y_rest_centre_m, atol=0, rtol=0)
    assert tr.delta_static_m == pytest.approx(0.0027 * G / 2.673e4, rel=1e-12)
    assert tr.settle_residual_m < 1e-6
    # the impact table: every listed rebound rises, the count is finite
    assert (tr.impacts["h_after_m"] > 0.5 * tr.h_rest_m).all()


def test_track_is_continuous_across_segments():
    tr = simulate("tennis", 1.0, g_m_s2=G, t_end_s=10.0)
    starts = np.array([s[0] for s in tr._segments[1:-1]])  # exclude the -inf hand segment and the rest snap
    eps = 1e-13
    a, b = tr.sample(starts - eps), tr.sample(starts + eps)
    assert np.max(np.abs(a["y_centre_m"] - b["y_centre_m"])) < 1e-11
    assert np.max(np.abs(a["v_m_s"] - b["v_m_s"])) < 1e-6
    snap = tr.t_settled_s
    jump = abs(tr.y_centre(snap - 1e-12)[0] - tr.y_centre(snap + 1e-12)[0])
    assert jump <= tr.settle_residual_m + 1e-12


def test_points_bottom_centre_top():
    tr = simulate("tennis", 1.0, g_m_s2=G, t_end_s=1.0)
    r = tr.impacts.iloc[0]
    t = np.array([0.0, r["t_max_penetration_s"], r["t_apex_after_s"]])
    c, bt, tp = tr.y_centre(t), tr.y_bottom(t), tr.y_top(t)
    assert np.allclose(tp - c, tr.radius_m)
    assert bt[0] == pytest.approx(1.0) and bt[1] == tr.floor_m  # bottom flattened on the floor
    assert c[1] == pytest.approx(tr.contact_height_m - r["max_penetration_m"], abs=1e-12)
    assert c[2] - tr.contact_height_m == pytest.approx(r["h_after_m"], abs=1e-12)


def test_friction_rolling_and_sliding():
    base = Ball("s", 0.0642, 0.0125, HertzDamped(2.57e9, 1.1e4), drag_coefficient=0.0,
                friction_coefficient=0.5, inertia_factor=0.4)
    r = impact_response(base, 3.0, g_m_s2=0.0, u_in_m_s=1.0)
    assert r["u_out_m_s"] == pytest.approx(5.0 / 7.0, rel=1e-9)  # rolls: angular momentum about the contact
    assert r["u_out_m_s"] + r["spin_out_rad_s"] * 0.0125 == pytest.approx(0.0, abs=1e-9)
    low = Ball("s", 0.0642, 0.0125, HertzDamped(2.57e9, 1.1e4), drag_coefficient=0.0,
               friction_coefficient=0.02, inertia_factor=0.4)
    r = impact_response(low, 3.0, g_m_s2=0.0, u_in_m_s=1.0)
    # slides all through: tangential impulse = mu * normal impulse = mu m (1 + e) v_in
    assert r["u_out_m_s"] == pytest.approx(1.0 - 0.02 * (1 + r["e"]) * 3.0, rel=1e-9)


def test_2d_flight_and_frictionless_keeps_u():
    ball = refsim.preset("steel").without_drag()
    ball = Ball(ball.name, ball.mass_kg, ball.radius_m, ball.contact, drag_coefficient=0.0)
    tr = simulate(ball, 0.5, g_m_s2=G, u0_m_s=0.3, x0_m=0.1, t_end_s=0.7)
    im = tr.impacts
    assert np.allclose(im["u_out_m_s"], 0.3, rtol=1e-12)
    assert im["x_touchdown_m"].iloc[0] == pytest.approx(0.1 + 0.3 * im["t_touchdown_s"].iloc[0], rel=1e-10)


def test_shifted_time_base():
    tr = simulate("steel", 0.2, g_m_s2=G, t_end_s=0.6)
    sh = tr.shifted(1.7e9)
    assert sh.impacts["t_touchdown_s"].iloc[0] == tr.impacts["t_touchdown_s"].iloc[0] + 1.7e9
    assert sh.t_release_s == 1.7e9
    t = tr.impacts["t_apex_after_s"].iloc[0]
    assert sh.y_centre(t + 1.7e9)[0] == pytest.approx(tr.y_centre(t)[0], abs=1e-6)
    with pytest.raises(ValueError):
        tr.y_centre(0.61)
