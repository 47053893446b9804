"""The Snakemake workflow, run in a copy of the repository: lint, dry run, and (slow) a whole batch with
three bad recordings, checked against the synthetic ground truth and against ``dropfit run`` and
``dropfit.analyse_recording`` on single recordings."""

import json
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import xarray as xr
import yaml

from dropfit import analyse_recording
from dropfit.settings import settings_from_config, stage_arguments

from helpers import (RECORDING_FILES, VIDEO_RECORDING_FILES, bouncing_ball, check_seed_example3, dropfit,
                     write_no_bounce_log)

REPO = Path(__file__).resolve().parents[1]
#: Time limit of a whole workflow run (about 25 s on a laptop).
RUN_TIMEOUT_S = 600  # s
#: Time limit of a lint or dry run.
QUICK_TIMEOUT_S = 120  # s
#: The constant e must match the true e of the analysed impacts, weighted alike, to this.
E_TOL = 0.002  # 1 (dimensionless)
#: Log scenarios whose constant e is checked (for rubber_e_falls it is the weighted mean of a falling e).
CONSTANT_E_SCENARIOS = ["tennis_itf", "steel_ball", "table_tennis_drag", "rubber_e_falls"]
#: The bad recordings appended to the sample sheet: sample_id → path relative to the copy
#: (the last one is never written: a missing file must not stop the batch either).
BAD_SAMPLES = {"bad_empty": "data/bad/empty.csv", "bad_no_bounce": "data/bad/no_bounce.csv",
               "bad_missing": "data/bad/missing.csv"}
#: The default sample sheet's deliberately bad recording (a log that stops before the first impact).
DEFAULT_FAILED = "tennis_lot_A_ball3_drop4_truncated"
#: The ball lot of the default data: ball → ITF verdict it was designed to get (data/synthetic/scenarios.yaml).
LOT = "tennis_lot_A"
LOT_VERDICTS = {"A1": "pass", "A2": "pass", "A3": "pass", "A4": "fail", "A5": "indeterminate"}
#: Samples that ``dropfit run`` repeats outside the workflow: a px log calibrated from gravity (drag held
#: at the nominal prior), a log with its floor known (contact times, k, c) and a video (floor found in the
#: image, scale from the diameter, frames guarded around the contacts) and the seed's Example 3 (x and y).
RUN_SAMPLES = ["steel_ball", "tennis_contact_2khz", "contact_2000fps_closeup", "seed_example3_oblique"]
#: A ball's mean rebound must match the mean true rebound of its drops to this (about 4 measurement se).
REBOUND_TOL_M = 0.001  # m


def copy_workflow(destination):
    """Copy the Snakefile, workflow/, config/, data/ and refsim/ (no results or .snakemake) to ``destination``."""
    ignore = shutil.ignore_patterns("results", ".snakemake", "__pycache__")
    shutil.copy2(REPO / "Snakefile", destination / "Snakefile")
    for name in ("workflow", "config", "data", "refsim"):  # refsim renders the synthetic sound
        shutil.copytree(REPO / name, destination / name, ignore=ignore)
    return destination


def snakemake(*args, cwd, timeout=QUICK_TIMEOUT_S):
    """Run ``snakemake ARGS`` in ``cwd``; return the CompletedProcess (text)."""
    executable = shutil.which("snakemake")
    assert executable is not None, "snakemake is not installed"
    return subprocess.run([executable, *args], cwd=cwd, capture_output=True, text=True, timeout=timeout)


def sample_sheet(root):
    """The repository's sample sheet (pandas.DataFrame)."""
    return pd.read_csv(root / "config" / "samples.tsv", sep="\t", comment="#")


def good_samples(root):
    """Sample ids of the good recordings (all but :data:`DEFAULT_FAILED` and :data:`BAD_SAMPLES`)."""
    return [sample for sample in sample_sheet(root)["sample_id"] if sample != DEFAULT_FAILED and sample not in BAD_SAMPLES]


def test_lint_reports_only_conda_and_container_hints(tmp_path):
    """``snakemake --lint``: every lint is the conda/container hint (we run in one Python environment)."""
    root = copy_workflow(tmp_path)
    result = snakemake("--lint", cwd=root)
    output = result.stdout + result.stderr
    assert "Traceback" not in output and "Error" not in output
    # a lint report is "Lints for rule R (line, file):" followed by "* <lint>:" items and their text
    headers = re.findall(r"^Lints for (.*)$", output, flags=re.MULTILINE)
    items = re.findall(r"^\s*\* (.*)$", output, flags=re.MULTILINE)
    assert all(header.startswith("rule ") for header in headers)  # no lints about the Snakefile as a whole
    assert all("conda environment or container" in item for item in items), items
    assert len(items) == len(headers)  # one item per rule
    # snakemake exits 1 when it printed any lint, 0 when there was none
    assert result.returncode == (1 if items else 0)


def test_dry_run_plans_every_sample(tmp_path):
    """``snakemake -n`` with the default profile succeeds and plans one measure job per sample (a video's
    also writes its tracked table) and one overlay job per video."""
    root = copy_workflow(tmp_path)
    result = snakemake("-n", "--profile", "workflow/profiles/default", cwd=root)
    assert result.returncode == 0, result.stderr
    output = result.stdout + result.stderr
    counts = dict(re.findall(r"^(\w+)\s+(\d+)$", output, flags=re.MULTILINE))
    sheet = sample_sheet(root)
    videos = int(np.count_nonzero(sheet["kind"] == "video"))
    assert int(counts["measure"]) + int(counts["measure_video"]) == len(sheet)
    assert int(counts["measure_video"]) == int(counts["overlay"]) == videos > 0
    for rule in ("analyse", "fit", "report"):
        assert int(counts[rule]) == len(sheet)
    assert int(counts["summary"]) == 1
    assert int(counts["qc"]) == sheet["batch"].nunique()


def test_sample_sheet_import_columns_reach_measure(tmp_path):
    """A tracking table in the sample sheet with its format, fps and track_id columns: the measure job reads it
    with them (the trajectory says how) and its log holds the line saying what was read as what."""
    root = copy_workflow(tmp_path)
    time = np.arange(0, 1.6, 1 / 50)
    rows = 400 - 300 * (bouncing_ball(time, 1.0, 0.5) + 0.02)  # image rows of the ball, px (down)
    lines = ["Tracks 1 to 2", "Frame\tX1\tY1\tFlag1\tX2\tY2\tFlag2"]
    lines += [f"{i + 1}\t12.0\t30.0\t0\t{100 + 20 * t:.3f}\t{r:.3f}\t0" for i, (t, r) in enumerate(zip(time, rows))]
    (root / "data" / "Results.txt").write_text("\n".join(lines) + "\n", encoding="utf-8")
    sheet = sample_sheet(root)
    row = {"sample_id": "mtrack2_ball", "kind": "height_log", "path": "data/Results.txt", "ball_type": "other",
           "ball_radius_m": 0.02, "ball_mass_kg": 0.05, "format": "mtrack2", "fps": 50.0, "track_id": 2}
    pd.concat([sheet, pd.DataFrame([row])]).to_csv(root / "config" / "samples.tsv", sep="\t", index=False)
    result = snakemake("results/mtrack2_ball/trajectory.nc", "-c1", cwd=root, timeout=RUN_TIMEOUT_S)
    assert result.returncode == 0, result.stderr
    log = (root / "results" / "logs" / "measure" / "mtrack2_ball.log").read_text(encoding="utf-8")
    assert "as MTrack2 track 2 (given) [px, y down], frames at 50 frames/s" in log
    with xr.open_dataset(root / "results" / "mtrack2_ball" / "trajectory.nc") as trajectory:
        assert trajectory.attrs["import_format"] == "mtrack2"
        assert trajectory.attrs["scale_m_per_px"] == pytest.approx(-1 / 300, rel=3e-3)


@pytest.fixture(scope="module")
def batch_run(tmp_path_factory):
    """The default workflow with three bad recordings added, run in a copy of the repository; its root."""
    root = copy_workflow(tmp_path_factory.mktemp("workflow"))
    bad_dir = root / "data" / "bad"
    bad_dir.mkdir()
    (root / BAD_SAMPLES["bad_empty"]).write_text("", encoding="utf-8")
    write_no_bounce_log(root / BAD_SAMPLES["bad_no_bounce"], "thud")
    with open(root / "config" / "samples.tsv", "a", encoding="utf-8") as sheet:
        for sample_id, path in BAD_SAMPLES.items():
            sheet.write(f"{sample_id}\theight_log\t{path}\ttennis\t0.0335\t0.057\t\tbad\n")

    result = snakemake("--profile", "workflow/profiles/default", "--cores", "2", cwd=root, timeout=RUN_TIMEOUT_S)
    assert result.returncode == 0, result.stderr[-3000:]
    return root


@pytest.mark.slow
def test_batch_with_bad_recordings(batch_run):
    """A full run with three bad recordings: exit 0, good samples fitted and reported, bad ones in the summary.

    The good samples' e must match the ground truth of the constant-e scenarios within 0.002.
    """
    root = batch_run
    good = good_samples(root)

    videos = set(sample_sheet(root).query("kind == 'video'")["sample_id"])
    for sample in good:
        assert (root / "results" / sample / "report.html").is_file()
        if sample in videos:  # the report shows what was tracked
            assert (root / "results" / sample / "contact_sheet.png").read_bytes().startswith(b"\x89PNG")
            assert "contact sheet of the video" in (root / "results" / sample / "report.html").read_text("utf-8")
        fit = json.loads((root / "results" / sample / "fit.json").read_text(encoding="utf-8"))
        assert fit["status"] == "ok", fit
        assert fit["sample_id"] == sample

    summary = pd.read_csv(root / "results" / "batch" / "summary.csv").set_index("sample_id")
    assert sorted(summary.index) == sorted(good + [DEFAULT_FAILED] + list(BAD_SAMPLES))
    assert summary.loc[DEFAULT_FAILED, "status"] == "failed" and "bounce" in summary.loc[DEFAULT_FAILED, "error"]
    for sample_id, path in BAD_SAMPLES.items():
        assert summary.loc[sample_id, "status"] == "failed"
        assert summary.loc[sample_id, "error"].startswith(path)
        assert np.isnan(summary.loc[sample_id, "e"])
    assert "empty" in summary.loc["bad_empty", "error"]
    assert "bounce" in summary.loc["bad_no_bounce", "error"]
    assert "not found" in summary.loc["bad_missing", "error"]
    assert (summary.loc[good, "status"] == "ok").all()

    for scenario in CONSTANT_E_SCENARIOS:
        truth = json.loads((root / "data" / "synthetic" / f"{scenario}.truth.json").read_text(encoding="utf-8"))
        fit = json.loads((root / "results" / scenario / "fit.json").read_text(encoding="utf-8"))
        impacts = pd.read_csv(root / "results" / scenario / "impacts.csv")
        # per-impact truth, matched by touchdown time: the log sees only some of the generator's impacts
        touchdowns = np.array([impact["t_s"] for impact in truth["impacts"]])
        matched = [int(np.argmin(np.abs(touchdowns - t))) for t in impacts["t_touchdown_s"]]
        true_e = np.dot(fit["restitution"]["weights"], [truth["impacts"][i]["e"] for i in matched])
        assert fit["restitution"]["e"]["value"] == pytest.approx(true_e, abs=E_TOL)
        assert summary.loc[scenario, "e"] == pytest.approx(true_e, abs=E_TOL)
    # ITF: the 254 cm drop is judged on its measured rebound (141 cm, inside the window)
    itf = json.loads((root / "results" / "tennis_itf" / "fit.json").read_text(encoding="utf-8"))["itf"]
    assert itf["rebound_m"]["method"].startswith("measured")
    assert itf["verdict"] == "pass"

    check_lot_qc(root)
    bad_qc = (root / "results" / "batch" / "qc_bad.html").read_text(encoding="utf-8")
    assert all(f"<b>{sample_id}</b>" in bad_qc for sample_id in BAD_SAMPLES)


@pytest.mark.slow
def test_seed_example3_through_the_workflow(tmp_path):
    """The seed's Example 3 alone through the workflow (about 30 s): rule synth_refsim remakes its
    recording (x and y) as committed, and the results reproduce its peaks, t∞, u t∞ and e within their
    standard errors; the report shows the path y(x)."""
    root = copy_workflow(tmp_path)  # with refsim/, which remakes the recording
    recording = root / "data" / "synthetic" / "seed_example3_oblique.csv"
    recording.unlink()
    results = root / "results" / "seed_example3_oblique"
    result = snakemake("--cores", "2", "results/seed_example3_oblique/fit.json",
                       "results/seed_example3_oblique/report.html", cwd=root, timeout=RUN_TIMEOUT_S)
    assert result.returncode == 0, result.stderr[-3000:]
    assert recording.read_bytes() == (REPO / "data" / "synthetic" / "seed_example3_oblique.csv").read_bytes()
    check_seed_example3(pd.read_csv(results / "impacts.csv"), json.loads((results / "fit.json").read_text("utf-8")))
    assert 'alt="path y(x)"' in (results / "report.html").read_text("utf-8")


def check_lot_qc(root):
    """The default ball lot's QC report against the generator's truth: verdicts, ball means, failed drop."""
    sheet = sample_sheet(root).set_index("sample_id")
    balls = pd.read_csv(root / "results" / "batch" / f"qc_{LOT}_balls.csv").set_index("ball_id")
    assert balls["itf_verdict"].to_dict() == LOT_VERDICTS
    for ball, drops in sheet[sheet["batch"] == LOT].groupby("ball_id"):
        truth = [json.loads((root / "data" / "synthetic" / f"{sample}.truth.json").read_text(encoding="utf-8"))
                 for sample in drops.index if sample != DEFAULT_FAILED]
        true_mean = np.mean([record["impacts"][0]["rebound_height_m"] for record in truth])
        assert balls.loc[ball, "rebound_m"] == pytest.approx(true_mean, abs=REBOUND_TOL_M)
        assert balls.loc[ball, "n_drops"] == len(truth)
    assert balls.loc["A3", "n_failed"] == 1
    html = (root / "results" / "batch" / f"qc_{LOT}.html").read_text(encoding="utf-8")
    assert f"<b>{DEFAULT_FAILED}</b> (ball A3)" in html
    assert (root / "results" / "batch" / f"qc_{LOT}.png").read_bytes().startswith(b"\x89PNG")


@pytest.mark.slow
@pytest.mark.parametrize("sample", RUN_SAMPLES)
def test_run_and_a_notebook_give_the_workflows_numbers(batch_run, sample, monkeypatch):
    """``dropfit run`` on one recording, with the options the workflow gives that sample, writes the
    workflow's impacts and flights byte for byte and its fit result number for number; so does
    ``dropfit.analyse_recording`` with the same config and sample row, in memory."""
    root = batch_run
    config = yaml.safe_load((root / "config" / "config.yaml").read_text(encoding="utf-8"))
    row = sample_sheet(root).set_index("sample_id", drop=False).loc[sample]
    out = root / "run" / sample
    result = dropfit("run", row["path"], "--out", out, "--sample-id", sample, *stage_arguments("run", config, row),
                     cwd=root)
    assert result.returncode == 0, result.stderr
    assert result.stdout.startswith(f"{sample}: e = ") and len(result.stdout.splitlines()) == 1
    workflow = root / "results" / sample
    video = row["kind"] == "video"
    for name in ("impacts.csv", "flights.csv") + (("track.csv",) if video else ()):
        assert (out / name).read_bytes() == (workflow / name).read_bytes(), name
    run_fit = json.loads((out / "fit.json").read_text(encoding="utf-8"))
    assert run_fit == json.loads((workflow / "fit.json").read_text(encoding="utf-8"))
    assert sorted(path.name for path in out.iterdir()) == sorted(RECORDING_FILES
                                                                 + (VIDEO_RECORDING_FILES if video else ()))

    ball, settings = settings_from_config(config, row)
    monkeypatch.chdir(root)  # the recording's path as the workflow gives it (messages quote it)
    notebook = analyse_recording(row["path"], ball_radius_m=ball.radius_m, ball_mass_kg=ball.mass_kg,
                                 ball_type=ball.type, sample_id=sample, settings=settings)
    assert notebook.to_dict() == run_fit
