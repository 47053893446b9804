"""The Snakemake workflow, run in a copy of the repository: lint, dry run (chunks), sample-sheet errors, and
(slow) a whole batch with three bad recordings, checked against the synthetic ground truth and against
``dropfit run`` and ``dropfit.analyse_recording`` on single recordings, and the ``.test/`` configuration of
good and bad rows."""

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
#: The bad recording that is a drop of a ball of the lot (the others form the batch "bad"), and its ball.
LOT_FAILED, LOT_FAILED_BALL = "bad_no_bounce", "A3"
#: The ball lot of the default data: ball → ITF verdict it was designed to get (data/synthetic/scenarios.yaml).
LOT = "tennis_lot_A"
LOT_VERDICTS = {"A1": "pass", "A2": "pass", "A3": "pass", "A4": "fail", "A5": "indeterminate"}
#: The cores of the test runs (config/config.yaml's parallel_jobs), and the most recordings per job (chunk_size).
CORES = 2
CHUNK_SIZE = {"logs": 100, "videos": 4}
#: The .test/ sample sheet's recordings that fail, and a word of each one's reason.
TEST_FAILED = {"truncated": "no bounce", "missing_file": "not found", "log_as_video": "not a video"}
#: .test/'s sheet with mistakes: (line of the file, column or None, words of the message) of each problem.
BAD_SHEET_PROBLEMS = [(6, "ball_type", "'Steel' is not one of"), (7, None, "spaces stand where a tab belongs"),
                      (8, "ball_radius_m", "'12.5mm' is not of type 'number'"), (9, "ball_mass_kg", "missing"),
                      (None, None, "sample_id tennis_itf is on lines 4, 5")]
#: Samples that ``dropfit run`` repeats outside the workflow: a px log calibrated from gravity (drag held
#: at the nominal prior), a log with its floor known (contact times, k, c) and a video (floor found in the
#: image, scale from the diameter, frames guarded around the contacts) and the seed's Example 3 (x and y).
RUN_SAMPLES = ["steel_ball", "tennis_contact_2khz", "contact_2000fps_closeup", "seed_example3_oblique"]
#: A ball's mean rebound must match the mean true rebound of its drops to this (about 4 measurement se).
REBOUND_TOL_M = 0.001  # m


def copy_workflow(destination):
    """Copy the Snakefile, workflow/, config/, data/, .test/ and refsim/ (no results or .snakemake) to
    ``destination``."""
    ignore = shutil.ignore_patterns("results", ".snakemake", "__pycache__")
    shutil.copy2(REPO / "Snakefile", destination / "Snakefile")
    for name in ("workflow", "config", "data", ".test", "refsim"):  # refsim renders the synthetic sound
        shutil.copytree(REPO / name, destination / name, ignore=ignore)
    return destination


def snakemake(*args, cwd, timeout=QUICK_TIMEOUT_S):
    """Run ``snakemake ARGS`` in ``cwd``; return the CompletedProcess (text)."""
    executable = shutil.which("snakemake")
    assert executable is not None, "snakemake is not installed"
    return subprocess.run([executable, *args], cwd=cwd, capture_output=True, text=True, timeout=timeout)


def sample_sheet(root, sheet="config/samples.tsv"):
    """A sample sheet of the copy (pandas.DataFrame), the default one unless told."""
    return pd.read_csv(root / sheet, sep="\t", comment="#")


def good_samples(root):
    """Sample ids of the good recordings (all but :data:`BAD_SAMPLES`)."""
    return [sample for sample in sample_sheet(root)["sample_id"] if sample not in BAD_SAMPLES]


def recording_files(kind):
    """The files the workflow writes for a recording of sample-sheet ``kind``."""
    return RECORDING_FILES + (VIDEO_RECORDING_FILES if kind == "video" else ())


def test_lint_is_quiet(tmp_path):
    """``snakemake --lint`` finds nothing to say (and exits 0)."""
    root = copy_workflow(tmp_path)
    result = snakemake("--lint", cwd=root)
    output = result.stdout + result.stderr
    assert result.returncode == 0, output
    assert "Lints for" not in output and "Congratulations" in output


def planned_jobs(output):
    """Rule name → list of output lists of the jobs a dry run prints."""
    jobs = {}
    for rule, outputs in re.findall(r"^(?:local)?rule (\w+):\n(?:    .*\n)*?    output: (.*)$", output,
                                    flags=re.MULTILINE):
        jobs.setdefault(rule, []).append(outputs.split(", "))
    return jobs


def test_dry_run_plans_every_sample_in_chunks(tmp_path):
    """``snakemake -n`` with the default profile (2 cores) plans every recording's files exactly once, in
    chunks of consecutive sample-sheet rows, videos apart, as many chunks as parallel_jobs (or a multiple of
    them when a chunk would hold more than chunk_size), one summary and one QC job per batch."""
    root = copy_workflow(tmp_path)
    sheet = sample_sheet(root)
    for size in (None, 5):
        if size is not None:
            (root / "config" / "chunks.yaml").write_text(f"chunk_size: {{logs: {size}}}\n", encoding="utf-8")
        options = [] if size is None else ["--configfile", "config/config.yaml", "config/chunks.yaml"]
        result = snakemake("-n", "--profile", "workflow/profiles/default", *options, cwd=root)
        assert result.returncode == 0, result.stderr
        jobs = planned_jobs(result.stdout + result.stderr)
        for group, rows in (("logs", sheet[sheet["kind"] != "video"]), ("videos", sheet[sheet["kind"] == "video"])):
            most = size if size is not None and group == "logs" else CHUNK_SIZE[group]
            chunks = [jobs[f"process_{group}_{i}"] for i in range(1, 100) if f"process_{group}_{i}" in jobs]
            expected_count = min(len(rows), CORES * int(np.ceil(len(rows) / (most * CORES))))
            assert len(chunks) == expected_count > 0 and all(len(job) == 1 for job in chunks)
            planned = [path for (outputs,) in chunks for path in outputs]
            expected = [f"results/{row.sample_id}/{name}" for row in rows.itertuples() for name in recording_files(row.kind)]
            assert planned == expected  # every file once, chunks in sheet order
            sizes = [len({path.split("/")[1] for path in outputs}) for (outputs,) in chunks]
            assert max(sizes) - min(sizes) <= 1 and max(sizes) <= most
    assert len(jobs["summary"]) == 1
    assert len(jobs["qc"]) == sheet["batch"].nunique()
    assert not any(path.startswith("data/") for rule_jobs in jobs.values()
                   for outputs in rule_jobs for path in outputs)


def test_sample_sheet_errors_are_one_line_each(tmp_path):
    """A sheet with a duplicated sample_id, spaces where a tab belongs and bad values stops the workflow before
    any job with one line per problem (line of the file, column, what is wrong), not a schema dump."""
    root = copy_workflow(tmp_path)
    result = snakemake("-n", "--directory", ".test", "--config", "samples=config/samples_bad_sheet.tsv", cwd=root)
    assert result.returncode == 1
    lines = [line for line in result.stderr.splitlines() if line.startswith("config/samples_bad_sheet.tsv")]
    assert len(lines) == len(BAD_SHEET_PROBLEMS), result.stderr
    for line, (number, column, words) in zip(lines, BAD_SHEET_PROBLEMS):
        assert number is None or f": line {number}" in line, line
        assert column is None or f"column {column}:" in line, line
        assert words in line, line
    assert "Traceback" not in result.stderr and "Failed validating" not in result.stderr
    assert "Job stats" not in result.stdout + result.stderr


def test_config_values_on_the_command_line_are_read_as_in_a_config_file(tmp_path):
    """``--config fail_on_failed_recordings=false`` is the boolean a config file's ``false`` is (it was refused
    as "'false' is not of type 'boolean'"), nested numbers (``itf={drop_height_m: 2.5}``) are numbers; a value
    of the wrong type is still one line."""
    root = copy_workflow(tmp_path)
    given = snakemake("-n", "--directory", ".test", "--config", "fail_on_failed_recordings=false",
                      "itf={drop_height_m: 2.5, rebound_min_m: 1.3}", cwd=root)
    assert given.returncode == 0, given.stderr
    wrong = snakemake("-n", "--directory", ".test", "--config", "fail_on_failed_recordings=perhaps", cwd=root)
    assert wrong.returncode == 1
    assert "config, key fail_on_failed_recordings: 'perhaps' is not of type 'boolean'" in wrong.stderr
    assert "Traceback" not in wrong.stderr


def test_sample_sheet_import_columns_reach_measure(tmp_path):
    """A tracking table in the sample sheet with its format, fps and track_id columns: its job reads it with
    them (the trajectory says how) and the job's log holds the line saying what was read as what."""
    root = copy_workflow(tmp_path)
    time = np.arange(0, 1.6, 1 / 50)
    rows = 400 - 300 * (bouncing_ball(time, 1.0, 0.5) + 0.02)  # image rows of the ball, px (down)
    lines = ["Tracks 1 to 2", "Frame\tX1\tY1\tFlag1\tX2\tY2\tFlag2"]
    lines += [f"{i + 1}\t12.0\t30.0\t0\t{100 + 20 * t:.3f}\t{r:.3f}\t0" for i, (t, r) in enumerate(zip(time, rows))]
    (root / "data" / "Results.txt").write_text("\n".join(lines) + "\n", encoding="utf-8")
    row = {"sample_id": "mtrack2_ball", "kind": "height_log", "path": "data/Results.txt", "ball_type": "other",
           "ball_radius_m": 0.02, "ball_mass_kg": 0.05, "format": "mtrack2", "fps": 50.0, "track_id": 2}
    pd.DataFrame([row]).to_csv(root / "config" / "samples.tsv", sep="\t", index=False)
    result = snakemake("results/mtrack2_ball/trajectory.nc", "-c1", cwd=root, timeout=RUN_TIMEOUT_S)
    assert result.returncode == 0, result.stderr
    log = (root / "results" / "logs" / "process" / "process_logs_1.log").read_text(encoding="utf-8")
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
        for sample_id, path in BAD_SAMPLES.items():  # the row's last, empty cells left out
            batch, ball = (LOT, LOT_FAILED_BALL) if sample_id == LOT_FAILED else ("bad", "")
            sheet.write(f"{sample_id}\theight_log\t{path}\ttennis\t0.0335\t0.057\t\t{batch}\t\t\t{ball}\n")

    result = snakemake("--profile", "workflow/profiles/default", "--cores", str(CORES), cwd=root,
                       timeout=RUN_TIMEOUT_S)
    # the bad recordings do not stop the batch, and the run ends by listing them with exit status 1
    assert result.returncode == 1, result.stderr[-3000:]
    assert "Error in rule" not in result.stderr
    heading = f"{len(BAD_SAMPLES)} of {len(good_samples(root)) + len(BAD_SAMPLES)} recordings failed"
    listed = result.stderr[result.stderr.index(heading):].splitlines()
    assert sorted(line.split(":")[0].strip() for line in listed[1:1 + len(BAD_SAMPLES)]) == sorted(BAD_SAMPLES)
    return root


@pytest.mark.slow
def test_batch_with_bad_recordings(batch_run):
    """A full run with three bad recordings: good samples fitted and reported, bad ones in the summary.

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
    assert sorted(summary.index) == sorted(good + list(BAD_SAMPLES))
    for sample_id, path in BAD_SAMPLES.items():
        assert summary.loc[sample_id, "status"] == "failed"
        assert summary.loc[sample_id, "error"].startswith(path)
        assert np.isnan(summary.loc[sample_id, "e"])
    assert "empty" in summary.loc["bad_empty", "error"]
    assert "bounce" in summary.loc["bad_no_bounce", "error"]
    assert "not found" in summary.loc["bad_missing", "error"]
    assert (summary.loc[good, "status"] == "ok").all()

    for scenario in CONSTANT_E_SCENARIOS:
        truth = json.loads((root / "results" / "synthetic" / f"{scenario}.truth.json").read_text(encoding="utf-8"))
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
    assert all(f"<b>{sample_id}</b>" in bad_qc for sample_id in BAD_SAMPLES if sample_id != LOT_FAILED)


@pytest.mark.slow
def test_seed_example3_through_the_workflow(tmp_path):
    """The seed's Example 3 alone through the workflow (about 30 s): rule synth_refsim makes its recording
    (x and y) as committed, under results/, and the results reproduce its peaks, t∞, u t∞ and e within their
    standard errors; the report shows the path y(x)."""
    root = copy_workflow(tmp_path)  # with refsim/, which makes the recording
    sheet = sample_sheet(root)
    sheet[sheet["sample_id"] == "seed_example3_oblique"].to_csv(root / "config" / "one.tsv", sep="\t", index=False)
    recording = root / "results" / "synthetic" / "seed_example3_oblique.csv"
    results = root / "results" / "seed_example3_oblique"
    result = snakemake("--cores", "2", "--config", "samples=config/one.tsv", cwd=root, timeout=RUN_TIMEOUT_S)
    assert result.returncode == 0, result.stderr[-3000:]
    assert recording.read_bytes() == (REPO / "data" / "synthetic" / "seed_example3_oblique.csv").read_bytes()
    check_seed_example3(pd.read_csv(results / "impacts.csv"), json.loads((results / "fit.json").read_text("utf-8")))
    assert 'alt="path y(x)"' in (results / "report.html").read_text("utf-8")


def check_lot_qc(root):
    """The default ball lot's QC report against the generator's truth: verdicts, ball means, the failed drop."""
    sheet = sample_sheet(root).set_index("sample_id")
    balls = pd.read_csv(root / "results" / "batch" / f"qc_{LOT}_balls.csv").set_index("ball_id")
    assert balls["itf_verdict"].to_dict() == LOT_VERDICTS
    for ball, drops in sheet[sheet["batch"] == LOT].groupby("ball_id"):
        truth = [json.loads((root / "results" / "synthetic" / f"{sample}.truth.json").read_text(encoding="utf-8"))
                 for sample in drops.index if sample != LOT_FAILED]
        true_mean = np.mean([record["impacts"][0]["rebound_height_m"] for record in truth])
        assert balls.loc[ball, "rebound_m"] == pytest.approx(true_mean, abs=REBOUND_TOL_M)
        assert balls.loc[ball, "n_drops"] == len(truth)
    assert balls.loc[LOT_FAILED_BALL, "n_failed"] == 1
    html = (root / "results" / "batch" / f"qc_{LOT}.html").read_text(encoding="utf-8")
    assert f"<b>{LOT_FAILED}</b> (ball {LOT_FAILED_BALL})" in html
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


@pytest.mark.slow
def test_dot_test_config_runs_good_and_bad_rows(tmp_path):
    """``snakemake --directory .test``: the good rows (a path starting with "-", a floor of -5e-05 m) give
    their results, the bad ones (a truncated log, a mistyped path, a log given as a video) failure records
    in every file; the run ends with the failed recordings and their reasons, exit status 1. What a killed
    job left behind and the QC page of a batch no longer in the sheet are gone."""
    root = copy_workflow(tmp_path)
    test = root / ".test"
    leftovers = [test / "results" / "tennis_itf" / ".fit.json.k1ll3d_x.json",
                 test / "results" / "tennis_itf" / ".dropfit-run.abcd1234" / "trajectory.nc",
                 test / "results" / "batch" / "qc_old_lot.html"]
    for path in leftovers:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text("left behind", encoding="utf-8")
    result = snakemake("--directory", ".test", "--cores", str(CORES), cwd=root, timeout=RUN_TIMEOUT_S)
    assert result.returncode == 1, result.stderr[-3000:]
    assert "Error in rule" not in result.stderr and "Traceback" not in result.stderr
    sheet = sample_sheet(test, "config/samples.tsv").set_index("sample_id")
    listed = result.stderr[result.stderr.index(f"{len(TEST_FAILED)} of {len(sheet)} recordings failed"):]
    for sample, words in TEST_FAILED.items():
        assert re.search(rf"^  {sample}: .*{words}", listed, flags=re.MULTILINE), listed
    for sample, row in sheet.iterrows():
        for name in recording_files(row["kind"]):
            assert (test / "results" / sample / name).is_file(), (sample, name)
        fit = json.loads((test / "results" / sample / "fit.json").read_text(encoding="utf-8"))
        assert fit["status"] == ("failed" if sample in TEST_FAILED else "ok"), (sample, fit)
    assert not any(path.exists() for path in leftovers)
    assert (test / "results" / "batch" / "qc_lot.html").is_file()


def test_dropfit_batch_writes_failure_records_and_goes_on(tmp_path):
    """``dropfit batch`` by hand on rows of the .test sheet, with the config as a YAML file: a missing file and
    a truncated log each get failure records in every file and a ``failed:`` line with the reason, and the
    command exits 0; a sample id that is not in the sheet is one line and exit status 1, before any row."""
    root = copy_workflow(tmp_path) / ".test"
    result = dropfit("batch", "--samples=config/samples.tsv", "--config=../config/config.yaml", "--",
                     "missing_file", "truncated", cwd=root)
    assert result.returncode == 0, result.stderr
    lines = result.stdout.splitlines()
    assert lines[0].startswith("missing_file: failed: data/no_such_log.csv: file not found")
    assert lines[1].startswith("truncated: failed: data/tennis_lot_A_ball3_drop4_truncated.csv: no bounce")
    for sample in ("missing_file", "truncated"):
        for name in RECORDING_FILES:
            assert (root / "results" / sample / name).is_file(), name
        fit = json.loads((root / "results" / sample / "fit.json").read_text(encoding="utf-8"))
        assert fit["status"] == "failed" and fit["error"] in result.stdout
    result = dropfit("batch", "--samples=config/samples.tsv", "--results=elsewhere", "--", "tennis_itf", "no_such_row",
                     cwd=root)
    assert result.returncode == 1 and result.stdout == ""
    assert result.stderr.strip().splitlines() == [
        "dropfit: error: config/samples.tsv: no row with sample_id no_such_row; give sample ids of the sheet"]
    assert not (root / "elsewhere").exists()
