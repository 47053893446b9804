"""Tables of impact times: a CSV of the times a ball was heard to hit the floor, or the export of
phyphox's "(In)elastic collision" or "Acoustic Stopwatch" experiment.

A CSV of times names its unit in the column: ``impact_time_s`` or ``impact_time_ms``, optionally with
``impact_time_se_s`` / ``impact_time_se_ms`` (standard errors); other columns are ignored. Such a table is
told from a height log by these names. A table the user gives as one of impact times (kind ``audio``) may
name its time column otherwise, with its unit (``time (ms)``, ``t [s]``, ``impact time/s``), or have it
mapped (``--columns time=COL[ms]``, as for logs).

phyphox's "(In)elastic collision" experiment exports the set "Energy" with the columns
``Bounce 0 (s)`` … ``Bounce 5 (s)`` (each the time of the loudest sample of a sound above the
threshold), ``Height n (m)`` and ``Energy n``; an impact not heard is 0 or empty. Its "Acoustic
Stopwatch" (the tool lab manuals name for timing a bouncing ball) exports one row per sound heard,
``Event time (s)`` and ``Interval (s)`` (the time since the event before): the event times are the
impacts, told from a height log by that column's name. phyphox writes CSV with
a comma, a tab or a semicolon (then with decimal commas) between the columns; all three are read, as
a CSV or as the zip phyphox exports by default (:func:`dropfit.importers.sensors.phyphox_sets`).
"""

from __future__ import annotations

import io
import re

import numpy as np
import pandas as pd

from ..errors import InputError, shown, shown_path
from ..importers.base import TIME_UNITS_S, quoted
from ..importers.sensors import phyphox_sets
from ..importers.table import named_column, parse_column, parse_mapping
from ..numerics import linear_fit

#: Suffixes a table of impact times may have.
TABLE_SUFFIXES = (".csv", ".tsv", ".txt")
#: The suffix of phyphox's zipped export.
ZIP_SUFFIX = ".zip"
#: Standard error given to times without one when too few of them to measure their scatter, s: the
#: loudest sample of a click (what phyphox and most tools report) lags its onset by a varying fraction
#: of a millisecond to a few (benchmarks/audio_onsets.py measures it).
DEFAULT_TABLE_SE_S = 1.0e-3
_PHYPHOX = re.compile(r"^\s*bounce\s+(\d+)\s*\(s\)\s*$", re.IGNORECASE)
_UNITS = {"impact_time_s": 1.0, "impact_time_ms": 1e-3}
#: The least fall of the logarithm of the intervals per impact a bouncing ball shows (e < 0.999): sample times
#: spaced exactly alike fall or rise by their rounding, ~1e-17, and passed the 3 se test at random.
MIN_SHRINK_PER_IMPACT = 1e-3
#: Names (without their unit) of a column of impact times in a table given as one.
IMPACT_TIME_NAMES = {"impact time", "impact times", "impact", "time of impact", "touchdown", "touchdown time",
                     "bounce time", "time", "t"}


#: The most of a header line looked at to tell a table of impact times from a height log, characters.
HEADER_PEEK_CHARS = 65536
_TIME_COLUMN = re.compile(r"(?:^|[,;\t\"\s])impact_time_m?s(?:[,;\t\"\s]|$)", re.IGNORECASE)
_PHYPHOX_IN_HEADER = re.compile(r"bounce\s+\d+\s*\(s\)", re.IGNORECASE)
#: The column of event times of phyphox's Acoustic Stopwatch export.
_STOPWATCH = re.compile(r"^\s*event\s+time\s*\(s\)\s*$", re.IGNORECASE)
_STOPWATCH_IN_HEADER = re.compile(r"(?:^|[,;\t\"])\s*event\s+time\s*\(s\)\s*(?:[,;\t\"]|$)", re.IGNORECASE)


def _is_impact_header(header):
    """Whether a header line names impact times: ``impact_time_s``/``_ms``, phyphox's ``Bounce n (s)`` or its
    Acoustic Stopwatch's ``Event time (s)``."""
    return bool(_TIME_COLUMN.search(header) or _PHYPHOX_IN_HEADER.search(header) or _STOPWATCH_IN_HEADER.search(header))


def _first_line(lines):
    """The first of ``lines`` (an iterable of text lines) that is not empty or a comment, else ""."""
    return next((line for line in lines if line.strip() and not line.lstrip().startswith("#")), "")


def _header(path, limit=None):
    """The first line that is not empty or a comment (at most ``limit`` characters of it)."""
    try:
        with open(path, "r", encoding="utf-8-sig", errors="replace") as handle:
            return _first_line(iter(lambda: handle.readline(limit or -1), ""))
    except OSError:
        return ""


def _phyphox_impact_set(path):
    """The CSV text of the set of impact times of a zipped phyphox export ("(In)elastic collision" or
    "Acoustic Stopwatch"), or None."""
    try:
        with open(path, "rb") as handle:
            sets = phyphox_sets(handle.read(), path)
    except OSError:
        return None
    texts = (raw.decode("utf-8-sig", "replace") for raw in (sets or {}).values())
    return next((text for text in texts if _PHYPHOX_IN_HEADER.search(_first_line(text.splitlines()))
                 or _STOPWATCH_IN_HEADER.search(_first_line(text.splitlines()))), None)


def is_table_file(path):
    """True if ``path`` may be a table by its suffix (:data:`TABLE_SUFFIXES`, or a phyphox zip)."""
    return str(path).lower().endswith(TABLE_SUFFIXES + (ZIP_SUFFIX,))


def is_impact_table(path):
    """True if ``path`` is a table of impact times (a CSV naming ``impact_time_s``/``_ms``, or a phyphox
    "(In)elastic collision" or "Acoustic Stopwatch" export), judged by its suffix and the start of its
    header line (a height log's header of a million columns is not read whole)."""
    if str(path).lower().endswith(ZIP_SUFFIX):
        return _phyphox_impact_set(path) is not None
    if not str(path).lower().endswith(TABLE_SUFFIXES):
        return False
    return _is_impact_header(_header(path, HEADER_PEEK_CHARS))


def read_impact_table(path, columns=None):
    """Impact times (s) and their standard errors (s; NaN where the table gives none) from a table.

    Parameters
    ----------
    path : str or pathlib.Path
        A CSV of impact times or a phyphox "(In)elastic collision" or "Acoustic Stopwatch" export.
    columns : str, optional
        The column of times where its name does not tell, ``"time=COL[ms]"`` (the unit in brackets,
        or in the column's name).

    Returns
    -------
    (numpy.ndarray, numpy.ndarray, str)
        Times, standard errors, and what the table was (``"phyphox"``, ``"phyphox stopwatch"`` or ``"csv"``).

    Raises
    ------
    dropfit.errors.InputError
        For a table without times, with a time that is not a number, or with times not increasing.
    """
    name = shown_path(path)
    zipped = _phyphox_impact_set(path) if str(path).lower().endswith(ZIP_SUFFIX) else None
    if zipped is None and str(path).lower().endswith(ZIP_SUFFIX):
        raise InputError(f"{name}: is not a phyphox \"(In)elastic collision\" or \"Acoustic Stopwatch\" export (no "
                         f"set with columns 'Bounce n (s)' or 'Event time (s)'); export that experiment, or give its CSV")
    source = path if zipped is None else io.StringIO(zipped)
    header = _header(path) if zipped is None else _first_line(zipped.splitlines())
    separator = ";" if header.count(";") > max(header.count(","), header.count("\t")) else \
        "\t" if header.count("\t") > header.count(",") else ","
    try:
        table = pd.read_csv(source, sep=separator, comment="#", decimal="," if separator == ";" else ".",
                            skipinitialspace=True)
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError, OSError) as error:
        raise InputError(f"{name}: cannot be read as a table of impact times ({type(error).__name__}); export it "
                         f"again as CSV") from None
    table.columns = [str(column).strip() for column in table.columns]
    bounces = {int(match.group(1)): column for column in table.columns if (match := _PHYPHOX.match(column))}
    if bounces:
        if table.empty:
            raise InputError(f"{name}: the phyphox export has no row of times; export the experiment after a drop")
        row = table.iloc[-1]
        values = [pd.to_numeric(row[bounces[number]], errors="coerce") for number in sorted(bounces)]
        times = np.array([value for value in values if np.isfinite(value) and value > 0], dtype=float)
        kind, se = "phyphox", np.full(times.size, np.nan)
    elif not columns and (stopwatch := next((column for column in table.columns if _STOPWATCH.match(column)), None)):
        times = _numbers(table[stopwatch], name, stopwatch)
        kind, se = "phyphox stopwatch", np.full(times.size, np.nan)
    else:
        time_column, unit = _time_column(path, list(table.columns), columns)
        times = _numbers(table[time_column], name, time_column) * TIME_UNITS_S[unit]
        lowered = {column.lower(): column for column in table.columns}
        se_column = time_column.lower().replace("_time_", "_time_se_")
        se = (_numbers(table[lowered[se_column]], name, lowered[se_column]) * TIME_UNITS_S[unit]
              if time_column.lower() in _UNITS and se_column in lowered else np.full(times.size, np.nan))
        kind = "csv"
    if np.any(np.diff(times) <= 0):
        bad = int(np.flatnonzero(np.diff(times) <= 0)[0])
        raise InputError(f"{name}: the impact times do not increase (row {bad + 2} is {times[bad + 1]:g} s after "
                         f"{times[bad]:g} s); sort them, one impact per row")
    if not _intervals_shrink(np.diff(times)):
        # a bouncing ball's flights shrink; a log's sample times (read as impacts, e = 1) do not
        raise InputError(f"{name}: the times are not a bouncing ball's impacts: their intervals do not shrink "
                         f"(their logarithm falls by less than 3 standard errors per impact); a height log is read "
                         f"without --kind audio")
    if np.any(se[np.isfinite(se)] < 0):
        raise InputError(f"{name}: a standard error of an impact time is negative; give it as a positive number")
    return times, se, kind


def _intervals_shrink(intervals):
    """Whether ``intervals`` (s) shrink as a bouncing ball's do: the slope of their logarithm against the impact
    number (ln e, per impact) below 0 by 3 of its standard errors and by :data:`MIN_SHRINK_PER_IMPACT`; fewer
    than three intervals pass."""
    if intervals.size < 3:
        return True
    (_, slope), covariance = linear_fit(np.column_stack([np.ones(intervals.size), np.arange(intervals.size)]),
                                        np.log(intervals))
    return slope < -3 * np.sqrt(covariance[1, 1]) and slope < -MIN_SHRINK_PER_IMPACT


def _time_column(path, headers, columns=None):
    """(header, unit) of the column of impact times among ``headers``: the one ``columns`` maps to time,
    else ``impact_time_s``/``_ms``, else the one column named as a time (:data:`IMPACT_TIME_NAMES`) with its unit.

    Raises InputError naming the columns and the mapping to give when no column, or several, could be it.
    """
    name = shown_path(path)
    parsed = {header: parse_column(header) for header in headers}
    if columns:
        mapping = parse_mapping(path, columns)
        if "time" not in mapping:
            raise InputError(f"{name}: --columns '{shown(columns)}' names no time column; give the impact times' "
                             f"column as time=COL[ms]")
        wanted, unit = mapping["time"]
        header = headers[named_column(path, [parsed[header] for header in headers], wanted, "time")]
        unit = unit or parsed[header].unit
        if unit not in TIME_UNITS_S:
            what = f"is {unit}, not a unit of time" if unit else "is not known"
            raise InputError(f"{name}: the unit of the impact times in '{shown(header, 30)}' {what}; give it: "
                             f"--columns time={shown(parsed[header].name or header, 30)}[ms] (or [s])")
        return header, unit
    lowered = {header.lower(): header for header in headers}
    named = next((column for column in _UNITS if column in lowered), None)
    if named:
        return lowered[named], named.rsplit("_", 1)[1]
    candidates = [header for header, column in parsed.items()
                  if column.name in IMPACT_TIME_NAMES and column.unit in TIME_UNITS_S]
    if len(candidates) == 1:
        return candidates[0], parsed[candidates[0]].unit
    unitless = next((header for header, column in parsed.items() if column.name in IMPACT_TIME_NAMES), None)
    example = f"--columns time={shown(unitless or (headers[0] if headers else 'COL'), 30)}[ms] (or [s])"
    raise InputError(f"{name}: no single column of impact times with its unit among {quoted(headers)}; name it "
                     f"impact_time_s or impact_time_ms, or map it: {example}")


def _numbers(column, name, label):
    """A column's values as floats (empty cells dropped), or InputError naming the first that is not a number."""
    column = column.dropna()
    values = pd.to_numeric(column, errors="coerce")
    if values.isna().any():
        row = int(np.flatnonzero(values.isna().to_numpy())[0])
        raise InputError(f"{name}: column {shown(label, 30)} has a value that is not a number "
                         f"('{shown(column.iloc[row])}'); give times as numbers")
    values = values.to_numpy(dtype=float)
    if not np.all(np.isfinite(values)):
        raise InputError(f"{name}: column {shown(label, 30)} has a value that is not finite; give times as numbers")
    return values
