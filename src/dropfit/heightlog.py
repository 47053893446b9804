"""Height logs: parse and validate a sensor's CSV into the trajectory dataset.

A height log is a CSV file. Lines starting with ``#`` are comments; the header names two columns
whose suffix is their unit: time ``time_s`` or ``time_ms``, and height ``y_m``, ``y_cm``, ``y_mm``
or ``y_px``. Empty height values are dropouts. Example::

    # dropfit height log
    time_s,y_m
    0.00,2.7735
    0.01,2.7741
"""

from __future__ import annotations

import csv
import io
import math
import re
from pathlib import Path

import numpy as np
import pandas as pd
import xarray as xr

from .errors import InputError, one_line, shown, shown_path
from .files import check_input_file, decoded_text, read_table_bytes
from .physics import STANDARD_GRAVITY_M_S2, drag_parameter

TIME_UNITS_S = {"s": 1.0, "ms": 1e-3}
LENGTH_UNITS_M = {"m": 1.0, "cm": 1e-2, "mm": 1e-3}
QUALITY_OK, QUALITY_DROPOUT = 0, 1
#: A scale from gravity less precise than this (relative standard error) is still used (e, flight-time and
#: height ratios need no scale at all), but its heights are said to be only as good as it: a note says so, and
#: the headline names what the heights rest on (:func:`heights_basis`).
MAX_GRAVITY_SCALE_RELATIVE_SE = 0.01
#: A header with more columns than this is refused before parsing (a height log has two; a
#: million-column line took minutes to parse).
MAX_COLUMNS = 256
#: Heights further than this from the sensor zero, m, are refused: no drop test spans 1 km, a wrong
#: unit or an offset (altitude) does, and the flight fits lose their precision far from zero.
MAX_ABS_HEIGHT_M = 1000.0

#: Files that are not height logs, by the first bytes: (signature, offset, what it is, what to do).
_SIGNATURES = [
    (b"\x89PNG", 0, "a PNG image", None), (b"GIF8", 0, "a GIF image", None), (b"\xff\xd8\xff", 0, "a JPEG image", None),
    (b"%PDF", 0, "a PDF document", None),
    (b"PK\x03\x04", 0, "a ZIP archive (as an .xlsx or .ods spreadsheet is)", "export the sheet as CSV"),
    (b"\xd0\xcf\x11\xe0", 0, "an Office document (an old .xls spreadsheet?)", "export the sheet as CSV"),
    (b"\x1a\x45\xdf\xa3", 0, "a WebM or Matroska video", "convert it to .mp4 or .avi"),
    (b"ftyp", 4, "an MP4 or MOV video", "give it the suffix .mp4 or .mov"),
    (b"CDF\x01", 0, "a NetCDF file, such as a trajectory", "give a trajectory to dropfit analyse"),
    (b"CDF\x02", 0, "a NetCDF file, such as a trajectory", "give a trajectory to dropfit analyse"),
    (b"\x89HDF", 0, "a NetCDF-4/HDF5 file", "give a trajectory to dropfit analyse"),
    (b"\x1f\x8b", 0, "a gzip-compressed file", "decompress it first"),
    (b"BZh", 0, "a bzip2-compressed file", "decompress it first"),
    (b"\xfd7zXZ", 0, "an xz-compressed file", "decompress it first"),
    (b"7z\xbc\xaf", 0, "a 7-Zip archive", "extract the CSV first"),
    (b"Rar!", 0, "a RAR archive", "extract the CSV first"),
    (b"\x93NUMPY", 0, "a NumPy array file", "save the data as CSV"),
    (b"SQLite format 3", 0, "an SQLite database", "export the data as CSV"),
    (b"OggS", 0, "an Ogg media file", None), (b"ID3", 0, "an MP3 audio file", None),
    (b"FLV", 0, "a Flash video", "convert it to .mp4 or .avi"),
    (b"\x30\x26\xb2\x75", 0, "a Windows Media file", "convert it to .mp4 or .avi"),
]
#: Suffixes of files that are not height logs and not videos dropfit reads: what each is, what to do.
_OTHER_SUFFIXES = {
    **dict.fromkeys([".webm", ".ogv", ".wmv", ".flv", ".mpg", ".mpeg", ".3gp", ".ts", ".mts", ".m2ts", ".vob"],
                    ("a video in a format dropfit does not read", "convert it to .mp4 or .avi")),
    **dict.fromkeys([".gif", ".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".webp", ".heic"],
                    ("an image", "give the height log (CSV) or the video")),
    **dict.fromkeys([".xlsx", ".xlsm", ".xls", ".ods", ".numbers"], ("a spreadsheet", "export the sheet as CSV")),
    ".json": ("a JSON file", "give the height log (CSV) or the video"),
    ".nc": ("a NetCDF file, such as a trajectory", "give a trajectory to dropfit analyse, a height log to measure"),
    **dict.fromkeys([".zip", ".gz", ".bz2", ".xz", ".7z", ".rar", ".tar"], ("an archive", "extract the CSV first")),
    **dict.fromkeys([".pdf", ".doc", ".docx", ".odt"], ("a document", "export the data as CSV")),
    **dict.fromkeys([".wav", ".mp3", ".m4a", ".flac"], ("an audio file", "give the height log (CSV) or the video")),
}
_OTHER_SEPARATORS = {";": "semicolons", "\t": "tabs", "|": "vertical bars"}
_DECIMAL_COMMA = re.compile(r"^\s*[-+]?\d+,\d+\s*$")


def _column_unit(columns, quantity, units, path):
    matches = [(name, name[len(quantity) + 1:]) for name in columns
               if name.startswith(quantity + "_") and name[len(quantity) + 1:] in units]
    if len(matches) == 1:
        return matches[0]
    expected = " or ".join(f"{quantity}_{unit}" for unit in units)
    listed = ", ".join(shown(name, 30) for name in columns[:6]) + (", …" if len(columns) > 6 else "")
    name = shown_path(path)
    if len(matches) > 1:
        raise InputError(f"{name}: {len(matches)} {'time' if quantity == 'time' else 'height'} columns "
                         f"({', '.join(shown(m[0], 30) for m in matches)}); keep one of them")
    other_unit = [column for column in columns if column.startswith(quantity + "_")]
    if other_unit:
        raise InputError(f"{name}: column {shown(other_unit[0], 30)} has a unit dropfit does not read; expected "
                         f"{expected}")
    folded = [column for column in columns if column.lower().startswith(quantity + "_")
              and column.lower()[len(quantity) + 1:] in units]
    hint = f" (names are case-sensitive: write {folded[0].lower()})" if folded else \
        "; name the columns as in 'time_s,y_m' (see the README, Height logs)"
    raise InputError(f"{name}: expected one column {expected}, found columns {listed or 'none'}{hint}")


def check_not_other_file(path, raw):
    """InputError for a file that is not a text CSV at all: another format, binary data, UTF-16 text."""
    name = shown_path(path)
    suffix = Path(path).suffix.lower()
    if suffix in _OTHER_SUFFIXES:
        what, advice = _OTHER_SUFFIXES[suffix]
        raise InputError(f"{name}: is {what}, not a height log (CSV) or a video dropfit reads "
                         f"({', '.join(_video_suffixes())}); {advice}")
    if not raw:
        raise InputError(f"{name}: the file is empty (0 bytes); give the height log (CSV) with a header and samples")
    for signature, offset, what, advice in _SIGNATURES:
        if what and raw[offset: offset + len(signature)] == signature:
            raise InputError(f"{name}: is {what}, not a height log (CSV) or a video with one of the suffixes "
                             f"{', '.join(_video_suffixes())}; {advice or 'give the height log (CSV) or the video'}")
    if raw[:4] == b"RIFF" and raw[8:12] == b"AVI ":
        raise InputError(f"{name}: is an AVI video; give it the suffix .avi")
    head = raw[:65536]
    # UTF-32 text is three quarters zero bytes (its byte-order mark begins as UTF-16's), UTF-16 text half
    if raw.startswith((b"\xff\xfe\x00\x00", b"\x00\x00\xfe\xff")) or head.count(b"\x00") > 0.6 * len(head):
        raise InputError(f"{name}: is UTF-32 text (or binary data), not UTF-8; save it as CSV in UTF-8")
    if raw.startswith((b"\xff\xfe", b"\xfe\xff")) or head.count(b"\x00") > 0.3 * len(head):
        raise InputError(f"{name}: is UTF-16 text (or binary data), not UTF-8; save it as CSV in UTF-8")
    control = sum(head.count(bytes([code])) for code in range(32) if code not in (9, 10, 13))
    if b"\x00" in raw or control > 0.01 * len(head):
        raise InputError(f"{name}: is binary data, not a text CSV; give the height log (CSV) or the video")


def _video_suffixes():
    from .videolog import VIDEO_SUFFIXES

    return VIDEO_SUFFIXES


def _check_fields(path, header, rows):
    """InputError for rows whose field count differs from the header's, naming the likely cause."""
    name = shown_path(path)
    width = len(header)
    limit = csv.field_size_limit()
    try:
        csv.field_size_limit(max(limit, max(map(len, rows), default=0) + 1))
        fields = list(csv.reader(rows, skipinitialspace=True))
    finally:
        csv.field_size_limit(limit)
    ragged = [i for i, row in enumerate(fields) if len(row) != width]
    if not ragged:
        return
    if len(ragged) == len(fields) and all(len(row) == width + 1 and not row[-1].strip() for row in fields):
        raise InputError(f"{name}: every data row ends with a comma ({width + 1} fields under a header of {width}); "
                         f"remove the trailing commas, or end the header with one too")
    first = ragged[0]
    row = fields[first]
    # (a row of empty fields, ',,,,', has no digits to be decimal commas)
    if len(row) > width and any(field.strip() for field in row) \
            and all(field.strip().lstrip("-+").isdigit() for field in row if field.strip()):
        raise InputError(f"{name}: uses decimal commas (data row {first + 1}: '{shown(rows[first], 30)}' has "
                         f"{len(row)} fields under a header of {width}); save it with a decimal point")
    advice = "every row needs one value per column" + (", a dropout an empty one (as in '0.05,')"
                                                       if len(row) < width else "")
    raise InputError(f"{name}: data row {first + 1} has {len(row)} field{'s' if len(row) != 1 else ''} but the "
                     f"header has {width} ('{shown(rows[first], 40)}'); {advice}")


def _check_header(path, header, rows):
    """InputError for a header line that cannot be a height log's: too long, another separator, numbers."""
    name = shown_path(path)
    if header.count(",") + 1 > MAX_COLUMNS or len(header) > 64 * MAX_COLUMNS:
        raise InputError(f"{name}: its header line has {header.count(',') + 1} columns and {len(header)} characters: "
                         f"not the header of a height log (a time and a height column); give the height log (CSV)")
    if "," in header:
        return
    sample = rows[0] if rows else ""
    for separator, words in _OTHER_SEPARATORS.items():
        if separator in header:
            if any(_DECIMAL_COMMA.match(field) for field in sample.split(separator)):
                raise InputError(f"{name}: uses {words} between the columns and decimal commas; save it as CSV with "
                                 f"commas between the columns and a decimal point")
            raise InputError(f"{name}: the columns are separated by {words}, not commas; save it as CSV with commas "
                             f"between the columns")
    tokens, values = header.split(), sample.split()
    named = any(token.startswith(("time_", "y_")) for token in tokens)
    if len(tokens) > 1 and (named or (len(values) == len(tokens) and all(map(is_number, values)))):
        raise InputError(f"{name}: the columns are separated by spaces, not commas; save it as CSV with commas "
                         f"between the columns")


def read_height_log(path, horizontal=False, exact_repeats=False):
    """Read and validate a height log.

    Parameters
    ----------
    path : str or pathlib.Path
        The CSV file.
    horizontal : bool
        Also return the optional horizontal column (``x_m``, ``x_cm``, ``x_mm`` or ``x_px``).
    exact_repeats : bool
        Pass a row that repeats the previous one exactly (a row exported twice) for the caller to drop
        (:func:`dropfit.importers.base.checked_track`, with a note); refused otherwise.

    Returns
    -------
    (numpy.ndarray, numpy.ndarray, str)
        Time in s, height in the log's unit (NaN for dropouts), and that unit
        (``m``, ``cm``, ``mm`` or ``px``); with ``horizontal``, also the horizontal position in its unit
        (NaN where empty) and that unit, (None, None) for a log without one.

    Raises
    ------
    InputError
        Missing, unreadable or empty file, a file of another kind (an image, a spreadsheet, UTF-16
        or binary data), another separator or decimal commas, rows of the wrong length, wrong
        columns, values that are not numbers, time not strictly increasing or not finite, no valid
        height at all.
    """
    path = Path(path)
    raw = read_table_bytes(path, "height log (CSV) or video", check_not_other_file)
    check_not_other_file(path, raw)
    name = shown_path(path)
    text, _ = decoded_text(raw)
    lines = [line for line in text.splitlines() if line.strip() and not line.lstrip().startswith("#")]
    if not lines:
        raise InputError(f"{name}: the file is empty (no header and no samples)")
    first = lines[0].lstrip()
    if first.startswith("<"):
        raise InputError(f"{name}: is an HTML or XML document, not a height log (CSV); give the height log")
    if first.startswith(("{", "[")):
        raise InputError(f"{name}: is a JSON file, not a height log (CSV); give the height log")
    _check_header(path, lines[0], lines[1:])
    header = [field.strip().strip('"').strip() for field in lines[0].split(",")]
    repeated = sorted({field for field in header if field and header.count(field) > 1})
    if repeated:
        raise InputError(f"{name}: the header names column {shown(repeated[0], 30)} twice; keep one of them")
    if all(is_number(field) for field in header if field):
        raise InputError(f"{name}: has no header: its first line holds numbers ('{shown(lines[0], 30)}'); add a "
                         f"header line such as time_s,y_m")
    _check_fields(path, header, lines[1:])
    try:
        table = pd.read_csv(io.StringIO("\n".join(lines)), skipinitialspace=True, index_col=False, dtype=str,
                            keep_default_na=False)
    except (pd.errors.ParserError, ValueError) as error:
        raise InputError(f"{name}: not a valid CSV table ({shown(str(error).splitlines()[0])})") from None
    table.columns = [str(name_).strip() for name_ in table.columns]
    time_column, time_unit = _column_unit(list(table.columns), "time", TIME_UNITS_S, path)
    height_column, height_unit = _column_unit(list(table.columns), "y", {**LENGTH_UNITS_M, "px": None}, path)
    if table.empty:
        raise InputError(f"{name}: the header is there but there are no samples")
    time = _numeric(table[time_column], time_column, path) * TIME_UNITS_S[time_unit]
    height = _numeric(table[height_column], height_column, path)
    if not np.all(np.isfinite(time)):
        row = int(np.flatnonzero(~np.isfinite(time))[0])
        raise InputError(f"{name}: time is missing or not finite in data row {row + 1}")
    steps = np.diff(time)
    if exact_repeats:
        repeated = np.all(table.values[1:] == table.values[:-1], axis=1)  # the cells' text, every column
        steps = np.where(repeated, 1.0, steps)
    if np.any(steps <= 0):
        row = int(np.flatnonzero(steps <= 0)[0])
        if steps[row] == 0 and not np.all(table.values[row + 1] == table.values[row]):
            raise InputError(f"{name}: time {time[row]:g} s is given twice with different positions (data rows "
                             f"{row + 1} and {row + 2}); remove the wrong row, or give the times with more decimals")
        raise InputError(f"{name}: time does not increase at data row {row + 2} "
                         f"({time[row]:g} s then {time[row + 1]:g} s); sort the log or remove repeated rows")
    if np.any(np.isinf(height)):
        row = int(np.flatnonzero(np.isinf(height))[0])
        raise InputError(f"{name}: column {height_column} is infinite in data row {row + 1}")
    if not np.any(np.isfinite(height)):
        raise InputError(f"{name}: column {height_column} has no valid value (all empty or NaN)")
    if not horizontal:
        return time, height, height_unit
    if not any(column.startswith("x_") for column in table.columns):
        return time, height, height_unit, None, None
    x_column, x_unit = _column_unit(list(table.columns), "x", {**LENGTH_UNITS_M, "px": None}, path)
    x = _numeric(table[x_column], x_column, path)
    if np.any(np.isinf(x)):
        raise InputError(f"{name}: column {x_column} is infinite in data row {int(np.flatnonzero(np.isinf(x))[0]) + 1}")
    return time, height, height_unit, x, x_unit


#: What pandas' CSV reader takes for a missing value by default: a dropout.
_MISSING = {"", "#N/A", "#N/A N/A", "#NA", "-1.#IND", "-1.#QNAN", "-NaN", "-nan", "1.#IND", "1.#QNAN", "<NA>", "N/A",
            "NA", "NULL", "NaN", "None", "n/a", "nan", "null"}


def is_number(text):
    """Whether ``text`` reads as a float (``-5e-05``, ``nan``, ``inf`` too)."""
    try:
        float(text)
    except ValueError:
        return False
    return True


def _numeric(column, name, path):
    texts = column.str.strip()
    missing = texts.isin(_MISSING).to_numpy()
    values = pd.to_numeric(texts.where(~missing), errors="coerce").to_numpy(dtype=float)
    bad = np.flatnonzero(np.isnan(values) & ~missing)
    if bad.size:
        value = str(texts.iloc[bad[0]])
        where = f"in data row {bad[0] + 1}"
        if value == name:
            raise InputError(f"{shown_path(path)}: the header appears again {where} (two logs joined into one?); "
                             f"keep one log per file")
        if _DECIMAL_COMMA.match(value):
            raise InputError(f"{shown_path(path)}: uses decimal commas (column {name} {where}: '{value}'); save it "
                             f"with a decimal point")
        hint = " (the file is not UTF-8 text: save it as UTF-8)" if "\ufffd" in value else ""
        raise InputError(f"{shown_path(path)}: column {name} has a value that is not a number {where} "
                         f"('{shown(value)}'){hint}")
    return values


def make_trajectory(time_s, height_m, source, calibration, attrs=None, x_m=None):
    """Build the trajectory dataset of the design brief.

    Parameters
    ----------
    time_s : numpy.ndarray
        Sample times in s.
    height_m : numpy.ndarray
        Centre height in m, up, NaN for dropouts.
    source : str
        The raw file the data came from.
    calibration : str
        How heights were brought to metres.
    attrs : dict, optional
        More attributes (ball radius and mass in m and kg, scale in m/px, sample id, ...).
    x_m : numpy.ndarray, optional
        Horizontal position of the centre in m (NaN where not measured), for a 2-D recording.

    Returns
    -------
    xarray.Dataset
        Dimension ``time`` (s); variables ``y`` (m) and ``quality`` (0 ok, 1 dropout), and ``x`` (m)
        when given.
    """
    quality = np.where(np.isfinite(height_m), QUALITY_OK, QUALITY_DROPOUT).astype("int8")
    dataset = xr.Dataset(
        {
            "y": ("time", np.asarray(height_m, dtype=float),
                  {"units": "m", "long_name": "height of the ball centre, up, sensor zero"}),
            "quality": ("time", quality, {"flag_values": "0 1", "flag_meanings": "ok dropout"}),
        },
        coords={"time": ("time", np.asarray(time_s, dtype=float), {"units": "s"})},
        attrs={"source": str(source), "calibration": calibration, "y_reference": "sensor zero",
               "n_dropouts": int(np.count_nonzero(quality))},
    )
    dataset.attrs.update({key: value for key, value in (attrs or {}).items() if value is not None})
    if x_m is not None:
        dataset["x"] = ("time", np.asarray(x_m, dtype=float), {"units": "m", "long_name": "horizontal position"})
    return dataset


def flight_acceleration(time_s, height_px, source="log", nominal_drag_k_per_m=0.0, nominal_drag_relative_se=0.25,
                        gravity_m_s2=STANDARD_GRAVITY_M_S2, seen_px=None):
    """Downward acceleration of the flights in pixel units, averaged over the drag models the data allow.

    The flights are found by dropfit's segmentation (:func:`dropfit.analysis.segment`: tracking jumps
    and the hand's samples left out, and the samples that may touch the floor) and fitted jointly
    with a shared acceleration and, by model, no drag, a fitted drag or the ball's own
    (:func:`dropfit.analysis.shared_acceleration_with_drag`). The axis direction comes from the impacts
    (:func:`dropfit.analysis.vertical_sign`).

    Parameters
    ----------
    time_s : numpy.ndarray
        Sample times in s (of the file: a slow-motion file's container time gives its own acceleration).
    height_px : numpy.ndarray
        Positions in px along the vertical pixel axis, NaN where not measured.
    source : str
        Recording name for error messages.
    nominal_drag_k_per_m, nominal_drag_relative_se : float
        The ball's drag parameter (1/m; 0 when its size or mass is not known, nor its rules') and its
        relative se.
    gravity_m_s2 : float
        g in m/s², to bring the drag parameter to px.
    seen_px : numpy.ndarray, optional
        Positions in px wherever the ball was seen, measured cleanly or not: the flights are found on them
        (``seen_height`` of :func:`dropfit.analysis.segment`) and fitted on the clean ``height_px``.

    Returns
    -------
    (float, dropfit.analysis.SharedAcceleration)
        The axis direction (−1 for image rows, which point down, +1 for up) and the fit in px/s²
        (drag k in 1/px).
    """
    from .analysis import MIN_SAMPLES_PER_FLIGHT, segment, shared_acceleration, shared_acceleration_with_drag, \
        vertical_sign
    from .analysis.bounces import MAX_PLAUSIBLE_DRAG_K_PER_M
    from .analysis.flights import parabola_start
    from .analysis.segmentation import CONTACT_CLEARANCE_S, free_flights

    sign = vertical_sign(time_s, height_px, seen_px)
    try:
        found = segment(time_s - time_s[0], sign * height_px, source,
                        seen_height=None if seen_px is None else sign * np.asarray(seen_px, dtype=float))
    except InputError as error:  # (a fall without a bounce: a high-speed clip of the last millimetres)
        raise InputError(f"{error}: a px track is scaled from its flights' curvature, which needs a bounce; give the "
                         f"scale with --scale-m-per-px (negative for image rows, which point down)") from None
    t, y = found.time, found.height
    fitted = np.ones(t.size, dtype=bool) if found.clean is None else found.clean
    clear = max(1, int(round(CONTACT_CLEARANCE_S / float(np.median(np.diff(t))))))
    # the flights from the release to the last impact (the one after it may end in a hand or at rest),
    # clear of the samples that may touch the floor; their clean samples
    edges = np.concatenate([[found.release - clear], found.impacts])
    parts = [slice(a + clear, b - clear + 1) for a, b in zip(edges[:-1], edges[1:])]
    pieces = [(t[part][fitted[part]], y[part][fitted[part]]) for part in parts]
    drop = pieces[0]
    pieces = [piece for piece in pieces if piece[0].size >= MIN_SAMPLES_PER_FLIGHT]
    pieces = pieces[: free_flights(pieces, found.acceleration)]
    if pieces and pieces[0] is drop:  # the drop starts at its apex: a ball held still at the top is not yet falling
        y_apex, t_apex = parabola_start(*pieces[0], found.acceleration)
        pieces[0] = tuple(part[pieces[0][0] >= t_apex] for part in pieces[0])
        pieces = pieces if pieces[0][0].size >= MIN_SAMPLES_PER_FLIGHT else pieces[1:]
    if not pieces:
        raise InputError(f"{shown_path(source)}: cannot calibrate pixels from gravity: no flight with at least "
                         f"{MIN_SAMPLES_PER_FLIGHT} samples between bounces; give scale_m_per_px")
    rough, _ = shared_acceleration(pieces)
    metres_per_px = gravity_m_s2 / rough if rough > 0 else 0.0
    nominal = nominal_drag_k_per_m * metres_per_px
    fit = shared_acceleration_with_drag(pieces, nominal, nominal_drag_relative_se * nominal,
                                        MAX_PLAUSIBLE_DRAG_K_PER_M * metres_per_px)
    if fit.acceleration <= 0:
        raise InputError(f"{shown_path(source)}: cannot calibrate pixels from gravity: the flights do not curve downwards")
    return sign, fit


def scale_from_gravity(time_s, height_px, gravity_m_s2=STANDARD_GRAVITY_M_S2, source="log", nominal_drag_k_per_m=0.0,
                       nominal_drag_relative_se=0.25, seen_px=None, speed_error_px=0.0):
    """Metres per pixel from the curvature of the flights, drag included: s = g / A_px.

    A_px is the flights' shared acceleration in px/s² from :func:`flight_acceleration` (flights found on
    ``seen_px`` when given); its standard
    error includes what the choice of drag model does to it, and what a position error growing with the
    ball's speed does (``speed_error_px``, px at the fastest fitted sample, as v²: the relative error
    ``speed_error_px`` / the largest fall below an apex). The uncertainty of g itself is not in it:
    an analysis carries that (it scales every length with the scale).

    Returns
    -------
    (float, float, dict)
        Signed scale in m/px (negative for an axis pointing down), its standard error in m/px, and the
        attributes that describe the calibration (drag model, each model's scale and weight, a note).
    """
    sign, fit = flight_acceleration(time_s, height_px, source, nominal_drag_k_per_m, nominal_drag_relative_se,
                                    gravity_m_s2, seen_px)
    scale = gravity_m_s2 / fit.acceleration
    relative_se = float(np.hypot(fit.acceleration_se / fit.acceleration, speed_error_px / fit.largest_fall))
    details = {"gravity_scale_drag_model": fit.drag_model}
    for name, model in fit.models.items():
        key = name.split(" ")[0]
        details[f"gravity_scale_{key}_m_per_px"] = gravity_m_s2 / model["acceleration"]
        details[f"gravity_scale_{key}_weight"] = model.get("weight", 0.0)
    notes = [fit.note] if fit.note else []
    if relative_se > MAX_GRAVITY_SCALE_RELATIVE_SE:
        notes.append(f"the flights give the scale only to {100 * relative_se:.2g} %: e, the flight-time and height "
                     f"ratios do not need it, the heights carry its error (give --scale-m-per-px for better heights)")
    if notes:
        details["gravity_scale_note"] = "; ".join(notes)
    return sign * scale, scale * relative_se, details


#: Apparent acceleration over g (dimensionless) → the slip of units that makes it, for a log in m and s.
UNIT_SLIPS = {100.0: "heights in cm under a metre header", 1000.0: "heights in mm under a metre header",
              10.0: "heights in mm under a cm header", 0.01: "heights in m under a cm header",
              0.001: "heights in m under a mm header", 0.1: "heights in cm under a mm header",
              1e-6: "times in ms under a seconds header", 1e6: "times in s under a ms header"}
#: A ratio within this factor of a slip's points to it (the flights found in slipped units are cut where g
#: would cut them: a cm log read as m fell with 69 g, not 100 g).
UNIT_SLIP_FACTOR = 2.0
#: Height spans (m) a drop test's ball covers: a length slip is named only if it brings the log's span into them.
PLAUSIBLE_SPAN_M = (0.005, 10.0)


def acceleration_reading(acceleration_ratio, sample_rate_hz, span_m=np.nan):
    """What a log's flights falling with ``acceleration_ratio`` × g point to, in words: a slip of units
    (:data:`UNIT_SLIPS`; a length slip only where it brings the heights' span ``span_m``, m as read, into
    :data:`PLAUSIBLE_SPAN_M`), a slow-motion time base (a table tracked on a slow-motion video at its playback
    rate: :func:`dropfit.video.calibrate.slow_motion_reading` at ``sample_rate_hz``, samples/s), or None."""
    from .video.calibrate import slow_motion_reading

    if not (np.isfinite(acceleration_ratio) and acceleration_ratio > 0):
        return None
    readings = [words for ratio, words in UNIT_SLIPS.items()
                if abs(math.log(acceleration_ratio / ratio)) < math.log(UNIT_SLIP_FACTOR)
                and (words.startswith("times") or not np.isfinite(span_m)
                     or PLAUSIBLE_SPAN_M[0] <= span_m / ratio <= PLAUSIBLE_SPAN_M[1])]
    slow = slow_motion_reading(acceleration_ratio, sample_rate_hz,
                               advice="if tracked on a slow-motion video, give that rate to the tracking tool")
    readings += [f"the ball {slow}"] if slow else []
    return "the numbers point to " + ", or ".join(readings) if readings else None


def heights_basis(attrs):
    """What a px recording's heights rest on, in words: "heights from g: scale known to 2.7 %" (a scale from the
    flights' curvature), "heights from the diameter: scale known to 2 %" (another source), "heights from the
    given scale"; the scales g names as suspect follow ("the diameter's is 19 % off g's: suspect"). None for a
    recording in metres."""
    if "scale_m_per_px" not in attrs:
        return None
    source = str(attrs.get("scale_source") or ("gravity" if str(attrs.get("calibration", "")).startswith(
        "scale from gravity") else "given"))
    relative = float(attrs.get("scale_rel_se") or 0.0)
    words = "heights from g" if source == "gravity" else f"heights from the {source} scale"
    if relative > 0:
        words += f": scale known to {100 * relative:.2g} %"
    for key in sorted(attrs):
        if key.startswith("scale_suspect_"):
            name = key[len("scale_suspect_"):]
            off = attrs.get(f"scale_disagreement_{name}")
            words += (f"; the {name} scale is {100 * abs(off):.0f} % off, suspect" if off is not None
                      else f"; the {name} scale is suspect")
    return words


def nominal_drag_of(attrs):
    """The drag parameter k (1/m) of a smooth ball of the kind, size and mass in ``attrs`` and its relative
    standard error; a kind with a regulation size and mass (tennis, table tennis) takes the one not given
    from its rules, with their spread in the standard error (:func:`regulation_note` says so); (0, 0)
    when the size or mass is not known otherwise."""
    from .balls import ball_kind

    radius, mass = attrs.get("ball_radius_m"), attrs.get("ball_mass_kg")
    kind = ball_kind(attrs.get("ball_type"))
    relative_se = kind.drag_coefficient_se / kind.drag_coefficient
    regulation = _standing_in(attrs)
    if regulation is not None:  # only what is not given is the rules' (its spread into k's se)
        spread = regulation.area_per_mass_relative_se(radius_given=bool(radius), mass_given=bool(mass))
        return (float(drag_parameter(kind.drag_coefficient, radius or regulation.radius_m,
                                     mass or regulation.mass_middle_kg)), math.hypot(relative_se, spread))
    if not (radius and mass):
        return 0.0, 0.0
    return float(drag_parameter(kind.drag_coefficient, radius, mass)), relative_se


def _standing_in(attrs):
    """The ball kind's :class:`dropfit.balls.Regulation` when it stands in for a size or mass not given, else None."""
    from .balls import ball_kind

    given = attrs.get("ball_radius_m") and attrs.get("ball_mass_kg")
    return None if given else ball_kind(attrs.get("ball_type")).regulation


def regulation_note(attrs):
    """What :func:`nominal_drag_of` took for a ball whose size or mass is not given, or None."""
    regulation = _standing_in(attrs)
    if regulation is None:
        return None
    return (f"the ball's size or mass is not given: its drag is that of a {attrs.get('ball_type')} ball as its rules "
            f"allow ({100 * regulation.diameter_m[0]:g}-{100 * regulation.diameter_m[1]:g} cm, "
            f"{1e3 * regulation.mass_kg[0]:g}-{1e3 * regulation.mass_kg[1]:g} g; {regulation.rule})")


#: The point of the ball a log may give, and how many radii its centre lies above it.
HEIGHT_REFERENCES = {"centre": 0.0, "bottom": 1.0, "top": -1.0}


def trajectory_from_log(path, scale_m_per_px=None, gravity_m_s2=STANDARD_GRAVITY_M_S2, attrs=None,
                        height_reference="centre", import_options=None):
    """Read a height log and convert it to the trajectory dataset (heights of the ball's centre in m, up).

    Parameters
    ----------
    path : str or pathlib.Path
        The height log.
    scale_m_per_px : float, optional
        For logs in px: metres per pixel, positive for an axis pointing up and negative for image
        rows (down). Without it the scale is calibrated from gravity.
    gravity_m_s2 : float
        Gravitational acceleration in m/s², for the gravity calibration.
    attrs : dict, optional
        Extra attributes for the dataset (``ball_radius_m`` is needed for a log of the bottom or top).
    height_reference : {"centre", "bottom", "top"}
        The point of the ball the log gives: its centre, its bottom (an ultrasonic sensor looking up, a
        tracker on the ball's lowest point) or its top; the trajectory is of the centre, one radius
        above the bottom (below the top).
    import_options : dropfit.importers.ImportOptions, optional
        The file's format, frame rate, track, column mapping or sensor height (:mod:`dropfit.importers`
        reads tracking tables, sensor exports and high-speed clips); default: found from the content.
    """
    from .importers import read_track

    imported = read_track(path, import_options)
    return imported.with_x(_trajectory_of(path, imported, scale_m_per_px, gravity_m_s2, attrs, height_reference))


def _trajectory_of(path, imported, scale_m_per_px, gravity_m_s2, attrs, height_reference):
    time, height, unit = imported.time_s, imported.y, imported.unit
    extra = dict(attrs or {})
    extra.update(imported.attrs())
    if height_reference not in HEIGHT_REFERENCES:
        raise InputError(f"{shown_path(path)}: height_reference {shown(height_reference)!r} is not one of "
                         f"{', '.join(HEIGHT_REFERENCES)}")
    radius = extra.get("ball_radius_m")
    if HEIGHT_REFERENCES[height_reference] and not radius:
        raise InputError(f"{shown_path(path)}: the log gives the ball's {height_reference}: give the ball radius "
                         f"(ball_radius_m) to find its centre")
    extra["height_reference"] = height_reference
    to_centre = HEIGHT_REFERENCES[height_reference] * (radius or 0.0)
    if unit != "px":
        return make_trajectory(time, _checked(height * LENGTH_UNITS_M[unit] + to_centre, path, extra), path,
                               f"unit conversion from {unit}", extra, _horizontal_m(imported.x, imported.unit, extra, path))
    if scale_m_per_px is not None:
        if scale_m_per_px == 0:
            raise InputError(f"{shown_path(path)}: scale_m_per_px is 0; give metres per pixel (negative for image rows)")
        from .analysis import vertical_sign

        heights = height * scale_m_per_px
        if vertical_sign(time, heights) < 0:
            raise InputError(f"{shown_path(path)}: with scale_m_per_px = {scale_m_per_px:g} the ball bounces "
                             f"downwards: if the pixel axis points down (image rows), give a negative scale")
        extra["scale_m_per_px"] = float(scale_m_per_px)
        return make_trajectory(time, _checked(heights + to_centre, path, extra), path, "given scale in m/px", extra,
                               _horizontal_m(imported.x, imported.unit, extra, path))
    scale, scale_se, details = scale_from_gravity(time, height, gravity_m_s2, str(path), *nominal_drag_of(extra))
    extra.update(details, scale_m_per_px=float(scale), scale_se_m_per_px=float(scale_se),
                 scale_rel_se=float(scale_se / abs(scale)), scale_source="gravity")
    return make_trajectory(time, _checked(height * scale + to_centre, path, extra), path,
                           "scale from gravity (flight curvature)", extra, _horizontal_m(imported.x, imported.unit, extra, path))


def _horizontal_m(x, unit, attrs, path):
    """A log's horizontal column (in ``unit``) in m, None without one: px through the scale's size (image
    columns point right whichever way its rows point)."""
    if x is None:
        return None
    if unit == "px" and "scale_m_per_px" not in attrs:
        raise InputError(f"{shown_path(path)}: column x_px needs a scale, but the heights are not in px; give x in "
                         f"m, cm or mm")
    x_m = x * (abs(attrs["scale_m_per_px"]) if unit == "px" else LENGTH_UNITS_M[unit])
    farthest = float(np.nanmax(np.abs(x_m), initial=0.0))
    if farthest > MAX_ABS_HEIGHT_M:
        raise InputError(f"{shown_path(path)}: column x_{unit} reaches {farthest:.3g} m from its zero (more than "
                         f"{MAX_ABS_HEIGHT_M:g} m); check its unit in the column name, or subtract the offset")
    return x_m


def _checked(height_m, path, attrs):
    """``height_m``, after checking that no height lies absurdly far from the sensor zero and that a given
    floor (``attrs["floor_m"]``) is where the ball can touch it."""
    finite = height_m[np.isfinite(height_m)]
    farthest = float(np.max(np.abs(finite)))
    if farthest > MAX_ABS_HEIGHT_M:
        raise InputError(f"{shown_path(path)}: heights reach {farthest:.3g} m from the sensor zero (more than "
                         f"{MAX_ABS_HEIGHT_M:g} m); check the height unit in the column name, or subtract the offset")
    check_floor(finite, attrs, path)
    return height_m


def check_floor(height_m, attrs, path):
    """Raise InputError if a given floor height (``attrs["floor_m"]``, m, in the trajectory's frame) is far
    from where the ball's centre comes down: above its lowest height, or far below it (the radius added).

    The margins are coarse: they catch a floor in the wrong unit or frame, not one a few mm off (the
    analysis checks that one against the flights).
    """
    floor = attrs.get("floor_m")
    if floor is None or height_m.size == 0:
        return
    radius = attrs.get("ball_radius_m") or 0.0
    span = float(np.ptp(height_m))
    low = float(np.partition(height_m, min(2, height_m.size - 1))[min(2, height_m.size - 1)])  # past two spikes
    lowest_possible = floor + 0.5 * radius  # the centre of a ball flattened to half its radius
    if low < lowest_possible - 0.005 - 0.01 * span:
        bottom = radius > 0 and abs(low - floor) < 0.3 * radius and attrs.get("height_reference") == "centre"
        advice = ("the heights look like the ball's bottom: set height_reference bottom" if bottom else
                  "give floor_m as the floor's height in the log's frame, m, and check the radius")
        raise InputError(f"{shown_path(path)}: the ball's centre comes down to {low:.4g} m, below the floor "
                         f"(floor_m = {floor:g} m) plus half the ball's radius ({radius:g} m); {advice}")
    gap = low - (floor + radius)
    if gap > max(0.5 * span, 0.05):
        raise InputError(f"{shown_path(path)}: the ball's centre stays {gap:.3g} m above the contact height (floor_m "
                         f"{floor:g} m + radius {radius:g} m) at its lowest; check floor_m (the floor's height in "
                         f"the log's frame, m) and the ball radius")


def read_trajectory(path):
    """Open a trajectory NetCDF file written by ``dropfit measure``, checked; raise InputError for a failure
    record (with its message) and for a missing, unreadable, damaged or foreign file."""
    name = shown_path(path)
    with open(check_input_file(path, "trajectory (NetCDF) written by dropfit measure"), "rb") as handle:
        head = handle.read(8)
    if not head:
        raise InputError(f"{name}: the file is empty (0 bytes); run dropfit measure again")
    try:
        with xr.open_dataset(path) as dataset:
            dataset = dataset.load()
    except Exception:  # noqa: BLE001 — a foreign or damaged file can make the NetCDF readers raise anything
        what = "a damaged or truncated NetCDF file" if head.startswith((b"CDF", b"\x89HDF")) else "not a NetCDF file"
        raise InputError(f"{name}: is {what}, not a trajectory written by dropfit measure; run dropfit measure "
                         f"again") from None
    if dataset.attrs.get("status") == "failed":
        raise InputError(one_line(dataset.attrs.get("error") or f"{name}: a failure record without its message"))
    if "impact_time_s" in dataset.data_vars:  # a sound recording's impact times (dropfit.audio)
        times = dataset["impact_time_s"].values
        if not np.issubdtype(times.dtype, np.number) or times.size < 3 or np.any(~np.isfinite(times)) \
                or np.any(np.diff(times) <= 0):
            raise InputError(f"{name}: its impact times are not three or more increasing numbers; run dropfit measure "
                             f"again")
        return dataset
    missing = [variable for variable in ("y", "quality") if variable not in dataset.data_vars]
    if missing or "time" not in dataset.coords or dataset["y"].dims != ("time",):
        raise InputError(f"{name}: is a NetCDF file but not a trajectory written by dropfit measure (it needs y and "
                         f"quality over time); run dropfit measure again")
    time = dataset["time"].values
    if not (np.issubdtype(time.dtype, np.number) and np.issubdtype(dataset["y"].dtype, np.number)):
        raise InputError(f"{name}: time or y is not numeric; run dropfit measure again")
    if time.size == 0 or not np.all(np.isfinite(time)) or np.any(np.diff(time) <= 0):
        raise InputError(f"{name}: its time is empty, not finite or not increasing; run dropfit measure again")
    return dataset
