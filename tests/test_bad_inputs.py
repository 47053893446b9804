"""Every bad input gets one clear line: a sweep of bad inputs through the real command line.

Each kind of bad input is made in ``tmp_path`` and given to the stage it belongs to (``measure`` for
recordings and option values, ``analyse`` for trajectories, ``fit`` and ``report`` for the files the
analysis writes, ``summary`` and ``qc`` for fit results). For each, the stage must exit 1 with exactly
one line on standard error, ``dropfit: error: <file>: <what is wrong>; <what to try>``, that names the
offending file, holds no traceback and no control character, is at most 600 characters long (whole: the
user text it quotes is shortened, never its diagnosis or advice; 300 was once a cut), and
leaves no output or temporary file; with ``--record-failure`` it must exit 0 and write every output
as a failure record carrying that same line. The summary and QC stages list a bad fit result as a
failed row instead (a batch goes on): there the row's message obeys the same rules.

The sweep runs in this process (``dropfit.cli.main`` with ``capsys``); a handful of cases also run in
a subprocess, to see that nothing else (decoder noise, warnings) reaches the terminal.
"""

from __future__ import annotations

import builtins
import errno
import io
import json
import os
import shutil
import subprocess
import sys
import time
import unicodedata
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

from dropfit.cli import main
from dropfit.errors import LINE_LIMIT, shown_path
from dropfit.video.opencv import cv2
from dropfit.synth import sample_height_log, simulate_drop

from helpers import CALL_TIMEOUT_S, dropfit, without_progress

#: The longest line a bad input's message may make, prefix included (characters): whole, it quotes a path
#: (up to 100 characters) at most twice and cells of at most 60.
MAX_LINE = 600
#: The true e of the good recording, and how close its analysis must come (a 100 Hz, 1 mm log).
TRUE_E = 0.8  # 1
E_TOL = 0.005  # 1
#: A refusal of an absurd header must come this fast (s): 40 000 columns took 31 s before.
HUGE_HEADER_S = 1.0

MISSING, DIRECTORY = "<missing>", "<directory>"


# --- the good recording and what the stages make of it -------------------------------------------

@dataclass
class Good:
    """A good 100 Hz height log, its px twin, the stage outputs of it, and a small video (tmp files)."""

    header: str
    rows: list
    directory: Path
    px_rows: list = field(default_factory=list)

    @property
    def text(self):
        return "# a good height log\n" + self.log(self.rows)

    def log(self, rows, header=None):
        """CSV text: ``header`` (default the good one) and data ``rows``."""
        return "\n".join([self.header if header is None else header, *rows]) + "\n"

    def mapped(self, change):
        """The good log with every data row ``time,height`` (strings) replaced by ``change(time, height)``."""
        return self.log([change(*row.split(",")) for row in self.rows])

    def with_row(self, index, row):
        rows = list(self.rows)
        rows[index] = row
        return self.log(rows)

    def file(self, name):
        return (self.directory / name).read_bytes()


def _clip_frames(fps=120.0, duration_s=1.5, px_per_m=400.0, size=(96, 256), floor_row=240, seed=0):
    """Frames (BGR) of a 4 cm ball dropped from 45 cm, e = 0.7: a clip small enough to track in a second."""
    truth = simulate_drop(0.45, 0.02, {"kind": "constant", "e0": 0.7}, release_time_s=0.1)
    rng = np.random.default_rng(seed)
    width, height = size
    rows, columns = np.mgrid[0:height, 0:width]
    frames = []
    for index in range(int(round(duration_s * fps))):
        centre_row = floor_row - px_per_m * float(truth.height(index / fps))
        image = np.full((height, width), 50.0)
        image[floor_row:, :] = 120.0  # the floor
        cover = np.clip(0.5 - (np.hypot(columns - width / 2, rows - centre_row) - 0.02 * px_per_m), 0.0, 1.0)
        image = image * (1 - cover) + 220.0 * cover + rng.normal(0.0, 1.5, image.shape)
        frames.append(cv2.cvtColor(image.clip(0, 255).astype(np.uint8), cv2.COLOR_GRAY2BGR))
    return frames, fps


def write_clip(path, frames, fps, fourcc):
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*fourcc), fps, (frames[0].shape[1], frames[0].shape[0]))
    for frame in frames:
        writer.write(frame)
    writer.release()
    return path


@pytest.fixture(scope="module")
def good(tmp_path_factory):
    """The good recording run through measure, analyse and fit (in this process)."""
    return make_good(tmp_path_factory.mktemp("good"))


def make_good(directory):
    """Write the good recording, its stage outputs and the videos into ``directory``."""
    truth = simulate_drop(1.0, 0.03, {"kind": "constant", "e0": TRUE_E}, release_time_s=0.2)
    frame = sample_height_log(truth, np.random.default_rng(3), 100.0, duration_s=2.5, noise_m=0.001)
    lines = frame.to_csv(index=False, float_format="%.6f", na_rep="").splitlines()
    px = sample_height_log(truth, np.random.default_rng(4), 100.0, duration_s=2.5, noise_m=0.001, unit="px",
                           px_per_m=800.0, image_row_of_floor_px=900.0)
    g = Good(lines[0], lines[1:], directory, px.to_csv(index=False, float_format="%.3f").splitlines()[1:])
    (directory / "log.csv").write_text(g.text, encoding="utf-8")
    d = directory
    for argv in (["measure", d / "log.csv", "--out", d / "trajectory.nc", "--sample-id", "good"],
                 ["analyse", d / "trajectory.nc", "--impacts", d / "impacts.csv", "--flights", d / "flights.csv",
                  "--summary", d / "analysis.json"],
                 ["fit", "--analysis", d / "analysis.json", "--impacts", d / "impacts.csv", "--out", d / "fit.json"]):
        assert main([str(arg) for arg in argv]) == 0
    frames, fps = _clip_frames()
    write_clip(d / "clip.avi", frames, fps, "MJPG")
    write_clip(d / "clip.mp4", frames, fps, "mp4v")
    write_clip(d / "blank.avi", [np.full_like(frames[0], 50)] * 60, fps, "MJPG")
    write_clip(d / "one_frame.avi", frames[:1], fps, "MJPG")
    write_clip(d / "five_frames.avi", frames[20:25], fps, "MJPG")
    write_clip(d / "still.avi", [frames[0]] * 90, fps, "MJPG")
    return g


# --- the cases -------------------------------------------------------------------------------------

@dataclass
class Case:
    """A bad input: the stage, its input files (role → (file name, content)), options, and what the line
    must name (default: the bad file's name)."""

    stage: str
    name: str
    inputs: dict
    options: list = field(default_factory=list)
    names: str | None = None
    deny: str | None = None  # the role whose file cannot be read (permission)
    marks: tuple = ()


CASES = []


def bad(stage, name, role, file_name, content, options=(), names=None, deny=False, marks=()):
    """Register a case whose input ``role`` is ``file_name`` with ``content``; the others are good."""
    CASES.append(Case(stage, name, {role: (file_name, content)}, list(options), names, role if deny else None,
                      marks))


def log(name, content, options=(), file_name=None, **kwargs):
    bad("measure", name, "log", file_name or f"{name}.csv", content, options, **kwargs)


def text(value):
    """Content: a fixed text (so that ``lambda g: …`` and fixed contents look alike)."""
    return lambda g: value


def _utf16(g, encoding, bom):
    return (b"\xff\xfe" if bom and encoding == "utf-16-le" else b"\xfe\xff" if bom else b"") + g.text.encode(encoding)


def _netcdf(dataset):
    return bytes(dataset.to_netcdf())


def _trajectory(time_s, y):
    return xr.Dataset({"y": ("time", np.asarray(y, float)), "quality": ("time", np.zeros(len(time_s), "int8"))},
                      coords={"time": np.asarray(time_s, float)}, attrs={"source": "log.csv"})


def _json(value):
    return lambda g: json.dumps(value)


def _edited_json(file_name, edit):
    """Content: the good ``file_name`` (JSON) changed by ``edit(data)`` (which returns the new data)."""
    return lambda g: json.dumps(edit(json.loads(g.file(file_name))))


def _without(key):
    def edit(data):
        del data[key]
        return data
    return edit


def _set(key, value):
    def edit(data):
        data[key] = value
        return data
    return edit


def _table_lines(file_name, edit):
    """Content: the good CSV table ``file_name`` with its lines changed by ``edit(lines)``."""
    return lambda g: "\n".join(edit(g.file(file_name).decode().splitlines())) + "\n"


def _drop_column(file_name, column):
    def edit(lines):
        index = lines[0].split(",").index(column)
        return [",".join(field for i, field in enumerate(line.split(",")) if i != index) for line in lines]
    return _table_lines(file_name, edit)


def _cell(file_name, column, value):
    def edit(lines):
        index = lines[0].split(",").index(column)
        fields = lines[1].split(",")
        fields[index] = value
        return [lines[0], ",".join(fields), *lines[2:]]
    return _table_lines(file_name, edit)


def _failure_record(suffix, message):
    if suffix == "json":
        return _json({"status": "failed", "error": message})
    if suffix == "csv":
        return text(f"# dropfit failed: {message}\n")
    return lambda g: _netcdf(xr.Dataset(attrs={"status": "failed", "error": message}))


# measure: the file itself --------------------------------------------------------------------------
log("missing", MISSING)
log("directory", DIRECTORY)
log("directory_without_suffix", DIRECTORY, file_name="recording")
log("permission", lambda g: g.text, deny=True)
log("empty", b"")
log("only_whitespace", b"   \n\n\t \n")
log("only_comments", text("# dropfit height log\n# nothing was recorded\n"))
log("comments_and_blank_lines", text("# one\n\n# two\n   \n"))
log("binary_garbage", lambda g: np.random.default_rng(1).bytes(4096))
log("nul_bytes", lambda g: g.text.encode()[:100] + b"\x00" * 20 + g.text.encode()[100:])
log("utf16_le_bom", lambda g: _utf16(g, "utf-16-le", True))
log("utf16_be_bom", lambda g: _utf16(g, "utf-16-be", True))
log("utf16_no_bom", lambda g: _utf16(g, "utf-16-le", False))
log("non_utf8_cell", lambda g: g.with_row(5, "0.050000,2.69\xb5").encode("latin-1"))
log("non_utf8_header", lambda g: g.log(g.rows, "time_s,y_\xb5m").encode("latin-1"))
log("bom_and_wrong_columns", lambda g: b"\xef\xbb\xbf" + g.log(g.rows, "t,height").encode())
for suffix, content in [("webm", b"\x1a\x45\xdf\xa3" + b"\x00" * 64), ("gif", b"GIF89a" + b"\x00" * 64),
                        ("png", b"\x89PNG\r\n\x1a\n" + b"\x00" * 64), ("jpg", b"\xff\xd8\xff\xe0" + b"\x00" * 64),
                        ("xlsx", b"PK\x03\x04" + b"\x00" * 64), ("xls", b"\xd0\xcf\x11\xe0" + b"\x00" * 64),
                        ("pdf", b"%PDF-1.4\n"), ("json", b'{"time_s": [0, 0.01]}'), ("nc", b"CDF\x01" + b"\x00" * 32),
                        ("zip", b"PK\x03\x04" + b"\x00" * 64), ("wmv", b"\x30\x26\xb2\x75" + b"\x00" * 64),
                        ("mpg", b"\x00\x00\x01\xba" + b"\x00" * 64), ("ods", b"PK\x03\x04" + b"\x00" * 64),
                        ("wav", b"RIFF\x00\x00\x00\x00WAVE")]:
    log(f"suffix_{suffix}", content, file_name=f"recording.{suffix}")
log("webm_with_csv_content", lambda g: g.text, file_name="log.webm")
log("png_named_csv", b"\x89PNG\r\n\x1a\n" + b"\x00" * 64)
log("xlsx_named_csv", b"PK\x03\x04" + b"\x14\x00" * 40)
log("gzip_named_csv", b"\x1f\x8b\x08\x00" + b"\x00" * 64)
log("avi_named_csv", b"RIFF\x00\x10\x00\x00AVI LIST" + b"\x00" * 64)
log("mp4_named_csv", b"\x00\x00\x00\x18ftypmp42" + b"\x00" * 64)
log("netcdf_named_csv", lambda g: g.file("trajectory.nc"))
log("txt_with_prose", text("These are my drop test notes.\nThe ball bounced four times.\n"), file_name="notes.txt")
log("html_page", text("<!doctype html>\n<html><body>time_s,y_m</body></html>\n"), file_name="page.csv")
log("huge_header_1e6_columns", text(",".join(f"c{i}" for i in range(1_000_000)) + "\n"))
log("huge_header_300_columns", lambda g: ",".join(["time_s", "y_m"] + [f"c{i}" for i in range(298)]) + "\n"
    + "\n".join(row + ",0" * 298 for row in g.rows) + "\n")
log("huge_header_5mb_name", text("time_s," + "y" * 5_000_000 + "\n0.0,1.0\n"))
log("one_5mb_line", text("time_s,y_m\n" + "1" * 5_000_000 + "\n"))

# measure: the table ------------------------------------------------------------------------------
def bad_recording(name, content, options=()):
    bad("recording", name, "log", f"{name}.csv", content, options)


log("no_header", lambda g: "\n".join(g.rows) + "\n")
log("header_only", text("time_s,y_m\n"))
log("header_and_comments_only", text("# log\ntime_s,y_m\n# nothing\n"))
log("unknown_columns", lambda g: g.log(g.rows, "t,height"))
log("only_time_column", lambda g: g.log([row.split(",")[0] for row in g.rows], "time_s"))
log("only_height_column", lambda g: g.log([row.split(",")[1] for row in g.rows], "y_m"))
log("two_height_columns", lambda g: g.log([row + "," + row.split(",")[1] for row in g.rows], "time_s,y_m,y_mm"))
log("two_time_columns", lambda g: g.log([row.split(",")[0] + "," + row for row in g.rows], "time_ms,time_s,y_m"))
log("duplicate_column_names", lambda g: g.log([row + ",1" for row in g.rows], "time_s,y_m,y_m"))
log("unit_inches", lambda g: g.log(g.rows, "time_s,y_in"))
log("unit_hours", lambda g: g.log(g.rows, "time_h,y_m"))
log("decimal_comma_in_comma_csv", lambda g: g.log([row.replace(".", ",") for row in g.rows]))
log("decimal_comma_integer_mm", lambda g: g.log([f"{row.split(',')[0].replace('.', ',')},"
                                                 f"{round(float(row.split(',')[1] or 'nan') * 1000)}"
                                                 for row in g.rows if row.split(",")[1]], "time_s,y_mm"))
log("decimal_comma_quoted", lambda g: g.mapped(lambda t, y: f'"{t.replace(".", ",")}","{y.replace(".", ",")}"'))
log("trailing_comma_on_data_rows", lambda g: g.log([row + "," for row in g.rows]))
log("leading_comma_on_data_rows", lambda g: g.log(["," + row for row in g.rows]))
log("a_row_with_an_extra_field", lambda g: g.with_row(30, g.rows[30] + ",7"))
log("a_row_with_a_missing_field", lambda g: g.with_row(30, g.rows[30].split(",")[0]))
log("text_cell", lambda g: g.with_row(5, "0.050000,abc"))
log("mathtext_cell", lambda g: g.with_row(5, "0.050000,$x$"))
log("mathtext_fraction_cell", lambda g: g.with_row(5, r"0.050000,$\frac{1}{0}$"))
log("mathtext_broken_cell", lambda g: g.with_row(5, r"0.050000,$\sqrt{$"))
log("newline_in_quoted_cell", lambda g: g.with_row(5, '0.050000,"2.6\n93"'))
log("carriage_return_in_cell", lambda g: g.with_row(5, '0.050000,"2.6\r93"'))
log("ansi_escape_cell", lambda g: g.with_row(5, "0.050000,\x1b[31;1mRED\x1b[0m\x1b]0;pwned\x07"))
log("bell_and_backspace_cell", lambda g: g.with_row(5, "0.050000,2.6\x07\x08\x08"))
log("bidi_override_cell", lambda g: g.with_row(5, "0.050000,\u202e2.69"))
log("5mb_cell", lambda g: g.with_row(5, "0.050000," + "9" * 2_000_000 + "x" * 3_000_000))
log("units_in_cells", lambda g: g.mapped(lambda t, y: f"{t},{y} m"))
log("thousands_separator", lambda g: g.mapped(lambda t, y: f'{t},"{float(y or 0) * 1000:,.1f}"'),
    file_name="thousands.csv")
log("hex_number", lambda g: g.with_row(5, "0.050000,0x1F"))
log("nan_time", lambda g: g.with_row(5, "nan,1.0"))
log("empty_time", lambda g: g.with_row(5, ",1.0"))
log("inf_time", lambda g: g.with_row(5, "inf,1.0"))
log("inf_height", lambda g: g.with_row(5, "0.050000,inf"))
log("minus_inf_height", lambda g: g.with_row(5, "0.050000,-inf"))
log("overflowing_height", lambda g: g.with_row(5, "0.050000,1e999"))
log("huge_heights", lambda g: g.mapped(lambda t, y: f"{t},{float(y or 'nan') * 1e300}"))
log("height_offset_1e6_m", lambda g: g.mapped(lambda t, y: f"{t},{float(y or 'nan') + 1e6:.6f}"))
log("repeated_time", lambda g: g.with_row(6, g.rows[5].split(",")[0] + ",1.0"))  # a row repeated exactly is read once
log("decreasing_times", lambda g: g.log(g.rows[::-1]))
log("one_step_back", lambda g: g.with_row(40, f"{float(g.rows[38].split(',')[0]):.6f},1.0"))
log("shuffled_rows", lambda g: g.log([g.rows[i] for i in np.random.default_rng(0).permutation(len(g.rows))]))
log("all_times_equal", lambda g: g.mapped(lambda t, y: f"0.5,{y}"))
log("time_beyond_float_precision", lambda g: g.mapped(lambda t, y: f"{1e300 + float(t):.6g},{y}"))
log("negative_time_steps", lambda g: g.mapped(lambda t, y: f"{-float(t):.6f},{y}"))
# measure: tables of other tools (dropfit.importers) that cannot be read
log("columns_without_meaning", lambda g: g.log([row + ",1" for row in g.rows], "a,b,c"))
log("columns_option_names_no_column", lambda g: g.log(g.rows, "a,b"), ("--columns", "time=a[s],y=q[m]"))
log("columns_option_malformed", lambda g: g.log(g.rows, "a,b"), ("--columns", "when=a"))
log("columns_option_unknown_unit", lambda g: g.log(g.rows, "a,b"), ("--columns", "time=a[h],y=b[m]"))
log("two_possible_heights", lambda g: g.log([row + "," + row.split(",")[1] for row in g.rows],
                                            "t (s),height (m),y (m)"))
log("time_column_in_metres", lambda g: g.log(g.rows, "time (m),height (m)"))
log("two_runs_without_choice", lambda g: g.log([row + "," + row for row in g.rows],
                                               "Run 1: Time (s),Run 1: Position (m),Run 2: Time (s),Run 2: Position (m)"))
log("mtrack2_without_fps", text("Tracks 1 to 1\nFrame\tX1\tY1\tFlag1\n1\t10\t20\t0\n2\t10\t22\t0\n3\t10\t26\t0\n"))
log("mtrack2_no_positions", text("Tracks 1 to 1\nFrame\tX1\tY1\tFlag1\n1\t\t\t\n2\t\t\t\n"), ("--fps", "30"))
log("mtrack2_missing_track", text("Tracks 1 to 1\nFrame\tX1\tY1\tFlag1\n1\t10\t20\t0\n2\t10\t22\t0\n"),
    ("--fps", "30", "--track-id", "4"))
log("trackmate_spots_in_no_track", text("LABEL,ID,TRACK_ID,POSITION_X,POSITION_Y,FRAME\nID1,1,None,1.0,2.0,0\n"
                                        "ID2,2,None,1.5,2.5,1\n"), ("--fps", "30"))
log("tracker_project_without_point_mass", text('<?xml version="1.0" encoding="UTF-8"?>\n<object class='
                                               '"org.opensourcephysics.cabrillo.tracker.TrackerPanel">\n</object>\n'),
    file_name="empty.trk")
log("zip_without_tracker_project", b"PK\x03\x04" + b"\x00" * 64, file_name="project.trz")
log("mraw_without_cihx", b"\x00" * 64, file_name="clip.mraw")
log("cihx_not_photron", text("not the metadata of a camera\n"), file_name="clip.cihx")
log("cihx_without_file_info", text("<cih><fileFormat>MRaw</fileFormat></cih>\n"), file_name="clip2.cihx")
log("format_option_mismatch", lambda g: g.text, ("--format", "mtrack2", "--fps", "30"))
bad_recording("single_row", lambda g: g.log(g.rows[:1]))
bad_recording("two_rows", lambda g: g.log(g.rows[:2]))
bad_recording("three_rows", lambda g: g.log(g.rows[:3]))
bad_recording("ten_rows", lambda g: g.log(g.rows[:10]))
log("all_heights_empty", lambda g: g.mapped(lambda t, y: f"{t},"))
log("all_heights_nan", lambda g: g.mapped(lambda t, y: f"{t},NaN"))
log("all_heights_NA", lambda g: g.mapped(lambda t, y: f"{t},NA"))
log("repeated_header", lambda g: g.log(g.rows[:100] + [g.header] + g.rows[100:]))
log("second_log_with_other_columns", lambda g: g.log(g.rows[:100] + ["time_s,y_mm"] + g.rows[100:]))
log("column_name_with_escapes", lambda g: g.log(g.rows, "time_s,y\x1b[2J_m"))
log("column_name_with_mathtext", lambda g: g.log(g.rows, "time_s,$y_m$"))
log("nul_in_a_cell", lambda g: g.with_row(5, "0.050000,2.6\x00"))
for quantity, unit in [("time", "s"), ("time", "ms"), ("y", "m"), ("y", "mm"), ("y", "px")]:
    log(f"numbers_only_{quantity}_{unit}", lambda g, q=quantity, u=unit: g.log(
        [row.split(",")[0 if q == "time" else 1] for row in g.rows], f"{q}_{u}"))

# a recording whose values are not a drop test: measure or, after it, the analysis refuses it ------
NOT_A_DROP = [
    ("constant_height", lambda g: g.mapped(lambda t, y: f"{t},1.000000"), []),
    ("two_samples", lambda g: g.log(g.rows[:2]), []),
    ("held_still", lambda g: g.mapped(lambda t, y: f"{t},{1.0 + 0.001 * np.sin(float(t) * 50):.6f}"), []),
    ("only_the_fall", lambda g: g.log(g.rows[:60]), []),
    ("rising_only", lambda g: g.log([f"{r.split(',')[0]},{0.5 * float(r.split(',')[0]):.6f}" for r in g.rows]), []),
    ("time_in_ms_under_time_s", lambda g: g.mapped(lambda t, y: f"{float(t) * 1000:.3f},{y}"), []),
    ("time_in_s_under_time_ms", lambda g: g.log(g.rows, "time_ms,y_m"), []),
    ("height_in_cm_under_y_m", lambda g: g.mapped(lambda t, y: f"{t},{float(y or 'nan') * 100:.4f}"), []),
    ("height_in_mm_under_y_m", lambda g: g.mapped(lambda t, y: f"{t},{float(y or 'nan') * 1000:.3f}"), []),
    ("height_in_m_under_y_mm", lambda g: g.log(g.rows, "time_s,y_mm"), []),
    ("noise_of_1_m", lambda g: g.mapped(lambda t, y: f"{t},{float(y or 'nan') + np.random.default_rng(int(float(t) * 100)).normal(0, 1):.6f}"), []),
    ("floor_a_little_low", lambda g: g.text, ["--floor-m", "-0.05", "--ball-radius-m", "0.03"]),
    ("radius_too_large_for_the_floor", lambda g: g.text, ["--floor-m", "0", "--ball-radius-m", "0.2"]),
]
for name, content, options in NOT_A_DROP:
    bad("recording", name, "log", f"{name}.csv", content, options)

# measure: px logs ---------------------------------------------------------------------------------
log("px_too_short_to_calibrate", lambda g: g.log(g.px_rows[:12], "time_s,y_px"))
log("px_flat_cannot_calibrate", lambda g: g.log([f"{r.split(',')[0]},500.0" for r in g.px_rows], "time_s,y_px"))
log("px_with_positive_scale_rows_down", lambda g: g.log(g.px_rows, "time_s,y_px"), ["--scale-m-per-px", "0.00125"])
log("px_noisy_cannot_calibrate", lambda g: g.log(
    [f"{r.split(',')[0]},{float(r.split(',')[1]) + np.random.default_rng(i).normal(0, 300):.3f}"
     for i, r in enumerate(g.px_rows)], "time_s,y_px"))

# measure: paths ------------------------------------------------------------------------------------
log("dollar_path", text("t,height\n0,1\n"), file_name="$x$.csv")
log("mathtext_path", text("t,height\n0,1\n"), file_name=r"$\frac{a}{0}$.csv")
log("newline_in_path", text("t,height\n0,1\n"), file_name="bad\nname.csv", names="bad name.csv")
log("ansi_in_path", text("t,height\n0,1\n"), file_name="red\x1b[31m.csv", names="red?.csv")
log("long_path", text("t,height\n0,1\n"), file_name="n" * 200 + ".csv", names="nnnn.csv")
log("unicode_path", text("t,height\n0,1\n"), file_name="Höhe_Ball_ü.csv")

# measure: option values ---------------------------------------------------------------------------
for option, values in [("--ball-radius-m", ["-0.03", "0", "nan", "inf", "33.5"]),
                       ("--ball-mass-kg", ["-0.057", "0", "nan", "57"]),
                       ("--scale-m-per-px", ["0", "nan", "inf"]),
                       ("--gravity-m-s2", ["-9.8", "0", "nan", "inf"]),
                       ("--floor-m", ["nan", "100", "-100", "0.6"]),
                       ("--capture-fps", ["0", "-240"]),
                       ("--ruler-tick-m", ["0", "-0.01", "10"])]:
    for value in values:
        extra = ["--ball-radius-m", "0.03"] if option == "--floor-m" else []
        log(f"option{option}={value}", lambda g: g.text, [option, value, *extra], file_name="log.csv")
log("option--scale-m-per-px=-inf", lambda g: g.text, ["--scale-m-per-px=-inf"], file_name="log.csv")
log("negative_scale_axis_up", lambda g: g.log([f"{r.split(',')[0]},{-float(r.split(',')[1]):.3f}"
                                               for r in g.px_rows], "time_s,y_px"), ["--scale-m-per-px", "-0.00125"])


# measure: videos ----------------------------------------------------------------------------------
def video(name, file_name, content, options=("--ball-radius-m", "0.02"), **kwargs):
    bad("measure", f"video_{name}", "log", file_name, content, options, **kwargs)


def truncated(file_name, fraction):
    return lambda g: g.file(file_name)[: int(len(g.file(file_name)) * fraction)]


video("zero_bytes_avi", "clip.avi", b"")
video("zero_bytes_mp4", "clip.mp4", b"")
video("truncated_avi_40_percent", "clip.avi", truncated("clip.avi", 0.4))
video("truncated_avi_90_percent", "clip.avi", truncated("clip.avi", 0.9))
video("truncated_avi_header_only", "clip.avi", truncated("clip.avi", 0.02))
video("truncated_mp4", "clip.mp4", truncated("clip.mp4", 0.7))
video("random_bytes_avi", "clip.avi", lambda g: np.random.default_rng(2).bytes(50_000))
video("random_bytes_mov", "clip.mov", lambda g: np.random.default_rng(3).bytes(50_000))
video("text_named_mp4", "clip.mp4", text("this is not a video\n"))
video("height_log_named_mp4", "clip.mp4", lambda g: g.text)
video("png_named_avi", "clip.avi", b"\x89PNG\r\n\x1a\n" + b"\x00" * 64)
video("mp4_named_avi_damaged", "clip.avi", truncated("clip.mp4", 0.3))
video("directory_named_avi", "clip.avi", DIRECTORY)
video("missing_mp4", "clip.mp4", MISSING)
video("permission_avi", "clip.avi", lambda g: g.file("clip.avi"), deny=True)
video("blank_frames", "clip.avi", lambda g: g.file("blank.avi"))
video("one_frame", "clip.avi", lambda g: g.file("one_frame.avi"))
video("five_frames", "clip.avi", lambda g: g.file("five_frames.avi"))
video("ball_never_moves", "clip.avi", lambda g: g.file("still.avi"))
video("negative_radius", "clip.avi", lambda g: g.file("clip.avi"), ["--ball-radius-m", "-0.02"])
video("zero_capture_fps", "clip.avi", lambda g: g.file("clip.avi"), ["--ball-radius-m", "0.02", "--capture-fps", "0"])
video("nan_scale", "clip.avi", lambda g: g.file("clip.avi"), ["--scale-m-per-px", "nan"])
video("floor_far_above", "clip.avi", lambda g: g.file("clip.avi"), ["--ball-radius-m", "0.02", "--floor-m", "5"])

# analyse: the trajectory ----------------------------------------------------------------------------
TIME = np.arange(0.0, 2.0, 0.01)


def trajectory(name, content, options=(), names=None, **kwargs):
    bad("analyse", name, "trajectory", "trajectory.nc", content, options, names, **kwargs)


trajectory("missing", MISSING)
trajectory("directory", DIRECTORY)
trajectory("permission", lambda g: g.file("trajectory.nc"), deny=True)
trajectory("empty", b"")
trajectory("truncated_half", truncated("trajectory.nc", 0.5))
trajectory("truncated_header", truncated("trajectory.nc", 0.01))
trajectory("garbage", lambda g: np.random.default_rng(4).bytes(2000))
trajectory("height_log_instead", lambda g: g.text)
trajectory("json_instead", text('{"time": [0, 1]}'))
trajectory("png_instead", b"\x89PNG\r\n\x1a\n" + b"\x00" * 64)
trajectory("netcdf_without_y", lambda g: _netcdf(xr.Dataset({"h": ("time", TIME)}, coords={"time": TIME})))
trajectory("netcdf_y_without_time", lambda g: _netcdf(xr.Dataset({"y": ("n", TIME), "quality": ("n", TIME)})))
trajectory("netcdf_text_y", lambda g: _netcdf(xr.Dataset({"y": ("time", TIME.astype(str)),
                                                          "quality": ("time", TIME)}, coords={"time": TIME})))
trajectory("decreasing_time", lambda g: _netcdf(_trajectory(TIME[::-1], np.ones_like(TIME))))
trajectory("nan_time", lambda g: _netcdf(_trajectory(np.r_[TIME[:5], np.nan, TIME[6:]], np.ones_like(TIME))))
trajectory("no_samples", lambda g: _netcdf(_trajectory([], [])))
trajectory("all_heights_nan", lambda g: _netcdf(_trajectory(TIME, np.full_like(TIME, np.nan))), names="log.csv")
trajectory("three_samples", lambda g: _netcdf(_trajectory(TIME[:3], [1.0, 0.9, 0.8])), names="log.csv")
trajectory("failure_record", _failure_record("nc", "data/ball.csv: time does not increase at data row 12"),
           names="data/ball.csv")
trajectory("failure_record_5mb_with_escapes", _failure_record(
    "nc", "data/ball.csv: \x1b[31mbad\x1b[0m\n" + "x" * 5_000_000), names="data/ball.csv")
trajectory("failure_record_without_message", lambda g: _netcdf(xr.Dataset(attrs={"status": "failed"})))
trajectory("option_gravity_negative", lambda g: g.file("trajectory.nc"), ["--gravity-m-s2", "-9.8"])
trajectory("option_gravity_nan", lambda g: g.file("trajectory.nc"), ["--gravity-m-s2", "nan"])
trajectory("option_gravity_ten_times_too_high", lambda g: g.file("trajectory.nc"), ["--gravity-m-s2", "98.0665"],
           names="log.csv")


# fit: the analysis summary and the impacts table ---------------------------------------------------
def fit_input(name, role, content, names=None, **kwargs):
    file_name = {"analysis": "analysis.json", "impacts": "impacts.csv"}[role]
    bad("fit", name, role, file_name, content, names=names, **kwargs)


fit_input("analysis_missing", "analysis", MISSING)
fit_input("analysis_directory", "analysis", DIRECTORY)
fit_input("analysis_permission", "analysis", lambda g: g.file("analysis.json"), deny=True)
fit_input("analysis_empty", "analysis", b"")
fit_input("analysis_truncated", "analysis", truncated("analysis.json", 0.5))
fit_input("analysis_binary", "analysis", lambda g: np.random.default_rng(5).bytes(300))
fit_input("analysis_json_list", "analysis", _json([1, 2, 3]))
fit_input("analysis_json_number", "analysis", _json(3.5))
fit_input("analysis_json_string", "analysis", _json("analysis"))
fit_input("analysis_json_null", "analysis", _json(None))
fit_input("analysis_json_true", "analysis", _json(True))
fit_input("analysis_empty_object", "analysis", _json({}))
fit_input("analysis_without_e_covariance", "analysis", _edited_json("analysis.json", _without("e_covariance")))
fit_input("analysis_without_drop_height", "analysis", _edited_json("analysis.json", _without("drop_height_m")))
fit_input("analysis_text_drop_height", "analysis", _edited_json("analysis.json", _set("drop_height_m", "2.5 m")))
fit_input("analysis_covariance_wrong_shape", "analysis", _edited_json("analysis.json", _set("e_covariance", [[1.0]])))
fit_input("analysis_covariance_of_text", "analysis", _edited_json("analysis.json", _set("e_covariance", "big")))
fit_input("analysis_attrs_list", "analysis", _edited_json("analysis.json", _set("trajectory_attrs", [1])))
fit_input("analysis_failure_record", "analysis", _failure_record("json", "data/ball.csv: no bounce found"),
          names="data/ball.csv")
fit_input("analysis_trajectory_instead", "analysis", lambda g: g.file("trajectory.nc"))
fit_input("impacts_missing", "impacts", MISSING)
fit_input("impacts_directory", "impacts", DIRECTORY)
fit_input("impacts_permission", "impacts", lambda g: g.file("impacts.csv"), deny=True)
fit_input("impacts_empty", "impacts", b"")
fit_input("impacts_header_only", "impacts", _table_lines("impacts.csv", lambda lines: lines[:1]))
fit_input("impacts_truncated_mid_row", "impacts", lambda g: g.file("impacts.csv")[:-40])
fit_input("impacts_truncated_mid_header", "impacts", lambda g: g.file("impacts.csv")[:200])
fit_input("impacts_without_e", "impacts", _drop_column("impacts.csv", "e"))
fit_input("impacts_text_e", "impacts", _cell("impacts.csv", "e", "abc"))
fit_input("impacts_dollar_e", "impacts", _cell("impacts.csv", "e", "$e$"))
fit_input("impacts_one_row_too_many", "impacts", _table_lines("impacts.csv", lambda lines: lines + lines[-1:]))
fit_input("impacts_failure_record", "impacts", _failure_record("csv", "data/ball.csv: no bounce found"),
          names="data/ball.csv")
fit_input("impacts_binary", "impacts", lambda g: np.random.default_rng(6).bytes(500))
fit_input("impacts_flights_instead", "impacts", lambda g: g.file("flights.csv"))
fit_input("impacts_json_instead", "impacts", lambda g: g.file("analysis.json"))
bad("fit", "option_itf_window_reversed", "analysis", "analysis.json", lambda g: g.file("analysis.json"),
    ["--itf-rebound-min-m", "1.47", "--itf-rebound-max-m", "1.35"])
bad("fit", "option_itf_drop_height_nan", "analysis", "analysis.json", lambda g: g.file("analysis.json"),
    ["--itf-drop-height-m", "nan"])


# report: each of its five inputs -------------------------------------------------------------------
def report_input(name, role, file_name, content, names=None):
    bad("report", name, role, file_name, content, names=names)


report_input("trajectory_truncated", "trajectory", "trajectory.nc", truncated("trajectory.nc", 0.5))
report_input("trajectory_missing", "trajectory", "trajectory.nc", MISSING)
report_input("flights_truncated", "flights", "flights.csv", lambda g: g.file("flights.csv")[:-30])
report_input("flights_missing_columns", "flights", "flights.csv", _drop_column("flights.csv", "t_apex_s"))
report_input("flights_empty", "flights", "flights.csv", b"")
report_input("impacts_truncated", "impacts", "impacts.csv", lambda g: g.file("impacts.csv")[:-40])
report_input("impacts_missing_columns", "impacts", "impacts.csv", _drop_column("impacts.csv", "e_se"))
report_input("analysis_json_list", "analysis", "analysis.json", _json([]))
report_input("analysis_null_noise", "analysis", "analysis.json", _edited_json("analysis.json", _set("noise_m", None)))
report_input("fit_json_list", "fit", "fit.json", _json(["fit"]))
report_input("fit_json_number", "fit", "fit.json", _json(1))
report_input("fit_without_theory", "fit", "fit.json", _edited_json("fit.json", _without("theory")))
report_input("fit_restitution_is_text", "fit", "fit.json", _edited_json("fit.json", _set("restitution", "0.8")))
report_input("fit_truncated", "fit", "fit.json", truncated("fit.json", 0.6))
report_input("fit_failure_record", "fit", "fit.json", _failure_record("json", "data/$x$.csv: no bounce found"),
             names="data/$x$.csv")
report_input("fit_missing", "fit", "fit.json", MISSING)
bad("report", "fit_permission", "fit", "fit.json", lambda g: g.file("fit.json"), deny=True)

BAD_IN_SUMMARY = [  # fit results the batch summary and QC list as failed rows: (name, content, what the row names)
    ("json_list", _json([1, 2]), None), ("json_number", _json(2), None), ("json_string", _json("fit"), None),
    ("json_null", _json(None), None), ("truncated", truncated("fit.json", 0.5), None), ("missing", MISSING, None),
    ("directory", DIRECTORY, None), ("binary", lambda g: np.random.default_rng(7).bytes(100), None),
    ("without_itf", _edited_json("fit.json", _without("itf")), None),
    ("itf_is_a_list", _edited_json("fit.json", _set("itf", [])), None),
    ("failure_record_5mb_with_escapes", _json({"status": "failed", "error": "data/b.csv: \x1b[2J\r\n" + "y" * 5_000_000}),
     "data/b.csv"),
    ("failure_record_without_message", _json({"status": "failed"}), None),
]


# --- running a case ----------------------------------------------------------------------------------

def deny_reading(monkeypatch, path):
    """Make ``open`` (and so every reader of the stages) fail on ``path`` as for a file without read permission."""
    target = os.path.abspath(path)
    real_open = builtins.open

    def guarded(file, *args, **kwargs):
        if isinstance(file, (str, os.PathLike)) and os.path.abspath(os.fspath(file)) == target:
            raise PermissionError(errno.EACCES, "Permission denied", os.fspath(file))
        return real_open(file, *args, **kwargs)

    monkeypatch.setattr(builtins, "open", guarded)
    monkeypatch.setattr(io, "open", guarded)


GOOD_INPUTS = {"log": "log.csv", "trajectory": "trajectory.nc", "flights": "flights.csv", "impacts": "impacts.csv",
               "analysis": "analysis.json", "fit": "fit.json"}
STAGE_INPUTS = {"measure": ["log"], "recording": ["log"], "analyse": ["trajectory"], "fit": ["analysis", "impacts"],
                "report": ["trajectory", "flights", "impacts", "analysis", "fit"]}
STAGE_OUTPUTS = {"measure": ["trajectory.nc"], "analyse": ["impacts.csv", "flights.csv", "analysis.json"],
                 "fit": ["fit.json"], "report": ["report.html", "report.png"]}


def put(path, content, good):
    """Write ``content`` (bytes, text, a function of the good recording, MISSING or DIRECTORY) at ``path``."""
    content = content(good) if callable(content) else content
    if content == MISSING:
        return
    if content == DIRECTORY:
        path.mkdir()
        return
    path.write_bytes(content if isinstance(content, bytes) else content.encode("utf-8"))


def prepare(case, good, directory):
    """The inputs of ``case`` in ``directory``: role → path (the good file where the case changes nothing)."""
    directory.mkdir()
    paths = {}
    for role in STAGE_INPUTS[case.stage]:
        file_name, content = case.inputs.get(role, (GOOD_INPUTS[role], lambda g, r=role: g.file(GOOD_INPUTS[r])))
        paths[role] = directory / file_name
        put(paths[role], content, good)
    return paths


def argv(stage, inputs, out, options):
    i = {role: str(path) for role, path in inputs.items()}
    o = {name: str(out / name) for name in STAGE_OUTPUTS[stage]}
    return {"measure": ["measure", i.get("log", ""), "--out", o.get("trajectory.nc", "")],
            "analyse": ["analyse", i.get("trajectory", ""), "--impacts", o.get("impacts.csv", ""),
                        "--flights", o.get("flights.csv", ""), "--summary", o.get("analysis.json", "")],
            "fit": ["fit", "--analysis", i.get("analysis", ""), "--impacts", i.get("impacts", ""),
                    "--out", o.get("fit.json", "")],
            "report": ["report", *[arg for role in STAGE_INPUTS["report"] for arg in (f"--{role}", i.get(role, ""))],
                       "--html", o.get("report.html", ""), "--figure", o.get("report.png", "")]}[stage] + options


def check_line(stderr, names):
    """stderr is one clear line naming ``names`` (besides a tracked clip's progress line); return the
    message (the line without its prefix)."""
    assert "Traceback" not in stderr
    lines = without_progress(stderr)
    assert len(lines) == 1, stderr[:2000]
    line = lines[0]
    assert line.startswith("dropfit: error: "), line
    # longer only when the message is a failure record's, forged with megabytes of text: the guard cuts it
    assert len(line) <= MAX_LINE or (len(line) <= len("dropfit: error: ") + LINE_LIMIT and "\u2026" in line), line
    assert not any(unicodedata.category(char) in ("Cc", "Cf") for char in line), repr(line)
    assert names in line, (names, line)
    return line.removeprefix("dropfit: error: ")


def assert_no_output(out):
    """Nothing, not even a temporary ``.name.*`` file, was left in the output directory."""
    assert not out.exists() or list(out.iterdir()) == [], list(out.iterdir())


def assert_failure_record(path, message):
    """``path`` is a failure record that carries ``message``."""
    suffix = path.suffix
    if suffix == ".nc":
        with xr.open_dataset(path) as dataset:
            assert dataset.attrs == {"status": "failed", "error": message}
    elif suffix == ".json":
        assert json.loads(path.read_text(encoding="utf-8")) == {"status": "failed", "error": message}
    elif suffix == ".csv":
        assert path.read_text(encoding="utf-8") == f"# dropfit failed: {message}\n"
    elif suffix == ".html":
        from html import escape

        assert escape(message) in path.read_text(encoding="utf-8")
    else:
        assert path.read_bytes().startswith(b"\x89PNG")


def _case_id(case):
    return f"{case.stage}-{case.name}".replace("\n", "_").replace("\x1b", "ESC")


@pytest.mark.parametrize("case", [pytest.param(case, id=_case_id(case), marks=case.marks) for case in CASES])
def test_bad_input_gets_one_clear_line(case, good, tmp_path, capsys, monkeypatch):
    """Exit 1 with one clear line naming the bad file and nothing written; with --record-failure, exit 0
    and every output a failure record carrying that line."""
    inputs = prepare(case, good, tmp_path / "in")
    if case.deny:
        deny_reading(monkeypatch, inputs[case.deny])
    bad_role = next(iter(case.inputs))
    names = case.names or shown_path(inputs[bad_role]).rsplit("/", 1)[-1]
    stage, options = case.stage, case.options
    if stage == "recording":  # measure may accept it: then the analysis must refuse it, naming the recording
        stage = "measure"
        if main(argv(stage, inputs, tmp_path / "measured", options)) == 0:
            assert capsys.readouterr().err == ""
            stage, inputs, options = "analyse", {"trajectory": tmp_path / "measured" / "trajectory.nc"}, []
    capsys.readouterr()
    started = time.perf_counter()
    assert main(argv(stage, inputs, tmp_path / "out", options)) == 1
    elapsed = time.perf_counter() - started
    message = check_line(capsys.readouterr().err, names)
    assert_no_output(tmp_path / "out")
    if "huge_header" in case.name:
        assert elapsed < HUGE_HEADER_S

    assert main(argv(stage, inputs, tmp_path / "records", options) + ["--record-failure"]) == 0
    assert check_line(capsys.readouterr().err, names) == message
    for name in STAGE_OUTPUTS[stage]:
        assert_failure_record(tmp_path / "records" / name, message)
    assert sorted(p.name for p in (tmp_path / "records").iterdir()) == sorted(STAGE_OUTPUTS[stage])


@pytest.mark.parametrize("name, content, names", BAD_IN_SUMMARY, ids=[case[0] for case in BAD_IN_SUMMARY])
def test_bad_fit_result_is_a_failed_row_of_the_summary_and_qc(name, content, names, good, tmp_path, capsys):
    """The batch goes on: summary and QC exit 0 and list the bad fit result as failed, with one clear line
    naming it; nothing reaches the terminal."""
    bad_fit = tmp_path / "bad_sample" / "fit.json"
    bad_fit.parent.mkdir()
    put(bad_fit, content, good)
    fits = [str(good.directory / "fit.json"), str(bad_fit)]
    out = tmp_path / "out"
    assert main(["summary", *fits, "--csv", str(out / "summary.csv"), "--html", str(out / "summary.html")]) == 0
    assert main(["qc", *fits, "--batch", "b", "--html", str(out / "qc.html"), "--figure", str(out / "qc.png"),
                 "--csv", str(out / "balls.csv"), "--ball-ids", "$a$", "$\\frac{b}{0}$"]) == 0
    assert capsys.readouterr().err == ""
    import pandas as pd

    table = pd.read_csv(out / "summary.csv")
    assert table["status"].tolist() == ["ok", "failed"]
    message = table.loc[1, "error"]
    check_line(f"dropfit: error: {message}\n", names or shown_path(bad_fit).rsplit("/", 1)[-1])
    assert (out / "qc.png").read_bytes().startswith(b"\x89PNG")


def test_the_sweep_covers_enough_kinds_of_bad_input():
    """At least 170 distinct bad inputs, every file-level, table-level, stage and option class."""
    assert len(CASES) + len(BAD_IN_SUMMARY) >= 170
    assert len({_case_id(case) for case in CASES}) == len(CASES)


# --- odd but valid inputs: these must work ----------------------------------------------------------

VALID = [
    ("utf8_bom", lambda g: b"\xef\xbb\xbf" + g.text.encode(), "log.csv", ()),
    ("crlf_line_ends", lambda g: g.text.replace("\n", "\r\n"), "log.csv", ()),
    ("cr_line_ends", lambda g: g.text.replace("\n", "\r"), "log.csv", ()),
    ("quoted_numbers", lambda g: g.mapped(lambda t, y: f'"{t}","{y}"'), "log.csv", ()),
    ("spaces_after_commas", lambda g: g.mapped(lambda t, y: f"{t}, {y}"), "log.csv", ()),
    ("trailing_comma_on_every_line", lambda g: g.log([row + "," for row in g.rows], g.header + ","), "log.csv", ()),
    ("extra_index_column", lambda g: g.log([f"{i},{row}" for i, row in enumerate(g.rows)], "," + g.header), "log.csv",
     ()),
    ("latin1_comment", lambda g: b"# H\xf6he in m\n" + g.log(g.rows).encode(), "log.csv", ()),
    ("txt_suffix", lambda g: g.text, "log.txt", ()),
    ("nan_dropouts", lambda g: g.log([row if i % 17 else row.split(",")[0] + ",NaN" for i, row in enumerate(g.rows)]),
     "log.csv", ()),
    ("negative_times", lambda g: g.mapped(lambda t, y: f"{float(t) - 1.0:.6f},{y}"), "log.csv", ()),
    ("dollar_in_path", lambda g: g.text, "$x$.csv", ()),
    ("floor_given", lambda g: g.text, "log.csv", ("--floor-m", "0.0", "--ball-radius-m", "0.03")),
    ("epoch_offset_1e6_s", lambda g: g.mapped(lambda t, y: f"{float(t) + 1e6:.6f},{y}"), "log.csv", ()),
    ("epoch_offset_1e9_s", lambda g: g.mapped(lambda t, y: f"{float(t) + 1e9:.6f},{y}"), "log.csv", ()),
    ("unix_epoch_times", lambda g: g.mapped(lambda t, y: f"{float(t) + 1_763_856_000.0:.6f},{y}"), "log.csv", ()),
]


@pytest.mark.parametrize("name, content, file_name, options",
                         [v if hasattr(v, "marks") else pytest.param(*v, id=v[0]) for v in VALID])
def test_odd_but_valid_input_is_analysed(name, content, file_name, options, good, tmp_path, capsys):
    """Valid logs written oddly go through measure, analyse and fit silently and give the true e."""
    log_path = tmp_path / file_name
    put(log_path, content, good)
    d = tmp_path / "out"
    for args in (["measure", log_path, "--out", d / "trajectory.nc", *options],
                 ["analyse", d / "trajectory.nc", "--impacts", d / "impacts.csv", "--flights", d / "flights.csv",
                  "--summary", d / "analysis.json"],
                 ["fit", "--analysis", d / "analysis.json", "--impacts", d / "impacts.csv", "--out", d / "fit.json"]):
        assert main([str(arg) for arg in args]) == 0, capsys.readouterr().err
    assert capsys.readouterr().err == ""
    fit = json.loads((d / "fit.json").read_text(encoding="utf-8"))
    assert fit["restitution"]["e"]["value"] == pytest.approx(TRUE_E, abs=E_TOL)


#: Layouts the height log refused before dropfit read other tools' tables: now read, the mapping printed.
IMPORTED = {
    "units_in_brackets": lambda g: g.log(g.rows, "time [s],height [m]"),
    "uppercase_columns": lambda g: g.log(g.rows, "TIME_S,Y_M"),
    "decimal_comma_semicolons": lambda g: g.log([row.replace(",", ";").replace(".", ",") for row in g.rows],
                                                "time_s;y_m"),
    "semicolons": lambda g: g.log([row.replace(",", ";") for row in g.rows], "time_s;y_m"),
    "tabs": lambda g: g.log([row.replace(",", "\t") for row in g.rows], "time_s\ty_m"),
    "spaces": lambda g: g.log([row.replace(",", " ") for row in g.rows], "time_s y_m"),
    "vertical_bars": lambda g: g.log([row.replace(",", "|") for row in g.rows], "time_s|y_m"),
}


@pytest.mark.parametrize("name", IMPORTED)
def test_other_layouts_are_read_and_say_how(name, good, tmp_path, capsys):
    """Other separators, decimal commas and unit spellings are read: measure prints one line saying what it read
    as what (the guess, for the user to check), and the analysis gives the true e."""
    log_path = tmp_path / f"{name}.csv"
    put(log_path, IMPORTED[name], good)
    d = tmp_path / "out"
    assert main(["measure", str(log_path), "--out", str(d / "trajectory.nc")]) == 0
    err = capsys.readouterr().err
    assert err.startswith(f"read {shown_path(log_path)} as time ") and err.count("\n") == 1, err
    for args in (["analyse", d / "trajectory.nc", "--impacts", d / "impacts.csv", "--flights", d / "flights.csv",
                  "--summary", d / "analysis.json"],
                 ["fit", "--analysis", d / "analysis.json", "--impacts", d / "impacts.csv", "--out", d / "fit.json"]):
        assert main([str(arg) for arg in args]) == 0, capsys.readouterr().err
    fit = json.loads((d / "fit.json").read_text(encoding="utf-8"))
    assert fit["restitution"]["e"]["value"] == pytest.approx(TRUE_E, abs=E_TOL)


def test_user_text_in_figures_is_drawn_literally(good, tmp_path, capsys):
    """A sample id, ball ids and a batch name with ``$…$`` (mathtext) and control characters are drawn as
    they are: the report and the QC chart are written."""
    fit = json.loads(good.file("fit.json"))
    fit["sample_id"] = "$\\frac{a}{0}$ \x1b[31m" + "s" * 10_000
    fit["itf"].update(verdict="pass", rebound_m={"value": 1.40, "se": 0.001})  # a ball on the QC chart
    (tmp_path / "fit.json").write_text(json.dumps(fit), encoding="utf-8")
    d, out = good.directory, tmp_path / "out"
    assert main(["report", "--trajectory", str(d / "trajectory.nc"), "--flights", str(d / "flights.csv"),
                 "--impacts", str(d / "impacts.csv"), "--analysis", str(d / "analysis.json"),
                 "--fit", str(tmp_path / "fit.json"), "--html", str(out / "report.html"),
                 "--figure", str(out / "report.png")]) == 0
    assert main(["qc", str(tmp_path / "fit.json"), "--ball-ids", "$\\sqrt{$", "--batch", "$x$",
                 "--html", str(out / "qc.html"), "--figure", str(out / "qc.png"), "--csv", str(out / "b.csv")]) == 0
    assert capsys.readouterr().err == ""
    assert (out / "report.png").read_bytes().startswith(b"\x89PNG")
    assert (out / "qc.png").read_bytes().startswith(b"\x89PNG")


def test_internal_error_names_the_input_and_keeps_the_traceback_in_the_log(good, tmp_path, capsys, monkeypatch):
    """A bug (here a stage that raises ValueError) still gives one last line naming the stage's input, and
    the failure records carry only that line; the traceback goes to the log (standard error) before it."""
    from dropfit import stages

    def broken(*args, **kwargs):
        raise ValueError("f(a) and f(b) must have different signs")

    monkeypatch.setattr(stages, "fit_summary", broken)
    d = good.directory
    args = ["fit", "--analysis", str(d / "analysis.json"), "--impacts", str(d / "impacts.csv")]
    assert main([*args, "--out", str(tmp_path / "a" / "fit.json")]) == 1
    err = capsys.readouterr().err
    assert "Traceback" in err
    last = err.splitlines()[-1]
    assert last.startswith(f"dropfit: error: {d / 'analysis.json'}: internal error in dropfit fit (ValueError: ")
    assert "Traceback" not in last
    assert not (tmp_path / "a" / "fit.json").exists()
    assert main([*args, "--out", str(tmp_path / "b" / "fit.json"), "--record-failure"]) == 0
    record = json.loads((tmp_path / "b" / "fit.json").read_text(encoding="utf-8"))
    assert record == {"status": "failed", "error": capsys.readouterr().err.splitlines()[-1].removeprefix(
        "dropfit: error: ")}


# --- a few through a real subprocess: nothing else reaches the terminal -----------------------------

def test_truncated_video_gives_one_line_without_decoder_noise(good, tmp_path):
    """FFmpeg's and OpenCV's complaints about the damaged frames stay off the terminal; the line says
    how many frames were decoded of how many the container declares."""
    clip = tmp_path / "clip.avi"
    clip.write_bytes(good.file("clip.avi")[: len(good.file("clip.avi")) * 2 // 5])
    result = dropfit("measure", clip, "--out", "t.nc", "--ball-radius-m", "0.02", cwd=tmp_path)
    assert result.returncode == 1
    line = check_line(result.stderr, "clip.avi")
    assert "truncated or corrupt" in line and "frames its container declares" in line
    assert_no_output(tmp_path / "out")


def test_mp4_measures_without_an_opencv_warning(good, tmp_path):
    """An .mp4 is measured with nothing on standard error but its one progress line (OpenCV warned
    that its MJPEG backend cannot read it)."""
    shutil.copy(good.directory / "clip.mp4", tmp_path / "clip.mp4")
    result = dropfit("measure", "clip.mp4", "--out", "t.nc", "--ball-radius-m", "0.02", cwd=tmp_path)
    assert result.returncode == 0 and result.stderr.startswith("clip.mp4: 180 frames in ")
    assert without_progress(result.stderr) == [], result.stderr


def test_mathtext_in_a_cell_reaches_the_report_as_a_failure_figure(good, tmp_path):
    """A ``$…$`` cell: every stage with --record-failure exits 0 with the same line, and the report stage
    writes both report.html and report.png (mathtext crashed the failure figure)."""
    (tmp_path / "$x$.csv").write_text(good.with_row(5, "0.050000,$\\sqrt{$"), encoding="utf-8")
    d = tmp_path / "s"
    runs = [dropfit(*args, "--record-failure", cwd=tmp_path) for args in (
        ["measure", "$x$.csv", "--out", d / "trajectory.nc"],
        ["analyse", d / "trajectory.nc", "--impacts", d / "impacts.csv", "--flights", d / "flights.csv",
         "--summary", d / "analysis.json"],
        ["fit", "--analysis", d / "analysis.json", "--impacts", d / "impacts.csv", "--out", d / "fit.json"],
        ["report", "--trajectory", d / "trajectory.nc", "--flights", d / "flights.csv", "--impacts",
         d / "impacts.csv", "--analysis", d / "analysis.json", "--fit", d / "fit.json", "--html",
         d / "report.html", "--figure", d / "report.png"])]
    assert [run.returncode for run in runs] == [0, 0, 0, 0]
    assert len({run.stderr for run in runs}) == 1
    check_line(runs[0].stderr, "$x$.csv")
    assert (d / "report.png").read_bytes().startswith(b"\x89PNG")


def test_huge_header_is_refused_quickly_in_a_subprocess(tmp_path):
    """A one-line CSV of a million columns: one line, within the time of starting Python and a second."""
    (tmp_path / "wide.csv").write_text(",".join(f"c{i}" for i in range(1_000_000)) + "\n", encoding="utf-8")
    started = time.perf_counter()
    result = dropfit("measure", "wide.csv", "--out", "t.nc", cwd=tmp_path)
    assert time.perf_counter() - started < 30
    assert result.returncode == 1
    check_line(result.stderr, "wide.csv")


#: As root, a file's permissions bind only without the capabilities to override them: drop those.
WITHOUT_OVERRIDE = ["setpriv", "--inh-caps=-dac_override,-dac_read_search",
                    "--bounding-set=-dac_override,-dac_read_search"]


@pytest.mark.skipif(not hasattr(os, "geteuid") or (os.geteuid() == 0 and not shutil.which("setpriv")),
                    reason="root reads every file, and setpriv is not there to drop that capability")
def test_unreadable_file_gives_one_line(good, tmp_path):
    """Files without read permission, for real (the sweep simulates this with a denied open): the log
    given to measure and the analysis summary given to fit."""
    log_path = tmp_path / "log.csv"
    log_path.write_text(good.text, encoding="utf-8")
    analysis = tmp_path / "analysis.json"
    analysis.write_bytes(good.file("analysis.json"))
    prefix = WITHOUT_OVERRIDE if os.geteuid() == 0 else []
    for path, args in ((log_path, ["measure", log_path, "--out", "t.nc"]),
                       (analysis, ["fit", "--analysis", analysis, "--impacts", good.directory / "impacts.csv",
                                   "--out", "fit.json"])):
        path.chmod(0)
        result = subprocess.run([*prefix, sys.executable, "-m", "dropfit", *map(str, args)], cwd=tmp_path,
                                capture_output=True, text=True, timeout=CALL_TIMEOUT_S)
        assert result.returncode == 1
        assert "permission denied" in check_line(result.stderr, path.name)
