"""A long log's flights are fitted with a sparse Jacobian and an iterative solver (time and memory linear
in the samples): on a log both solvers can fit, it gives the dense exact solver's numbers."""

import numpy as np
import pytest

import dropfit
import dropfit.analysis.flights as flights
from dropfit import Ball, analyse_trajectory, measure_recording
from dropfit.settings import Settings

from helpers import DROP_BALL, bouncing_ball, write_drop_log


@pytest.mark.parametrize("drag", ["on", "off"])
def test_sparse_solver_matches_the_dense_one(tmp_path, monkeypatch, drag):
    """The same 200 Hz drop log (e = 0.8) analysed by the dense solver and, with the long-log threshold
    lowered, by the sparse one: every impact's e and the drop height agree to a thousandth of their
    standard errors (the solvers stop at 1e-12 tolerances by different paths), the standard errors to 1e-5."""
    log = write_drop_log(tmp_path / "drop.csv")
    ball = Ball(DROP_BALL["ball_radius_m"], DROP_BALL["ball_mass_kg"], DROP_BALL["ball_type"])
    trajectory = measure_recording(log, ball)
    settings = Settings(drag=drag)
    dense = analyse_trajectory(trajectory, settings)
    monkeypatch.setattr(flights, "LONG_LOG_SAMPLES", 10)
    sparse = analyse_trajectory(trajectory, settings)
    assert sparse.summary["n_impacts"] == dense.summary["n_impacts"] >= 3
    assert np.all(np.abs(sparse.impacts["e"] - dense.impacts["e"]) < 1e-3 * dense.impacts["e_se"])
    np.testing.assert_allclose(sparse.impacts["e_se"], dense.impacts["e_se"], rtol=1e-5)
    assert abs(sparse.summary["drop_height_m"] - dense.summary["drop_height_m"]) < 1e-3 * dense.summary["drop_height_se_m"]
    # and both are right: the generator's e within four standard errors
    assert np.all(np.abs(sparse.impacts["e"] - 0.8) < 4 * sparse.impacts["e_se"])


def test_shared_acceleration_of_a_long_log_is_the_joint_least_squares(monkeypatch):
    """The flight-by-flight projection of a long log gives the joint fit's A and standard error."""
    rng = np.random.default_rng(11)
    pieces = []
    for start, size in ((0.0, 40), (0.5, 55), (1.1, 30)):
        time = start + np.sort(rng.uniform(0.0, 0.4, size))
        tau = time - time[0]
        pieces.append((time, 1.0 + rng.normal() * tau - 0.5 * 9.81 * tau**2 + rng.normal(0.0, 0.002, size)))
    joint = flights.shared_acceleration(pieces)
    monkeypatch.setattr(flights, "LONG_LOG_SAMPLES", 10)
    projected = flights.shared_acceleration(pieces)
    assert projected == pytest.approx(joint, rel=1e-9)
    assert abs(projected[0] - 9.81) < 4 * projected[1]


@pytest.mark.parametrize("seed", [0, 1, 3])
def test_a_log_sampled_at_tens_of_kilohertz_finds_its_drop(tmp_path, seed):
    """At 20 kHz with 1 mm noise, noise makes dips over a few samples and the approach speeds read over
    five samples are noise: the dips are searched block-averaged, so the drop (the tests' closed form:
    1.2 m, e = 0.75, from t = 0.1 s) is found at its time, its height within 5 mm, and e₁ within the 0.01 that
    the analysis reads from the closed form's instantaneous contacts at any rate (as the importer tests)."""
    rng = np.random.default_rng(seed)  # seeds whose drop was missed (twice) or the first bounce too, before
    time = np.arange(0.0, 2.5, 1.0 / 20000.0)
    drop_m, e = 1.2, 0.75
    height = np.where(time < 0.1, drop_m, bouncing_ball(time - 0.1, drop_m, e)) + 0.02
    log = tmp_path / "fast.csv"
    log.write_text("time_s,y_m\n" + "".join(f"{t:.6f},{y:.5f}\n" for t, y in
                                            zip(time, height + rng.normal(0.0, 0.001, time.size))))
    result = dropfit.analyse_recording(log, ball_radius_m=0.02, ball_mass_kg=0.057, drag="off", gravity_m_s2=9.81)
    assert result.analysis.summary["drop_height_m"] == pytest.approx(drop_m, abs=0.005)
    first = result.impacts.iloc[0]
    assert first["t_touchdown_s"] == pytest.approx(0.1 + np.sqrt(2 * drop_m / 9.81), abs=0.002)
    assert first["e"] == pytest.approx(e, abs=0.01)


def test_a_short_burst_at_tens_of_kilohertz_is_refused_in_one_line(tmp_path):
    """A high-speed clip's few frames (15 samples at 30 kHz, a fall without bounce) are too few to block-average:
    the dip search runs on them whole and the recording is refused as having no bounce, not with a NaN error."""
    time = np.arange(15) / 30000.0
    log = tmp_path / "burst.csv"
    log.write_text("time_s,y_m\n" + "".join(f"{t:.8f},{1.0 - 3.0 * t - 4.905 * t * t:.8f}\n" for t in time))
    with pytest.raises(dropfit.InputError, match=r"burst.csv: (no bounce found|the ball never falls)"):
        dropfit.analyse_recording(log, ball_radius_m=0.02, ball_mass_kg=0.057, gravity_m_s2=9.81)
