"""Impacts the analysis leaves out (``in_fit`` false, with a ``note``) enter no fit of the fit stage:
marking an impact out must give the same restitution models, ITF prediction and contact k, c as
deleting it from the impacts table and from every covariance."""

import numpy as np
import pandas as pd
import pytest

from dropfit.analysis import analyse_bounces
from dropfit.contact import LinearContact
from dropfit.fitrecord import analysis_summary, fit_rows, fit_summary
from dropfit.settings import Settings
from dropfit.synth import sample_height_log, simulate_drop

RADIUS_M, MASS_KG = 0.0335, 0.057
LEFT_OUT = 1  # table position of the impact the analysis leaves out (impact 2)


@pytest.fixture(scope="module")
def contact_recording():
    """A 2 kHz log of a tennis ball on a spring–damper floor, the floor known: contact times resolved."""
    truth = simulate_drop(1.0, RADIUS_M, mass_kg=MASS_KG, contact_model=LinearContact(3e4, 8.2))
    log = sample_height_log(truth, np.random.default_rng(21), 2000.0, noise_m=1e-4, offset_m=0.0,
                            dropout_fraction=0.0)
    log = log[log["time_s"] < 2.6]
    result = analyse_bounces(log["time_s"], log["y_m"], contact_height_m=RADIUS_M)
    summary = analysis_summary(result, {"ball_mass_kg": MASS_KG, "ball_radius_m": RADIUS_M, "ball_type": "tennis"})
    return summary, result.impacts


def without_impact(summary, impacts, position):
    """The analysis as if impact ``position`` (table order) had never been there."""
    n = len(impacts)
    keep = np.delete(np.arange(n), position)
    both = np.concatenate([keep, n + keep])
    reduced = dict(summary)
    reduced["e_covariance"] = np.asarray(summary["e_covariance"])[np.ix_(keep, keep)].tolist()
    reduced["e_contact_covariance"] = np.asarray(summary["e_contact_covariance"])[np.ix_(both, both)].tolist()
    reduced["e_drag_covariance"] = np.asarray(summary["e_drag_covariance"])[keep].tolist()
    return reduced, impacts.iloc[keep].reset_index(drop=True)


def test_an_impact_left_out_enters_no_fit(contact_recording):
    summary, impacts = contact_recording
    assert impacts["contact_resolvable"].sum() >= 3 and len(impacts) >= 5  # the case is not trivial
    marked = impacts.copy()
    marked["in_fit"] = True
    marked.loc[LEFT_OUT, "in_fit"] = False
    marked["note"] = ""
    marked.loc[LEFT_OUT, "note"] = "e > 1: a hop the flights do not describe"
    marked.loc[LEFT_OUT, ["e", "t_contact_ms"]] = [1.3, 40.0]  # nonsense that must not reach any fit
    settings = Settings(itf_drop_height_m=2.0)  # a 1 m drop: the 2 m rebound is predicted
    with_mark = fit_summary(summary, marked, settings)
    without = fit_summary(*without_impact(summary, impacts, LEFT_OUT), settings)

    for name, model in without["restitution_models"].items():
        for parameter, value in model["parameters"].items():
            if parameter.startswith("e_"):
                continue  # per_impact names its parameters by impact number, which deleting shifts
            assert with_mark["restitution_models"][name]["parameters"][parameter]["value"] == pytest.approx(
                value["value"], rel=1e-12), (name, parameter)
            assert with_mark["restitution_models"][name]["parameters"][parameter]["se"] == pytest.approx(
                value["se"], rel=1e-9), (name, parameter)
    assert with_mark["restitution"]["model"] == without["restitution"]["model"]
    assert with_mark["itf"]["rebound_m"]["value"] == pytest.approx(without["itf"]["rebound_m"]["value"], rel=1e-12)
    assert with_mark["itf"]["rebound_m"]["se"] == pytest.approx(without["itf"]["rebound_m"]["se"], rel=1e-9)
    for name in ("stiffness_n_m", "damping_n_s_m"):
        assert with_mark["contact_model"][name]["value"] == pytest.approx(without["contact_model"][name]["value"],
                                                                         rel=1e-12)
        assert with_mark["contact_model"][name]["se"] == pytest.approx(without["contact_model"][name]["se"], rel=1e-9)
    assert with_mark["contact_model"]["n_impacts"] == without["contact_model"]["n_impacts"]

    restitution = with_mark["restitution"]
    assert restitution["n_impacts"] == len(impacts) - 1 and restitution["n_impacts_total"] == len(impacts)
    assert restitution["impacts_excluded"] == [{"impact": LEFT_OUT + 1,
                                                "note": "e > 1: a hop the flights do not describe"}]
    assert restitution["weights"][LEFT_OUT] == 0.0


def test_fit_rows_reads_the_column_as_the_analysis_writes_it():
    """No column: every impact; booleans; text from a CSV with an empty cell (counted as in the fit)."""
    assert fit_rows(pd.DataFrame({"e": [0.7, 0.8]})).tolist() == [0, 1]
    assert fit_rows(pd.DataFrame({"e": [0.7, 0.8, 0.9], "in_fit": [True, False, True]})).tolist() == [0, 2]
    assert fit_rows(pd.DataFrame({"e": [0.7, 0.8, 0.9], "in_fit": ["True", "False", None]})).tolist() == [0, 2]


def test_an_impact_whose_e_is_not_a_number_enters_no_fit(contact_recording):
    """An impacts table from an analysis that gave a tiny last hop a NaN e (its rebound below the contact
    height) and no ``in_fit`` column: the fits left it out, where the constant e failed with "SVD did not
    converge" and lost the whole recording."""
    summary, impacts = contact_recording
    old = impacts.drop(columns=["in_fit", "note"])
    old.loc[len(old) - 1, "e"] = np.nan
    fitted = fit_summary(summary, old, Settings())
    assert fitted["restitution"]["n_impacts"] == len(old) - 1
    assert np.isfinite(fitted["restitution"]["e"]["value"])
    assert list(fit_rows(old)) == list(range(len(old) - 1))


def test_a_note_with_commas_reads_back_whole(tmp_path):
    """An impact's note holds commas ("a hand, a tracking error or a missed impact"): the table written
    by the analysis reads back with it as one field (it was taken for a damaged row, losing the fit)."""
    from dropfit.files import read_table, write_table

    table = pd.DataFrame({"e": [0.8, 1.02], "in_fit": [True, False],
                          "note": ["", "e > 1: a hand, a tracking error or a missed impact; left out"]})
    write_table(tmp_path / "impacts.csv", table)
    back = read_table(tmp_path / "impacts.csv")
    assert back["note"].iloc[1] == table["note"].iloc[1]
    assert list(fit_rows(back)) == [0]


def test_the_drag_note_says_combined_only_where_k_was_combined():
    """With the drag option 'off' k is the kind's nominal value, never weighed against the flights': the fit
    record said "combined with what the flights say about k" there too. With 'auto' and k held, it is."""
    truth = simulate_drop(1.0, RADIUS_M, mass_kg=MASS_KG, contact_model=LinearContact(3e4, 8.2))
    log = sample_height_log(truth, np.random.default_rng(21), 2000.0, noise_m=1e-4, offset_m=0.0,
                            dropout_fraction=0.0)
    log = log[log["time_s"] < 2.6]
    attrs = {"ball_mass_kg": MASS_KG, "ball_radius_m": RADIUS_M, "ball_type": "tennis"}
    notes = {}
    for drag in ("off", "auto"):
        result = analyse_bounces(log["time_s"], log["y_m"], contact_height_m=RADIUS_M, drag=drag,
                                 nominal_drag_k_per_m=1e-5)
        record = fit_summary(analysis_summary(result, attrs), result.impacts, Settings())
        notes[drag] = (record["drag"]["model"], record["drag"].get("note", ""), record["drag"]["why"])
    assert notes["off"][0] == "nominal" and "k is not fitted freely" in notes["off"][1]
    assert "combined" not in notes["off"][1] and notes["off"][2] == "fixed by the --drag option"
    assert notes["auto"][0] == "nominal" and "combined with what the flights say" in notes["auto"][1]
