"""Importers: the files people already have (tracking tables, sensor exports, high-speed clips) → one track.

:func:`read_track` finds a file's format from its content (or takes the one named) and returns an
:class:`ImportedTrack`: time in s, the height (and the horizontal position, when the file has it)
in a length unit or image px, and how it was read. :func:`dropfit.heightlog.trajectory_from_log`
turns it into the trajectory, calibrating px as a px height log is.
"""

from __future__ import annotations

import dataclasses
import io
import zipfile
from pathlib import Path

import numpy as np

from ..errors import InputError, shown_path
from ..files import ZIP_ERRORS
from .base import LENGTH_UNITS_M, ImportedTrack, ImportOptions, checked_track, drop_repeated_positions

#: Every format, by the name ``--format`` and the ``format`` column of samples.tsv take.
FORMATS = {
    "dropfit": "dropfit's height log: time_s or time_ms, and y_m, y_cm, y_mm or y_px, commas",
    "csv": "any table: a time (or frame) column and a height column, each named with its unit",
    "tracker": "Tracker project (.trk, .trz) or its exported data table (t x y)",
    "mtrack2": "ImageJ MTrack2 table (Frame X1 Y1 Flag1 …), frames: give --fps",
    "trackmate": "TrackMate spot table (TRACK_ID, POSITION_X, POSITION_Y, POSITION_T or FRAME)",
    "kinovea": "Kinovea trajectory export (time, x, y with their units)",
    "vernier": "Vernier Logger Pro / Graphical Analysis export (Run 1: Time (s), Position (m))",
    "pasco": "PASCO Capstone export (Time (s) Run #1, Position (m) Run #1)",
    "phyphox": "phyphox export of a position-like quantity (Time (s), …)",
    "motion-detector": "a motion detector's distance down from the sensor (height = sensor height − distance)",
    "mraw": "Photron high-speed recording (.cihx/.cih with its .mraw)",
}
#: The length units the trajectory path converts itself; others are converted to m here.
_TRAJECTORY_UNITS = ("m", "cm", "mm", "px")


def read_track(path, options=None):
    """Read a recording's track, its format found from the content or named in ``options``.

    Parameters
    ----------
    path : str or pathlib.Path
        The file.
    options : ImportOptions, optional
        The format, frame rate (frames/s), track, column mapping and sensor height (m).

    Returns
    -------
    ImportedTrack
        Times strictly increasing (a frame exported twice dropped), lengths in m, cm, mm or px.

    Raises
    ------
    InputError
        One line naming the file, what is wrong and what to try.
    """
    from . import highspeed, sensors, tracker
    from .table import text_lines
    from ..files import read_table_bytes
    from ..heightlog import check_not_other_file

    options = options or ImportOptions()
    if options.format is not None and options.format not in FORMATS:
        raise InputError(f"{shown_path(path)}: --format {options.format} is not a format dropfit reads; give one of "
                         f"{', '.join(FORMATS)}")
    if options.format == "mraw" or options.format is None and highspeed.is_highspeed(path):
        return _finished(path, highspeed.read_highspeed(path, options))
    raw = read_table_bytes(path, "height log, tracking table, sensor export (CSV) or video",
                           lambda path_, head: head.startswith(b"PK") or check_not_other_file(path_, head))
    if options.format == "tracker" and raw.lstrip()[:1] in (b"<", b"P") or \
            options.format in (None, "tracker") and _is_tracker_project(path, raw):
        return _finished(path, tracker.read_project(path, raw, options))
    sets = sensors.phyphox_sets(raw, path) if options.format in (None, "phyphox") else None
    if sets is not None:
        raw, options = sensors.phyphox_position_set(path, sets), dataclasses.replace(options, format="phyphox")
    else:
        check_not_other_file(path, raw)
    lines, encoding = text_lines(path, raw)
    track = _read_text(path, lines, options)
    if encoding != "utf-8":  # say it: a wrong guess shows in the column names
        track.mapping += f" (the text is not UTF-8: decoded as Windows {encoding})"
    return track


def _read_text(path, lines, options):
    """A text file's track, from its ``lines``, its format found or named in ``options``."""
    from . import imagej, sensors, tracker
    from .table import MAX_LINE_CHARACTERS, SEPARATORS, read_table, split, track_from_table

    # a mapping given is applied, to dropfit's own columns too (named wrongly, it is refused, not ignored)
    if options.format == "dropfit" or options.format is None and (
            max(map(len, lines[:50]), default=0) > MAX_LINE_CHARACTERS
            or _is_native(lines) and not options.columns):
        return _native(path)
    if options.format == "mtrack2" or options.format is None and imagej.is_mtrack2(lines):
        return _finished(path, imagej.read_mtrack2(path, lines, options))
    if options.format == "trackmate" or options.format is None and imagej.is_trackmate(lines):
        return _finished(path, imagej.read_trackmate(path, lines, options))
    if options.format in (None, "tracker") and tracker.track_groups(lines):
        return _finished(path, tracker.read_tracks_table(path, lines, options))
    try:
        table = read_table(path, lines)
    except InputError:
        if len(lines) == 1 and any(character.isalpha() for character in lines[0]) and any(
                len(split(lines[0], separator)) >= 2 for separator in SEPARATORS):  # names, not numbers
            raise InputError(f"{shown_path(path)}: the header is there but there are no samples") from None
        if options.format is None:
            return _native(path)  # its own checks say best what is wrong with a file that is no table
        raise
    if options.format == "tracker" or options.format is None and _is_tracker_table(table):
        return _finished(path, tracker.read_data_table(table, options))
    columns = table.columns()
    if options.format in ("vernier", "pasco", "phyphox") or any(column.run for column in columns):
        named = options.format or ("pasco" if any(c.run and c.run.lower().startswith("run") and c.header.endswith(c.run)
                                                  for c in columns) else "vernier")
        return _finished(path, sensors.read_sensor_table(table, named, options))
    track = track_from_table(table, options.format or "csv", options, y_up=options.format != "motion-detector")
    return _finished(path, track)


def _is_tracker_project(path, raw):
    suffix = Path(path).suffix.lower()
    if suffix == ".trk" or raw.lstrip()[:200].startswith(b"<?xml") and b"opensourcephysics.cabrillo" in raw[:4096]:
        return True
    if raw.startswith(b"PK\x03\x04"):
        if suffix == ".trz":
            return True
        try:
            with zipfile.ZipFile(io.BytesIO(raw)) as archive:
                return any(name.lower().endswith(".trk") for name in archive.namelist())
        except ZIP_ERRORS:
            return False
    return False


def _is_tracker_table(table):
    """Whether a table is Tracker's data export: ``t`` first (or after Tracker's ``step`` or ``frame``), then
    ``x`` or ``y``, after a line naming the track or separated by tabs (Tracker's default)."""
    names = [field.strip().lower() for field in table.header]
    if names[:1] in (["step"], ["frame"]):
        names = names[1:]
    return names[:1] == ["t"] and bool({"x", "y"} & set(names[1:])) and (
        bool(table.preamble) or table.separator == "\t")


def _is_native(lines):
    """Whether the first line is a dropfit height log's header (``time_s``/``time_ms`` and ``y_…``, commas)."""
    if not lines:
        return True  # the height log's checks say what is missing
    header = [field.strip().strip('"').strip() for field in lines[0].split(",")]
    return len(header) >= 2 and any(f in ("time_s", "time_ms") for f in header) and any(
        f.startswith("y_") for f in header) or lines[0].lstrip().startswith(("<", "{", "["))


def _native(path):
    from ..heightlog import MAX_ABS_HEIGHT_M, read_height_log

    time, height, unit, x, x_unit = read_height_log(path, horizontal=True, exact_repeats=True)
    if x is not None and x_unit != unit:
        if x_unit == "px":
            raise InputError(f"{shown_path(path)}: column x_px needs a scale, but the heights are not in px; give x in "
                             f"m, cm or mm")
        if unit == "px":
            raise InputError(f"{shown_path(path)}: the heights are in px but x in {x_unit}; give x in px too")
        farthest = float(np.nanmax(np.abs(x), initial=0.0)) * LENGTH_UNITS_M[x_unit]
        if farthest > MAX_ABS_HEIGHT_M:
            raise InputError(f"{shown_path(path)}: column x_{x_unit} reaches {farthest:.3g} m from its zero (more "
                             f"than {MAX_ABS_HEIGHT_M:g} m); check its unit in the column name, or subtract the offset")
        x = x * LENGTH_UNITS_M[x_unit] / LENGTH_UNITS_M[unit]
    return _finished(path, ImportedTrack(time, height, unit, "dropfit",
                                         f"read {shown_path(path)} as a dropfit height log [{unit}]", x=x))


def _finished(path, track):
    """The track checked (:func:`checked_track`), a duplicated video frame taken out
    (:func:`drop_repeated_positions`), its lengths in a unit the trajectory path converts."""
    track = drop_repeated_positions(checked_track(path, track))
    if track.unit not in _TRAJECTORY_UNITS:
        metres = LENGTH_UNITS_M[track.unit]
        track = dataclasses.replace(track, y=track.y * metres, x=None if track.x is None else track.x * metres,
                                    unit="m")
    return track


__all__ = ["FORMATS", "ImportOptions", "ImportedTrack", "read_track"]
