"""Sensor exports: Vernier Logger Pro / Graphical Analysis, PASCO Capstone, phyphox, and motion detectors.

These are tables (:mod:`.table`) whose columns name their unit in brackets, ``Time (s)``,
``Position (m)``; Logger Pro names each run in front (``Run 1: Time (s)``, ``Latest: Time (s)``),
Capstone behind (``Time (s) Run #1``). A file of several runs is read one run at a time
(``--track-id N``: run N).

phyphox's CSV export (all but its "minimalistic" variant) is a zip: one ``<set>.csv`` per data set of
the experiment, quoted headers, numbers as ``1.234567890E-1`` (with a decimal comma in the semicolon
variant), ``NaN`` where a column is shorter, and ``meta/device.csv``, ``meta/time.csv`` beside them
(its source, ``DataExport.java``). :func:`phyphox_sets` opens it; :func:`phyphox_position_set` picks
the set that holds a length.

A motion detector measures the distance *down* from the sensor to the ball. With the sensor's height
(``--sensor-height-m``) the height is that height minus the distance. Without it the direction is
found from the bounces (they point towards the floor), and the distance at which the ball comes to
rest, the longest plateau at the largest distances, is the zero of the heights.
"""

from __future__ import annotations

import dataclasses
import io
import re
import zipfile

import numpy as np

from ..errors import InputError, shown_path
from ..files import MAX_ARCHIVE_MEMBER_BYTES, ZIP_ERRORS, read_archive_member
from .base import LENGTH_UNITS_M
from .table import track_from_table

#: The folder of phyphox's zipped export that holds its metadata, not data sets.
PHYPHOX_META_FOLDER = "meta/"
#: A column holding a length: its unit in brackets, as phyphox names columns (``Distance (m)``).
_LENGTH_COLUMN = re.compile(r"\((?:m|cm|mm)\)", re.IGNORECASE)

#: A plateau of the distance (the ball at rest on the floor) lies within this of the largest distance, m.
REST_TOLERANCE_M = 0.005
#: ... and lasts at least this long, s.
MIN_REST_S = 0.2


def height_from_distance(path, track, sensor_height_m=None):
    """A track of distances from a sensor (any length unit) → heights in m, up.

    Parameters
    ----------
    path : str
        The file, for messages.
    track : dropfit.importers.ImportedTrack
        The distances (``y``) in their unit.
    sensor_height_m : float, optional
        The sensor's height above the floor, m: the height is this minus the distance.
    """
    from ..analysis import vertical_sign
    from .base import checked_track

    track = checked_track(path, track)  # a missing time refused before the bounces are looked for
    if track.unit == "px":
        raise InputError(f"{shown_path(path)}: a distance from a sensor in px cannot be a height; give it in m, cm or mm")
    distance = track.y * LENGTH_UNITS_M[track.unit]
    if sensor_height_m is not None:
        finite = distance[np.isfinite(distance)]
        farthest = float(np.percentile(finite, 99.5)) if finite.size else 0.0  # (a stray reading left out)
        if farthest > sensor_height_m + REST_TOLERANCE_M:
            raise InputError(f"{shown_path(path)}: the distances reach {farthest:.3g} m, more than the sensor height "
                             f"{sensor_height_m:g} m given: the ball would be below the floor; give the sensor's "
                             f"height above the floor with --sensor-height-m, or leave it out to take the floor "
                             f"where the ball comes to rest")
        note = f"height = sensor height {sensor_height_m:g} m − distance"
        return dataclasses.replace(track, y=sensor_height_m - distance, unit="m", notes=track.notes + [note])
    if vertical_sign(track.time_s, distance) > 0:  # the bounces point up: it is a height already
        return dataclasses.replace(track, y=distance, unit="m",
                                   notes=track.notes + ["read as a height: its bounces point up"])
    rest = rest_level(track.time_s, distance)
    zero = rest if rest is not None else 0.0
    note = (f"distance down from the sensor: height = {rest:.4g} m (where the ball comes to rest) − distance"
            if rest is not None else "distance down from the sensor: height = − distance (no rest position in view)")
    return dataclasses.replace(track, y=zero - distance, unit="m", notes=track.notes + [note])


def rest_level(time_s, distance_m):
    """The distance in m at which the ball lies at rest (the longest run of samples within
    :data:`REST_TOLERANCE_M` of the largest distances, at least :data:`MIN_REST_S` long), or None."""
    finite = np.isfinite(distance_m)
    if not finite.any():
        return None
    far = float(np.percentile(distance_m[finite], 99.5))
    near = finite & (np.abs(distance_m - far) <= REST_TOLERANCE_M)
    best, start = None, None
    for index in range(near.size + 1):
        if index < near.size and near[index]:
            start = index if start is None else start
            continue
        if start is not None:
            if best is None or time_s[index - 1] - time_s[start] > time_s[best[1] - 1] - time_s[best[0]]:
                best = (start, index)
            start = None
    if best is None or time_s[best[1] - 1] - time_s[best[0]] < MIN_REST_S:
        return None
    return float(np.median(distance_m[best[0]: best[1]]))


def runs_of(table):
    """The runs a table's columns name (Logger Pro's ``Run 1:``, Capstone's ``Run #1``), in order."""
    runs = []
    for column in table.columns():
        if column.run is not None and column.run not in runs:
            runs.append(column.run)
    return runs


def read_sensor_table(table, format_name, options):
    """A Logger Pro, Capstone or phyphox table → :class:`dropfit.importers.ImportedTrack` of one run."""
    runs = [run for run in runs_of(table) if any(c.role == "time" and c.run == run for c in table.columns())]
    run = None
    if len(runs) > 1 or options.track_id is not None and runs:
        if options.track_id is None:
            raise InputError(f"{shown_path(table.path)}: holds {len(runs)} runs ({', '.join(runs)}); choose one with "
                             f"--track-id N (the run's number)")
        wanted = [r for r in runs if re.search(rf"(?<!\d){options.track_id}(?!\d)", r)]
        if len(wanted) != 1:
            raise InputError(f"{shown_path(table.path)}: no run {options.track_id} among {', '.join(runs)}; choose "
                             f"one with --track-id N")
        run = wanted[0]
        table = _rows_with_time(table, run)
    elif runs:
        run = runs[0]
    track = track_from_table(table, format_name, options, run=run)
    if run is not None:
        track.mapping += f" (run '{run}')"
    return track


def _rows_with_time(table, run):
    """``table`` without the rows where ``run`` has no time (a shorter run's blank tail)."""
    index = next(i for i, column in enumerate(table.columns()) if column.role == "time" and column.run == run)
    times = table.numbers(index)
    return dataclasses.replace(table, rows=[row for row, time in zip(table.rows, times) if np.isfinite(time)])


def phyphox_sets(raw, path=""):
    """The data sets of phyphox's zipped CSV export, ``{set name: bytes of its CSV}``; None when ``raw``
    (a file's bytes) is not such an export (not a zip, or a zip without phyphox's ``meta/`` folder).
    InputError for a set larger than :data:`dropfit.files.MAX_ARCHIVE_MEMBER_BYTES` (``path`` names the file)."""
    if not raw.startswith(b"PK\x03\x04"):
        return None
    try:
        with zipfile.ZipFile(io.BytesIO(raw)) as archive:
            names = archive.namelist()
            if not any(name.startswith(PHYPHOX_META_FOLDER) for name in names):
                return None
            sets, left = {}, MAX_ARCHIVE_MEMBER_BYTES  # (the bound holds for all the sets together)
            for name in names:
                if name.lower().endswith(".csv") and not name.startswith(PHYPHOX_META_FOLDER):
                    sets[name[:-len(".csv")]] = read_archive_member(
                        path, archive, name, "record only the drops (a shorter run) and export again", left)
                    left -= len(sets[name[:-len(".csv")]])
            return sets
    except ZIP_ERRORS:
        return None


def phyphox_position_set(path, sets):
    """The one data set of a phyphox export (:func:`phyphox_sets`) with a length column (m, cm or mm),
    as bytes of CSV; InputError when there is none or several."""
    lengths = [name for name, raw in sets.items()
               if _LENGTH_COLUMN.search(raw.split(b"\n", 1)[0].decode("utf-8", "replace"))]
    if len(lengths) == 1:
        return sets[lengths[0]]
    listed = ", ".join(sorted(sets)) or "none"
    if not lengths:
        raise InputError(f"{shown_path(path)}: this phyphox export holds no set with a position or distance in m, cm "
                         f"or mm (sets: {listed}); export the experiment that measures the ball's height")
    raise InputError(f"{shown_path(path)}: this phyphox export holds several sets with a length ({', '.join(lengths)});"
                     f" export only the one with the ball's height (phyphox: Export data, choose the set)")
