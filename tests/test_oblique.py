"""Oblique bounces (2-D motion): the horizontal column of a height log, the tangential velocities and angles
at each impact against closed-form bounce sequences written here (no dropfit code), e free of any
horizontal drift, and the seed's Example 3 (refsim's recording) through the workflow's settings."""

import dataclasses
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

import refsim
import refsim.record

from dropfit import analyse_recording
from dropfit.errors import InputError
from dropfit.heightlog import make_trajectory, read_height_log, trajectory_from_log
from dropfit.physics import horizontal_flight
from dropfit.report import recording_report_html
from dropfit.settings import settings_from_config

from helpers import SEED_EXAMPLE3, check_seed_example3

REPO = Path(__file__).resolve().parents[1]
G = SEED_EXAMPLE3["g_m_s2"]  # m/s², the seed's
E_SEED = SEED_EXAMPLE3["e"]
EXAMPLE3 = "seed_example3_oblique"


def bounce_log(e=0.745, drop_m=0.9, speed_m_s=3.0, tangential_ratio=1.0, rate_hz=200.0, noise_m=1e-3, seed=3,
               duration_s=2.6, drift_m_s=0.0):
    """Closed-form bounces of a point ball (instantaneous impacts, no drag, contact height 0): each impact
    reverses the vertical velocity times e and multiplies the horizontal one by ``tangential_ratio``;
    ``drift_m_s`` adds a constant horizontal velocity to every sample (a camera panning). Returns time
    (s), y and x (m) with Gaussian noise, and the true (vy_in, vx_in, vx_out) of each impact."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, duration_s, 1.0 / rate_hz)
    y, x = np.zeros_like(t), np.zeros_like(t)
    start, height, vy, vx, x0 = 0.0, drop_m, 0.0, speed_m_s, 0.0
    impacts = []
    while start < duration_s and len(impacts) < 40:
        # flight: y = height + vy τ − g τ²/2 until y = 0
        end = start + (vy + np.sqrt(vy**2 + 2 * G * height)) / G
        inside = (t >= start) & (t < end)
        tau = t[inside] - start
        y[inside] = height + vy * tau - 0.5 * G * tau**2
        x[inside] = x0 + vx * tau
        v_in = np.sqrt(vy**2 + 2 * G * height)
        impacts.append((v_in, vx, tangential_ratio * vx))
        x0 += vx * (end - start)
        start, height, vy, vx = end, 0.0, e * v_in, tangential_ratio * vx
    return t, y + rng.normal(0, noise_m, t.size), x + drift_m_s * t + rng.normal(0, noise_m, t.size), impacts


def analysed(t, y, x=None):
    """dropfit's analysis of the point ball's bounces, logged as a ball of radius 3 cm's centre."""
    trajectory = make_trajectory(t, y + 0.03, "closed-form bounces", "synthetic", x_m=x)
    return analyse_recording(trajectory, floor_m=0.0, ball_radius_m=0.03, gravity_m_s2=G, drag="off")


def test_horizontal_flight_with_drag():
    """u(t) under quadratic drag on the full velocity: with no vertical motion (g = 0) the closed form
    u = u₀/(1 + k|u₀|τ), x = sign(u₀) ln(1 + k|u₀|τ)/k, both directions in time; in a fall, refsim's
    integration of the coupled 2-D flight (its own code), within 0.1 mm and 0.3 mm/s (its vertical flight
    feels the coupled drag too, dropfit's vertical flight only v|v|); drag along x alone,
    u/(1 + k u τ), would be 18 mm/s off after 0.4 s."""
    k, t = 0.02, np.linspace(-0.3, 0.8, 12)
    for u in (3.0, -2.0):
        x, velocity = horizontal_flight(t, 0.0, u, 0.0, 1.0, k, 0.0)
        assert np.allclose(velocity, u / (1 + k * abs(u) * t), rtol=1e-5, atol=0)
        assert np.allclose(x, np.sign(u) * np.log1p(k * abs(u) * t) / k, rtol=1e-5, atol=1e-7)
    ball = refsim.preset("tennis")
    truth = refsim.simulate(dataclasses.replace(ball, friction_coefficient=0.0), 1.0, u0_m_s=3.0, g_m_s2=G, t_end_s=0.4)
    t = np.linspace(0.0, 0.4, 9)
    x, velocity = horizontal_flight(t, 0.0, 3.0, 0.0, 1.0, ball.drag_k_1_m, G)
    states = truth.sample(t)
    assert np.allclose(x, truth.x(t), atol=1e-4) and np.allclose(velocity, states["u_m_s"], atol=3e-4)
    assert abs(velocity[-1] - 3.0) > 0.02  # the drag shows
    assert np.allclose(horizontal_flight(t, 0.2, 3.0, 0.0, 1.0, 0.0, G)[0], 3.0 * (t - 0.2))


@pytest.mark.parametrize("ratio", [1.0, 0.8])
def test_tangential_velocities_angles_and_the_check(ratio):
    """vx before and after each impact, the angles above the floor and tan θ′ = e tan θ, against the closed
    form: a smooth floor keeps vx ("consistent"), one that takes 20 % of it is named."""
    t, y, x, truth = bounce_log(tangential_ratio=ratio)
    impacts = analysed(t, y, x).impacts
    n = min(len(impacts), 5)
    assert n >= 4
    for i in range(n):
        v_in, vx_in, vx_out = truth[i]
        row = impacts.iloc[i]
        assert abs(row["vx_in_m_s"] - vx_in) < 3 * row["vx_in_se_m_s"] + 1e-6
        assert abs(row["vx_out_m_s"] - vx_out) < 3 * row["vx_out_se_m_s"] + 1e-6
        assert abs(row["tangential_ratio"] - ratio) < 3 * row["tangential_ratio_se"]
        assert abs(row["delta_vx_m_s"] - (vx_out - vx_in)) < 3 * row["delta_vx_se_m_s"] + 1e-6
        theta_in = np.degrees(np.arctan2(v_in, vx_in))  # above the floor
        theta_out = np.degrees(np.arctan2(E_SEED * v_in, vx_out))
        assert abs(row["theta_in_deg"] - theta_in) < 3 * row["theta_in_se_deg"] + 1e-6
        assert abs(row["theta_out_deg"] - theta_out) < 3 * row["theta_out_se_deg"] + 1e-6
        assert abs(row["e_tan_theta_in"] - E_SEED * v_in / vx_in) < 3 * row["e_tan_theta_in_se"]
        assert abs(row["tan_theta_out"] - E_SEED * v_in / vx_out) < 3 * row["tan_theta_out_se"]
        if ratio == 1.0:
            assert row["angle_check"] == "consistent: tangential velocity kept"
        else:
            lost = float(row["angle_check"].split("lost ")[1].split(" %")[0])
            assert row["angle_check"].endswith("%: friction or spin") and abs(lost - 20.0) < 1.0


def test_a_tracker_jump_in_x_is_left_out():
    """Three samples of x displaced by 0.2 m (a tracker on another object) move no vx: the flight's fit
    leaves them out."""
    t, y, x, _ = bounce_log()
    jumped = x.copy()
    jumped[40:43] += 0.2
    clean, moved = analysed(t, y, x), analysed(t, y, jumped)
    assert np.allclose(moved.impacts["vx_in_m_s"], clean.impacts["vx_in_m_s"], atol=1e-12)
    assert moved.analysis.summary["horizontal"]["n_samples"][0] == clean.analysis.summary["horizontal"]["n_samples"][0] - 3


def test_friction_spin_and_drag_against_refsim():
    """refsim's tennis ball (its own integration: Coulomb friction μ = 0.6 sets it spinning at the first
    impact, quadratic drag on the full velocity) thrown at 2 m/s: dropfit's vx before and after each of
    the first 5 impacts within 3 standard errors of refsim's, the drag k that x shows within 3 se of the
    ball's, the first impact's loss (35.5 %) named within 3 se, and no e moved by x."""
    ball = refsim.preset("tennis")
    truth = refsim.simulate(ball, 1.0, u0_m_s=2.0, g_m_s2=G, t_end_s=3.0)
    log = refsim.record.record(truth, 200.0, t_start_s=0.0, duration_s=2.9, noise_sd=1e-3, rng=1, horizontal=True)
    options = {"ball_radius_m": ball.radius_m, "ball_mass_kg": ball.mass_kg, "ball_type": "tennis", "floor_m": 0.0,
               "gravity_m_s2": G}
    time_s, y = log["time_s"].to_numpy(), log["y_m"].to_numpy()
    result = analyse_recording(make_trajectory(time_s, y, "refsim", "m", x_m=log["x_m"].to_numpy()), **options)
    impacts, true = result.impacts.iloc[:5], truth.impacts.iloc[:5]
    assert np.all(np.abs(impacts["vx_in_m_s"] - true["u_in_m_s"].to_numpy()) < 3 * impacts["vx_in_se_m_s"])
    assert np.all(np.abs(impacts["vx_out_m_s"] - true["u_out_m_s"].to_numpy()) < 3 * impacts["vx_out_se_m_s"])
    drag = result.analysis.summary["horizontal"]
    assert abs(drag["drag_k_per_m"] - ball.drag_k_1_m) < 3 * drag["drag_k_se_per_m"]
    true_ratio = true["u_out_m_s"].iloc[0] / true["u_in_m_s"].iloc[0]
    first = impacts.iloc[0]
    assert abs(first["tangential_ratio"] - true_ratio) < 3 * first["tangential_ratio_se"]
    assert first["angle_check"] == f"tangential velocity lost {100 * (1 - first['tangential_ratio']):.1f} %: friction or spin"
    vertical = analyse_recording(make_trajectory(time_s, y, "refsim", "m"), **options).impacts
    assert vertical["e"].tolist() == result.impacts["e"].tolist()


def test_horizontal_drift_never_biases_e():
    """The same vertical motion with no x, with x at rest, and with a ball moving at 3 m/s plus a drift:
    every column of the 1-D analysis is the same, and the 1-D one has no oblique columns."""
    t, y, x, _ = bounce_log(tangential_ratio=1.0, drift_m_s=0.4)
    plain = analysed(t, y)
    assert "vx_in_m_s" not in plain.impacts and "horizontal" not in plain.analysis.summary
    assert "horizontal_distance" not in plain.fit["theory"]
    for horizontal in (np.zeros_like(t), x):
        moving = analysed(t, y, horizontal)
        pd.testing.assert_frame_equal(moving.impacts[plain.impacts.columns], plain.impacts, rtol=1e-12)
        assert moving.fit["restitution"]["e"] == plain.fit["restitution"]["e"]
    still = analysed(t, y, np.random.default_rng(1).normal(0, 1e-3, t.size)).impacts
    assert all(check.startswith("not tested: no horizontal motion") for check in still["angle_check"])
    # x lost after 1 s: the impacts whose flights have it keep their numbers, the others say why not
    partial = analysed(t, y, np.where(t < 1.0, x, np.nan)).impacts
    assert partial["angle_check"].iloc[0] == "consistent: tangential velocity kept"
    assert np.isfinite(partial["vx_in_se_m_s"].iloc[1]) and np.isnan(partial["vx_out_m_s"].iloc[1])
    assert (partial["angle_check"].iloc[1:] == "not tested: too few x samples in the flights before and after").all()
    assert "vx_in_m_s" not in analysed(t, y, np.full_like(t, np.nan)).impacts


def write(path, text):
    path.write_text(text, encoding="utf-8")
    return path


def test_height_log_horizontal_column(tmp_path):
    """x_m, x_cm, x_mm, x_px (through the scale's size) into the trajectory's x in m; empty cells NaN."""
    rows = "\n".join(f"{0.01 * i:.2f},{100 - i},{12.5 * i}" for i in range(5))
    for unit, factor in (("cm", 0.01), ("mm", 0.001), ("m", 1.0)):
        trajectory = trajectory_from_log(write(tmp_path / f"{unit}.csv", f"time_s,y_cm,x_{unit}\n{rows}\n"))
        assert np.allclose(trajectory["x"].values, factor * 12.5 * np.arange(5))
        assert trajectory["x"].attrs["units"] == "m"
    trajectory = trajectory_from_log(write(tmp_path / "px.csv", f"time_s,y_px,x_px\n{rows}\n"), scale_m_per_px=0.002)
    assert np.allclose(trajectory["x"].values, 0.002 * 12.5 * np.arange(5))
    gap = trajectory_from_log(write(tmp_path / "gap.csv", "time_s,y_m,x_m\n0,1,0.1\n0.01,0.99,\n"))
    assert np.isnan(gap["x"].values[1]) and gap["quality"].values.tolist() == [0, 0]
    assert "x" not in trajectory_from_log(write(tmp_path / "1d.csv", "time_s,y_m\n0,1\n0.01,0.99\n"))
    assert read_height_log(tmp_path / "1d.csv", horizontal=True)[3:] == (None, None)


@pytest.mark.parametrize("text, message", [
    ("time_s,y_m,x_m,x_cm\n0,1,0,0\n", "keep one of them"),
    ("time_s,y_m,x_in\n0,1,0\n", "x_in has a unit dropfit does not read"),
    ("time_s,y_m,x_m\n0,1,abc\n", "x_m"),
    ("time_s,y_m,x_m\n0,1,inf\n", "x_m is infinite in data row 1"),
    ("time_s,y_m,x_px\n0,1,3\n", "column x_px needs a scale"),
    ("time_s,y_mm,x_m\n0,1000,3000\n", "column x_m reaches 3e\\+03 m from its zero"),
])
def test_bad_horizontal_column(tmp_path, text, message):
    """Each bad horizontal column gets one line naming the file."""
    path = write(tmp_path / "bad.csv", text)
    with pytest.raises(InputError, match=message) as error:
        trajectory_from_log(path)
    assert "bad.csv" in str(error.value) and "\n" not in str(error.value)


def example3_row():
    config = yaml.safe_load((REPO / "config" / "config.yaml").read_text(encoding="utf-8"))
    sheet = pd.read_csv(REPO / "config" / "samples.tsv", sep="\t", comment="#").set_index("sample_id", drop=False)
    return config, sheet.loc[EXAMPLE3]


def test_seed_example3_data_is_refsims(tmp_path):
    """The committed recording is what the workflow's rule (python -m refsim) writes."""
    subprocess.run([sys.executable, "-m", "refsim", EXAMPLE3, str(tmp_path / "log.csv")], cwd=REPO, check=True,
                   timeout=120)
    assert (tmp_path / "log.csv").read_bytes() == (REPO / "data" / "synthetic" / f"{EXAMPLE3}.csv").read_bytes()


def test_seed_example3_reproduced_with_the_workflows_settings(monkeypatch):
    """The seed's Example 3, simulated by refsim and analysed as the workflow analyses its sample (config
    and sample row): its peaks, t∞, u t∞ and e (:func:`helpers.check_seed_example3`); the report's
    section on oblique bounces."""
    config, row = example3_row()
    ball, settings = settings_from_config(config, row)
    monkeypatch.chdir(REPO)
    # the workflow makes results/synthetic/<name>.csv with refsim; the committed copy is the same bytes
    recording = REPO / "data" / "synthetic" / Path(row["path"]).name
    result = analyse_recording(recording, ball_radius_m=ball.radius_m, ball_mass_kg=ball.mass_kg,
                               ball_type=ball.type, sample_id=EXAMPLE3, settings=settings)
    impacts, fit = result.impacts, result.fit
    check_seed_example3(impacts, fit)
    html = recording_report_html(result.trajectory, result.flights, impacts, fit, b"png", path_png=b"path")
    assert "Oblique bounces (2-D motion)" in html and 'alt="path y(x)"' in html
    assert "consistent: tangential velocity kept" in html
