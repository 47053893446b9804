"""The command line: one-line errors for bad recordings, failure records that carry the original
message through the stages, and a small good run checked against the generator's ground truth."""

import json
import shutil
import subprocess
from html import escape

import numpy as np
import pandas as pd
import pytest
import xarray as xr
import yaml

from dropfit.cli import main

from helpers import (BAD_LOGS, CALL_TIMEOUT_S, assert_nothing_written, assert_one_line_error, dropfit, stage_args, write_bad_log,
                     write_no_bounce_log)

#: A 200 Hz, 1 mm log of 3 s of a no-drag ball gives e to a few 1e-5; the requirement is 0.002.
E_TOL = 0.002  # 1 (dimensionless)
SMALL_SCENARIO = {
    "seed": 5,
    "drop_height_m": 1.0,  # m
    "release_time_s": 0.2,  # s
    "duration_s": 3.0,  # s
    "drag_coefficient": 0.0,
    "ball": {"radius_m": 0.025, "mass_kg": 0.05},  # m, kg
    "restitution": {"kind": "constant", "e0": 0.8},
    "sensor": {"sample_rate_hz": 200, "noise_m": 0.001, "offset_m": 0.1, "dropout_fraction": 0.01, "unit": "mm"},
}


def test_console_script_exists(tmp_path):
    """The ``dropfit`` console script is installed and answers ``--help``."""
    script = shutil.which("dropfit")
    assert script is not None
    result = subprocess.run([script, "--help"], cwd=tmp_path, capture_output=True, text=True, timeout=CALL_TIMEOUT_S)
    assert result.returncode == 0
    assert "measure" in result.stdout


@pytest.mark.parametrize("name", sorted(BAD_LOGS))
def test_measure_bad_log_fails_with_one_line(tmp_path, name):
    """``dropfit measure BAD.csv``: exit 1, one line naming the file, no output or temporary file left."""
    path = write_bad_log(tmp_path, name)
    result = dropfit("measure", path, "--out", "x.nc", cwd=tmp_path)
    assert result.returncode == 1
    assert_one_line_error(result.stderr, path.name)
    assert_nothing_written(tmp_path, "x.nc")


def test_analyse_no_bounce_fails_with_one_line(tmp_path):
    """A log without a bounce measures fine, then ``dropfit analyse`` exits 1 naming the original log."""
    log = write_no_bounce_log(tmp_path / "thud.csv", "thud")
    args = stage_args(tmp_path, log)
    assert dropfit(*args["measure"], cwd=tmp_path).returncode == 0
    result = dropfit(*args["analyse"], cwd=tmp_path)
    assert result.returncode == 1
    assert_one_line_error(result.stderr, log.name)
    assert_nothing_written(tmp_path, "impacts.csv", "flights.csv", "analysis.json")


def check_failure_records(directory, log, message):
    """Every output of every stage is a failure record carrying ``message``, which names ``log``."""
    assert message.startswith(str(log))
    fit = json.loads((directory / "fit.json").read_text(encoding="utf-8"))
    assert fit["status"] == "failed"
    assert fit["error"] == message
    analysis = json.loads((directory / "analysis.json").read_text(encoding="utf-8"))
    assert analysis == {"status": "failed", "error": message}
    for table in ("impacts.csv", "flights.csv"):
        assert message in (directory / table).read_text(encoding="utf-8")
    assert escape(message) in (directory / "report.html").read_text(encoding="utf-8")
    assert (directory / "report.png").read_bytes().startswith(b"\x89PNG")


@pytest.mark.parametrize("name", ["missing", "no_bounce"])
def test_record_failure_propagates_the_original_message(tmp_path, name):
    """With ``--record-failure`` each stage exits 0 and passes the first stage's message on to the summary."""
    sample = tmp_path / f"sample_{name}"
    log = write_no_bounce_log(tmp_path / "thud.csv", "thud") if name == "no_bounce" else write_bad_log(tmp_path, name)
    args = stage_args(sample, log)
    stderr = {}
    for stage in ("measure", "analyse", "fit", "report"):
        result = dropfit(*args[stage], "--record-failure", cwd=tmp_path)
        assert result.returncode == 0, result.stderr
        stderr[stage] = result.stderr
    first = "analyse" if name == "no_bounce" else "measure"
    assert_one_line_error(stderr[first], log.name)
    message = stderr[first].strip().removeprefix("dropfit: error: ")
    if first == "measure":
        with xr.open_dataset(sample / "trajectory.nc") as trajectory:
            assert trajectory.attrs["status"] == "failed"
            assert trajectory.attrs["error"] == message
    else:
        with xr.open_dataset(sample / "trajectory.nc") as trajectory:
            assert trajectory.attrs.get("status") != "failed"
    check_failure_records(sample, log, message)
    # the later stages report the same message, each on one line
    for stage in ("fit", "report"):
        assert stderr[stage].strip() == f"dropfit: error: {message}"

    result = dropfit("summary", sample / "fit.json", "--csv", "summary.csv", "--html", "summary.html", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    table = pd.read_csv(tmp_path / "summary.csv")
    assert table["sample_id"].tolist() == [sample.name]
    assert table["status"].tolist() == ["failed"]
    assert table["error"].tolist() == [message]

    result = dropfit("qc", sample / "fit.json", "--ball-ids", "X", "--batch", "b", "--html", "qc.html",
                     "--figure", "qc.png", "--csv", "balls.csv", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert pd.read_csv(tmp_path / "balls.csv")["itf_verdict"].tolist() == ["not analysed"]
    assert f"<b>{sample.name}</b> (ball X): {escape(message)}" in (tmp_path / "qc.html").read_text(encoding="utf-8")


@pytest.mark.parametrize("name", sorted(BAD_LOGS))
def test_record_failure_in_process_for_every_bad_log(tmp_path, capsys, name):
    """The same chain, in process, for every kind of bad log: exit 0 and the measure message everywhere."""
    log = write_bad_log(tmp_path, name)
    args = stage_args(tmp_path / "out", log)
    for stage in ("measure", "analyse", "fit", "report"):
        assert main([*map(str, args[stage]), "--record-failure"]) == 0
    lines = capsys.readouterr().err.splitlines()
    assert "Traceback" not in "\n".join(lines)
    assert len(lines) == 4 and len(set(lines)) == 1  # one line per stage, all the original one
    assert_one_line_error(lines[0], log.name)
    check_failure_records(tmp_path / "out", log, lines[0].removeprefix("dropfit: error: "))


def test_good_run_recovers_the_scenario_e(tmp_path):
    """synth → measure → analyse → fit on a small no-drag scenario: e within 0.002 of the ground truth."""
    (tmp_path / "scenarios.yaml").write_text(yaml.safe_dump({"scenarios": {"small": SMALL_SCENARIO}}),
                                             encoding="utf-8")
    result = dropfit("synth", "--scenarios", "scenarios.yaml", "--name", "small", "--log", "small.csv",
                     "--truth", "small.truth.json", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    truth = json.loads((tmp_path / "small.truth.json").read_text(encoding="utf-8"))
    assert truth["seed"] == SMALL_SCENARIO["seed"]
    args = stage_args(tmp_path / "small", tmp_path / "small.csv")
    for stage in ("measure", "analyse", "fit"):
        result = dropfit(*args[stage], cwd=tmp_path)
        assert result.returncode == 0, result.stderr
        assert result.stderr == ""
    fit = json.loads((tmp_path / "small" / "fit.json").read_text(encoding="utf-8"))
    assert fit["status"] == "ok"
    assert fit["source"] == str(tmp_path / "small.csv")
    # the constant e weighs the analysed impacts: compare with their true e, weighted alike
    true_e = [impact["e"] for impact in truth["impacts"]][: fit["restitution"]["n_impacts"]]
    assert fit["restitution"]["e"]["value"] == pytest.approx(np.dot(fit["restitution"]["weights"], true_e), abs=E_TOL)
    assert fit["restitution"]["n_impacts"] >= 3
    # no stray temporary files
    assert [p.name for p in (tmp_path / "small").iterdir() if p.name.startswith(".")] == []
