"""Per-recording report and batch summary, built from a small synthetic run through the stages."""

import json
from html import escape

import numpy as np
import pandas as pd
import pytest

from dropfit import stages
from dropfit.fitrecord import fit_summary
from dropfit.settings import Ball, Settings
from dropfit.errors import InputError
from dropfit.report import batch_report_html, batch_rows, format_pm

SCENARIOS = """\
scenarios:
  tennis_short:
    seed: 3
    drop_height_m: 2.54
    release_time_s: 0.3
    duration_s: 7.0
    drag_coefficient: 0.55
    ball: {radius_m: 0.0335, mass_kg: 0.057}
    restitution: {kind: constant, e0: 0.745}
    sensor: {sample_rate_hz: 100, noise_m: 0.001, offset_m: 0.12, dropout_fraction: 0.01, unit: m}
"""

SECTIONS = ["Recording", "Result", "Restitution models", "ITF verdict", "Drag", "Theory checks", "Contact time", "Impacts table", "Figure"]


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """Paths of a synthetic recording carried through synth → measure → analyse → fit → report."""
    root = tmp_path_factory.mktemp("run")
    paths = {name: root / name for name in ["log.csv", "truth.json", "trajectory.nc", "impacts.csv",
                                            "flights.csv", "analysis.json", "fit.json", "report.html", "figure.png"]}
    (root / "sc.yaml").write_text(SCENARIOS, encoding="utf-8")
    stages.synth(root / "sc.yaml", "tennis_short", paths["log.csv"], paths["truth.json"])
    stages.measure(paths["log.csv"], paths["trajectory.nc"], Ball(radius_m=0.0335, mass_kg=0.057, type="tennis"),
                   sample_id="tennis_short")
    stages.analyse(paths["trajectory.nc"], paths["impacts.csv"], paths["flights.csv"], paths["analysis.json"])
    stages.fit(paths["analysis.json"], paths["impacts.csv"], paths["fit.json"])
    stages.report(paths["trajectory.nc"], paths["flights.csv"], paths["impacts.csv"], paths["analysis.json"],
                  paths["fit.json"], paths["report.html"], paths["figure.png"])
    return paths


def test_report_has_sections_in_order_and_e(run):
    html = run["report.html"].read_text(encoding="utf-8")
    positions = [html.index(f"<h2>{title}</h2>") for title in SECTIONS]
    assert positions == sorted(positions)
    e = json.loads(run["fit.json"].read_text(encoding="utf-8"))["restitution"]["e"]
    assert format_pm(e["value"], e["se"]) in html
    assert "tennis_short" in html
    assert "data:image/png;base64," in html


def test_figure_is_png(run):
    assert run["figure.png"].read_bytes().startswith(b"\x89PNG\r\n\x1a\n")


def test_format_pm():
    assert format_pm(0.745073344, 6.81e-5) == "0.745073 ± 0.000068"
    assert format_pm(float("nan"), 0.1) == "—"
    assert format_pm(1.5, None) == "1.5"


def test_batch_lists_failed_recording(run):
    failed = {"status": "failed", "error": "t.csv: no samples <b>", "sample_id": "broken"}
    table = batch_rows([json.loads(run["fit.json"].read_text(encoding="utf-8")), failed])
    assert list(table["status"]) == ["ok", "failed"]
    assert table.loc[1, "error"] == failed["error"]
    assert pd.isna(table.loc[1, "e"]) and not pd.isna(table.loc[0, "e"])
    html = batch_report_html(table)
    assert "1 analysed, 1 failed" in html
    assert '<tr class="failed"><td>broken</td><td>failed</td>' in html
    assert "t.csv: no samples &lt;b&gt;" in html


def test_summary_stage_reads_failure_records(run, tmp_path):
    failed_path = tmp_path / "broken" / "fit.json"
    failed_path.parent.mkdir()
    failed_path.write_text(json.dumps({"status": "failed", "error": "bad log"}), encoding="utf-8")
    stages.summary([run["fit.json"], failed_path], tmp_path / "summary.csv", tmp_path / "summary.html")
    table = pd.read_csv(tmp_path / "summary.csv")
    assert table.loc[1, "sample_id"] == "broken" and table.loc[1, "status"] == "failed"
    assert table.loc[1, "error"] == "bad log"
    assert "bad log" in (tmp_path / "summary.html").read_text(encoding="utf-8")


@pytest.mark.parametrize("content", ["{}", "[1, 2]"])
def test_summary_stage_lists_json_that_is_no_fit_result_as_failed(run, tmp_path, content):
    """Valid JSON that is not a fit result (a wrong file on the command line) is a failed row with one
    line naming the file, not a traceback."""
    stray = tmp_path / "stray" / "fit.json"
    stray.parent.mkdir()
    stray.write_text(content, encoding="utf-8")
    stages.summary([run["fit.json"], stray], tmp_path / "summary.csv", tmp_path / "summary.html")
    table = pd.read_csv(tmp_path / "summary.csv")
    assert list(table["status"]) == ["ok", "failed"]
    assert table.loc[1, "error"].startswith(f"{stray}: ")
    assert "not a fit result written by dropfit fit" in table.loc[1, "error"]


def test_qc_stage_groups_drops_by_ball(run, tmp_path):
    """Three drops of ball A (rebounds 1.40, 1.41, 1.42 m) and a failed fourth: the per-ball mean, the
    Student-t interval, the verdict, the chart and the failed recording with its reason."""
    fit = json.loads(run["fit.json"].read_text(encoding="utf-8"))
    paths = []
    for index, rebound in enumerate([1.40, 1.41, 1.42]):
        fit["itf"]["rebound_m"] = {"value": rebound, "se": 0.001}
        path = tmp_path / f"drop{index + 1}" / "fit.json"
        path.parent.mkdir()
        path.write_text(json.dumps(fit), encoding="utf-8")
        paths.append(path)
    failed_path = tmp_path / "drop4" / "fit.json"
    failed_path.parent.mkdir()
    failed_path.write_text(json.dumps({"status": "failed", "error": "drop4.csv: no bounce found"}), encoding="utf-8")
    out = {name: tmp_path / "batch" / name for name in ["qc.html", "qc.png", "balls.csv"]}
    stages.qc(paths + [failed_path], "lot_x", out["qc.html"], out["qc.png"], out["balls.csv"],
              ball_ids=["A", "A", "A", "A"])
    balls = pd.read_csv(out["balls.csv"])
    assert balls["ball_id"].tolist() == ["A"] and balls.loc[0, ["n_drops", "n_failed"]].tolist() == [3, 1]
    assert balls.loc[0, "rebound_m"] == pytest.approx(1.41, abs=1e-6)  # m
    assert balls.loc[0, "rebound_ci95_high_m"] == pytest.approx(1.41 + 4.303 * 0.01 / 3 ** 0.5, abs=1e-4)  # m
    assert balls.loc[0, "itf_verdict"] == "pass"
    html = out["qc.html"].read_text(encoding="utf-8")
    for title in ["Batch summary", "Control chart", "Balls", "Drops", "Failed recordings"]:
        assert f"<h2>{title}</h2>" in html
    assert "<b>drop4</b> (ball A): drop4.csv: no bounce found" in html
    assert "141.00 ± 0.58" in html  # cm, ball A's mean and se
    assert out["qc.png"].read_bytes().startswith(b"\x89PNG\r\n\x1a\n")


def test_qc_stage_wants_one_ball_id_per_fit(run, tmp_path):
    with pytest.raises(InputError, match="2 ball ids for 1 fit results"):
        stages.qc([run["fit.json"]], "lot_x", tmp_path / "a.html", tmp_path / "a.png", tmp_path / "a.csv",
                  ball_ids=["A", "B"])


def _refit(run, e_of_speed, seed):
    """The run's analysis refitted with per-impact e replaced: e_of_speed(v) plus noise drawn from the
    analysis' own e covariance (seeded). Returns (impacts, fit result)."""
    from dropfit.files import read_json, read_table

    summary = {key: float("nan") if value is None else value for key, value in read_json(run["analysis.json"]).items()}
    impacts = read_table(run["impacts.csv"])
    noise = np.linalg.cholesky(np.asarray(summary["e_covariance"])) @ np.random.default_rng(seed).standard_normal(
        len(impacts))
    impacts["e"] = e_of_speed(impacts["v_in_m_s"].to_numpy()) + noise
    return impacts, fit_summary(summary, impacts, Settings(itf_drop_height_m=2.0), ball_type="tennis")


# Per-impact e against speed (m/s) that make the fit choose each kind of headline: a constant, a law of
# speed, and no law (e alternating by ±0.03, far beyond errors of 0.0005–0.01).
HEADLINE_CASES = {
    "constant": lambda v: np.full(v.size, 0.75),
    "linear": lambda v: 0.85 - 0.02 * v,
    "per_impact": lambda v: 0.75 + 0.03 * (-1.0) ** np.arange(v.size),
}


@pytest.mark.parametrize("expected", sorted(HEADLINE_CASES))
def test_headline_model_section_and_figure_show_the_same_model(run, monkeypatch, tmp_path, expected):
    """The Result section states the chosen model, the model section marks it, and panel (c) of the
    figure is asked to draw its curve (through the headline e at the first impact's speed) or, with
    no law, the points alone."""
    from dropfit import report
    from dropfit.heightlog import read_trajectory
    from dropfit.files import read_json, read_table
    from dropfit.speed_dependence import LAWS

    impacts, fit = _refit(run, HEADLINE_CASES[expected], seed=1)
    restitution = fit["restitution"]
    assert restitution["model"] == expected
    drawn = []
    original = report.speed_panel
    monkeypatch.setattr(report, "speed_panel", lambda *args, **kwargs: drawn.append(original(*args, **kwargs))
                        or drawn[-1])
    report.write_recording_report(read_trajectory(run["trajectory.nc"]), read_table(run["flights.csv"]), impacts,
                                  read_json(run["analysis.json"]), fit, tmp_path / "r.html", tmp_path / "r.png")
    html = (tmp_path / "r.html").read_text(encoding="utf-8")
    result = html[html.index("<h2>Result</h2>"):html.index("<h2>Restitution models</h2>")]
    models = html[html.index("<h2>Restitution models</h2>"):html.index("<h2>ITF verdict</h2>")]
    assert f"<strong>{escape(LAWS[expected])}</strong>" in result
    assert format_pm(restitution["e"]["value"], restitution["e"]["se"]) in result
    assert f"<td>▶ {expected}</td>" in models and models.count("▶") == 1
    assert f"Chosen: <b>{expected}</b>" in models
    (panel,) = drawn
    assert panel["model"] == expected
    if expected == "per_impact":
        assert panel["curve"] is None
        assert "no law describes these impacts" in result
        assert restitution["e"]["value"] == pytest.approx(impacts["e"].iloc[0])  # e₁ is the headline
        assert "best law by BIC" in fit["itf"]["rebound_m"]["method"]
    else:
        curve = panel["curve"]
        at_first = np.interp(restitution["reference_speed_m_s"], curve["speed_m_s"], curve["e"])
        assert at_first == pytest.approx(restitution["e"]["value"], abs=1e-4 * restitution["e"]["se"] + 1e-9)
        assert np.all(curve["low"] < curve["e"]) and np.all(curve["e"] < curve["high"])
        assert f"chosen {expected} law" in fit["itf"]["rebound_m"]["method"]
    assert restitution["verdict"] != "rejected"
    row = batch_rows([fit]).iloc[0]
    assert row["restitution_model"] == expected
    assert row["e"] == pytest.approx(restitution["e"]["value"])
    assert row["e1"] == pytest.approx(impacts["e"].iloc[0])
