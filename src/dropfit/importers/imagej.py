"""ImageJ / Fiji tracking tables: MTrack2 and TrackMate spot tables.

MTrack2 writes one row per frame and three columns per tracked object: ``Frame X1 Y1 Flag1 X2 Y2
Flag2 …`` (tab separated, or saved again with commas, semicolons or spaces), after a line ``Tracks 1
to N`` (or with it as the first data row), and ends with a summary block ``Track  Length  Distance
traveled  Nr of Frames``. A flag is ``*`` where MTrack2 flagged the object (objects met), blank
elsewhere: with spaces between the fields blank flags vanish (:func:`_spaced_table`). The
positions are image px, y growing down; a frame in which an object was not found leaves its cells
blank (or, at the end of a row, absent). Its "Raw Tracks" window saved from ImageJ has no Frame
column (``X1 Y1 Flag1 …``, after the row numbers or without them) and one row per frame: the row
number, or the row's place, is the frame. The table counts frames, so the frame rate is given
(``--fps``).

TrackMate's spot table (Tracks → Export spots to CSV) has one row per spot: ``TRACK_ID``,
``POSITION_X``, ``POSITION_Y``, ``POSITION_T`` and ``FRAME`` among others, possibly followed by three
header rows (names, short names, units). Positions are in the image's unit (``pixel`` unless it was
calibrated), y growing down; ``POSITION_T`` is in the image's time unit (``sec``) or, without one,
the frame is used with ``--fps``.

Each importer reads one track: ``--track-id N``, or the one that moves like a dropped ball
(:func:`dropfit.importers.base.pick_track`).
"""

from __future__ import annotations

import re

import numpy as np

from ..errors import InputError, shown, shown_path
from .base import LENGTH_UNITS_M, TIME_UNITS_S, ImportedTrack, frame_times, pick_track, \
    unique_frames
from .table import Table, describe, normal_unit, read_table

_TRACKS_LINE = re.compile(r"^\s*tracks\s+\d+\s+to\s+\d+\s*$", re.IGNORECASE)
_SUMMARY_LINE = re.compile(r"^\s*track\s*[\t,; ]+\s*length\b", re.IGNORECASE)


#: The header of MTrack2's "Raw Tracks" window saved from ImageJ: no Frame column, ``X1 Y1 Flag1 …`` after an
#: empty name (the row numbers) or first.
_RAW_TRACKS_HEADER = re.compile(r'^\s*(?:"?\s*"?[\t,;]\s*)?"?x1"?[\t,; ]+"?y1"?[\t,; ]+"?flag1"?', re.IGNORECASE)


def is_mtrack2(lines):
    """Whether ``lines`` look like an MTrack2 table (a ``Tracks 1 to N`` line, a ``Frame X1 Y1`` header, or
    the Raw Tracks window's ``X1 Y1 Flag1`` one)."""
    return any(_TRACKS_LINE.match(line.strip('"')) for line in lines[:5]) or any(
        re.match(r"^\s*\"?frame\"?[\t,; ]+\"?x1\"?[\t,; ]+\"?y1\"?", line, re.IGNORECASE)
        or _RAW_TRACKS_HEADER.match(line) for line in lines[:5])


def is_trackmate(lines):
    """Whether ``lines`` look like a TrackMate spot table (``TRACK_ID`` and ``POSITION_Y`` in a header line)."""
    return any("TRACK_ID" in line and "POSITION_Y" in line for line in lines[:5])


def _finish(path, format_name, frames, x, y, options, parts, unit="px"):
    """The chosen track's rows → :class:`ImportedTrack`: repeated frames dropped, times from the frames."""
    order = np.argsort(frames, kind="stable")
    (frames, x, y), note = unique_frames(frames[order], x[order], y[order])
    time = frame_times(path, frames, options.fps, "the table")
    parts.append(f"frames at {options.fps:g} frames/s")
    track = ImportedTrack(time, y, unit, format_name, describe(path, parts), x, options.fps,
                          notes=[note] if note else [])
    return track


def read_mtrack2(path, lines, options):
    """An MTrack2 table → :class:`ImportedTrack` (image px, y down) of one object."""
    name = shown_path(path)
    body = []
    for line in lines:
        if _SUMMARY_LINE.match(line):
            break  # the per-track summary: not positions
        if not _TRACKS_LINE.match(re.sub(r'[\t,;"]', " ", line)):  # alone, or in the first row's Frame cell
            body.append(line)
    table = _spaced_table(path, body) or read_table(path, body)
    header = [field.strip().upper() for field in table.header]
    if "FRAME" in header:
        frames, what = table.numbers(header.index("FRAME"), "Frame"), "MTrack2"
    elif header[:2] == ["", "X1"]:  # the Raw Tracks window saved with its row numbers: one row per frame
        frames, what = table.numbers(0, "row number"), "MTrack2 Raw Tracks, frame = row number,"
    elif header[0] == "X1":  # … saved without them
        frames, what = np.arange(1.0, len(table.rows) + 1), "MTrack2 Raw Tracks, frame = row,"
    else:
        raise InputError(f"{name}: an MTrack2 table needs the header 'Frame X1 Y1 Flag1 …' (or the Raw Tracks "
                         f"window's 'X1 Y1 Flag1 …'), found '{shown(' '.join(table.header), 40)}'")
    tracks = {}
    for index, column in enumerate(header):
        match = re.fullmatch(r"X(\d+)", column)
        if match and f"Y{match[1]}" in header:
            x, y = table.numbers(index), table.numbers(header.index(f"Y{match[1]}"))
            found = np.isfinite(x) & np.isfinite(y) & np.isfinite(frames)
            if found.any():
                tracks[int(match[1])] = (frames[found], x[found], y[found])
    if not tracks:
        raise InputError(f"{name}: the MTrack2 table has no track with positions (columns X1, Y1, …); check the export")
    number = pick_track(path, tracks, options.track_id, "track")
    chosen = "given" if options.track_id is not None else f"the most ball-like of {len(tracks)}"
    track = _finish(path, "mtrack2", *tracks[number], options, [f"{what} track {number} ({chosen}) [px, y down]"])
    if f"FLAG{number}" in header:
        flags = [row[header.index(f"FLAG{number}")].strip().strip('"') if header.index(f"FLAG{number}") < len(row)
                 else "" for row in table.rows]
        flagged = sum(flag == "*" for flag in flags)
        if flagged:
            track.notes.append(f"{flagged} position{'s' if flagged > 1 else ''} of track {number} flagged '*' by "
                               f"MTrack2 (objects met) kept: the analysis leaves out those off the ballistic track")
    return track


def _is_flag(text):
    """Whether a cell of an MTrack2 Flag column: ``*``, empty, or a 0/1 digit."""
    return text in ("", "*", "0", "1") or not _is_float(text)


def _is_float(text):
    try:
        float(text)
    except ValueError:
        return False
    return True


def _spaced_table(path, body):
    """An MTrack2 table whose fields are separated by spaces, as a :class:`~.table.Table` with one cell per
    header field; None for a table with tabs, commas or semicolons (:func:`~.table.read_table` reads those).

    Runs of spaces hide empty cells: a Flag left blank (MTrack2 writes ``*`` only where it flags) and the
    cells of objects past the row's end are absent. A row with three fields per object (after the Frame)
    is read as it is; else each object is its X and Y, and a ``*`` after them is its flag. A row whose
    objects cannot be told apart so (an object lost in mid-row) is refused.
    """
    lines = [line for line in body if line.strip()]
    if not lines or any(separator in lines[0] for separator in ("\t", ",", ";")):
        return None
    header = lines[0].split()
    names = [field.upper() for field in header]
    start = 1 if names[:1] == ["FRAME"] else 0
    groups = (len(names) - start) // 3
    if groups == 0 or [f"{axis}{k}" for k in range(1, groups + 1) for axis in ("X", "Y", "FLAG")] != names[start:]:
        return None
    firsts = [line.split()[0] for line in lines[1:]]
    if start == 0 and firsts and firsts == [str(number) for number in range(1, len(firsts) + 1)]:
        header, start = [""] + header, 1  # the Raw Tracks window saved with its row numbers (no name over them)
    rows = []
    for number, line in enumerate(lines[1:], 1):
        tokens = line.split()
        cells, rest = tokens[:start], tokens[start:]
        if len(rest) % 3 == 0 and all(_is_flag(flag) for flag in rest[2::3]) and \
                all(_is_float(value) for i, value in enumerate(rest) if i % 3 != 2):
            cells += rest
        else:
            while rest:
                if len(rest) < 2 or not (_is_float(rest[0]) and _is_float(rest[1])):
                    raise InputError(f"{shown_path(path)}: MTrack2 row {number} ('{shown(line, 40)}') cannot be split "
                                     f"into X, Y and flag of each object with spaces between them; save the table "
                                     f"with tabs (MTrack2's own format)")
                flag = rest[2] if len(rest) > 2 and not _is_float(rest[2]) else ""
                cells += [rest[0], rest[1], flag]
                rest = rest[3 if flag else 2:]
        if len(cells) > len(header):
            raise InputError(f"{shown_path(path)}: MTrack2 row {number} has {len(cells) - start} cells for "
                             f"{groups} objects; check the table")
        rows.append(cells + [""] * (len(header) - len(cells)))
    return Table(str(path), header, rows, " ")


def read_trackmate(path, lines, options):
    """A TrackMate spot table → :class:`ImportedTrack` of one track (image unit, y turned up for lengths)."""
    name = shown_path(path)
    table = read_table(path, lines)
    header = [field.strip().upper() for field in table.header]
    missing = [column for column in ("TRACK_ID", "POSITION_X", "POSITION_Y") if column not in header]
    if missing:
        raise InputError(f"{name}: a TrackMate spot table needs the columns TRACK_ID, POSITION_X, POSITION_Y and "
                         f"POSITION_T or FRAME; {', '.join(missing)} missing")
    units = {column: normal_unit(str(unit).strip().strip("()")) for column, unit in
             zip(header, table.units_row or [""] * len(header))}
    ids = [row[header.index("TRACK_ID")].strip().strip('"') if header.index("TRACK_ID") < len(row) else ""
           for row in table.rows]
    x, y = table.numbers(header.index("POSITION_X")), table.numbers(header.index("POSITION_Y"))
    time_unit = units.get("POSITION_T")
    use_time = "POSITION_T" in header and time_unit in TIME_UNITS_S
    if use_time:
        order_values = table.numbers(header.index("POSITION_T")) * TIME_UNITS_S[time_unit]
    elif "FRAME" in header:
        order_values = table.numbers(header.index("FRAME"))
    elif "POSITION_T" in header:  # T in frames (no time unit): a frame number
        order_values = table.numbers(header.index("POSITION_T"))
    else:
        raise InputError(f"{name}: the TrackMate table has neither POSITION_T nor FRAME; export the spots again")
    tracks = {}
    for track_id in dict.fromkeys(ids):
        if not track_id.lstrip("-").isdigit():
            continue  # a spot in no track (TrackMate writes None)
        rows = np.array([i for i, value in enumerate(ids) if value == track_id])
        keep = rows[np.isfinite(x[rows]) & np.isfinite(y[rows]) & np.isfinite(order_values[rows])]
        if keep.size:
            tracks[int(track_id)] = (order_values[keep], x[keep], y[keep])
    if not tracks:
        raise InputError(f"{name}: no spot of the TrackMate table belongs to a track (TRACK_ID); track the spots in "
                         f"TrackMate before exporting")
    number = pick_track(path, tracks, options.track_id, "TRACK_ID")
    values, x, y = tracks[number]
    unit = units.get("POSITION_Y") or "px"
    if unit not in LENGTH_UNITS_M and unit != "px":
        raise InputError(f"{name}: the TrackMate positions are in '{shown(unit)}', not a length dropfit reads; "
                         f"calibrate the image in px, mm, cm or m")
    if unit != "px":
        y = -y  # image rows point down; a length in the trajectory points up
    parts = [f"TrackMate TRACK_ID {number} ({'given' if options.track_id is not None else f'of {len(tracks)}'})",
             f"positions [{unit}{', y down' if unit == 'px' else ', y turned up'}]"]
    if not use_time:
        return _finish(path, "trackmate", values, x, y, options, parts, unit)
    order = np.argsort(values, kind="stable")
    parts.append("time 'POSITION_T' [s]" if time_unit == "s" else f"time 'POSITION_T' [{time_unit}]")
    return ImportedTrack(values[order], y[order], unit, "trackmate", describe(path, parts), x[order])
