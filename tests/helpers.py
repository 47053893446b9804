"""Helpers the tests share (tests import these, never each other): synthetic height logs, bad logs,
small synthetic video clips, and running the ``dropfit`` command line."""

import subprocess
import sys

import numpy as np

from dropfit.synth import sample_height_log, simulate_drop

#: Seconds a single ``dropfit`` call may take (imports included) before the test gives up.
CALL_TIMEOUT_S = 120  # s


def write_log(path, frame, comment="# synthetic height log written by the tests"):
    """Write ``frame`` as a height-log CSV, the way ``dropfit synth`` does (comment line, ``%.6f``).

    Returns
    -------
    pathlib.Path
        ``path``.
    """
    path.write_text(comment + "\n" + frame.to_csv(index=False, float_format="%.6f", na_rep=""), encoding="utf-8")
    return path


def thud_truth():
    """A ball that falls 1 m and lies still where it lands (e = 0): no bounce at all."""
    return simulate_drop(1.0, 0.03, {"kind": "constant", "e0": 0.0})


#: name → (file content or None for a missing file, words the message must contain)
BAD_LOGS = {
    "missing": (None, ["not found"]),
    "empty": ("", ["empty"]),
    "only_comments": ("# dropfit height log\n# nothing was recorded\n", ["empty"]),
    "wrong_columns": ("t,height\n0.0,1.0\n0.01,0.99\n", ["time_s", "t, height"]),
    "no_rows": ("# header only\ntime_s,y_m\n", ["no samples"]),
    "not_a_number": ("time_s,y_m\n0.00,1.0\n0.01,abc\n0.02,0.98\n", ["y_m", "not a number", "abc"]),
    "repeated_time": ("time_s,y_m\n0.00,1.0\n0.01,0.99\n0.01,0.99\n0.02,0.98\n", ["does not increase"]),
    "all_nan": ("time_s,y_m\n0.00,\n0.01,\n0.02,nan\n", ["y_m", "no valid value"]),
    "infinite": ("time_s,y_m\n0.00,1.0\n0.01,inf\n0.02,0.98\n", ["y_m", "infinite"]),
}


def write_bad_log(directory, name):
    """Write the bad log ``name`` of :data:`BAD_LOGS` (or nothing, for the missing file); return its path."""
    content = BAD_LOGS[name][0]
    path = directory / f"{name}.csv"
    if content is not None:
        path.write_text(content, encoding="utf-8")
    return path


def write_no_bounce_log(path, kind, seed=21):
    """A 1 mm-noise log in which the ball never bounces: ``thud`` (falls, lies still) or ``held`` (never falls)."""
    truth = thud_truth()
    frame = sample_height_log(truth, np.random.default_rng(seed), 100.0, duration_s=2.0, noise_m=0.001)
    if kind == "held":
        frame["y_m"] = truth.height(0.0) + np.random.default_rng(seed + 1).normal(0.0, 0.001, len(frame))
    return write_log(path, frame)


def dropfit(*args, cwd):
    """Run ``python -m dropfit ARGS`` in ``cwd``; return the CompletedProcess (text)."""
    return subprocess.run([sys.executable, "-m", "dropfit", *map(str, args)], cwd=cwd, capture_output=True,
                          text=True, timeout=CALL_TIMEOUT_S)


def assert_one_line_error(stderr, file_name):
    """stderr is exactly one line ``dropfit: error: …`` naming ``file_name``, without a traceback."""
    assert "Traceback" not in stderr
    lines = stderr.splitlines()
    assert len(lines) == 1, stderr
    assert lines[0].startswith("dropfit: error: ")
    assert file_name in lines[0]


def assert_nothing_written(directory, *names):
    """None of the outputs ``names``, nor their temporary files ``.name.*``, exist in ``directory``."""
    for name in names:
        assert not (directory / name).exists()
        assert list(directory.glob(f".{name}.*")) == []


def stage_args(directory, source):
    """Argument lists of the four stages after ``synth`` for the recording ``source``, outputs in ``directory``."""
    d = directory
    return {
        "measure": ["measure", source, "--out", d / "trajectory.nc"],
        "analyse": ["analyse", d / "trajectory.nc", "--impacts", d / "impacts.csv", "--flights", d / "flights.csv",
                    "--summary", d / "analysis.json"],
        "fit": ["fit", "--analysis", d / "analysis.json", "--impacts", d / "impacts.csv", "--out", d / "fit.json"],
        "report": ["report", "--trajectory", d / "trajectory.nc", "--flights", d / "flights.csv",
                   "--impacts", d / "impacts.csv", "--analysis", d / "analysis.json", "--fit", d / "fit.json",
                   "--html", d / "report.html", "--figure", d / "report.png"],
    }


def matched_truth(impacts, true_impacts):
    """The rows of a simulator's impact table nearest in touchdown time to each analysed impact.

    Parameters
    ----------
    impacts : pandas.DataFrame
        An analysis' impacts (``t_touchdown_s``).
    true_impacts : pandas.DataFrame
        The truth's impacts (``t_touchdown_s``, refsim's names).

    Returns
    -------
    pandas.DataFrame
        One truth row per analysed impact, index reset to match ``impacts``.
    """
    true_times = true_impacts["t_touchdown_s"].to_numpy()
    nearest = [int(np.argmin(np.abs(true_times - time))) for time in impacts["t_touchdown_s"]]
    return true_impacts.iloc[nearest].reset_index(drop=True)


#: The ball of :func:`write_drop_log`: a rubber ball (radius m, mass kg) with the drag of a smooth sphere.
DROP_BALL = {"ball_radius_m": 0.025, "ball_mass_kg": 0.05, "ball_type": "rubber"}
#: The files ``dropfit run`` and the workflow write per recording.
RECORDING_FILES = ("trajectory.nc", "impacts.csv", "flights.csv", "analysis.json", "fit.json", "report.html",
                   "report.png")
#: What ``dropfit run`` and the workflow write for a video besides: the tracked table and the contact sheet.
VIDEO_RECORDING_FILES = ("track.csv", "contact_sheet.png")
#: Fields of fit.json that name the recording rather than measure it (results are compared without them).
PROVENANCE_FIELDS = ("source", "sample_id")


#: The floor's height in m in the frame of :func:`write_drop_log` (the sensor's zero is below it).
DROP_FLOOR_M = 0.1


def write_drop_log(path, seed=5, unit="mm"):
    """A 3 s, 200 Hz, 1 mm-noise log of the :data:`DROP_BALL` from 1 m (e = 0.8, C_d = 0.5), seeded; the
    floor at :data:`DROP_FLOOR_M`. Returns ``path``."""
    truth = simulate_drop(1.0, DROP_BALL["ball_radius_m"], {"kind": "constant", "e0": 0.8},
                          mass_kg=DROP_BALL["ball_mass_kg"], drag_coefficient=0.5, release_time_s=0.2)
    frame = sample_height_log(truth, np.random.default_rng(seed), 200.0, duration_s=3.0, noise_m=0.001,
                              offset_m=DROP_FLOOR_M, dropout_fraction=0.01, unit=unit)
    return write_log(path, frame, f"# drop log for the tests, seed {seed}")


def option_arguments(options):
    """``--flag value`` strings of option name → value (``dropfit.settings.OPTIONS`` names)."""
    from dropfit.settings import OPTIONS

    return [text for name, value in options.items() for text in (OPTIONS[name].flag, str(value))]


def fit_numbers(fit):
    """A fit result without its provenance fields (:data:`PROVENANCE_FIELDS`)."""
    return {key: value for key, value in fit.items() if key not in PROVENANCE_FIELDS}


#: The small clip of :func:`render_drop_clip`: image scale (px/m), floor row (px) and the ball's radius (m).
CLIP_PX_PER_M = 200.0
CLIP_FLOOR_ROW_PX = 205.0
CLIP_BALL_RADIUS_M = 0.025


def render_drop_clip(path, truth, fps, seed=0):
    """A 1.7 s, 160 × 220 px MJPEG clip of ``truth`` (a ball of :data:`CLIP_BALL_RADIUS_M`: 5 px; sensor
    noise σ 2 grey levels) rendered by :mod:`dropfit.video_synth`.

    Returns
    -------
    pandas.DataFrame
        The renderer's per-frame truth (``x_px``, ``y_px`` …; ``attrs["video_path"]``: the clip).
    """
    from dropfit.video_synth import Camera, Scene, render_video

    camera = Camera(160, 220, fps, None, px_per_m=CLIP_PX_PER_M, image_row_of_floor_px=CLIP_FLOOR_ROW_PX,
                    noise_sigma=2.0)
    return render_video(truth, camera, Scene(), 1.7, seed, path)
