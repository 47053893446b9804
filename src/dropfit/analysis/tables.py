"""Column conventions of the analysis tables: every value with its standard error and 95 % interval."""

from __future__ import annotations

from ..restitution import Z95


def se_column_name(column, tag="se"):
    """Name of a column's standard error (or other ``tag``) that keeps the unit suffix last:
    v_in_m_s → v_in_se_m_s, t_contact_ms → t_contact_se_ms, theta_in_deg → theta_in_se_deg."""
    for unit in ("_m_s", "_ms", "_s", "_m", "_deg"):
        if column.endswith(unit):
            return column[: -len(unit)] + f"_{tag}" + unit
    return column + f"_{tag}"


def add_with_interval(table, column, value, se):
    """Add a column, its standard error and its normal 95 % interval (``_ci95_low``/``_ci95_high``)."""
    table[column] = value
    table[se_column_name(column)] = se
    table[se_column_name(column, "ci95_low")] = value - Z95 * se
    table[se_column_name(column, "ci95_high")] = value + Z95 * se
