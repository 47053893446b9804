"""Batch QC statistics against hand-computed examples and seeded coverage trials."""

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

from dropfit.batch import ball_rows, batch_statistics, failed_recordings, mean_over_drops
from dropfit.report import BATCH_COLUMNS, batch_rows, extras_png, numeric_extras, sample_sheet_extras

REPO = Path(__file__).resolve().parents[1]

#: Student's t quantiles t(0.975, dof) from printed tables, for 1 and 2 degrees of freedom.
T975 = {1: 12.706, 2: 4.303}
#: Agreement of hand-computed heights with the functions' results.
HEIGHT_TOL_M = 1e-9  # m
#: Seeded coverage trials of the ball-mean 95 % interval, and the half-width of the accepted band
#: (about 2.5 binomial standard errors of a 95 % coverage in that many trials).
COVERAGE_TRIALS = 4000
COVERAGE_TOL = 0.009


def recordings_table(rows):
    """Per-recording table as the QC stage builds it: (sample_id, ball_id, rebound m, se m, e, e_se, error)."""
    table = pd.DataFrame(rows, columns=["sample_id", "ball_id", "itf_rebound_m", "itf_rebound_se_m", "e", "e_se",
                                        "error"])
    table["status"] = np.where(table["error"].isna(), "ok", "failed")
    return table


def test_mean_of_three_drops_takes_the_scatter_and_student_t():
    result = mean_over_drops([1.40, 1.41, 1.42], [0.001, 0.001, 0.001])
    # sd = 0.01 m, se = 0.01/√3 = 0.0057735 m > √3·0.001/3 = 0.00057735 m (measurement)
    assert result["value"] == pytest.approx(1.41, abs=HEIGHT_TOL_M)
    assert result["sd_between_drops"] == pytest.approx(0.01, abs=HEIGHT_TOL_M)
    assert result["se"] == pytest.approx(0.0057735, abs=1e-7)
    assert result["se_from"] == "drop-to-drop scatter"
    assert result["ci95"][1] - result["value"] == pytest.approx(T975[2] * 0.0057735, rel=1e-3)
    assert result["n"] == 3


def test_mean_never_claims_less_than_the_measurement_error():
    # two identical drops: no scatter, but each is only known to 1 cm
    result = mean_over_drops([1.40, 1.40], [0.01, 0.01])
    assert result["se"] == pytest.approx(0.01 / np.sqrt(2), abs=HEIGHT_TOL_M)
    assert result["se_from"] == "measurement"
    assert result["ci95"][1] - result["value"] == pytest.approx(T975[1] * 0.01 / np.sqrt(2), rel=1e-3)


def test_one_drop_keeps_its_own_error_and_missing_drops_are_left_out():
    result = mean_over_drops([np.nan, 1.43], [np.nan, 0.002])
    assert result["n"] == 1 and np.isnan(result["sd_between_drops"])
    assert result["se"] == pytest.approx(0.002)
    assert result["ci95"] == pytest.approx([1.43 - 1.959964 * 0.002, 1.43 + 1.959964 * 0.002], abs=1e-7)
    assert mean_over_drops([np.nan], [np.nan]) is None


def test_ball_interval_covers_the_true_mean_95_percent_of_the_time():
    """Seeded trials: balls of true mean rebound 1.41 m, drop-to-drop sd 6 mm, 0.2 mm measurement noise.

    The t interval covers the truth 95 % of the time; a normal interval on the same se would cover it
    about 81 % of the time (t with 2 dof: P(|T| < 1.96) = 1.96/√(2 + 1.96²) = 0.811).
    """
    rng = np.random.default_rng(20261121)
    true_mean, drop_sd, noise = 1.41, 0.006, 0.0002  # m
    covered = covered_normal = 0
    for _ in range(COVERAGE_TRIALS):
        drops = true_mean + rng.normal(0, drop_sd, 3) + rng.normal(0, noise, 3)
        result = mean_over_drops(drops, np.full(3, noise))
        covered += result["ci95"][0] <= true_mean <= result["ci95"][1]
        covered_normal += abs(result["value"] - true_mean) <= 1.959964 * result["se"]
    assert covered / COVERAGE_TRIALS == pytest.approx(0.95, abs=COVERAGE_TOL)
    assert covered_normal / COVERAGE_TRIALS == pytest.approx(0.811, abs=2 * COVERAGE_TOL)


@pytest.fixture
def lot():
    """Tennis balls A (pass), B (fail, one failed drop), C (at the upper limit), a steel ball S and a
    ball D whose only drop failed. Rebound heights in m."""
    return recordings_table([
        ("a1", "A", 1.40, 0.0005, 0.770, 0.001, None),
        ("a2", "A", 1.41, 0.0005, 0.772, 0.001, None),
        ("a3", "A", 1.42, 0.0005, 0.774, 0.001, None),
        ("b1", "B", 1.30, 0.0005, 0.745, 0.001, None),
        ("b2", "B", 1.31, 0.0005, 0.747, 0.001, None),
        ("b3", "B", 1.32, 0.0005, 0.749, 0.001, None),
        ("b4", "B", np.nan, np.nan, np.nan, np.nan, "b4.csv: no bounce found"),
        ("c1", "C", 1.465, 0.0005, 0.790, 0.001, None),
        ("c2", "C", 1.475, 0.0005, 0.792, 0.001, None),
        ("s1", "S", np.nan, np.nan, 0.92, 0.001, None),
        ("d1", "D", np.nan, np.nan, np.nan, np.nan, "d1.csv: the file is empty"),
    ])


def test_ball_verdicts_and_spreads(lot):
    balls = ball_rows(lot).set_index("ball_id")
    # A: 1.41 ± 4.303·0.0057735 = [1.3852, 1.4348] m inside; B: 1.31 m, [1.2852, 1.3348] m below 1.35 m;
    # C: 1.47 ± 12.706·0.005 m straddles 1.47 m
    assert balls["itf_verdict"].to_dict() == {"A": "pass", "B": "fail", "C": "indeterminate",
                                              "S": "not applicable", "D": "not analysed"}
    assert balls.loc["B", ["n_drops", "n_failed"]].tolist() == [3, 1]
    assert balls.loc["B", "rebound_m"] == pytest.approx(1.31, abs=HEIGHT_TOL_M)
    assert balls.loc["B", "rebound_ci95_high_m"] == pytest.approx(1.31 + T975[2] * 0.01 / np.sqrt(3), rel=1e-4)
    assert balls.loc["C", "rebound_sd_between_drops_m"] == pytest.approx(0.01 / np.sqrt(2), abs=HEIGHT_TOL_M)
    assert balls.loc["C", "rebound_se_m"] == pytest.approx(0.005, abs=HEIGHT_TOL_M)
    assert balls.loc["A", "e"] == pytest.approx(0.772, abs=1e-12)
    assert balls.loc["A", "e_sd_between_drops"] == pytest.approx(0.002, abs=1e-12)
    assert balls.loc["S", "e"] == pytest.approx(0.92) and np.isnan(balls.loc["S", "rebound_m"])


def test_batch_statistics_and_control_limits(lot):
    balls = ball_rows(lot)
    statistics = batch_statistics(balls)
    means = np.array([1.41, 1.31, 1.47])  # m, balls A, B, C
    assert statistics["n_balls"] == 5 and statistics["n_balls_measured"] == 3
    assert statistics["verdict_counts"] == {"pass": 1, "fail": 1, "indeterminate": 1, "not applicable": 1,
                                            "not analysed": 1}
    assert statistics["rebound_mean_m"] == pytest.approx(means.mean(), abs=HEIGHT_TOL_M)
    assert statistics["rebound_sd_between_balls_m"] == pytest.approx(means.std(ddof=1), abs=HEIGHT_TOL_M)
    # pooled: A and B have sd 0.01 m with 2 dof each, C has sd 0.01/√2 m with 1 dof
    pooled = np.sqrt((2 * 0.01 ** 2 + 2 * 0.01 ** 2 + 0.01 ** 2 / 2) / 5)
    assert statistics["within_balls_dof"] == 5
    assert statistics["rebound_sd_within_balls_m"] == pytest.approx(pooled, abs=HEIGHT_TOL_M)
    assert statistics["control_low_m"] == pytest.approx(means.mean() - 3 * means.std(ddof=1), abs=HEIGHT_TOL_M)
    assert statistics["control_high_m"] == pytest.approx(means.mean() + 3 * means.std(ddof=1), abs=HEIGHT_TOL_M)
    assert statistics["out_of_control"] == []  # three balls 8 cm apart: ±3 sd spans 1.13 m to 1.65 m


def test_control_limits_flag_a_ball_far_from_a_consistent_lot():
    # eight balls within ±1 cm of 1.41 m (one drop each) and one at 1.25 m
    rebounds = [1.40, 1.41, 1.42, 1.405, 1.415, 1.41, 1.40, 1.42, 1.25]  # m
    balls = ball_rows(recordings_table([(f"r{i}", f"B{i}", h, 0.001, 0.77, 0.001, None)
                                        for i, h in enumerate(rebounds)]))
    statistics = batch_statistics(balls)
    assert statistics["out_of_control"] == []  # phase I: the far ball widens the limits it is judged by
    clean = batch_statistics(balls.iloc[:8])
    assert clean["control_low_m"] == pytest.approx(np.mean(rebounds[:8]) - 3 * np.std(rebounds[:8], ddof=1))
    assert clean["control_low_m"] > 1.25  # the lot without it excludes the far ball
    # single drops: no drop-to-drop spread, no pooled sd
    assert np.isnan(statistics["rebound_sd_within_balls_m"]) and statistics["within_balls_dof"] == 0


def test_one_ball_has_no_control_limits():
    statistics = batch_statistics(ball_rows(recordings_table([("x", "X", 1.40, 0.001, 0.77, 0.001, None)])))
    assert np.isnan(statistics["control_low_m"]) and statistics["out_of_control"] == []


def test_failed_recordings_keep_their_reason(lot):
    failed = failed_recordings(lot)
    assert failed.to_dict("records") == [
        {"sample_id": "b4", "ball_id": "B", "reason": "b4.csv: no bounce found"},
        {"sample_id": "d1", "ball_id": "D", "reason": "d1.csv: the file is empty"},
    ]


# --- the sample sheet's free columns in the summary ---------------------------------------------------

def test_sample_sheet_extras_are_the_columns_the_workflow_schema_does_not_name():
    """Every column of the workflow's sample-sheet schema is the workflow's; any other is carried, numbers
    as numbers (empty = NaN), text as text, one named as a summary column renamed."""
    schema = yaml.safe_load((REPO / "workflow" / "schemas" / "samples.schema.yaml").read_text(encoding="utf-8"))
    workflow = {name: ["1", "2"] for name in schema["properties"]}
    free = {"surface": ["concrete", ""], "temperature_C": ["21.5", " "], "e": ["high", "low"]}
    sheet = pd.DataFrame({**workflow, **free, "sample_id": ["a", "b"]}, dtype=str)
    extras = sample_sheet_extras(sheet)
    assert list(extras.columns) == ["surface", "temperature_C", "e (sample sheet)"]
    assert list(extras.index) == ["a", "b"]
    assert extras.loc["a", "surface"] == "concrete" and pd.isna(extras.loc["b", "surface"])
    assert extras.loc["a", "temperature_C"] == 21.5 and np.isnan(extras.loc["b", "temperature_C"])
    table = batch_rows([{"status": "failed", "error": "x", "sample_id": "b"},
                        {"status": "failed", "error": "y", "sample_id": "not_in_sheet"}], extras)
    assert table["surface"].isna().all()
    assert table["e (sample sheet)"].tolist()[0] == "low"
    assert numeric_extras(table) == []  # temperature only for a, which is not in the table
    table = batch_rows([{"status": "failed", "error": "x", "sample_id": "a"}], extras)
    assert numeric_extras(table) == ["temperature_C"]


def test_e_against_the_sheet_s_numbers_is_a_png_with_or_without_them():
    table = pd.DataFrame({"status": ["ok", "ok", "failed"], "e": [0.75, 0.76, np.nan], "e_ci95_low": [0.74, 0.75, np.nan],
                          "e_ci95_high": [0.76, 0.77, np.nan]}).reindex(columns=BATCH_COLUMNS)
    with_numbers = table.assign(temperature_C=[20.0, 25.0, 30.0], surface=["a", "b", "c"])
    for frame in (table, with_numbers):
        assert extras_png(frame).startswith(b"\x89PNG\r\n\x1a\n")


@pytest.mark.parametrize("config, said", [
    ({"analysis": "text"}, "analysis is 'text', not a mapping of its options"),
    ({"analysys": {"drag": "on"}}, "'analysys' is not a key dropfit reads; did you mean analysis?"),
    ({"itf": {"rebound_min": 1.35}}, "'itf.rebound_min' is not a key dropfit reads; did you mean rebound_min_m?"),
])
def test_a_batch_config_that_cannot_apply_is_refused(config, said):
    """``dropfit batch --config '{"analysis": "text"}'`` ran as if no config had been given."""
    from dropfit.errors import InputError
    from dropfit.settings import check_config

    with pytest.raises(InputError, match="--config: ") as refusal:
        check_config(config)
    assert said in str(refusal.value)


def test_the_workflow_config_and_its_schema_pass_the_batch_check():
    """Every key of the workflow's schema is one the check knows, and the shipped config passes it."""
    from dropfit.settings import OPTIONS, WORKFLOW_ONLY_KEYS, check_config

    root = Path(__file__).resolve().parents[1]
    schema = yaml.safe_load((root / "workflow" / "schemas" / "config.schema.yaml").read_text(encoding="utf-8"))
    known = {option.config[0] for option in OPTIONS.values() if option.config} | set(WORKFLOW_ONLY_KEYS)
    assert set(schema["properties"]) == known
    check_config(yaml.safe_load((root / "config" / "config.yaml").read_text(encoding="utf-8")))
