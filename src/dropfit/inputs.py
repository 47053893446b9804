"""What the fit, report, summary and QC stages read, checked before use.

Each reader returns the file's content, or raises :class:`dropfit.errors.InputError` with one line
that names the file: a failure record gives its own message; a file that is missing, unreadable,
truncated, of another kind (a JSON list where an object belongs) or lacks what the stage needs
says so, instead of failing deep inside the stage with a traceback.
"""

from __future__ import annotations

import json
import numbers

import numpy as np
import pandas as pd

from .errors import InputError, shown, shown_path
from .files import read_json, read_table

#: Keys of the analysis summary (``analysis.json``) that the fit stage reads: name → kind.
ANALYSIS_KEYS = {
    "contact_height_m": "number", "contact_height_se_m": "number", "contact_height_source": "text",
    "drag_model": "text", "drag_k_per_m": "number", "drag_k_se_per_m": "number", "bic_no_drag": "number",
    "bic_quadratic_drag": "number", "noise_m": "number", "drop_apex_time_s": "number", "drop_height_m": "number",
    "drop_height_se_m": "number", "rest_time_s": "number", "gravity_m_s2": "number", "e_covariance": "list",
    "e_contact_covariance": "list", "e_drag_covariance": "list",
}
#: Columns of the impacts table that the fit and report stages read (all numbers; NaN allowed).
IMPACTS_COLUMNS = ["impact", "t_touchdown_s", "v_in_m_s", "v_out_m_s", "e", "e_se", "e_height", "flight_time_ratio",
                   "h_after_m", "h_after_se_m", "t_contact_ms", "t_contact_se_ms", "contact_resolvable"]
#: Columns of the flights table that the report reads.
FLIGHTS_COLUMNS = ["flight", "t_start_s", "t_end_s", "t_apex_s", "y_apex_m"]
#: What a fit result (``fit.json``) must hold for the report and the batch summary: name → kind or
#: nested keys.
FIT_KEYS = {
    "restitution": {"e": {"value": "number", "se": "number", "ci95": "list"}},
    "drag": "object", "itf": {"verdict": "text"}, "drop_height_m": {"value": "number", "se": "number"},
    "theory": {"heights": "list", "total_bouncing_time": "object"}, "contact_time": {"resolvable": "any"},
}
_KINDS = {"number": "a number", "real": "a number", "text": "a text", "list": "a list", "object": "an object", "any": "a value"}


def _kind_of(value):
    """The JSON kind of a decoded value, in words."""
    if value is None:
        return "null"
    if isinstance(value, bool):
        return "true/false"
    if isinstance(value, numbers.Number):
        return "a number"
    if isinstance(value, str):
        return "a text"
    return "a list" if isinstance(value, list) else "an object"


def _fits(value, kind):
    if kind == "any":
        return True
    if kind in ("number", "real"):  # null stands for a number that is not known (JSON has no NaN)
        return (value is None and kind == "number") or (isinstance(value, numbers.Number)
                                                         and not isinstance(value, bool))
    if kind == "text":
        return value is None or isinstance(value, str)
    return isinstance(value, list if kind == "list" else dict)


def check_keys(data, spec, path, what, prefix=""):
    """Raise :class:`InputError` unless the decoded JSON ``data`` is an object with the keys of ``spec``
    (name → kind, or name → nested spec) of the right kinds; ``what`` names the expected file."""
    name = shown_path(path)
    if not isinstance(data, dict):
        if prefix:
            raise InputError(f"{name}: '{shown(prefix.rstrip('.'), 40)}' is {_kind_of(data)}, not an object: this is "
                             f"not {what}")
        preview = "" if data is None or isinstance(data, bool) else f" ({shown(json.dumps(data), 30)})"
        raise InputError(f"{name}: holds {_kind_of(data)}{preview}, not a JSON object: this is not {what}")
    missing = [key for key in spec if key not in data]
    if missing:
        listed = ", ".join(shown(prefix + key, 30) for key in missing[:4]) + (", …" if len(missing) > 4 else "")
        raise InputError(f"{name}: is not {what}: {len(missing)} entr{'y' if len(missing) == 1 else 'ies'} missing "
                         f"({listed}); give the file written by that stage, or run it again")
    for key, kind in spec.items():
        if isinstance(kind, dict):
            check_keys(data[key], kind, path, what, f"{prefix}{key}.")
        elif not _fits(data[key], kind):
            raise InputError(f"{name}: '{shown(prefix + key, 40)}' is {_kind_of(data[key])}, not {_KINDS[kind]}: "
                             f"this is not {what}; run that stage again")
    return data


def _nulls_to_nan(value):
    return [_nulls_to_nan(item) for item in value] if isinstance(value, list) else np.nan if value is None else value


def _matrix(value, shape, key, path, impacts_path):
    """``value`` as a float array of ``shape``, or InputError naming ``key`` of the analysis summary ``path``
    and the impacts table it must match."""
    try:
        array = np.array(_nulls_to_nan(value), dtype=float)
    except (TypeError, ValueError):
        raise InputError(f"{shown_path(path)}: '{key}' is not a table of numbers; run dropfit analyse again") from None
    if array.shape != shape:
        n = shape[0] // 2 if key == "e_contact_covariance" else shape[0]
        raise InputError(f"{shown_path(impacts_path)}: has {n} impacts, but '{key}' of {shown_path(path)} has shape "
                         f"{array.shape}: the files are from different runs; run dropfit analyse again")
    return array


def read_analysis(path):
    """The analysis summary written by ``dropfit analyse``, nulls as NaN, checked for the fit stage."""
    data = check_keys(read_json(path, "analysis summary (analysis.json) written by dropfit analyse"), ANALYSIS_KEYS,
                      path, "an analysis summary written by dropfit analyse")
    attrs = data.get("trajectory_attrs", {})
    if not isinstance(attrs, dict):
        raise InputError(f"{shown_path(path)}: 'trajectory_attrs' is {_kind_of(attrs)}, not an object: this is not "
                         f"an analysis summary written by dropfit analyse")
    return {key: float("nan") if value is None else value for key, value in data.items()}


def read_impacts(path, analysis=None, analysis_path=None):
    """The impacts table written by ``dropfit analyse``; with its ``analysis`` summary, checked against it."""
    table = read_table(path, "impacts table (impacts.csv) written by dropfit analyse")
    name = shown_path(path)
    missing = [column for column in IMPACTS_COLUMNS if column not in table.columns]
    if missing:
        raise InputError(f"{name}: is not an impacts table written by dropfit analyse: {len(missing)} "
                         f"column{'s' if len(missing) > 1 else ''} missing ({', '.join(shown(column, 30) for column in missing[:4])}"
                         f"{', …' if len(missing) > 4 else ''}); run dropfit analyse again")
    if table.empty:
        raise InputError(f"{name}: the impacts table has no rows; run dropfit analyse again")
    _check_numeric(table, IMPACTS_COLUMNS, name)
    if analysis is not None:
        n = len(table)
        for key, shape in (("e_covariance", (n, n)), ("e_contact_covariance", (2 * n, 2 * n)),
                           ("e_drag_covariance", (n,))):
            _matrix(analysis[key], shape, key, analysis_path, path)
    return table


def read_flights(path):
    """The flights table written by ``dropfit analyse``, checked for the report."""
    table = read_table(path, "flights table (flights.csv) written by dropfit analyse")
    name = shown_path(path)
    missing = [column for column in FLIGHTS_COLUMNS if column not in table.columns]
    if missing:
        raise InputError(f"{name}: is not a flights table written by dropfit analyse: columns missing "
                         f"({', '.join(shown(column, 30) for column in missing)}); run dropfit analyse again")
    if table.empty:
        raise InputError(f"{name}: the flights table has no rows; run dropfit analyse again")
    _check_numeric(table, FLIGHTS_COLUMNS, name)
    return table


def _check_numeric(table, columns, name):
    """InputError for the first column of ``columns`` holding a value that is not a number."""
    for column in columns:
        values = table[column]
        if pd.api.types.is_bool_dtype(values) or pd.api.types.is_numeric_dtype(values):
            continue
        if column == "contact_resolvable" and values.astype(str).isin(["True", "False"]).all():
            continue
        numbers_ = pd.to_numeric(values, errors="coerce")
        bad = np.flatnonzero(numbers_.isna().to_numpy() & values.notna().to_numpy())
        if bad.size:
            raise InputError(f"{name}: column {shown(column, 30)} has a value that is not a number in row "
                             f"{bad[0] + 1} ('{shown(values.iloc[bad[0]])}'); run dropfit analyse again")


def read_fit(path):
    """A fit result written by ``dropfit fit``, checked for the report and the batch summary."""
    what = "a fit result written by dropfit fit"
    return check_keys(read_json(path, "fit result (fit.json) written by dropfit fit"), FIT_KEYS, path, what)


def read_report_analysis(path):
    """The analysis summary as the report reads it (contact height, drag, gravity, noise)."""
    data = read_json(path, "analysis summary (analysis.json) written by dropfit analyse")
    attrs = data.get("trajectory_attrs") if isinstance(data, dict) else None
    # a sound recording has no height samples: its noise is null
    sound = isinstance(attrs, dict) and attrs.get("recording_kind") in ("audio", "impact_times")
    keys = dict.fromkeys(("contact_height_m", "drag_k_per_m", "gravity_m_s2") + (() if sound else ("noise_m",)), "real")
    return check_keys(data, keys, path, "an analysis summary written by dropfit analyse")
