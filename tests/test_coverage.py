"""Coverage of the reported 95 % intervals over seeded synthetic logs and videos (issue 5, item 1).

Every quantity the analysis and the fit report (per impact e, speeds, rebound heights and contact
times; per recording the drop height, constant e, the e(v) law, the drag parameter, k, c and the
predicted 254 cm rebound) is paired with the generator's truth; its 95 % interval must cover the
truth in 90–98 % of the pairs. benchmarks/coverage.py runs the same with 200 logs per scenario
(and, with --videos, the same 200 clips).
"""

import numpy as np
import pandas as pd
import pytest

from dropfit.coverage import SCENARIOS, coverage_table, log_trial, video_trial
from dropfit.errors import InputError

COVERAGE_MIN, COVERAGE_MAX = 0.90, 0.98  # fraction of 95 % intervals that cover the truth
# 1200 logs in all. The e(v) law's parameters cover 96.5–97 % (over 800 logs; a law that misfits is
# widened by its Birge ratio), so 200 pairs per law would put the band's 98 % edge only 1.2 binomial
# sd away; the 400 pairs of the two scenarios with a falling e put it 1.7 sd away.
LOGS_PER_SCENARIO = 200
VIDEOS = 200  # small clips, about 0.2 s each on a quiet core (rendering dominates)
MIN_PAIRS = 70  # a coverage from fewer pairs is too noisy to test against the 90–98 % band
VIDEO_BIAS_MAX = 0.6  # largest |mean (value − truth)/se| of the video quantities (200 clips: 0.17, 0.02)
# clips of the 200 dropfit may refuse: none (seed 48's release was read 0.4 s late, from a fit whose σ
# came from a few residuals closer to its parabola than the noise, and the clip was refused for "6 clean
# frames before impact 1")
VIDEOS_REFUSED_MAX = 0
VIDEOS_FLOOR_FOUND = 40  # clips with the floor found in the image (their intervals cover none: 40 are plenty)
CHOICE_MIN = 0.95  # fraction of logs in which the generating (or simpler) model must be chosen


@pytest.fixture(scope="module")
def log_trials():
    pairs, choices = [], []
    for name, scenario in SCENARIOS.items():
        for seed in range(LOGS_PER_SCENARIO):
            table, fitted = log_trial(scenario, seed)
            pairs.append(table.assign(scenario=name))
            rebound = fitted["itf"].get("rebound_m")
            choices.append({"scenario": name, "drag": fitted["drag"]["model"], "law": fitted["restitution"]["model"],
                            "itf_method": rebound and rebound["method"].split()[0]})
    return pd.concat(pairs), pd.DataFrame(choices)


@pytest.mark.slow
def test_every_quantity_is_covered_90_to_98_percent(log_trials):
    table = coverage_table(log_trials[0].drop(columns="scenario"))
    table = table[table["n"] >= MIN_PAIRS]
    expected = {"e", "v_in_m_s", "v_out_m_s", "h_after_m", "t_contact_s", "drop_height_m", "e_constant",
                "e_linear_e0", "e_linear_slope_s_m", "drag_k_per_m", "stiffness_n_m", "damping_n_s_m",
                "itf_rebound_m"}
    assert expected <= set(table["quantity"])
    outside = table[(table["coverage"] < COVERAGE_MIN) | (table["coverage"] > COVERAGE_MAX)]
    assert outside.empty, outside.to_string()


@pytest.mark.slow
def test_per_impact_e_is_covered_in_every_scenario(log_trials):
    table = coverage_table(log_trials[0])
    e = table[table["quantity"] == "e"]
    assert len(e) == len(SCENARIOS)
    assert e["coverage"].between(COVERAGE_MIN, COVERAGE_MAX).all(), e.to_string()


@pytest.mark.slow
def test_the_generating_models_are_chosen(log_trials):
    choices = log_trials[1].groupby("scenario")
    expected = {"tennis_drag_150cm": (None, "constant"), "tennis_e_falls_120cm": (None, "linear"),
                "steel_weak_drag": ("nominal", "constant"), "rubber_no_drag": ("none", "constant"),
                "rubber_e_falls": ("none", "linear")}
    for name, (drag, law) in expected.items():
        rows = choices.get_group(name)
        if drag:
            assert np.mean(rows["drag"] == drag) >= CHOICE_MIN, name
        assert np.mean(rows["law"] == law) >= CHOICE_MIN, name
    # from drops other than 254 cm the ITF rebound is predicted, never taken from the measured one
    for name in ("tennis_drag_150cm", "tennis_e_falls_120cm"):
        assert (choices.get_group(name)["itf_method"] == "predicted").all()


def video_trials(directory, seeds, floor_known=True):
    """The coverage table of the clips dropfit analyses, and (seed, message) of those it refuses."""
    pairs, refused = [], []
    for seed in seeds:
        try:
            pairs.append(video_trial(seed, directory, floor_known=floor_known))
        except InputError as error:
            refused.append((seed, str(error)))
    return coverage_table(pd.concat(pairs)), refused


@pytest.fixture(scope="module")
def video_coverage(tmp_path_factory):
    return video_trials(tmp_path_factory.mktemp("clips"), range(VIDEOS))


@pytest.mark.slow
def test_video_intervals_cover_the_truth_90_to_98_percent(video_coverage):
    table, refused = video_coverage
    print(f"\n[coverage] videos ({len(refused)} refused: {refused}):\n" + table.to_string())
    assert set(table["quantity"]) == {"e", "h_after_m"}
    assert (table["n"] >= MIN_PAIRS).all()
    assert table["coverage"].between(COVERAGE_MIN, COVERAGE_MAX).all(), table.to_string()
    assert (table["mean_z"].abs() < VIDEO_BIAS_MAX).all(), table.to_string()
    assert len(refused) <= VIDEOS_REFUSED_MAX, refused


@pytest.mark.slow
def test_video_intervals_cover_the_truth_with_the_floor_found_in_the_image(tmp_path):
    table, _ = video_trials(tmp_path, range(VIDEOS_FLOOR_FOUND), floor_known=False)
    print("\n[coverage] videos, floor found in the image:\n" + table.to_string())
    assert table["coverage"].between(COVERAGE_MIN, COVERAGE_MAX).all(), table.to_string()
