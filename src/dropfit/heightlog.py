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

import io
from pathlib import Path

import numpy as np
import pandas as pd
import xarray as xr

from .errors import InputError, one_line, shown_path
from .files import check_input_file
from .physics import STANDARD_GRAVITY_M_S2

TIME_UNITS_S = {"s": 1.0, "ms": 1e-3}
LENGTH_UNITS_M = {"m": 1.0, "cm": 1e-2, "mm": 1e-3}
QUALITY_OK, QUALITY_DROPOUT = 0, 1
#: A scale from gravity less precise than this (relative standard error) is refused.
MAX_GRAVITY_SCALE_RELATIVE_SE = 0.01


def _column_unit(columns, quantity, units, path):
    matches = [(name, name[len(quantity) + 1:]) for name in columns
               if name.startswith(quantity + "_") and name[len(quantity) + 1:] in units]
    if len(matches) != 1:
        expected = " or ".join(f"{quantity}_{unit}" for unit in units)
        raise InputError(f"{path}: expected one column {expected}, found columns {', '.join(columns) or 'none'}")
    return matches[0]


def read_height_log(path):
    """Read and validate a height log.

    Parameters
    ----------
    path : str or pathlib.Path
        The CSV file.

    Returns
    -------
    (numpy.ndarray, numpy.ndarray, str)
        Time in s, height in the log's unit (NaN for dropouts), and that unit
        (``m``, ``cm``, ``mm`` or ``px``).

    Raises
    ------
    InputError
        Missing or empty file, wrong columns, values that are not numbers, time not strictly
        increasing or not finite, no valid height at all.
    """
    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: file not found")
    text = path.read_text(encoding="utf-8", errors="replace")
    body = "\n".join(line for line in text.splitlines() if line.strip() and not line.lstrip().startswith("#"))
    if not body:
        raise InputError(f"{path}: the file is empty (no header and no samples)")
    try:
        table = pd.read_csv(io.StringIO(body), skipinitialspace=True)
    except pd.errors.ParserError as error:
        raise InputError(f"{path}: not a valid CSV table ({str(error).splitlines()[0]})") from None
    table.columns = [str(name).strip() for name in table.columns]
    time_column, time_unit = _column_unit(table.columns, "time", TIME_UNITS_S, path)
    height_column, height_unit = _column_unit(table.columns, "y", {**LENGTH_UNITS_M, "px": None}, path)
    if table.empty:
        raise InputError(f"{path}: the header is there but there are no samples")
    time = _numeric(table[time_column], time_column, path) * TIME_UNITS_S[time_unit]
    height = _numeric(table[height_column], height_column, path)
    if not np.all(np.isfinite(time)):
        row = int(np.flatnonzero(~np.isfinite(time))[0])
        raise InputError(f"{path}: time is missing or not finite in data row {row + 1}")
    steps = np.diff(time)
    if np.any(steps <= 0):
        row = int(np.flatnonzero(steps <= 0)[0])
        raise InputError(f"{path}: time does not increase at data row {row + 2} "
                         f"({time[row]:g} s then {time[row + 1]:g} s); sort the log or remove repeated rows")
    if np.any(np.isinf(height)):
        row = int(np.flatnonzero(np.isinf(height))[0])
        raise InputError(f"{path}: column {height_column} is infinite in data row {row + 1}")
    if not np.any(np.isfinite(height)):
        raise InputError(f"{path}: column {height_column} has no valid value (all empty or NaN)")
    return time, height, height_unit


def _numeric(column, name, path):
    values = pd.to_numeric(column, errors="coerce").to_numpy(dtype=float)
    bad = np.flatnonzero(np.isnan(values) & column.notna().to_numpy())
    if bad.size:
        raise InputError(f"{path}: column {name} has a value that is not a number in data row {bad[0] + 1} "
                         f"({column.iloc[bad[0]]!r})")
    return values


def make_trajectory(time_s, height_m, source, calibration, attrs=None):
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

    Returns
    -------
    xarray.Dataset
        Dimension ``time`` (s); variables ``y`` (m) and ``quality`` (0 ok, 1 dropout).
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
    return dataset


def flight_acceleration(time_s, height_px, source="log"):
    """Downward acceleration of the flights in pixel units, with air drag where the data show it.

    The flights are found in the pixel data and fitted jointly with a free acceleration and a
    quadratic drag shared by all of them (:func:`dropfit.analysis.shared_acceleration_with_drag`).
    The axis points down if the ball starts below its median position in pixel units (a drop starts
    high and ends low).

    Parameters
    ----------
    time_s : numpy.ndarray
        Sample times in s (of the file: a slow-motion file's container time gives its own acceleration).
    height_px : numpy.ndarray
        Positions in px along the vertical pixel axis, NaN where not measured.
    source : str
        Recording name for error messages.

    Returns
    -------
    (float, dropfit.analysis.SharedAcceleration)
        The axis direction (−1 for image rows, which point down, +1 for up) and the fit in px/s²
        (drag k in 1/px).
    """
    from .analysis import (MIN_SAMPLES_PER_FLIGHT, estimate_noise, find_impacts, find_release,
                           shared_acceleration_with_drag)

    valid = np.isfinite(height_px)
    t, y = time_s[valid], height_px[valid]
    # a dropped ball starts high and spends most of the log lower down: if the first sample lies
    # below the median in pixel units, the axis points down (image rows)
    sign = -1.0 if y[0] < np.median(y) else 1.0
    up = sign * y
    noise = max(estimate_noise(up), 1e-9 * float(np.ptp(up)))
    release = find_release(up, noise)
    minima = find_impacts(up, noise, start=(release or 0) + 1) if release is not None else np.array([], int)
    edges = np.concatenate([[release or 0], minima])
    pieces = [(a + 1, b) for a, b in zip(edges[:-1], edges[1:]) if b - a - 1 >= MIN_SAMPLES_PER_FLIGHT]
    if not pieces:
        raise InputError(f"{source}: cannot calibrate pixels from gravity: no flight with at least "
                         f"{MIN_SAMPLES_PER_FLIGHT} samples between bounces; give scale_m_per_px")
    fit = shared_acceleration_with_drag([(t[a:b], up[a:b]) for a, b in pieces])
    if fit.acceleration <= 0:
        raise InputError(f"{source}: cannot calibrate pixels from gravity: the flights do not curve downwards")
    return sign, fit


def scale_from_gravity(time_s, height_px, gravity_m_s2=STANDARD_GRAVITY_M_S2, source="log"):
    """Metres per pixel from the curvature of the flights, drag included: s = g / A_px.

    A_px is the flights' shared acceleration in px/s² from :func:`flight_acceleration`.

    Returns
    -------
    (float, float)
        Signed scale in m/px (negative for an axis pointing down) and its standard error in m/px.
    """
    sign, fit = flight_acceleration(time_s, height_px, source)
    scale = gravity_m_s2 / fit.acceleration
    relative_se = fit.acceleration_se / fit.acceleration
    if relative_se > MAX_GRAVITY_SCALE_RELATIVE_SE:
        raise InputError(f"{source}: cannot calibrate pixels from gravity: the flights give the scale only to "
                         f"{100 * relative_se:.1f} %; give scale_m_per_px")
    return sign * scale, scale * relative_se


def trajectory_from_log(path, scale_m_per_px=None, gravity_m_s2=STANDARD_GRAVITY_M_S2, attrs=None):
    """Read a height log and convert it to the trajectory dataset (heights in m, up).

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
        Extra attributes for the dataset.
    """
    time, height, unit = read_height_log(path)
    extra = dict(attrs or {})
    extra["log_unit"] = unit
    if unit != "px":
        return make_trajectory(time, height * LENGTH_UNITS_M[unit], path, f"unit conversion from {unit}", extra)
    if scale_m_per_px is not None:
        if scale_m_per_px == 0:
            raise InputError(f"{path}: scale_m_per_px is 0; give metres per pixel (negative for image rows)")
        heights = height * scale_m_per_px
        finite = heights[np.isfinite(heights)]
        if finite[0] < np.median(finite):
            raise InputError(f"{path}: with scale_m_per_px = {scale_m_per_px:g} the ball starts low and rises: "
                             f"if the pixel axis points down (image rows), give a negative scale")
        extra["scale_m_per_px"] = float(scale_m_per_px)
        return make_trajectory(time, heights, path, "given scale in m/px", extra)
    scale, scale_se = scale_from_gravity(time, height, gravity_m_s2, source=str(path))
    extra.update(scale_m_per_px=float(scale), scale_se_m_per_px=float(scale_se),
                 scale_rel_se=float(scale_se / abs(scale)))
    return make_trajectory(time, height * scale, path, "scale from gravity (flight curvature)", extra)


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
