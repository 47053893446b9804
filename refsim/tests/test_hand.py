"""Hand phase before the release and catch at the end."""

import math

import numpy as np
import pytest

from refsim import Catch, HandPhase, simulate

G = 9.81


@pytest.mark.parametrize("kind", ["hold", "lift", "lower", "shake"])
def test_release_is_continuous_and_starts_from_the_hands_velocity(kind):
    hand = HandPhase(kind, duration_s=0.8, speed_m_s=0.3, tremor_amp_m=1e-3, shake_amp_m=0.01, seed=3)
    tr = simulate("tennis", 0.8, hand=hand, g_m_s2=G, t_end_s=1.2)
    v0 = hand.release_velocity()
    assert tr.v_release_m_s == v0
    eps = 1e-9
    y = tr.y_centre([-eps, 0.0, eps])
    assert np.max(np.abs(np.diff(y))) < 1e-6
    assert tr.y_centre(0.0)[0] == pytest.approx(tr.contact_height_m + 0.8, abs=1e-15)
    v = tr.v([-eps, eps])
    assert v[0] == pytest.approx(v0, abs=1e-6) and v[1] == pytest.approx(v0, abs=1e-6)
    if kind == "lift":
        assert v0 > 0.25
        fl = tr.flights.iloc[0]
        assert fl["apex_is_turning_point"]
        assert fl["h_apex_m"] > 0.8 and tr.h_drop_apex_m == fl["h_apex_m"]
    if kind == "lower":
        assert v0 < -0.25
        assert not tr.flights.iloc[0]["apex_is_turning_point"]
    if kind == "hold":
        assert abs(v0) < 2 * math.pi * 12 * 1e-3  # tremor only
    # the hand moves before the release (tremor amplitude ~ 1 mm)
    t = np.linspace(-0.8, 0.0, 801)
    assert np.ptp(tr.y_centre(t)) > 2e-4
    # frozen before the phase start
    assert tr.y_centre(-5.0)[0] == tr.y_centre(-0.8)[0]


def test_moving_release_drag_free_apex():
    hand = HandPhase("lift", duration_s=1.0, speed_m_s=0.4, tremor_amp_m=0.0, seed=0)
    ball = simulate("steel", 0.3, hand=hand, g_m_s2=G, t_end_s=0.5).ball.without_drag()
    tr = simulate(ball, 0.3, hand=hand, g_m_s2=G, t_end_s=0.8)
    assert tr.v_release_m_s == pytest.approx(0.4, rel=1e-12)
    assert tr.flights["h_apex_m"].iloc[0] == pytest.approx(0.3 + 0.4**2 / (2 * G), abs=1e-10)
    assert tr.flights["t_apex_s"].iloc[0] == pytest.approx(0.4 / G, abs=1e-10)


def test_lift_that_stops_before_release():
    hand = HandPhase("lift", duration_s=1.0, speed_m_s=0.2, moving_at_release=False, tremor_amp_m=0.0)
    assert abs(hand.release_velocity()) < 1e-12
    dy, v = hand.relative(np.array([-1.0, -0.5, 0.0]))
    assert dy[-1] == 0.0 and dy[0] < -0.15 and v[1] == pytest.approx(0.2)


def test_catch_after_impact():
    catch = Catch(after_impact=3, seed=1)
    tr = simulate("table_tennis", 0.305, g_m_s2=G, catch=catch, t_end_s=5.0)
    assert tr.status == "catch"
    assert len(tr.impacts) == 3
    assert tr.t_catch_s == tr.impacts["t_apex_after_s"].iloc[-1]
    assert math.isnan(tr.rest_time_s)
    t = tr.t_catch_s
    y = tr.y_centre([t - 1e-9, t + 1e-9])
    assert abs(y[1] - y[0]) < 1e-8
    later = tr.sample(np.linspace(t, t + 2.0, 50))
    assert (later["phase"].iloc[1:] == "caught").all()
    assert later["y_centre_m"].iloc[-1] > later["y_centre_m"].iloc[0] + 0.2  # lifted away


def test_catch_at_time():
    tr = simulate("tennis", 1.0, g_m_s2=G, catch=Catch(t_s=1.0), t_end_s=5.0)
    assert tr.status == "catch" and tr.t_catch_s == pytest.approx(1.0)
    assert (tr.impacts["t_liftoff_s"] < 1.0).all()
    tr.y_centre(np.linspace(0, 4, 10))  # defined after the catch
