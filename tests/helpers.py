"""Helpers the tests share (tests import these, never each other): synthetic height logs, bad logs, small
synthetic video clips, running the ``dropfit`` command line, drawn calibration images (rulers, bands),
encoded clips, the real data's place, phonesim clips and a ball drawn into a frame."""

import os
import pathlib
import re
import subprocess
import sys

import numpy as np

from dropfit.synth import sample_height_log, simulate_drop

#: Sub-pixels per pixel and axis with which :func:`disc_coverage` draws a disc.
SUPERSAMPLING = 8

#: Seconds a single ``dropfit`` call may take (imports included) before the test gives up.
CALL_TIMEOUT_S = 120  # s

#: ``python -m dropfit ARGS`` that prints its peak memory (kB) as the last line of standard output: ``VmHWM`` of
#: ``/proc/self/status`` (Linux), unlike ``ru_maxrss`` not inherited from the process it was forked from.
_MEASURED = """
import re, runpy, sys
sys.argv = ["dropfit", *sys.argv[1:]]
try:
    runpy.run_module("dropfit", run_name="__main__")
finally:
    with open("/proc/self/status") as status:
        print(re.search(r"VmHWM:\\s*(\\d+) kB", status.read()).group(1), flush=True)
"""


def measured_dropfit(*args, cwd, timeout_s=CALL_TIMEOUT_S):
    """Run dropfit with ``args`` in ``cwd`` in a new process: (the CompletedProcess, its peak memory in MB)."""
    done = subprocess.run([sys.executable, "-c", _MEASURED, *map(str, args)], cwd=cwd, capture_output=True,
                          text=True, timeout=timeout_s)
    return done, int(done.stdout.split()[-1]) / 1024


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
    "repeated_time": ("time_s,y_m\n0.00,1.0\n0.01,0.99\n0.01,0.97\n0.02,0.98\n", ["given twice"]),
    "time_back": ("time_s,y_m\n0.00,1.0\n0.02,0.99\n0.01,0.97\n0.03,0.98\n", ["does not increase"]),
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


#: The one line a tracked clip writes to a log (dropfit.video.decode.Progress), written here
#: independently: name, frames, seconds and frames/s.
PROGRESS_LINE = re.compile(r"\S.*: \d+ frames in \d+\.\d s \(\d+ frames/s\)")


def without_progress(stderr):
    """The lines of ``stderr`` other than a tracked clip's progress line (one per clip, in logs)."""
    return [line for line in stderr.splitlines() if not PROGRESS_LINE.fullmatch(line)]


def assert_one_line_error(stderr, file_name):
    """stderr is exactly one line ``dropfit: error: …`` naming ``file_name``, without a traceback
    (besides a tracked clip's progress line)."""
    assert "Traceback" not in stderr
    lines = without_progress(stderr)
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


#: The seed's Example 3 (impulse-momentum-impact.txt): a tennis ball (e = 0.745) rolls off a 0.9 m table at
#: 3 m/s and bounces across a smooth floor; g = 9.81 m/s². Its printed results: the peaks (m), t∞ (s) and
#: u t∞ (m).
SEED_EXAMPLE3 = {"table_m": 0.9, "speed_m_s": 3.0, "e": 0.745, "g_m_s2": 9.81,
                 "peaks_m": [0.5, 0.277, 0.154, 0.085, 0.047], "t_inf_s": 2.93, "distance_m": 8.79}


def check_seed_example3(impacts, fit):
    """Assert that an analysis of the seed's Example 3 (impacts table, fit result) reproduces its numbers:
    the closed forms behind them (h_n = e^{2n} h₀, t∞ = t₀ (1 + e)/(1 − e), u t∞) round to the printed ones,
    and the measured peaks, t∞, u t∞, u and the headline e lie within 3 standard errors of them; every
    impact keeps its tangential velocity."""
    example = SEED_EXAMPLE3
    e, table, speed = example["e"], example["table_m"], example["speed_m_s"]
    peaks = table * e ** (2 * np.arange(1, 6))
    t_inf = np.sqrt(2 * table / example["g_m_s2"]) * (1 + e) / (1 - e)
    assert np.round(peaks, 3).tolist() == example["peaks_m"]
    assert round(t_inf, 2) == example["t_inf_s"] and round(speed * t_inf, 2) == example["distance_m"]
    measured = impacts["h_after_m"].to_numpy()[:5]
    assert np.all(np.abs(measured - peaks) < 3 * impacts["h_after_se_m"].to_numpy()[:5])
    for found, truth in ((fit["theory"]["total_bouncing_time"]["predicted"], t_inf),
                         (fit["theory"]["horizontal_distance"]["predicted"], speed * t_inf),
                         (fit["theory"]["horizontal_distance"]["release_speed"], speed),
                         (fit["restitution"]["e"], e)):
        assert abs(found["value"] - truth) < 3 * found["se"], (found, truth)
    assert fit["restitution"]["model"] == "constant"
    assert (impacts["angle_check"] == "consistent: tangential velocity kept").all()


#: Supersampling of drawn calibration images: marks land at fractional pixel positions, area-averaged.
DRAW_SUPERSAMPLING = 8


def ruler_image(px_per_m, length_m, tick_m, tick_levels, *, size_px=None, start_px=20.0, width_px=60,
                face_bgr=(40, 170, 60), wall_bgr=(150, 190, 210), mark_bgr=(20, 20, 20), tick_width_px=1.0,
                numbers_every=None, bands=False, whole_rows=False, lying=False, blur_px=0.7, noise=3.0, seed=0):
    """A BGR image of a ruler, tape measure or banded stick on a wall, drawn from the truth.

    Parameters
    ----------
    px_per_m : float
        Image scale along the ruler, px/m (the truth a scale must find).
    length_m : float
        The ruler's length in m; it starts ``start_px`` from the image's top (left when lying).
    tick_m : float
        Spacing of the finest marks in m (a band's length for ``bands``).
    tick_levels : sequence of (int, float)
        (every how many finest ticks, tick length as a fraction of the ruler's width), shortest
        first: ``((1, 0.25), (5, 0.4), (10, 0.6))`` for mm, half-cm and cm ticks.
    size_px : (int, int), optional
        (length, breadth) of the image along and across the ruler; default it fits the ruler.
    face_bgr, wall_bgr, mark_bgr : tuple of int
        Colours of the ruler's face, the wall and the marks.
    tick_width_px : float
        Width of a tick along the ruler, px.
    numbers_every : int, optional
        Print the running number every this many finest ticks, beside the tick (as on a tape).
    bands : bool
        Paint alternating bands of ``tick_m`` instead of ticks (their edges are the marks).
    whole_rows : bool
        Put every tick on whole pixel rows (no anti-aliasing), as a ruler seen at low resolution.
    lying : bool
        The ruler along image rows (transposed).
    blur_px, noise : float
        Gaussian blur sigma in px and noise sigma in levels.
    """
    import cv2

    ss = 1 if whole_rows else DRAW_SUPERSAMPLING
    length, breadth = size_px or (int(start_px + length_m * px_per_m + 40), width_px + 80)
    canvas = np.empty((length * ss, breadth * ss, 3), np.uint8)
    canvas[:] = wall_bgr
    left, top, bottom = 40 * ss, int(start_px * ss), int((start_px + length_m * px_per_m) * ss)
    canvas[top:bottom, left: left + width_px * ss] = face_bgr
    count = int(round(length_m / tick_m))
    for index in range(count + 1):
        centre = start_px + index * tick_m * px_per_m
        if bands:
            if index % 2 == 0 and index < count:
                canvas[int(centre * ss): int((centre + tick_m * px_per_m) * ss), left: left + width_px * ss] = mark_bgr
            continue
        level = max(fraction for every, fraction in tick_levels if index % every == 0) \
            if any(index % every == 0 for every, _ in tick_levels) else None
        if level is None:
            continue
        if whole_rows:
            first = int(round(centre - 0.5 * tick_width_px + 0.5))
            rows = slice(first, first + max(int(round(tick_width_px)), 1))
        else:
            rows = slice(int(round((centre - 0.5 * tick_width_px) * ss)), int(round((centre + 0.5 * tick_width_px) * ss)))
        canvas[rows, left: left + int(level * width_px * ss)] = mark_bgr
        if numbers_every and index % numbers_every == 0 and index:
            cv2.putText(canvas, str(index // numbers_every), (left + int(0.65 * width_px * ss), int((centre + 3) * ss)),
                        cv2.FONT_HERSHEY_SIMPLEX, 0.3 * ss, mark_bgr, max(ss, 1))
    image = canvas if ss == 1 else cv2.resize(canvas, (breadth, length), interpolation=cv2.INTER_AREA)
    image = image.astype(float)
    if blur_px:
        image = cv2.GaussianBlur(image, (0, 0), blur_px)
    image += np.random.default_rng(seed).normal(0.0, noise, image.shape)
    image = np.clip(image, 0, 255).astype(np.uint8)
    return np.ascontiguousarray(image.transpose(1, 0, 2)) if lying else image


def real_data_dir(name):
    """The folder ``name`` of the shared real recordings (``../shared/realdata`` from the repository,
    or ``$DROPFIT_REALDATA``), or None where it is absent."""
    root = pathlib.Path(__file__).resolve().parents[1]
    candidates = [os.environ.get("DROPFIT_REALDATA"), root.parent / "shared" / "realdata",
                  root.parent.parent / "shared" / "realdata"]
    for candidate in candidates:
        if candidate and (pathlib.Path(candidate) / name).is_dir():
            return pathlib.Path(candidate) / name
    return None


def encode_clip(path, frames, fps=30, codec="libx264", rotation_deg=None, pts=None, time_base=None, gop=None,
                pix_fmt=None, x264_params=None):
    """Encode BGR uint8 ``frames`` with PyAV into ``path`` (container from the suffix); return ``path``.

    Parameters
    ----------
    fps : int or fractions.Fraction
        The container's frame rate, frames/s.
    codec : str
        ``libx264`` (yuv420p) or ``mjpeg`` (yuvj420p).
    rotation_deg : int, optional
        Counter-clockwise display rotation written as the stream's display matrix, degrees.
    pts, time_base : sequence of int, fractions.Fraction, optional
        Each frame's presentation time stamp, in ``time_base`` units, for irregular timing.
    gop : int, optional
        Frames between key frames.
    pix_fmt : str, optional
        The stored pixel format, instead of the codec's 4:2:0 one (``yuv444p`` for libx264).
    x264_params : str, optional
        libx264's own options (``open-gop=1:bframes=3``).
    """
    import av

    height, width = frames[0].shape[:2]
    container = av.open(str(path), "w")
    stream = container.add_stream(codec, rate=fps)
    stream.width, stream.height = width, height
    stream.pix_fmt = pix_fmt or ("yuvj420p" if codec == "mjpeg" else "yuv420p")
    if gop:
        stream.codec_context.gop_size = gop
    if codec == "libx264":
        # small clips, little loss: the tracker's accuracy is tested elsewhere
        stream.options = {"crf": "12"} | ({"x264-params": x264_params} if x264_params else {})
    if time_base is not None:
        stream.codec_context.time_base = time_base
    if rotation_deg is not None:
        stream.set_display_rotation(rotation_deg)
    for index, image in enumerate(frames):
        frame = av.VideoFrame.from_ndarray(np.ascontiguousarray(image), format="bgr24")
        if pts is not None:
            frame.pts, frame.time_base = int(pts[index]), time_base
        container.mux(stream.encode(frame))
    container.mux(stream.encode())
    container.close()
    return path


def ball_frames(count=40, shape=(96, 160), radius=6.0, seed=0, step_px=(3.0, 0.0), start=(20.3, 20.2),
                gravity_px=0.08):
    """``count`` BGR frames of a bright ball on a smoothly patterned grey background moving on a parabola, and
    the true centres (x, y), px (anti-aliased by 4 × 4 supersampling). Frame ``k`` has the centre
    ``start + k step_px + (0, gravity_px k² / 2)``: the defaults keep 40 frames in view."""
    rng = np.random.default_rng(seed)
    rows, columns = np.mgrid[0:shape[0], 0:shape[1]]
    phase = rng.uniform(0, 2 * np.pi, 2)
    background = 90.0 + 10.0 * np.sin(columns / 9.0 + phase[0]) * np.cos(rows / 7.0 + phase[1]) + 0.1 * columns
    rows, columns = np.mgrid[0:shape[0] * 4, 0:shape[1] * 4] / 4.0 - 0.375
    frames, centres = [], []
    for k in range(count):
        x, y = start[0] + step_px[0] * k, start[1] + step_px[1] * k + 0.5 * gravity_px * k * k
        inside = ((columns - x) ** 2 + (rows - y) ** 2 <= radius ** 2).reshape(shape[0], 4, shape[1], 4).mean(axis=(1, 3))
        grey = np.clip(np.round(background * (1 - inside) + 230.0 * inside), 0, 255).astype(np.uint8)
        frames.append(np.repeat(grey[:, :, None], 3, axis=2))
        centres.append((x, y))
    return frames, np.array(centres)


def real_recording(folder, name):
    """Path of a real recording in :func:`real_data_dir` ``folder``; skips the test when it is not there."""
    import pytest

    directory = real_data_dir(folder)
    if directory is None or not (directory / name).exists():
        pytest.skip(f"real recording {folder}/{name} not found (../shared/realdata beside the repository, or "
                    f"$DROPFIT_REALDATA)")
    return directory / name


def tracker_point_mass(trz_path):
    """The hand-marked positions and the calibration of a Tracker project (.trz), as the product reads them
    (:func:`dropfit.importers.tracker.read_tracker_project`).

    Returns
    -------
    (numpy.ndarray, dict)
        Rows (Tracker frame index, x_px, y_px), image px with y down, of its first point mass; and the first
        frame's coordinate system ``{"x_origin_px", "y_origin_px", "angle_rad", "px_per_m"}`` and the
        clip's step ``delta_t_s``.
    """
    from dropfit.importers.tracker import read_tracker_project

    project = read_tracker_project(trz_path)
    ball = project.point_masses[0]
    x0, y0, angle, x_scale, _ = (values[0] for values in project.frame_coords(ball.frames[:1]))
    return np.column_stack([ball.frames, ball.x_px, ball.y_px]), {
        "x_origin_px": x0, "y_origin_px": y0, "angle_rad": angle, "px_per_m": x_scale,
        "delta_t_s": project.frame_interval_s}


#: Gravity where Tracker's ball toss was filmed (Aptos, California, 37° N, near sea level), m/s².
BALL_TOSS_G_M_S2 = 9.80


def grey_frames(path):
    """Every frame of a video as grey levels (float32 arrays), decoded with PyAV."""
    import av

    with av.open(str(path)) as container:
        return [frame.to_ndarray(format="gray").astype(np.float32) for frame in container.decode(video=0)]


def excerpt_frames_in_clip(trz_path, clip_frames):
    """The clip frame each frame of a Tracker project's own video (the excerpt in its ``.trz``) matches best.

    Returns
    -------
    numpy.ndarray
        For each excerpt frame, the index into ``clip_frames`` with the least mean absolute difference.
    """
    import tempfile
    import zipfile

    with zipfile.ZipFile(trz_path) as archive, tempfile.TemporaryDirectory() as directory:
        name = next(n for n in archive.namelist() if n.endswith(".mp4"))
        excerpt = pathlib.Path(directory) / "excerpt.mp4"
        excerpt.write_bytes(archive.read(name))
        excerpt_frames = grey_frames(excerpt)
    return np.array([int(np.argmin([np.abs(frame - c).mean() for c in clip_frames])) for frame in excerpt_frames])


def depth_motion_fit(time_s, x, y):
    """g of a free flight seen by a camera the ball moves towards or away from at a steady speed.

    The image of a point at depth Z₀(1 + c·t) shrinks by 1/(1 + c·t) about the principal point, so in the
    plane's units the path is x = (x₀ + vₓt)/(1 + ct), y = (y₀ + v_y t − g t²/2)/(1 + ct), y up (the principal
    point is absorbed in x₀, vₓ, y₀, v_y). A parabola fitted to such a path gets a horizontal acceleration
    and a g off by the depth's change; this model does not. Its g is at the scale of t = 0: at time t it is
    g / (1 + c·t).

    Parameters
    ----------
    time_s, x, y : numpy.ndarray
        Times in s and positions in the plane's length unit (m), y up.

    Returns
    -------
    dict
        ``g`` and ``g_se`` (unit/s², se scaled by the residuals), ``c`` and ``c_se`` (1/s), ``rms`` (unit).
    """
    from scipy.optimize import curve_fit

    count = len(time_s)

    def path(stacked_t, x0, vx, y0, vy, g, c):
        t = stacked_t[:count]
        shrink = 1 + c * t
        return np.concatenate([(x0 + vx * t) / shrink, (y0 + vy * t - 0.5 * g * t ** 2) / shrink])

    stacked_t, observed = np.concatenate([time_s, time_s]), np.concatenate([x, y])
    start = [x[0], 0.0, y[0], 0.0, 9.8, 0.0]
    values, cov = curve_fit(path, stacked_t, observed, p0=start)
    residual = observed - path(stacked_t, *values)
    return {"g": values[4], "g_se": float(np.sqrt(cov[4, 4])), "c": values[5], "c_se": float(np.sqrt(cov[5, 5])),
            "rms": float(np.sqrt(np.mean(residual ** 2)))}


def phone_clip(preset, directory, seed=0, downscale=0.5, suffix=None, **changes):
    """Render a phonesim preset (with ``changes`` to its :class:`phonesim.ClipConfig`) into ``directory``.

    Returns
    -------
    (pathlib.Path, dict)
        The clip, in the container ``suffix`` names (by default the one the preset was described with), and its
        truth (``<stem>.truth.json``).
    """
    import dataclasses
    import json

    import phonesim

    config = dataclasses.replace(phonesim.PRESETS[preset].scaled(downscale), **changes)
    path = pathlib.Path(directory) / f"{preset}{suffix or phonesim.PRESET_SUFFIX[preset]}"
    phonesim.render_clip(config, path, seed=seed)
    return path, json.loads(path.with_suffix(".truth.json").read_text())
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


def disc_coverage(shape, cx, cy, r):
    """Fraction of each pixel covered by a disc (centre cx, cy and radius r, px), by supersampling.

    Pixel (i, j) spans [j-0.5, j+0.5] × [i-0.5, i+0.5] (OpenCV's convention, as the tracker's).
    Returns a float array of ``shape`` (height, width).
    """
    a = np.zeros(shape)
    h, w = shape
    x0, x1 = max(int(np.floor(cx - r - 1)), 0), min(int(np.ceil(cx + r + 1)) + 1, w)
    y0, y1 = max(int(np.floor(cy - r - 1)), 0), min(int(np.ceil(cy + r + 1)) + 1, h)
    if x1 <= x0 or y1 <= y0:
        return a
    offsets = (np.arange(SUPERSAMPLING) + 0.5) / SUPERSAMPLING - 0.5
    xs = (np.arange(x0, x1)[:, None] + offsets).ravel()
    ys = (np.arange(y0, y1)[:, None] + offsets).ravel()
    inside = (xs[None, :] - cx) ** 2 + (ys[:, None] - cy) ** 2 <= r * r
    a[y0:y1, x0:x1] = inside.reshape(y1 - y0, SUPERSAMPLING, x1 - x0, SUPERSAMPLING).mean(axis=(1, 3))
    return a


def centre_errors(table, truth):
    """Distance (px) of each tracked centre (``x_px``, ``y_px``) from the true one, truth shape (n, 2)."""
    return np.hypot(table["x_px"].to_numpy() - truth[:, 0], table["y_px"].to_numpy() - truth[:, 1])


def rms(values):
    """Root mean square."""
    return float(np.sqrt(np.mean(np.square(values))))


def bouncing_ball(time_s, drop_height_m, e, g=9.81):
    """Closed-form height (m) of a point ball released at rest from ``drop_height_m`` at t = 0 onto a
    floor at 0, bouncing with constant ``e`` and no drag, and at rest once its bounces fade out: the
    tests' own truth for importer fixtures (no dropfit code)."""
    time_s = np.asarray(time_s, float)
    height = np.zeros_like(time_s)
    start, speed = 0.0, 0.0  # the first flight starts at the apex
    fall = np.sqrt(2 * drop_height_m / g)
    first = time_s < fall
    height[first] = drop_height_m - 0.5 * g * time_s[first] ** 2
    start, speed = fall, e * g * fall
    while speed > 1e-4:
        duration = 2 * speed / g
        inside = (time_s >= start) & (time_s < start + duration)
        tau = time_s[inside] - start
        height[inside] = speed * tau - 0.5 * g * tau ** 2
        start, speed = start + duration, e * speed
    return height


def with_sound_track(video_path, out_path, samples, rate_hz, sound_start_s=0.0):
    """Copy a video's frames (re-encoded with H.264, little loss) into ``out_path`` (.mov) with a mono 16-bit PCM
    sound track of ``samples`` (full scale 1) whose first sample is stamped ``sound_start_s`` (s) on the
    container's clock; return ``out_path``."""
    import fractions

    import av

    with av.open(str(video_path)) as source, av.open(str(out_path), "w") as container:
        video_in = source.streams.video[0]
        video = container.add_stream("libx264", rate=video_in.average_rate)
        video.width, video.height, video.pix_fmt = video_in.width, video_in.height, "yuv420p"
        video.options = {"crf": "12"}
        sound = container.add_stream("pcm_s16le", rate=int(rate_hz), layout="mono")
        sound.codec_context.time_base = fractions.Fraction(1, int(rate_hz))
        for frame in source.decode(video_in):
            picture = av.VideoFrame.from_ndarray(frame.to_ndarray(format="bgr24"), format="bgr24")
            picture.pts, picture.time_base = frame.pts, frame.time_base
            container.mux(video.encode(picture))
        container.mux(video.encode())
        pcm = np.clip(np.round(np.asarray(samples) * 32767), -32768, 32767).astype(np.int16)
        start = int(round(sound_start_s * rate_hz))
        for first in range(0, pcm.size, 4096):
            block = av.AudioFrame.from_ndarray(pcm[None, first:first + 4096], format="s16", layout="mono")
            block.sample_rate, block.pts = int(rate_hz), start + first
            block.time_base = fractions.Fraction(1, int(rate_hz))
            container.mux(sound.encode(block))
        container.mux(sound.encode())
    return out_path


def phyphox_number(value, decimal_point="."):
    """A number as phyphox's CSV export writes it: Java's DecimalFormat pattern ``0.000000000E0``
    (``2.500000000E-1``: no plus sign, no leading zeros in the exponent), ``NaN`` for no value."""
    if not np.isfinite(value):
        return "NaN"
    mantissa, exponent = f"{value:.9E}".split("E")
    return f"{mantissa}E{int(exponent)}".replace(".", decimal_point)


def write_phyphox_export(path, sets, separator=",", decimal_point="."):
    """phyphox's zipped CSV export, as its source writes it (phyphox-android, ``DataExport.java``,
    ``CsvFormat``): per data set ``<name>.csv`` with the column names quoted, the rows as long as the
    longest column (``NaN`` padding), and ``meta/device.csv``, ``meta/time.csv``.

    ``sets`` maps each set's name to ``{column name: values}``.
    """
    import zipfile

    with zipfile.ZipFile(path, "w") as archive:
        for name, columns in sets.items():
            header = separator.join(f'"{column}"' for column in columns)
            length = max(len(values) for values in columns.values())
            lines = [separator.join(phyphox_number(values[row] if row < len(values) else np.nan, decimal_point)
                                    for values in columns.values()) for row in range(length)]
            archive.writestr(f"{name}.csv", "\n".join([header, *lines]) + "\n")
        archive.writestr("meta/device.csv", f'"property"{separator}"value"\n"deviceModel"{separator}"test"\n')
        archive.writestr("meta/time.csv", f'"event"{separator}"experiment time"{separator}"system time"{separator}'
                                          f'"system time text"\n"START"{separator}'
                                          f'{phyphox_number(0.0, decimal_point)}{separator}1700000000{decimal_point}000'
                                          f'{separator}"2023-11-14 22:13:20.000 UTC+00:00"\n')
    return path


#: A short synthetic tennis drop (254 cm, constant e 0.745, a 100 Hz sensor in m) as a scenarios file
#: (``dropfit synth --scenarios``): the scenario ``tennis_short`` the report tests run through the stages.
TENNIS_SHORT_SCENARIOS = """\
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
