"""Per-recording report and batch summary, built from a small synthetic run through the stages."""

import base64
import json
import re
from datetime import datetime, timedelta, timezone
from html import escape
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import xarray as xr

from dropfit import __version__, stages
from dropfit.cli import main
from dropfit.fitrecord import fit_summary
from dropfit.settings import Ball, Settings
from dropfit.errors import InputError
from dropfit.files import write_failure
from dropfit.report import (agreement_words, batch_report_html, batch_rows, bic_words, format_pm, model_bic_words,
                            recording_name, run_html, scatter_words)

from helpers import TENNIS_SHORT_SCENARIOS

REPO = Path(__file__).resolve().parents[1]

SECTIONS = ["Recording", "Result", "Restitution models", "ITF verdict", "Drag", "Theory checks", "Contact time", "Impacts table", "Figure"]


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """Paths of a synthetic recording carried through synth → measure → analyse → fit → report."""
    root = tmp_path_factory.mktemp("run")
    paths = {name: root / name for name in ["log.csv", "truth.json", "trajectory.nc", "impacts.csv",
                                            "flights.csv", "analysis.json", "fit.json", "report.html", "figure.png"]}
    (root / "sc.yaml").write_text(TENNIS_SHORT_SCENARIOS, encoding="utf-8")
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
    html = batch_report_html(table, [json.loads(run["fit.json"].read_text(encoding="utf-8")), failed])
    assert "1 analysed, 1 failed" in html
    # the failed row: its id, no ball, the verdict cell in words, the reason across the other columns
    assert ('<tr class="failed"><td>broken</td><td>—</td><td><span class="verdict-cell verdict-not-analysed">'
            'not analysed</span></td><td class="reason" colspan="8"><b>failed:</b> t.csv: no samples &lt;b&gt;'
            '</td></tr>') in html


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
    assert "141.00 ± 0.58" in re.sub("<[^>]+>", "", html)  # cm, ball A's mean and se
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


# --- pages a person would keep: links, run stamp, settings, words, the sample sheet's columns --------

class _Page(HTMLParser):
    """The links, table headers and images of an HTML page."""

    def __init__(self, html):
        super().__init__()
        self.links, self.headers, self.images, self._in_th = [], [], [], False
        self.feed(html)

    def handle_starttag(self, tag, attrs):
        attrs = dict(attrs)
        if tag == "a":
            self.links.append(attrs["href"])
        elif tag == "img":
            self.images.append(attrs)
        elif tag == "th":
            self._in_th = True
            self.headers.append("")

    def handle_endtag(self, tag):
        self._in_th = self._in_th and tag != "th"

    def handle_data(self, data):
        if self._in_th:
            self.headers[-1] += data


def _batch_of_two(run, directory):
    """The run's fit result as recording ``tennis_short`` and a failure record ``broken``, as the
    workflow lays them out (``<directory>/<sample>/fit.json`` beside its report); their paths."""
    good = directory / "tennis_short" / "fit.json"
    good.parent.mkdir(parents=True)
    good.write_text(run["fit.json"].read_text(encoding="utf-8"), encoding="utf-8")
    (good.parent / "report.html").write_text(run["report.html"].read_text(encoding="utf-8"), encoding="utf-8")
    broken = directory / "broken" / "fit.json"
    broken.parent.mkdir()
    broken.write_text(json.dumps({"status": "failed", "error": "bad log"}), encoding="utf-8")
    return [good, broken]


SHEET = ("sample_id\tkind\tpath\tball_type\tsurface\ttemperature_C\tsheets\n"
         "tennis_short\theight_log\tx.csv\ttennis\tconcrete\t21.5\t3\n"
         "broken\theight_log\ty.csv\ttennis\toak floor\t-4\t\n")


def test_summary_links_every_report_and_carries_the_sheet_s_free_columns(run, tmp_path):
    fits = _batch_of_two(run, tmp_path / "results")
    (tmp_path / "samples.tsv").write_text(SHEET, encoding="utf-8")
    out = tmp_path / "results" / "batch"
    stages.summary(fits, out / "summary.csv", out / "summary.html", tmp_path / "samples.tsv", out / "e_vs.png")
    html = (out / "summary.html").read_text(encoding="utf-8")
    page = _Page(html)
    # every recording links the report beside its fit.json, relative to the page
    assert [(out / href).resolve() for href in page.links] == [(path.parent / "report.html").resolve()
                                                               for path in fits]
    assert page.links[0] == "../tennis_short/report.html"
    # the free columns (not kind, path or ball_type, which the workflow reads) in the CSV and on the page
    table = pd.read_csv(out / "summary.csv")
    assert list(table.columns[-3:]) == ["surface", "temperature_C", "sheets"]
    assert "kind" not in table.columns and "path" not in table.columns
    assert table["surface"].tolist() == ["concrete", "oak floor"]
    assert table["temperature_C"].tolist() == [21.5, -4.0]
    assert table.loc[0, "sheets"] == 3 and pd.isna(table.loc[1, "sheets"])
    assert {"surface", "temperature_C", "sheets", "e law", "e₁ ± se (1)", "ITF verdict"} <= set(page.headers)
    fit = json.loads(run["fit.json"].read_text(encoding="utf-8"))
    e1 = fit["restitution"]["e1"]
    assert format_pm(e1["value"], e1["se"]) in re.sub("<[^>]+>", "", html)
    assert f"{fit['restitution']['model']} <span class='words'>(" in html
    verdict = fit["itf"]["verdict"]
    assert f'<span class="verdict-cell verdict-{verdict}">{verdict}</span>' in html
    # e against the numeric columns: written as PNG and shown on the page
    png = (out / "e_vs.png").read_bytes()
    assert png.startswith(b"\x89PNG\r\n\x1a\n")
    assert any(image["src"] == "data:image/png;base64," + base64.b64encode(png).decode("ascii")
               for image in page.images)
    assert "(temperature_C, sheets)" in html


def test_summary_refuses_a_sample_sheet_it_cannot_use_in_one_line(run, tmp_path):
    fits = _batch_of_two(run, tmp_path / "results")
    no_id = tmp_path / "no_id.tsv"
    no_id.write_text("sample id\tsurface\ntennis_short\tconcrete\n", encoding="utf-8")
    twice = tmp_path / "twice.tsv"
    twice.write_text("sample_id\tsurface\ntennis_short\tconcrete\ntennis_short\toak\n", encoding="utf-8")
    for sheet, message in [(no_id, "no sample_id column"), (twice, "sample_id tennis_short appears more than once"),
                           (tmp_path / "missing.tsv", "cannot read the sample sheet")]:
        with pytest.raises(InputError, match=message):
            stages.summary(fits, tmp_path / "s.csv", tmp_path / "s.html", sheet)
        assert not (tmp_path / "s.csv").exists() and not (tmp_path / "s.html").exists()


def test_summary_command_says_what_is_wrong_with_the_sheet_in_one_line(run, tmp_path, capsys):
    fits = _batch_of_two(run, tmp_path / "results")
    sheet = tmp_path / "samples.tsv"
    sheet.write_text("sample_id,surface\ntennis_short,concrete\n", encoding="utf-8")  # commas, not tabs
    out = tmp_path / "batch"
    assert main(["summary", *map(str, fits), "--csv", str(out / "s.csv"), "--html", str(out / "s.html"),
                 "--samples", str(sheet), "--figure", str(out / "s.png")]) == 1
    error = capsys.readouterr().err
    assert error.count("\n") == 1 and error.startswith(f"dropfit: error: {sheet}: no sample_id column")
    assert not out.exists() or not any(out.iterdir())


def test_every_page_carries_the_date_the_version_and_the_settings(run, tmp_path):
    fits = _batch_of_two(run, tmp_path / "results")
    out = tmp_path / "results" / "batch"
    stages.summary(fits, out / "summary.csv", out / "summary.html")
    stages.qc(fits, "lot", out / "qc.html", out / "qc.png", out / "qc.csv")
    fit = json.loads(run["fit.json"].read_text(encoding="utf-8"))
    config = fit["config"]
    today = {datetime.now(timezone.utc).date() + timedelta(days=days) for days in (-1, 0)}  # a run over midnight
    for page in [run["report.html"], out / "summary.html", out / "qc.html"]:
        html = page.read_text(encoding="utf-8")
        run_block = html[html.index('<section class="run">'):html.index("</section>")]
        assert any(f"<dd>{day:%Y-%m-%d} " in run_block for day in today), page.name
        assert f"by dropfit {__version__}</dd>" in run_block
        assert f"<dd>dropfit {fit['dropfit_version']}</dd>" in run_block
        assert f"{format_pm(config['gravity_m_s2'], config['gravity_se_m_s2'])} m/s² ({config['gravity_source']})" \
            in run_block
        assert f"<dd>{config['drag']}: " in run_block
        assert (f"rebound {config['itf_rebound_min_m']:.2f}–{config['itf_rebound_max_m']:.2f} m from a "
                f"{config['itf_drop_height_m']:.2f} m drop") in run_block
        assert f"<dd>{fit['ball']['type']}, radius {1e3 * fit['ball']['radius_m']:.1f} mm" in run_block


def test_a_failed_recording_s_page_carries_its_reason_the_date_and_the_version(tmp_path):
    write_failure(tmp_path / "report.html", "t.csv: no samples <b>")
    html = (tmp_path / "report.html").read_text(encoding="utf-8")
    assert "<p>t.csv: no samples &lt;b&gt;</p>" in html
    assert f"UTC by dropfit {__version__}</dd>" in html and "no recording was analysed" in html


def test_settings_that_differ_between_recordings_are_counted():
    fits = [{"config": {"drag": drag}, "ball": {"type": "tennis"}} for drag in ("auto", "off", "auto")]
    html = run_html(fits + [{"status": "failed", "error": "x"}])
    assert ("differs: auto: fitted where the BIC asks for it (a video: combined with that of the ball kind, where known) "
            "(2 recordings); off: never fitted (1 recording)") in html
    assert "no recording was analysed" in run_html([{"status": "failed", "error": "x"}])


@pytest.mark.parametrize("delta_bic, strength", [(1.0, "weak"), (3.0, "positive"), (7.0, "strong"),
                                                 (12.0, "very strong")])
def test_bic_in_words_follows_kass_and_raftery(delta_bic, strength):
    """2 ln B (≈ ΔBIC) 0–2 weak, 2–6 positive, 6–10 strong, > 10 very strong (Kass & Raftery 1995, table)."""
    assert bic_words(delta_bic, "the linear law", "the constant one") == \
        f"ΔBIC {delta_bic:.1f}: {strength} evidence for the linear law over the constant one"


def test_a_report_figure_drawn_after_others_is_the_figure_drawn_first(tmp_path):
    """A batch draws each recording on one figure made once (its axes and ticks kept): a 25-bounce steel ball
    drawn before and after a 2-bounce tennis drop on it gives the same picture (at most 1 grey level on a
    few antialiased pixels: the limits' last bit), so nothing of one recording is left in another's."""
    from PIL import Image

    def figure(name, sample_id, ball):
        out = tmp_path / sample_id
        if not out.exists():
            stages.run(REPO / "data" / "synthetic" / name, out, ball, sample_id=sample_id)
        stages.report(*(out / f for f in ("trajectory.nc", "flights.csv", "impacts.csv", "analysis.json",
                                          "fit.json", "report.html", "report.png")))
        return np.asarray(Image.open(out / "report.png").convert("RGB"), dtype=int)

    steel, tennis = Ball(0.0125, 0.0642, "steel"), Ball(0.0335, 0.057, "tennis")
    first = figure("steel_ball.csv", "steel", steel)
    figure("tennis_lot_A_ball1_drop1.csv", "tennis", tennis)
    again = figure("steel_ball.csv", "steel", steel)
    assert first.shape == again.shape and np.abs(first - again).max() <= 1
    assert np.count_nonzero(np.abs(first - again).max(axis=2)) < 500


def test_a_report_without_a_sample_id_is_titled_by_its_file():
    trajectory = xr.Dataset(attrs={"source": "/data/drops/pingpong.wav"})
    assert recording_name({}, trajectory) == "pingpong.wav"
    assert recording_name({"sample_id": "lot_A"}, trajectory) == "lot_A"


def test_a_model_with_a_lower_bic_than_the_chosen_one_is_said_to_be_passed_over_for_its_misfit():
    """The chosen model is the lowest BIC among those whose χ² test accepts them: one with a lower BIC (the
    real ping-pong table, constant e ΔBIC −11.4 against per impact) was rejected, and the words say so."""
    assert model_bic_words(-11.4) == "very strong evidence for it by its BIC, but its χ² test does not accept it"
    assert model_bic_words(7.0) == "strong evidence against it"


@pytest.mark.parametrize("p_value, words", [(0.4, "the scatter is what the errors predict"),
                                            (0.01, "somewhat larger than the errors predict"),
                                            (1e-6, "far larger than the errors predict"),
                                            (0.9999, "smaller than the errors predict")])
def test_chi2_in_words_follows_the_p_value(p_value, words):
    assert words in scatter_words({"chi2_per_dof": 1.1, "dof": 8, "p_value": p_value})
    assert "cannot be judged" in scatter_words({"chi2_per_dof": None, "dof": 0, "p_value": None})


def test_agreement_in_words():
    # 0.01 apart with a combined se of 0.0141: within 1.96 se
    assert agreement_words(1.00, 0.01, 1.01, 0.01) == "agrees within the errors"
    # 0.1 below a prediction of 1.0 with a combined se of 0.01: 10 % and 10 se
    assert agreement_words(0.90, None, 1.00, 0.01) == "10.0 % lower than predicted (10 se)"


def test_report_says_in_words_what_bic_chi2_and_the_theory_checks_mean(run):
    html = run["report.html"].read_text(encoding="utf-8")
    fit = json.loads(run["fit.json"].read_text(encoding="utf-8"))
    restitution, models = fit["restitution"], fit["restitution_models"]
    result = html[html.index("<h2>Result</h2>"):html.index("<h2>Restitution models</h2>")]
    assert f"p = {restitution['p_value']:.2g}: {restitution['verdict']}; <span class='words'>" \
           f"{escape(scatter_words(restitution))}</span>" in result
    chosen = restitution["model"]
    for name, model in models.items():  # the chosen law against every other not rejected, by the BICs in fit.json
        if name == chosen or model["verdict"] == "rejected":
            continue
        difference = model["bic"] - models[chosen]["bic"]
        better, worse = (chosen, name) if difference >= 0 else (name, chosen)
        assert f"ΔBIC {abs(difference):.1f}: " in result and escape(f"evidence for '{better}'") in result
    drag = fit["drag"]
    section = html[html.index("<h2>Drag</h2>"):html.index("<h2>Theory checks</h2>")]
    winner = "quadratic drag over none" if drag["bic_quadratic_drag"] < drag["bic_no_drag"] else \
        "no drag over quadratic drag"
    assert f"ΔBIC {abs(drag['bic_quadratic_drag'] - drag['bic_no_drag']):.1f}: " in section and winner in section
    theory = html[html.index("<h2>Theory checks</h2>"):html.index("<h2>Contact time</h2>")]
    first = fit["theory"]["heights"][0]
    assert escape(agreement_words(first["measured_m"], first["measured_se_m"], first["predicted_m"],
                                  first["predicted_se_m"])) in theory
    total = fit["theory"]["total_bouncing_time"]
    words = agreement_words(total["measured_s"], None, total["predicted"]["value"], total["predicted"]["se"])
    assert f"<dt>Measured against predicted</dt><dd>{escape(words)}</dd>" in theory
