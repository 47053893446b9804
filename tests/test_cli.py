"""The command line: one-line errors for bad recordings, failure records that carry the original
message through the stages, and a small good run checked against the generator's ground truth."""

import json
import os
import shutil
import subprocess
import sys
from html import escape

import numpy as np
import pandas as pd
import pytest
import xarray as xr
import yaml

from dropfit.cli import main
from dropfit.errors import shown

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


# --- refusals printed whole --------------------------------------------------------------------------

#: The longest line the command line printed before (characters after ``dropfit: error: ``): it cut a
#: 726-character refusal in its middle, where its diagnosis and its options were.
OLD_LINE_LIMIT = 284


def _video_trajectory(path, time_s, height_m, quality):
    """A video's trajectory (as dropfit measure writes it) at ``path`` (NetCDF), named after a video beside it
    whose path is long (a lab's folders), heights in m, ``quality`` 0 where measured."""
    from dropfit.heightlog import make_trajectory
    from dropfit.stages import write_trajectory

    video = str(path.parent / ("a lab's recordings of " + "the ball drop " * 4).replace(" ", "_") / "clip.mov")
    trajectory = make_trajectory(time_s, height_m, video, "scale from the ball's diameter",
                                 {"video": video, "ball_radius_m": 0.02,
                                  "frames_unclean": "the ball merged with something (its shadow, a hand) or partly "
                                                    "hidden in 60% of the frames, not found in 11% of the frames"})
    trajectory["quality"] = ("time", np.asarray(quality, np.int8))
    write_trajectory(path, trajectory)
    return video


def _printed_refusal(capsys, trajectory_path, tmp_path):
    """The line ``dropfit analyse`` prints for the trajectory at ``trajectory_path`` (and that it exits 1)."""
    assert main(["analyse", str(trajectory_path), "--impacts", str(tmp_path / "impacts.csv"), "--flights",
                 str(tmp_path / "flights.csv"), "--summary", str(tmp_path / "analysis.json")]) == 1
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("dropfit: error: ")
    return lines[0][len("dropfit: error: "):]


def test_a_video_that_does_not_fall_with_g_is_refused_in_one_whole_line(tmp_path, capsys):
    """The not-free-fall refusal of a poorly tracked video (a ball falling with 5 m/s², measured in a third of its
    frames) is longer than the old limit: it is printed whole, its diagnosis and every option the tracker takes."""
    from dropfit.heightlog import read_trajectory
    from dropfit.video.limits import TRACKER_HELP, not_free_fall

    time = np.arange(240) / 60.0
    flight = time % 0.8
    height = 1.0 - 0.5 * 5.0 * (flight - 0.4) ** 2 - 0.6 + np.random.default_rng(3).normal(0.0, 1e-4, time.size)
    quality = np.where(np.arange(time.size) % 3 == 0, 0, 1)
    video = _video_trajectory(tmp_path / "trajectory.nc", time, height, quality)
    line = _printed_refusal(capsys, tmp_path / "trajectory.nc", tmp_path)
    assert len(line) > OLD_LINE_LIMIT, line
    # only the path, user text, is shortened (at its start, keeping the file name)
    assert "not g" in line and line.endswith(TRACKER_HELP) and "\u2026" not in line.split("clip.mov")[1]
    assert "in the frames not measured cleanly the ball merged with something" in line
    assert video.replace("\\", "/").rsplit("/", 1)[0][-20:] in line  # the path shortened at its start only
    acceleration = float(line.split("falls with ")[1].split(" m/s")[0])
    assert line == not_free_fall(video, acceleration, read_trajectory(tmp_path / "trajectory.nc"))


def test_a_video_with_no_measurable_impact_is_refused_in_one_whole_line(tmp_path, capsys):
    """A 30 frames/s video whose flights are each measured in a fifth of their frames: every impact's reason, the
    frames not clean and the tracker's options, printed whole."""
    from dropfit.video.limits import TRACKER_HELP

    fps, g, e = 120.0, 9.80665, 0.8
    time = np.arange(int(2.4 * fps)) / fps
    height = np.full(time.size, np.nan)
    t_apex, apex = 0.0, 0.82
    while t_apex < time[-1]:
        half = np.sqrt(2 * (apex - 0.02) / g)
        inside = (time >= t_apex - half) & (time < t_apex + half)
        height[inside] = apex - 0.5 * g * (time[inside] - t_apex) ** 2
        apex = 0.02 + e ** 2 * (apex - 0.02)
        t_apex += half + np.sqrt(2 * (apex - 0.02) / g)
    clean = np.arange(time.size) % 5 == 0
    height = np.where(clean, height + np.random.default_rng(4).normal(0.0, 1e-4, time.size), np.nan)
    _video_trajectory(tmp_path / "trajectory.nc", time, height, np.where(clean, 0, 1))
    line = _printed_refusal(capsys, tmp_path / "trajectory.nc", tmp_path)
    assert len(line) > OLD_LINE_LIMIT, line
    assert "no impact can be measured: impact 1: " in line and "; impact 2: " in line
    assert line.endswith(TRACKER_HELP) and "\u2026" not in line.split("clip.mov")[1]


# --- output paths stay inside their folder; the user's disk is named as such -------------------------

REPO = __import__("pathlib").Path(__file__).resolve().parents[1]


def _good_log(path):
    """A 100 Hz, 1 mm log of a ball dropped from 1 m (e = 0.8) at ``path``."""
    from dropfit.synth import sample_height_log, simulate_drop

    from helpers import write_log

    truth = simulate_drop(1.0, 0.03, {"kind": "constant", "e0": 0.8}, release_time_s=0.2)
    return write_log(path, sample_height_log(truth, np.random.default_rng(3), 100.0, duration_s=2.5, noise_m=0.001))


#: sample id → words of its refusal (``{tmp}``: the test's folder, for an absolute path)
BAD_SAMPLE_IDS = {"../../escaped": "outside", "sub/dir": "path of folders", "{tmp}/abs": "outside",
                  "..": "outside", ".hidden": "not a plain name", "logs": "workflow's own folder"}


def test_batch_refuses_a_sample_id_that_would_leave_the_results(tmp_path, capsys):
    """``dropfit batch``: a row whose sample_id is not a plain name (``../../escaped`` wrote files two folders above
    --results, ``sub/dir`` made nested folders) is refused in one line naming the sheet's line, and the rest of the
    batch goes on; nothing is written outside ``results/<good id>/``."""
    work = tmp_path / "a" / "b"
    work.mkdir(parents=True)
    _good_log(work / "log.csv")
    bad_ids = {sample.format(tmp=tmp_path): words for sample, words in BAD_SAMPLE_IDS.items()}
    ids = ["first", *bad_ids, "last"]
    (work / "s.tsv").write_text("sample_id\tkind\tpath\tball_type\tball_radius_m\tball_mass_kg\n" + "".join(
        f"{sample}\theight_log\t{work / 'log.csv'}\tother\t0.03\t0.05\n" for sample in ids), encoding="utf-8")
    before = sorted(tmp_path.rglob("*"))
    assert main(["batch", "--samples", str(work / "s.tsv"), "--results", str(work / "results")]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert len(lines) == len(ids)
    assert lines[0].startswith("first: e = ") and lines[-1].startswith("last: e = ")
    for number, (line, (sample, words)) in enumerate(zip(lines[1:-1], bad_ids.items()), start=3):
        quoted = shown(sample)
        assert line.startswith(f"{quoted}: failed: {work / 's.tsv'}: line {number}: sample_id '{quoted}' "), line
        assert words in line and "give it a plain name" in line, line
    made = sorted(set(tmp_path.rglob("*")) - set(before))
    assert {path.parent for path in made if path.is_file()} == {work / "results" / "first", work / "results" / "last"}
    assert not (tmp_path / "escaped").exists() and not (work / "results" / "sub").exists()
    assert not (tmp_path / "abs").exists()


def test_the_batch_and_the_workflow_take_the_same_sample_ids():
    """``dropfit batch`` refuses the ids the workflow's schema refuses (one pattern)."""
    from dropfit.files import SAMPLE_ID_PATTERN

    schema = yaml.safe_load((REPO / "workflow" / "schemas" / "samples.schema.yaml").read_text(encoding="utf-8"))
    assert schema["properties"]["sample_id"]["pattern"] == SAMPLE_ID_PATTERN


def _environment_line(capsys, path, words):
    """Standard error is one line naming ``path`` with ``words`` (what is wrong and what to do), not an internal
    error; returns the line."""
    err = capsys.readouterr().err
    assert_one_line_error(err, str(path))
    assert "internal error" not in err and "please report" not in err, err
    line = err.strip()
    assert line.startswith(f"dropfit: error: {path}: "), line
    for word in words:
        assert word in line, (word, line)
    return line


def test_a_file_where_a_folder_belongs_is_named_with_what_to_do(tmp_path, capsys):
    """``--out`` that is a file (``dropfit run``), a file where an output's folder belongs (a stage) and a folder
    where an output file belongs: one line naming the path in the way and what to do, also under --record-failure
    (whose records cannot be written there either: exit 1)."""
    log = _good_log(tmp_path / "log.csv")
    blocker = tmp_path / "taken"
    blocker.write_text("not a folder", encoding="utf-8")
    for args in (["run", str(log), "--out", str(blocker)], ["run", str(log), "--out", str(blocker / "sub")],
                 ["measure", str(log), "--out", str(blocker / "t.nc")]):
        for record in ([], ["--record-failure"]):
            assert main(args + record) == 1
            _environment_line(capsys, blocker, ["is a file where a folder is needed", "move the file away"])
    assert blocker.read_text(encoding="utf-8") == "not a folder"
    (tmp_path / "t.nc").mkdir()
    assert main(["measure", str(log), "--out", str(tmp_path / "t.nc")]) == 1
    _environment_line(capsys, tmp_path / "t.nc", ["is a folder where a file is to be written", "give a file name"])
    assert list((tmp_path / "t.nc").iterdir()) == [] and sorted(p.name for p in tmp_path.iterdir()) == [
        "log.csv", "t.nc", "taken"]


def test_a_full_disk_is_the_disk_not_a_bug(tmp_path, capsys, monkeypatch):
    """A write that fails with ENOSPC (here the NetCDF writer's) names the file it was writing and says to free
    space; ``dropfit run`` leaves nothing in --out, not even its temporary folder; ``dropfit batch`` goes on."""
    import errno

    log = _good_log(tmp_path / "log.csv")

    def full(*args, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(xr.Dataset, "to_netcdf", full)
    out = tmp_path / "out"
    assert main(["run", str(log), "--out", str(out)]) == 1
    _environment_line(capsys, out / "trajectory.nc", ["no space left on device", "free space"])
    assert list(out.iterdir()) == []
    assert main(["measure", str(log), "--out", str(tmp_path / "t.nc")]) == 1
    _environment_line(capsys, tmp_path / "t.nc", ["no space left on device", "free space"])
    (tmp_path / "s.tsv").write_text("sample_id\tkind\tpath\nA\theight_log\tlog.csv\nB\theight_log\tlog.csv\n",
                                    encoding="utf-8")
    monkeypatch.chdir(tmp_path)
    assert main(["batch", "--samples", "s.tsv", "--results", "r"]) == 0
    captured = capsys.readouterr()
    assert "Traceback" not in captured.err and "internal error" not in captured.out
    assert captured.out.splitlines() == [f"{sample}: failed: {os.path.join('r', sample, 'trajectory.nc')}: cannot be "
                                         f"written (no space left on device); the disk is full: free space on it, or "
                                         f"write to another disk" for sample in "AB"]


def test_a_read_only_folder_is_named_with_what_to_do(tmp_path, capsys, monkeypatch):
    """An output on a read-only file system (EROFS, simulated: a test may run as root) and, for real, a folder
    without write permission (as root with the capability that overrides permissions dropped)."""
    import errno
    import tempfile

    log = _good_log(tmp_path / "log.csv")

    def read_only(*args, **kwargs):
        raise OSError(errno.EROFS, "Read-only file system")

    with monkeypatch.context() as patched:
        patched.setattr(tempfile, "mkstemp", read_only)
        patched.setattr(tempfile, "mkdtemp", read_only)
        for args, named in ((["measure", str(log), "--out", str(tmp_path / "t.nc")], tmp_path / "t.nc"),
                            (["run", str(log), "--out", str(tmp_path / "out")], tmp_path / "out")):
            assert main(args) == 1
            _environment_line(capsys, named, ["read-only", "writable disk"])
    locked = tmp_path / "locked"
    locked.mkdir()
    locked.chmod(0o555)
    prefix = WITHOUT_OVERRIDE if os.geteuid() == 0 else []
    if prefix and not shutil.which("setpriv"):
        pytest.skip("root writes into any folder, and setpriv is not there to drop that capability")
    for args, named in ((["run", log, "--out", locked], locked), (["fit", "--analysis", "a.json", "--impacts", "i.csv",
                                                                   "--out", locked / "fit.json"], None)):
        result = subprocess.run([*prefix, sys.executable, "-m", "dropfit", *map(str, args)], cwd=tmp_path,
                                capture_output=True, text=True, timeout=CALL_TIMEOUT_S)
        assert result.returncode == 1
        if named is not None:
            assert result.stderr == (f"dropfit: error: {locked}: cannot be written (permission denied); write into a "
                                     f"folder you may write to, or change its permissions\n")
    assert list(locked.iterdir()) == []


#: As root, a folder's permissions bind only without the capabilities to override them: drop those.
WITHOUT_OVERRIDE = ["setpriv", "--inh-caps=-dac_override,-dac_read_search",
                    "--bounding-set=-dac_override,-dac_read_search"]


# --- a notebook's report for every kind of recording; what a killed run left; the command line's help ----

def _impact_times_table(path, drop_height_m=1.0, e=0.8, g=9.81, n=12):
    """A CSV of ``n`` impact times (s) of a point ball dropped from ``drop_height_m`` at t = 0, closed form."""
    speed, times = np.sqrt(2 * g * drop_height_m), [np.sqrt(2 * drop_height_m / g)]
    for _ in range(n - 1):
        speed *= e
        times.append(times[-1] + 2 * speed / g)
    pd.DataFrame({"impact_time_s": times}).to_csv(path, index=False)
    return path


def test_report_works_for_every_kind_of_recording(tmp_path):
    """``analyse_recording(…).report()`` in a notebook: a height log, a table of impact times (it has no samples:
    the report read its ``time`` and raised KeyError), a sound (the real ping-pong recording) and a video."""
    from dropfit import analyse_recording
    from dropfit.synth import simulate_drop

    from helpers import CLIP_BALL_RADIUS_M, real_data_dir, render_drop_clip

    recordings = {"height log": (_good_log(tmp_path / "log.csv"), {}),
                  "impact times": (_impact_times_table(tmp_path / "times.csv"), {"ball_type": "table_tennis"})}
    sound = real_data_dir("ping-pong-audio")
    if sound is not None:
        recordings["sound"] = (sound / "pingpong.wav", {"ball_type": "table_tennis"})
    truth = simulate_drop(0.6, CLIP_BALL_RADIUS_M, {"kind": "constant", "e0": 0.8}, release_time_s=0.1)
    render_drop_clip(tmp_path / "clip.avi", truth, 120.0)
    recordings["video"] = (tmp_path / "clip.avi", {"ball_radius_m": CLIP_BALL_RADIUS_M})
    texts = {}
    for kind, (path, options) in recordings.items():
        result = analyse_recording(path, **options)
        texts[kind] = result.report()
        assert texts[kind].startswith(f"dropfit result: {path.name}") and "\nsamples " in texts[kind], kind
        assert result.summary() in repr(result) and result._repr_html_().startswith("<div>"), kind
    assert "12 impact times given over" in texts["impact times"]


def test_a_rerun_removes_the_temporary_folders_a_killed_run_left(tmp_path, capsys):
    """``dropfit run`` into an --out where a killed run left its ``.dropfit-run.*`` folder removes it: one named by a
    process that is gone, and one of an older dropfit (no process in its name) older than an hour; the folder of a
    run in progress (this process) and a fresh one of unknown process stay."""
    import time

    from dropfit.stages import LEFTOVER_AGE_S, RUN_FILES, run_temporary_prefix

    log = _good_log(tmp_path / "log.csv")
    out = tmp_path / "out"
    gone = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True,
                          timeout=CALL_TIMEOUT_S, check=True)
    live = run_temporary_prefix()
    folders = {"killed": live.replace(f".{os.getpid()}@", f".{int(gone.stdout)}@") + "k1ll3d00",
               "old": ".dropfit-run.0ld00000", "in progress": live + "l1ve0000", "fresh": ".dropfit-run.fr3sh000"}
    for name in folders.values():
        (out / name).mkdir(parents=True)
        (out / name / "trajectory.nc").write_bytes(b"half written")
    long_ago = time.time() - 2 * LEFTOVER_AGE_S
    os.utime(out / folders["old"], (long_ago, long_ago))
    assert main(["run", str(log), "--out", str(out)]) == 0
    capsys.readouterr()
    assert sorted(path.name for path in out.iterdir()) == sorted([*RUN_FILES, folders["in progress"], folders["fresh"]])


def test_a_misspelled_option_gets_the_one_meant_and_the_error_comes_first(tmp_path):
    """``--ball-raduis-m``: "did you mean --ball-radius-m?"; a missing ``--out``: the error is the first line,
    not after the 29 lines of ``dropfit run``'s usage (which ``--help`` shows)."""
    result = dropfit("run", "log.csv", "--out", "x", "--ball-raduis-m", "0.02", cwd=tmp_path)
    assert result.returncode == 2
    assert result.stderr.splitlines() == ["dropfit run: error: unrecognized arguments: --ball-raduis-m 0.02; did you "
                                          "mean --ball-radius-m?", "dropfit run --help lists every option"]
    result = dropfit("run", "log.csv", "--ball-raduis-m=0.02", "--gravty-m-s2", "9.8", cwd=tmp_path)
    assert result.returncode == 2
    assert result.stderr.splitlines()[0] == "dropfit run: error: the following arguments are required: --out"
    assert len(result.stderr.splitlines()) == 2
    result = dropfit("run", "log.csv", "--out", "x", "--ball-raduis-m=0.02", "--gravty-m-s2", "9.8", cwd=tmp_path)
    assert result.stderr.splitlines()[0].endswith("; --ball-raduis-m: did you mean --ball-radius-m?; --gravty-m-s2: "
                                                  "did you mean --gravity-m-s2?")
    assert "did you mean run?" in dropfit("rnu", "log.csv", cwd=tmp_path).stderr.splitlines()[0]
    assert not any(tmp_path.iterdir())
