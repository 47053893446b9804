"""Coverage of the 95 % intervals against refsim, a generator written independently of dropfit.synth.

refsim integrates the flights *and* the contacts (Hertz–Kuwabara–Kono, Hunt–Crossley and linear
contact laws, so e falls with the impact speed and every contact lasts 0.1–10 ms), with quadratic
drag in every phase; its logs follow the ball's centre or its bottom, in m, mm or image rows. The
trials, their scenarios and the harness are in ``refsim_trials.py`` (shared with
``benchmarks/refsim_coverage.py``, which runs the same at 200 recordings per scenario).
"""

import numpy as np
import pandas as pd
import pytest

import refsim_trials as rt

COVERAGE_MIN, COVERAGE_MAX = 0.90, 0.98

# ------------------------------------------------------------------------------------------------
# The slow test
# ------------------------------------------------------------------------------------------------
#: Recordings per scenario in the slow test, each analysed with the floor given and with it unknown.
#: Chosen from the benchmark's impacts per recording so that every asserted cell gets at least
#: MIN_PAIRS pairs; see test_refsim_intervals_cover_the_truth for the spread that buys.
TRIALS = {
    "tennis_100hz": 65,
    "tennis_500hz": 100,
    "steel_500hz": 78,
    "rubber_200hz": 58,
    "table_tennis_100_200hz": 35,
    "marble_px_200fps": 32,
    "tennis_bottom_1_2khz": 45,
}
#: A cell with fewer pairs than this fails: its coverage would be too noisy to test against the band.
MIN_PAIRS = 540
#: Cells whose error is one offset shared by every recording, so that their intervals cover the truth
#: either nearly always or nearly never: the 98 % bound, a test of statistical calibration, does not
#: apply; the offset must lie within the budget (|mean z| below SHARED_OFFSET_MAX_Z). A tennis ball
#: logged at 1–2 kHz to 0.05–0.2 mm with the floor unknown: the contact height then rests on the
#: shape of the contact-time law (dropfit.analysis.impacts.CONTACT_TIME_CURVATURE_SE), the same
#: Hertz–Kuwabara–Kono law in every recording (measured: coverage 99–100 %, mean z 0.73–0.85,
#: sd of z 0.22–0.51; without the law's share, 7–51 % at mean z 2.1–5.0).
SHARED_OFFSET_CELLS = {("tennis_bottom_1_2khz", "unknown")}
SHARED_OFFSET_MAX_Z = 1.0
#: At most this fraction of the recordings of a scenario may be refused (each refusal names its reason).
MAX_FAILED_FRACTION = 0.05


@pytest.fixture(scope="module")
def refsim_trials_run(tmp_path_factory):
    """All trials of :data:`TRIALS`, run on two worker processes."""
    directory = tmp_path_factory.mktemp("refsim")
    # interleaved, so that the two workers finish together
    jobs = [(name, seed) for seed in range(max(TRIALS.values())) for name, n in TRIALS.items() if seed < n]
    pairs, recordings = rt.run_trials(jobs, workers=2, directory=directory)
    return pairs, recordings, rt.coverage_table(pairs)


@pytest.mark.slow
@pytest.mark.parametrize("name", list(TRIALS))
def test_refsim_intervals_cover_the_truth(refsim_trials_run, name):
    """Per impact e, rebound height h_after_m, v_in and v_out: 90–98 % of the 95 % intervals cover
    refsim's truth, with the floor given and with it unknown (8 cells per scenario).

    Why these trial counts: a cell of n independent pairs whose intervals truly cover 95 % has a
    binomial spread of √(0.95 · 0.05 / n), 0.94 % at n = MIN_PAIRS = 540, which puts the band's 98 %
    edge 3.2 sd above 95 % and its 90 % edge 5.3 sd below. The impacts of one recording share its
    flights, noise and drag, so their pairs are not independent: with the recordings as clusters the
    benchmark (benchmarks/refsim_coverage.py, 200 recordings per scenario) measured design effects of
    0.9–1.9 in the cells where dropfit is calibrated, a spread of up to 1.29 % at 540 pairs: the 98 %
    edge stays ≥ 2.3 sd away (a calibrated cell fails by chance with probability ≤ 1.1 %) and the 90 %
    edge ≥ 3.9 sd. TRIALS gives every cell 585–600 pairs on average (the analysed impacts per
    recording range from 5.9, a tennis ball at 500 Hz with the floor unknown, to 19, the marble), so
    that a cell falls below MIN_PAIRS only if dropfit analyses fewer impacts than it does today. The
    test took 3.2 minutes on two cores that other jobs shared (load average 2.5–3.5): refsim 0.2–1 s per recording,
    dropfit 0.1–0.7 s per analysis, both analyses of a recording sharing its simulation.
    """
    pairs, recordings, table = refsim_trials_run
    cells = table[(table["scenario"] == name) & table["quantity"].isin(rt.ASSERTED_QUANTITIES)]
    expected = {(floor, quantity) for floor in rt.FLOOR_CONDITIONS for quantity in rt.ASSERTED_QUANTITIES}
    assert set(zip(cells["floor"], cells["quantity"])) == expected, \
        f"{name}: cells without a single pair: {expected - set(zip(cells['floor'], cells['quantity']))}"
    upper = cells["coverage"] > COVERAGE_MAX
    if (name, "unknown") in SHARED_OFFSET_CELLS:
        # a shared offset within its budget: covered, and its mean z well inside ±1
        shared = cells["floor"] == "unknown"
        upper = upper & ~(shared & (cells["mean_z"].abs() < SHARED_OFFSET_MAX_Z))
    bad = cells[(cells["n"] < MIN_PAIRS) | (cells["coverage"] < COVERAGE_MIN) | upper]
    assert bad.empty, (f"{name}: cells outside {COVERAGE_MIN:.0%}–{COVERAGE_MAX:.0%} (or with fewer than {MIN_PAIRS} "
                       f"pairs):\n{bad.to_string(index=False, float_format=lambda x: f'{x:.4g}')}")


@pytest.mark.slow
@pytest.mark.parametrize("name", list(TRIALS))
def test_refsim_recordings_are_analysed(refsim_trials_run, name):
    """At most 5 % of each scenario's recordings are refused, with the floor given or unknown, and none
    by a crash; every analysed impact belongs to a simulated one."""
    pairs, recordings, table = refsim_trials_run
    rows = recordings[recordings["scenario"] == name]
    failed = rows[rows["status"] == "failed"]
    crashed = failed[failed["message"].str.startswith("internal error")]
    assert crashed.empty, crashed[["seed", "floor", "stage", "message"]].to_string(index=False)
    for floor, group in rows.groupby("floor"):
        refused = group[group["status"] == "failed"]
        assert len(refused) <= MAX_FAILED_FRACTION * len(group), \
            f"{name}, floor {floor}: {len(refused)} of {len(group)} recordings failed:\n" + \
            refused[["seed", "stage", "message"]].to_string(index=False)
    assert (rows["n_unmatched"] == 0).all(), \
        rows.loc[rows["n_unmatched"] > 0, ["seed", "floor", "n_analysed", "n_unmatched"]].to_string()


# ------------------------------------------------------------------------------------------------
# Fast checks of the harness itself
# ------------------------------------------------------------------------------------------------
def _true_table(touchdowns, contact_s=0.005):
    touchdowns = np.asarray(touchdowns, dtype=float)
    return pd.DataFrame({"t_touchdown_s": touchdowns, "t_liftoff_s": touchdowns + contact_s})


def test_impacts_are_matched_by_touchdown_time():
    truth = _true_table([0.45, 1.25, 1.85, 2.30])  # flights of 0.45, 0.8, 0.6, 0.45 s
    # within 0.3 of the shorter neighbouring flight; a touchdown mid-flight matches nothing
    match = rt.match_impacts([0.452, 1.26, 1.55, 2.33], truth, t_release_s=0.0)
    np.testing.assert_array_equal(match, [0, 1, -1, 3])
    # a simulated impact claimed twice keeps the nearer analysed touchdown
    np.testing.assert_array_equal(rt.match_impacts([1.24, 1.253], truth, 0.0), [-1, 1])
    # later impacts are found whatever the earlier ones (a missed bounce shifts nothing)
    np.testing.assert_array_equal(rt.match_impacts([1.851], truth, 0.0), [2])
    assert rt.match_impacts([0.5], _true_table([]), 0.0).tolist() == [-1]


def test_pairs_take_value_se_and_truth_from_the_matched_rows():
    truth = pd.DataFrame({"e": [0.8, 0.7], "h_after_m": [0.5, 0.3], "v_in_m_s": [4.0, 3.1],
                          "v_out_m_s": [3.2, 2.17], "contact_time_s": [0.005, 0.0052]})
    impacts = pd.DataFrame({"impact": [1, 2, 3], "e": [0.71, 0.9, 0.79], "e_se": [0.01, 0.1, 0.01],
                            "h_after_m": [0.31, 0.0, 0.49], "h_after_se_m": [0.002, 1.0, 0.003],
                            "v_in_m_s": [3.0, 0.0, 4.1], "v_in_se_m_s": [0.05, 1.0, 0.02],
                            "v_out_m_s": [2.2, 0.0, 3.3], "v_out_se_m_s": [0.04, 1.0, 0.03],
                            "t_contact_ms": [5.3, 0.0, 4.9], "t_contact_se_ms": [0.2, 1.0, 0.1],
                            "contact_resolvable": [True, True, False]})
    pairs = rt.impact_pairs(impacts, truth, np.array([1, -1, 0]), floor_given=True)
    assert sorted(pairs["impact"].unique()) == [1, 3]  # the unmatched impact 2 is not paired
    first = pairs[pairs["impact"] == 1].set_index("quantity")
    assert first.loc["e", ["value", "se", "truth"]].tolist() == [0.71, 0.01, 0.7]
    assert first.loc["t_contact_s", "truth"] == 0.0052 and first.loc["t_contact_s", "value"] == pytest.approx(0.0053)
    assert (first["true_impact"] == 2).all()
    third = pairs[pairs["impact"] == 3].set_index("quantity")
    assert "t_contact_s" not in third.index  # not resolvable
    assert third.loc["h_after_m", "truth"] == 0.5
    # without the floor, contact times are never paired
    assert "t_contact_s" not in set(rt.impact_pairs(impacts, truth, np.array([1, -1, 0]), False)["quantity"])
    # a truth refsim does not have (a rebound whose apex was never simulated) is a harness error
    with pytest.raises(ValueError, match="no truth"):
        rt.impact_pairs(impacts, truth.assign(h_after_m=[0.5, np.nan]), np.array([1, -1, 0]), False)


def test_coverage_table_counts_and_clusters():
    pairs = pd.DataFrame({"scenario": "s", "floor": "given", "quantity": "e", "seed": [0, 0, 1, 1],
                          "value": [1.0, 1.0, 1.0, 1.0], "se": [1.0, 1.0, 1.0, 1.0], "truth": [1.5, 0.0, 3.5, 1.0]})
    row = rt.coverage_table(pairs).iloc[0]
    assert (row["n"], row["n_recordings"], row["coverage"]) == (4, 2, 0.75)
    assert row["mean_z"] == pytest.approx(np.mean([-0.5, 1.0, -2.5, 0.0]))
    # recording 0 covers 2/2, recording 1 1/2: cluster se of 3/4 from the residuals 0.5 and -0.5
    assert row["coverage_se"] == pytest.approx(np.sqrt(2 * 0.5) / 4)


def test_trials_are_seeded_and_drawn_within_the_scenario():
    first, again, other = rt.draw("tennis_100hz", 3), rt.draw("tennis_100hz", 3), rt.draw("tennis_100hz", 4)
    assert first == again and first != other
    assert first != rt.draw("tennis_500hz", 3)  # each scenario its own stream
    scenario = rt.SCENARIOS["tennis_100hz"]
    assert scenario.drop_height_m[0] <= first["drop_height_m"] <= scenario.drop_height_m[1]
    assert rt.GRAVITY_RANGE_M_S2[0] <= first["gravity_m_s2"] <= rt.GRAVITY_RANGE_M_S2[1]


def test_one_trial_matches_and_pairs_every_analysed_impact(tmp_path):
    """One tennis recording at 100 Hz end to end: the analysed impacts are the first simulated ones, in
    order, each paired with refsim's own numbers, and the contact time is not paired at 100 Hz."""
    result = rt.trial("tennis_100hz", 0, directory=tmp_path, floors=("given",))
    info = result.recordings[0]
    assert info["status"] == "ok", info["message"]
    assert 5 <= info["n_analysed"] <= info["n_simulated"]
    assert info["n_matched"] == info["n_analysed"] and info["n_unmatched"] == 0
    pairs = result.pairs
    assert set(pairs["quantity"]) == set(rt.ASSERTED_QUANTITIES)  # 100 Hz resolves no 5 ms contact
    assert (pairs["impact"] == pairs["true_impact"]).all()  # nothing missed at the start
    truth = rt.simulate_recording("tennis_100hz", 0).truth.impacts  # the same seed simulates the same drop
    for quantity, (_, column) in rt.IMPACT_QUANTITIES.items():
        rows = pairs[pairs["quantity"] == quantity]
        assert len(rows) == info["n_matched"]
        np.testing.assert_array_equal(rows["truth"], truth[column].to_numpy()[rows["true_impact"] - 1])
        assert (rows["se"] > 0).all()
    # with the floor given the numbers are close: every |z| of this one recording is below 5
    z = (pairs["value"] - pairs["truth"]) / pairs["se"]
    assert (z.abs() < 5).all(), pairs.assign(z=z).to_string()
    assert list(pairs.columns) == rt.PAIR_COLUMNS and len(pairs) == 4 * info["n_matched"]
    assert not list(tmp_path.iterdir())  # the trial's files are removed
