"""Any CSV or text table: the separator, the decimal mark, the header and its units, found from the content.

A table is lines of fields. The separator is the one of comma, semicolon, tab, vertical bar or
spaces that splits the header and the data rows into the same number of fields; with a semicolon,
tab or spaces between the fields, ``1,25`` is a decimal comma (a European spreadsheet). A UTF-8
byte-order mark is ignored. Lines before the header (a track name, ``Tracks 1 to 3``, a run name)
are kept as its preamble; text rows right after the header (TrackMate's short names and units) are
skipped, a row of units read.

A column's unit is in its name: ``height_m``, ``Position (m)``, ``y [cm]``, ``Zeit/s``. Its role
(time, frame, height, horizontal position, a sensor's distance) is guessed from the rest of the name,
in several languages; ``--columns time=COL,y=COL[,x=COL]`` names them where the guess fails.
"""

from __future__ import annotations

import csv
import re
import shlex
from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError, shown, shown_path
from ..files import decoded_text
from .base import LENGTH_UNITS_M, TIME_UNITS_S, ImportedTrack, frame_times, quoted, \
    unique_frames

#: A line longer than this, characters, is not a table's (a height log's checks refuse it, quickly).
MAX_LINE_CHARACTERS = 16384
SEPARATORS = {",": "commas", ";": "semicolons", "\t": "tabs", "|": "vertical bars", " ": "spaces"}
#: Names (lower case, without unit) of each role, in English, German, French, Spanish, Italian, Dutch.
ROLE_NAMES = {
    "time": {"t", "time", "zeit", "temps", "tiempo", "tempo", "tijd", "elapsed time", "timestamp", "position t",
             "time elapsed", "relative time"},
    "frame": {"frame", "frames", "frame number", "frame nr", "frame no", "frame #", "slice", "image", "step"},
    "y": {"y", "height", "h", "höhe", "hoehe", "hauteur", "altura", "altezza", "hoogte", "y position", "position y",
          "pos y", "y pos", "vertical position", "ball height", "height of ball", "elevation", "y1"},
    "x": {"x", "x position", "position x", "pos x", "x pos", "horizontal position", "x1"},
    "distance": {"position", "distance", "dist", "range", "abstand", "entfernung", "distance from sensor",
                 "sonar distance", "ultrasonic distance"},
}
ROLE_WORDS = {"time": "time", "frame": "frame", "y": "height", "x": "horizontal position",
              "distance": "position (or distance from a sensor)"}
#: Units as people write them, to the names of :data:`TIME_UNITS_S` and :data:`LENGTH_UNITS_M`.
UNIT_ALIASES = {"sec": "s", "secs": "s", "second": "s", "seconds": "s", "msec": "ms", "millisecond": "ms",
                "milliseconds": "ms", "μs": "us", "minutes": "min", "pixel": "px", "pixels": "px", "pix": "px",
                "meter": "m", "meters": "m", "metre": "m", "metres": "m", "centimeter": "cm", "millimeter": "mm",
                "inch": "in", "inches": "in", '"': "in", "feet": "ft", "foot": "ft", "µm": "um", "micron": "um",
                "microns": "um"}
_UNIT_IN_BRACKETS = re.compile(r"^(?P<name>.*?)\s*[\(\[\{]\s*(?P<unit>[^\)\]\}]*?)\s*[\)\]\}](?P<rest>.*)$")
_RUN_PREFIX = re.compile(r"^(?P<run>[^:]{1,40}):\s*(?P<name>.+)$")
_RUN_SUFFIX = re.compile(r"^(?P<name>.+?)\s+(?P<run>run\s*#?\s*\d+)\s*$", re.IGNORECASE)
_DECIMAL_COMMA = re.compile(r"^[-+]?\d*,\d+(?:[eE][-+]?\d+)?$")


@dataclass
class Column:
    """One column's header split into its parts: ``Run 1: Position (m)`` → run ``Run 1``, name ``position``,
    unit ``m``."""

    header: str
    name: str
    unit: str | None
    run: str | None

    @property
    def role(self):
        """``time``, ``frame``, ``y``, ``x``, ``distance`` or None."""
        return next((role for role, names in ROLE_NAMES.items() if self.name in names), None)


@dataclass
class Table:
    """A text table as read: the header, the data cells (text), what came before the header and a row of units."""

    path: str
    header: list
    rows: list
    separator: str
    decimal_comma: bool = False
    preamble: list = field(default_factory=list)
    units_row: list | None = None

    def columns(self):
        """:class:`Column` of each header field (the units row's unit where the header has none)."""
        parsed = [parse_column(name) for name in self.header]
        if self.units_row:
            for column, unit in zip(parsed, self.units_row):
                if column.unit is None and normal_unit(unit):
                    column.unit = normal_unit(unit)
        return parsed

    def numbers(self, index, what=None):
        """Column ``index`` as floats, NaN for an empty cell; InputError for text that is not a number."""
        values = np.full(len(self.rows), np.nan)
        for row_number, row in enumerate(self.rows):
            text = row[index].strip().strip('"').strip() if index < len(row) else ""
            if not text or text.lower() in ("nan", "na", "n/a", "-", "--", "null", "none"):
                continue
            if self.decimal_comma:
                text = text.replace(",", ".")
            try:
                values[row_number] = float(text)
            except ValueError:
                hint = " (decimal commas with commas between the columns: save it with semicolons between them)" \
                    if self.separator == "," and _DECIMAL_COMMA.match(text) else ""
                raise InputError(f"{shown_path(self.path)}: column '{shown(what or self.header[index], 30)}' has a "
                                 f"value that is not a number in data row {row_number + 1} ('{shown(text)}'){hint}") \
                    from None
        return values


#: A time of day or a timecode, as Kinovea writes time: ``m:ss``, ``h:mm:ss`` with decimals of a second, or
#: ``h:mm:ss:ff`` (ff: frames).
_CLOCK = re.compile(r"^(\d+):(\d{1,2})(?::(\d{1,2}))?(?:[.,](\d+)|:(\d{1,3}))?$")


def clock_seconds(path, texts, what, fps=None):
    """Times written as a clock (:data:`_CLOCK`) → s, or None when ``texts`` are not all clock times.

    ``h:mm:ss:ff`` counts frames after the seconds: it needs ``fps`` (frames/s), else InputError.
    """
    matches = [_CLOCK.match(text.strip().strip('"').strip()) for text in texts if text.strip().strip('"').strip()]
    if not matches or not all(matches) or not any(":" in m.group(0) for m in matches):
        return None
    seconds = []
    for match in matches:
        first, second, third, fraction, frame = match.groups()
        hours, minutes, whole = (int(first), int(second), int(third)) if third is not None else \
            (0, int(first), int(second))
        value = 3600 * hours + 60 * minutes + whole + (float(f"0.{fraction}") if fraction else 0.0)
        if frame is not None:
            if not fps:
                raise InputError(f"{shown_path(path)}: the time column '{shown(what, 30)}' is a timecode with frames "
                                 f"(h:mm:ss:ff); give the frame rate with --fps")
            value += int(frame) / fps
        seconds.append(value)
    return np.array(seconds)


def normal_unit(text):
    """A unit's name as :data:`TIME_UNITS_S` and :data:`LENGTH_UNITS_M` spell it (``px`` too), or None."""
    unit = str(text).strip().strip("\"'()[]").strip()
    unit = UNIT_ALIASES.get(unit.lower(), unit)
    folded = unit.lower() if unit not in ("µs",) else unit
    return folded if folded in TIME_UNITS_S or folded in LENGTH_UNITS_M or folded == "px" else None


def parse_column(header):
    """:class:`Column` of a header field: its run, its name (lower case, spaces for ``_``) and unit."""
    text = header.strip().strip('"').strip().removeprefix("\ufeff")
    run = None
    suffix = _RUN_SUFFIX.match(text)
    if suffix:
        text, run = suffix["name"], suffix["run"]
    prefix = _RUN_PREFIX.match(text)
    if prefix and not _UNIT_IN_BRACKETS.match(prefix["run"]):
        run, text = prefix["run"].strip(), prefix["name"]
    unit = None
    bracket = _UNIT_IN_BRACKETS.match(text)
    if bracket and normal_unit(bracket["unit"]):
        text, unit = (bracket["name"] + bracket["rest"]).strip(), normal_unit(bracket["unit"])
    elif "/" in text and normal_unit(text.rsplit("/", 1)[1]):  # Zeit/s, the German way
        text, unit = text.rsplit("/", 1)[0], normal_unit(text.rsplit("/", 1)[1])
    else:
        words = re.split(r"[_\s]+", text.strip())
        if len(words) > 1 and normal_unit(words[-1]):  # height_m, time s
            text, unit = " ".join(words[:-1]), normal_unit(words[-1])
        elif len(words) > 2 and words[-2].lower() == "in" and normal_unit(words[-1]):
            text, unit = " ".join(words[:-2]), normal_unit(words[-1])
    name = re.sub(r"[_\s]+", " ", text).strip().lower().rstrip(":").strip()
    return Column(header.strip(), name, unit, run)


def _is_number(text, decimal_comma=False):
    text = text.strip().strip('"').strip()
    if decimal_comma:
        text = text.replace(",", ".")
    try:
        float(text)
    except ValueError:
        return False
    return True


def split(line, separator):
    """The fields of one line (spaces: any run of whitespace; a quoted field may hold the separator)."""
    if separator == " ":
        return line.split()
    try:
        return next(csv.reader([line], delimiter=separator), [])
    except csv.Error:  # a field over the csv module's limit: a line :func:`read_table` refuses
        return line.split(separator)


def text_lines(path, raw):
    """The non-blank lines of a text file (``#`` comments kept out), and its encoding
    (:func:`dropfit.files.decoded_text`: UTF-8, else Windows-1252)."""
    text, encoding = decoded_text(raw)
    lines = [line.rstrip("\r\n") for line in text.splitlines() if line.strip() and not line.lstrip().startswith("#")]
    return lines, encoding


def _numeric_share(fields, decimal_comma):
    filled = [field for field in fields if field.strip()]
    return sum(_is_number(field, decimal_comma) for field in filled) / max(len(filled), 1)


def _trimmed(fields, width):
    """A header's ``fields`` without empty ones past the data's ``width`` (a header ending in a separator, as
    MTrack2 writes it)."""
    return fields[:width] if not any(field.strip() for field in fields[width:]) else fields


def _filled(fields):
    """How many of ``fields`` are not blank."""
    return sum(bool(field.strip().strip('"').strip()) for field in fields)


def _with_units(fields):
    """How many of ``fields`` name a column with its unit (``Time (s)``, ``height_m``), not a bare unit."""
    return sum(parse_column(field).unit is not None and normal_unit(field) is None for field in fields)


def _layout(lines, separator):
    """(header index, data start, decimal comma, data rows, data end, numbers) of ``lines`` split by
    ``separator``, or None.

    The data are the longest run of rows, mostly numbers, of two fields or more (of two equally long, the
    one with more numbers: decimal commas or not); the header is the first of the text rows of the same
    width right above them (the others: short names, units), not counting, above a header, a title padded
    with separators or a line that names no column with a unit over one whose names carry units.
    """
    best = None
    split_lines = [split(line, separator) for line in lines]
    for decimal_comma in ((False, True) if separator != "," else (False,)):
        numeric = [len(fields) >= 2 and _numeric_share(fields, decimal_comma) >= 0.5 for fields in split_lines]
        start = 0
        while start < len(lines):
            if not numeric[start]:
                start += 1
                continue
            end = start
            while end < len(lines) and numeric[end]:
                end += 1
            width = max(len(split_lines[i]) for i in range(start, end))
            header = None
            for above in range(start - 1, -1, -1):
                if len(_trimmed(split_lines[above], width)) != width or header is not None and (
                        _filled(split_lines[above]) == 1 < _filled(split_lines[header])
                        or _with_units(split_lines[above]) == 0 < _with_units(split_lines[header]) - 1):
                    # a title padded with separators (Tracker's track name), or a line of notes ("Experiment,Drop
                    # 3") over a header whose names carry their units
                    break
                header = above
            numbers = sum(_is_number(f, decimal_comma) for fields in split_lines[start:end] for f in fields)
            if header is not None and (best is None or (end - start, numbers) > (best[3], best[5])):
                best = (header, start, decimal_comma, end - start, end, numbers)
            start = end
    return best


def read_table(path, lines):
    """Split ``lines`` into a :class:`Table`: the separator, decimal mark, header and data found.

    Raises
    ------
    InputError
        When no separator splits a header and rows of numbers alike.
    """
    longest = max(range(len(lines)), key=lambda i: len(lines[i]), default=None)
    if longest is not None and len(lines[longest]) > MAX_LINE_CHARACTERS:
        raise InputError(f"{shown_path(path)}: line {longest + 1} of its table is {len(lines[longest])} characters "
                         f"long, more than the {MAX_LINE_CHARACTERS} a table's line may be (MAX_LINE_CHARACTERS); "
                         f"give a table of one sample per line, with fewer columns")
    if not lines:
        raise InputError(f"{shown_path(path)}: holds no line of text (only blanks or # comments); give a CSV file with "
                         f"a header line, such as time_s,y_m, and a sample per line")
    found = {}
    for separator in SEPARATORS:
        if separator == " " and any(sep in lines[0] for sep in ",;\t|"):
            continue
        layout = _layout(lines, separator)
        if layout is not None:
            found[separator] = layout
    if not found:
        first = shown(lines[0], 40) if lines else ""
        raise InputError(f"{shown_path(path)}: no table of numbers under a header found (first line '{first}'); "
                         f"give a CSV file with a header line, such as time_s,y_m")
    # the separator whose table is the longest, and widest among those
    separator = max(found, key=lambda sep: (found[sep][3], len(split(lines[found[sep][0]], sep)),
                                            -list(SEPARATORS).index(sep)))
    header_index, start, decimal_comma, _, end, _ = found[separator]
    rows = [split(line, separator) for line in lines[start:end]]
    header = [field.strip().strip('"').strip()
              for field in _trimmed(split(lines[header_index], separator), max(map(len, rows)))]
    between = [split(line, separator) for line in lines[header_index + 1: start]]
    units_row = next((fields for fields in between if sum(normal_unit(f) is not None for f in fields) >= 2), None)
    return Table(str(path), header, rows, separator, decimal_comma, lines[:header_index], units_row)


def parse_mapping(path, text):
    """``--columns time=COL,y=COL[,x=COL]`` → {role: (column name, unit or None)}."""
    mapping = {}
    for part in re.split(r",(?![^\[]*\])", str(text)):
        if not part.strip():
            continue
        role, _, column = part.partition("=")
        role = {"height": "y", "t": "time", "distance": "distance"}.get(role.strip().lower(), role.strip().lower())
        if role not in ROLE_WORDS or not column.strip():
            raise InputError(f"{shown_path(path)}: --columns '{shown(text)}' is not a mapping such as "
                             f"time=t[s],y=height[cm] (roles: time or frame, y or distance, x)")
        unit = None
        match = re.match(r"^(?P<name>.*?)\s*\[(?P<unit>[^\]]*)\]\s*$", column.strip())
        if not match and re.search(r"[\[\]]", column):  # a unit with text after it, or a bracket unclosed
            raise InputError(f"{shown_path(path)}: --columns '{shown(text)}' is not a mapping such as "
                             f"time=t[s],y=height[cm]: '{shown(column.strip(), 30)}' has text after its [unit] or an "
                             f"unclosed bracket")
        if match:
            column, unit = match["name"], normal_unit(match["unit"])
            if unit is None:
                raise InputError(f"{shown_path(path)}: --columns names the unit '{shown(match['unit'])}', not one "
                                 f"dropfit reads (s, ms, m, cm, mm, in, ft, px)")
        mapping[role] = (column.strip(), unit)
    return mapping


def named_column(path, columns, name, role):
    """Index of the column ``name`` among ``columns`` (:class:`Column`): its header as written, its name without
    unit, or its 1-based number; InputError naming ``path``, the ``role`` and the columns when none is."""
    for index, column in enumerate(columns):
        if name in (column.header, column.name) or name.lower() in (column.header.lower(), column.name):
            return index
    if name.isdigit() and 1 <= int(name) <= len(columns):
        return int(name) - 1
    raise InputError(f"{shown_path(path)}: --columns names '{shown(name, 30)}' for the {ROLE_WORDS[role]}, "
                     f"but the columns are {quoted(column.header for column in columns)}")


def choose_columns(table, columns, mapping=None, run=None):
    """{role: index} of the columns to read: as ``mapping`` names them, else guessed by their names.

    Raises InputError when the height (or time) column cannot be told, or several could be it.
    """
    name = shown_path(table.path)
    if mapping:
        if not {"time", "frame"} & mapping.keys() or not {"y", "distance"} & mapping.keys():
            missing = "time (time=COL[s])" if not {"time", "frame"} & mapping.keys() else "height (y=COL[m])"
            raise InputError(f"{name}: --columns names no {missing} column; a height log needs both (a table of "
                             f"impact times heard in a sound is read with --kind audio)")
        return {role: named_column(table.path, columns, column, role) for role, (column, _) in mapping.items()}
    chosen = {}
    for role in ROLE_NAMES:
        candidates = [i for i, column in enumerate(columns) if column.role == role and (run is None or column.run == run)]
        if len(candidates) > 1:
            if {columns[i].name for i in candidates} == {role, role + "1"}:  # x and x1: the plain name
                candidates = [i for i in candidates if columns[i].name == role]
            if len(candidates) > 1:
                raise InputError(f"{name}: {len(candidates)} columns could be the {ROLE_WORDS[role]} "
                                 f"({quoted(table.header[i] for i in candidates)}); name one with --columns "
                                 f"time=…,y=…")
        if candidates:
            chosen[role] = candidates[0]
    if "time" not in chosen and "frame" not in chosen:
        raise InputError(f"{name}: cannot tell which column is the time among {quoted(table.header)}; name it with "
                         f"--columns time=COL[s],y=COL[m]")
    if "y" not in chosen and "distance" not in chosen:
        time = columns[chosen.get("time", chosen.get("frame"))].header
        raise InputError(f"{name}: cannot tell which column is the height among {quoted(table.header)}; name it with "
                         f"--columns {shlex.quote(f'time={shown(time, 60)}[s],y=COL[m]')}")
    if "y" in chosen:
        chosen.pop("distance", None)
    return chosen


def describe(path, parts):
    """The one line saying how a file was read: ``read data.csv as time 'Zeit (s)' [s], height 'Höhe (cm)' [cm]``."""
    return f"read {shown_path(path)} as " + ", ".join(parts)


def track_from_table(table, format_name, options, default_time_unit=None, default_length_unit=None,
                     run=None, y_up=True):
    """An :class:`ImportedTrack` from a table: the columns chosen (:func:`choose_columns`), their units, the
    time from a time column or from frame numbers and ``options.fps``.

    Parameters
    ----------
    table : Table
    format_name : str
        The format's name, for the track and the messages.
    options : dropfit.importers.ImportOptions
    default_time_unit, default_length_unit : str, optional
        The unit of a column whose name has none, where the format defines it (Tracker: s and m).
    run : str, optional
        Read only the columns of this run (Logger Pro, Capstone).
    y_up : bool
        Whether a length column points up; a distance from a sensor is turned into a height by
        :func:`dropfit.importers.sensors.height_from_distance`.
    """
    from .sensors import height_from_distance

    name = shown_path(table.path)
    columns = table.columns()
    mapping = parse_mapping(table.path, options.columns) if options.columns else None
    chosen = choose_columns(table, columns, mapping, run)
    units = {role: (mapping or {}).get(role, (None, None))[1] or columns[index].unit for role, index in chosen.items()}
    parts = []
    if "time" in chosen:
        unit = units["time"] or default_time_unit or "s"
        if unit not in TIME_UNITS_S:
            raise InputError(f"{name}: the time column '{shown(table.header[chosen['time']], 30)}' is in {unit}, not a "
                             f"unit of time; name the right column with --columns time=COL[s]")
        texts = [row[chosen["time"]] if chosen["time"] < len(row) else "" for row in table.rows]
        clock = clock_seconds(table.path, texts, table.header[chosen["time"]], options.fps)
        if clock is not None and clock.size == len(table.rows):
            time = clock
            parts.append(f"time '{table.header[chosen['time']]}' [clock, h:mm:ss]")
        else:
            time = table.numbers(chosen["time"]) * TIME_UNITS_S[unit]
            parts.append(f"time '{table.header[chosen['time']]}' [{unit}{'' if units['time'] else ', assumed'}]")
        frames = None
    else:
        frames = table.numbers(chosen["frame"])
        parts.append(f"frame '{table.header[chosen['frame']]}' at {options.fps:g} frames/s" if options.fps else "")
    role = "y" if "y" in chosen else "distance"
    unit = units[role] or default_length_unit
    if unit is None:
        raise InputError(f"{name}: the {ROLE_WORDS[role]} column '{shown(table.header[chosen[role]], 30)}' names no "
                         f"unit; give it with --columns, e.g. {shlex.quote(f'y={shown(table.header[chosen[role]], 60)}[cm]')} "
                         f"(m, cm, mm or px)")
    if unit not in LENGTH_UNITS_M and unit != "px":
        raise InputError(f"{name}: the {ROLE_WORDS[role]} column '{shown(table.header[chosen[role]], 30)}' is in "
                         f"{unit}, not a length; name the height column with --columns y=COL[m]")
    y = table.numbers(chosen[role])
    x = table.numbers(chosen["x"]) if "x" in chosen else None
    parts.append(f"{ROLE_WORDS[role]} '{table.header[chosen[role]]}' [{unit}]")
    if x is not None:
        parts.append(f"horizontal position '{table.header[chosen['x']]}' [{unit}]")
    notes = []
    if frames is not None:
        keep = np.isfinite(frames)
        (frames, y, *rest), note = unique_frames(frames[keep], y[keep], *([x[keep]] if x is not None else []))
        x = rest[0] if rest else None
        notes += [note] if note else []
        time = frame_times(table.path, frames, options.fps, f"its column '{table.header[chosen['frame']]}'")
    track = ImportedTrack(time, y, unit, format_name, describe(table.path, [p for p in parts if p]), x,
                          options.fps if frames is not None else None, notes=notes)
    if role == "distance" or not y_up:
        track = height_from_distance(table.path, track, options.sensor_height_m)
    return track
